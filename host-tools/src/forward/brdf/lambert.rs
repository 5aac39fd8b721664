//! Lambertian diffuser: R = rho everywhere (a perfect diffuser reads 1).
use super::{Brdf, BrdfParamError, check};
use nalgebra::Vector3;

/// Lambertian BRDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambertian {
    /// Albedo.
    pub rho: f64,
}

impl Lambertian {
    /// Validated constructor.
    pub fn new(rho: f64) -> Result<Self, BrdfParamError> {
        check("lambertian", "rho", rho, 0.0, 1.0, "must be in [0, 1]")?;
        Ok(Self { rho })
    }
    /// The white standard.
    pub fn perfect() -> Self {
        Self { rho: 1.0 }
    }
}

impl Brdf for Lambertian {
    fn f_r(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> f64 {
        if wi.z <= 0.0 || wo.z <= 0.0 { 0.0 } else { self.rho / std::f64::consts::PI }
    }
}
