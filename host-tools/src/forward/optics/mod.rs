//! Optics: the instrument's geometry -> the rays that reach a surface point ->
//! the system matrix H (m x n) and simulated readings.
//!
//! Each illumination is a cluster of point sources on a small plane facing the
//! point (the near-field light distribution the method is about). A ray's
//! weight is the irradiance of its source, I cos(theta) / r^2; each
//! illumination is normalised so that a perfect diffuser reads 1 (white
//! standard calibration), hence every row of H sums to 1.
//!
//! [`Optics`] is the one place that makes rays. It is prepared for a
//! [`RayModel`] (near or far field, 3-D or in-plane, inverse square, emission
//! profile); a scene (`crate::forward::scene`) builds that model from the effects it
//! lists, and every flag that is off is not computed at all. The original
//! functions [`rays`], [`system_matrix`] and [`simulate_readings`] keep their
//! meaning: near or far field, 3-D, inverse square, isotropic sources.
mod instrument;
mod rays;
mod system_matrix;

pub use instrument::{
    ClusterSpec, EmissionSpec, ExtendedSpec, Instrument, LedSpec, LineAxis, PointSpec, SensorSpec, SourceSpec,
};
pub use rays::{Optics, Ray, RayModel, rays, surface_frame};
pub use system_matrix::{OpticsError, simulate_readings, system_matrix, system_matrix_at};
