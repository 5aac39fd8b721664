//! A polished dielectric with a black back (the black-glass gloss
//! standard): Fresnel reflection at the surface only, everything that
//! enters is absorbed; or over a diffuse base (a glossy paint or tile),
//! which returns the light that enters as a Lambertian layer would,
//! `base (1 - F(theta_i)) (1 - F(theta_o)) / pi`. Its reflection is a spike in the mirror direction,
//! which `f_r` (a density) cannot hold: the model reports it through
//! [`super::Brdf::mirror_reflectance`] and the forward model spreads it
//! over the angle grid's bin kernel ([`super::ray_reflectance`]).
use super::{Brdf, BrdfParamError, check};
use nalgebra::Vector3;

/// A smooth dielectric of refractive index `n`, black behind its surface.
#[derive(Clone, Debug, PartialEq)]
pub struct SmoothDielectric {
    n: f64,
    base: f64,
}

/// Refractive index of the black-glass gloss standard at the sodium D line
/// (ISO 2813, ASTM D523).
pub const BLACK_GLASS_INDEX: f64 = 1.567;

impl SmoothDielectric {
    /// A smooth dielectric of index `n` (1 < n <= 4).
    pub fn new(n: f64) -> Result<Self, BrdfParamError> {
        check("smooth-dielectric", "n", n, 1.0 + 1e-9, 4.0, "a refractive index above 1 (glass 1.4..1.9)")?;
        Ok(Self { n, base: 0.0 })
    }

    /// The same surface over a diffuse base of albedo `base` (0..=1).
    pub fn over_base(n: f64, base: f64) -> Result<Self, BrdfParamError> {
        check("smooth-dielectric", "base_albedo", base, 0.0, 1.0, "must be in [0, 1]")?;
        Ok(Self { base, ..Self::new(n)? })
    }

    /// The black-glass gloss standard.
    pub fn black_glass() -> Self {
        Self { n: BLACK_GLASS_INDEX, base: 0.0 }
    }

    /// Refractive index.
    pub fn index(&self) -> f64 {
        self.n
    }
}

/// Fresnel reflectance of unpolarised light at incidence `theta_deg` on a
/// smooth dielectric of index `n` (from air): the mean of the s and p
/// reflectances.
pub fn fresnel_unpolarised(theta_deg: f64, n: f64) -> f64 {
    let ci = theta_deg.to_radians().cos();
    let si = theta_deg.to_radians().sin();
    let st = si / n;
    let ct = (1.0 - st * st).sqrt();
    let rs = ((ci - n * ct) / (ci + n * ct)).powi(2);
    let rp = ((n * ci - ct) / (n * ci + ct)).powi(2);
    0.5 * (rs + rp)
}

impl Brdf for SmoothDielectric {
    fn f_r(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> f64 {
        if self.base == 0.0 || wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let t = |z: f64| 1.0 - fresnel_unpolarised(z.clamp(-1.0, 1.0).acos().to_degrees(), self.n);
        self.base * t(wi.z) * t(wo.z) / std::f64::consts::PI
    }

    fn mirror_reflectance(&self, theta_deg: f64) -> f64 {
        fresnel_unpolarised(theta_deg, self.n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_matches_known_values() {
        // Normal incidence: ((n-1)/(n+1))^2; black glass 1.567 at 45 deg and at 60 deg.
        let n = BLACK_GLASS_INDEX;
        assert!((fresnel_unpolarised(0.0, n) - ((n - 1.0) / (n + 1.0)).powi(2)).abs() < 1e-12);
        assert!((fresnel_unpolarised(45.0, n) - 0.0597).abs() < 2e-4, "{}", fresnel_unpolarised(45.0, n));
        // The 60 deg value gloss standards quote for n = 1.567: about 0.1 (100 GU).
        assert!((fresnel_unpolarised(60.0, n) - 0.1).abs() < 2e-3, "{}", fresnel_unpolarised(60.0, n));
        assert!(SmoothDielectric::new(1.0).is_err() && SmoothDielectric::new(1.5).is_ok());
    }
}
