//! Gloss readings: what the meter tells its user about a point besides its
//! BRDF vector, defined once here for the device and the host.
//!
//! Each point frame carries [`crate::shape::READINGS`] readings, in this
//! order, and a standard uncertainty for each:
//! - [`SPECULAR_GU`]: specular gloss in gloss units (GU), the black-glass
//!   standard (n = 1.567) reading 100;
//! - [`HAZE_HU`]: haze in haze units (HU), reflection just off the specular
//!   direction on the same black-glass scale;
//! - [`DISTINCTNESS`]: distinctness of the specular peak, in %.
//!
//! A reading of NaN means "no reading": the calibration carries no gloss
//! section, or the point's estimate was not finite.

/// Index of the specular gloss (GU) in a point's readings.
pub const SPECULAR_GU: usize = 0;
/// Index of the haze (HU) in a point's readings.
pub const HAZE_HU: usize = 1;
/// Index of the distinctness (%) in a point's readings.
pub const DISTINCTNESS: usize = 2;
/// Names of the readings in order, as the host's outputs label them.
pub const NAMES: [&str; crate::shape::READINGS] = ["gloss_gu", "haze_hu", "distinctness_pct"];
/// What a point without readings streams.
pub const NO_READINGS: [f32; crate::shape::READINGS] = [f32::NAN; crate::shape::READINGS];
