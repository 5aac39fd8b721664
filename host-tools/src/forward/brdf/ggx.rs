//! Cook-Torrance microfacet model with the GGX (Trowbridge-Reitz) normal
//! distribution, Smith height-uncorrelated masking and Schlick's Fresnel term.
//! It lies outside the Ward family, so tests can probe a prior's mismatch.
use super::{Brdf, BrdfParamError, check};
use nalgebra::Vector3;
use std::f64::consts::PI;

/// Cook-Torrance / GGX BRDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    /// Diffuse albedo.
    pub rho_d: f64,
    /// Specular scale.
    pub k_s: f64,
    /// GGX roughness (alpha = r^2 in some conventions).
    pub alpha: f64,
    /// Fresnel reflectance at normal incidence.
    pub f0: f64,
}

impl Ggx {
    /// Default F0, a dielectric with index ~1.5.
    pub fn default_f0() -> f64 {
        0.04
    }

    /// Validated constructor.
    pub fn new(rho_d: f64, k_s: f64, alpha: f64, f0: f64) -> Result<Self, BrdfParamError> {
        check("ggx", "rho_d", rho_d, 0.0, 1.0, "must be in [0, 1]")?;
        check("ggx", "k_s", k_s, 0.0, 100.0, "must be in [0, 100]")?;
        check("ggx", "alpha", alpha, 1e-4, 1.0, "must be in [1e-4, 1]")?;
        check("ggx", "f0", f0, 0.0, 1.0, "must be in [0, 1]")?;
        Ok(Self { rho_d, k_s, alpha, f0 })
    }

    fn smith_g1(&self, cos: f64) -> f64 {
        let a2 = self.alpha * self.alpha;
        2.0 * cos / (cos + (a2 + (1.0 - a2) * cos * cos).sqrt())
    }
}

impl Brdf for Ggx {
    fn f_r(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> f64 {
        let (ci, co) = (wi.z, wo.z);
        if ci <= 0.0 || co <= 0.0 {
            return 0.0;
        }
        let h = (wi + wo).normalize();
        let ch = h.z;
        let a2 = self.alpha * self.alpha;
        let denom = ch * ch * (a2 - 1.0) + 1.0;
        let d = a2 / (PI * denom * denom);
        let g = self.smith_g1(ci) * self.smith_g1(co);
        let f = self.f0 + (1.0 - self.f0) * (1.0 - wi.dot(&h)).clamp(0.0, 1.0).powi(5);
        self.rho_d / PI + self.k_s * d * g * f / (4.0 * ci * co)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peaks_at_the_mirror_and_is_reciprocal() {
        let g = Ggx::new(0.2, 1.0, 0.1, 0.04).unwrap();
        let peak = g.reflectance(45.0, 45.0);
        assert!(peak > g.reflectance(40.0, 45.0) && peak > g.reflectance(50.0, 45.0));
        assert!((g.reflectance(37.0, 45.0) - g.reflectance(45.0, 37.0)).abs() < 1e-12);
    }

    #[test]
    fn distribution_is_normalised() {
        // Integral of D(h) cos(theta_h) over the hemisphere is 1.
        let g = Ggx::new(0.0, 1.0, 0.3, 1.0).unwrap();
        let a2 = g.alpha * g.alpha;
        let steps = 200_000;
        let mut sum = 0.0;
        for k in 0..steps {
            let t = (k as f64 + 0.5) / steps as f64 * PI / 2.0;
            let c = t.cos();
            let denom = c * c * (a2 - 1.0) + 1.0;
            sum += a2 / (PI * denom * denom) * c * t.sin() * 2.0 * PI * (PI / 2.0 / steps as f64);
        }
        assert!((sum - 1.0).abs() < 1e-4, "integral {sum}");
    }
}
