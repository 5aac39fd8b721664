//! Optics: the instrument's geometry -> the rays that reach a surface point ->
//! the system matrix H (m x n) and simulated readings.
//!
//! Each illumination is a cluster of point sources on a small plane facing the
//! point (the near-field light distribution the method is about). A ray's
//! weight is the irradiance of its source, I cos(theta) / r^2; each
//! illumination is normalised so that a perfect diffuser reads 1 (white
//! standard calibration), hence every row of H sums to 1.
mod instrument;
mod rays;
mod system_matrix;

pub use instrument::{ClusterSpec, Instrument, LedSpec, PointSpec, SourceSpec};
pub use rays::{Ray, rays};
pub use system_matrix::{OpticsError, simulate_readings, system_matrix};
