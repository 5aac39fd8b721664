//! Isotropic Ward model, exactly as method.md states it:
//! f_r = rho_d/pi + rho_s exp(-tan^2(delta)/alpha^2) / (4 pi alpha^2 sqrt(cos th_i cos th_o)),
//! delta = angle between the normal and the half vector.
use super::{Brdf, BrdfParamError, check};
use nalgebra::Vector3;
use std::f64::consts::PI;

/// Isotropic Ward BRDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ward {
    /// Diffuse albedo.
    pub rho_d: f64,
    /// Specular albedo.
    pub rho_s: f64,
    /// Roughness (standard deviation of the surface slope).
    pub alpha: f64,
}

impl Ward {
    /// Validated constructor.
    pub fn new(rho_d: f64, rho_s: f64, alpha: f64) -> Result<Self, BrdfParamError> {
        check("ward", "rho_d", rho_d, 0.0, 1.0, "must be in [0, 1]")?;
        check("ward", "rho_s", rho_s, 0.0, 1.0, "must be in [0, 1]")?;
        check("ward", "alpha", alpha, 1e-4, 1.0, "must be in [1e-4, 1]")?;
        Ok(Self { rho_d, rho_s, alpha })
    }

    /// The patent profile's sample: rho_s = 1 - rho_d.
    pub fn patent(rho_d: f64, alpha: f64) -> Self {
        Self::new(rho_d, 1.0 - rho_d, alpha).expect("patent parameters are valid")
    }

    /// Reflectance factor in-plane from cosines and tan^2 of the half-angle;
    /// shared with the fitting code, which needs it without building vectors.
    pub fn reflectance_from(rho_d: f64, rho_s: f64, alpha: f64, cos_i: f64, cos_o: f64, tan2_delta: f64) -> f64 {
        let a2 = alpha * alpha;
        rho_d + rho_s * (-tan2_delta / a2).exp() / (4.0 * a2 * (cos_i * cos_o).sqrt())
    }
}

impl Brdf for Ward {
    fn f_r(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> f64 {
        let (ci, co) = (wi.z, wo.z);
        if ci <= 0.0 || co <= 0.0 {
            return 0.0;
        }
        let h = wi + wo;
        let tan2 = (h.x * h.x + h.y * h.y) / (h.z * h.z);
        Ward::reflectance_from(self.rho_d, self.rho_s, self.alpha, ci, co, tan2) / PI
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirror_peak_matches_the_closed_form() {
        let w = Ward::patent(0.3, 0.05);
        // At the mirror direction delta = 0: R = rho_d + rho_s / (4 a^2 cos 45).
        let expect = 0.3 + 0.7 / (4.0 * 0.0025 * 45f64.to_radians().cos());
        assert!((w.reflectance(45.0, 45.0) - expect).abs() < 1e-9 * expect);
    }

    #[test]
    fn off_specular_matches_the_in_plane_half_angle() {
        let w = Ward::patent(0.4, 0.08);
        // In-plane, delta = |theta_i - theta_o| / 2.
        let (ti, to) = (37.0f64, 45.0f64);
        let d = ((ti - to) / 2.0).to_radians();
        let expect =
            Ward::reflectance_from(0.4, 0.6, 0.08, ti.to_radians().cos(), to.to_radians().cos(), d.tan().powi(2));
        assert!((w.reflectance(ti, to) - expect).abs() < 1e-12 * expect);
        assert!(w.reflectance(ti, to) < w.reflectance(45.0, 45.0));
    }
}
