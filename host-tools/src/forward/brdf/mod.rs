//! Reflection models. Every model gives f_r for a pair of directions in the
//! surface frame (z = normal); the quantity the instrument estimates is the
//! reflectance factor R = pi f_r, relative to a perfect diffuser (method.md).
//!
//! Directions point away from the surface: `wi` towards the light, `wo`
//! towards the viewer. In-plane, the light is on the -x side at incidence
//! theta_i and the viewer on the +x side at theta_o (the mirror direction of
//! theta_i = theta_o).
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

pub mod astm_table;
mod ggx;
mod lambert;
pub mod merl_binary;
pub mod nbrdf;
pub mod roughened;
pub mod smooth_dielectric;
pub mod stretched;
mod tabulated;
mod ward;

pub use astm_table::AstmTable;
pub use ggx::Ggx;
pub use lambert::Lambertian;
pub use nbrdf::{Nbrdf, NbrdfSet};
pub use smooth_dielectric::SmoothDielectric;
pub use tabulated::Tabulated;
pub use ward::Ward;

/// A bidirectional reflectance distribution function.
pub trait Brdf: Send + Sync + std::fmt::Debug {
    /// f_r (1/sr) for unit directions `wi` (to the light) and `wo` (to the viewer).
    fn f_r(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> f64;

    /// Reflectance factor R = pi f_r, in-plane, light at `theta_i_deg` and
    /// viewer at `theta_o_deg` on the opposite side of the normal.
    fn reflectance(&self, theta_i_deg: f64, theta_o_deg: f64) -> f64 {
        std::f64::consts::PI * self.f_r(&light_dir(theta_i_deg), &view_dir(theta_o_deg))
    }

    /// The reflectance of the part of the reflection concentrated in the
    /// mirror direction (a smooth surface's Fresnel reflection) at
    /// incidence `theta_deg`; 0 for a rough model, whose `f_r` holds all.
    fn mirror_reflectance(&self, _theta_deg: f64) -> f64 {
        0.0
    }
}

/// Out-of-plane extent of the receptor aperture of the 45 deg gloss
/// geometry (ASTM D2457 / ASTM C346: 8.0 deg in the plane of incidence x
/// 10.0 deg across it), degrees: what ties the in-plane model's mirror
/// spike to the 3-D flux a gloss meter receives ([`mirror_area_deg`]).
pub const GLOSS_APERTURE_ACROSS_DEG: f64 = 10.0;

/// The in-plane weight of a mirror spike: `R(theta) = A delta(theta -
/// theta_o)` with `A` (reflectance factor x degrees) such that a mirror of
/// reflectance `f` and a diffuser of reflectance factor `R` send the flux
/// ratio of the 3-D gloss geometry into a receptor of extent `beta` across
/// the plane of incidence: the diffuser's `(R/pi) cos(theta_o) alpha beta`
/// over the mirror's `f` equals the in-plane `R alpha_deg / A`, so
/// `A = 180 f / (cos(theta_o) beta_rad)`.
pub fn mirror_area_deg(f: f64, theta_o_deg: f64) -> f64 {
    180.0 * f / (theta_o_deg.to_radians().cos() * GLOSS_APERTURE_ACROSS_DEG.to_radians())
}

/// The reflectance factor one ray sees, as the forward model integrates it:
/// `pi f_r` plus the mirror spike spread over the angle grid's bin kernel
/// (the triangle of half-width `step_deg` by which a ray's weight is split
/// between bins, normalised to unit area), centred on the view's mirror
/// incidence `theta_o_deg`. So a mirror's readings are exactly `H rho` of
/// its binned spike ([`binned_reflectance`]) whenever `theta_o` is a bin.
pub fn ray_reflectance(
    brdf: &dyn Brdf,
    wi: &Vector3<f64>,
    wo: &Vector3<f64>,
    theta_ray_deg: f64,
    theta_o_deg: f64,
    step_deg: f64,
) -> f64 {
    std::f64::consts::PI * brdf.f_r(wi, wo) + spike(brdf, theta_ray_deg, theta_o_deg, step_deg)
}

fn spike(brdf: &dyn Brdf, theta_deg: f64, theta_o_deg: f64, step_deg: f64) -> f64 {
    let f = brdf.mirror_reflectance(theta_o_deg);
    if f == 0.0 {
        return 0.0;
    }
    let t = 1.0 - (theta_deg - theta_o_deg).abs() / step_deg;
    if t <= 0.0 { 0.0 } else { mirror_area_deg(f, theta_o_deg) * t / step_deg }
}

/// The model's true binned BRDF at bin centre `theta_deg` (view `theta_o_deg`,
/// grid step `step_deg`): the reflectance factor there, plus a mirror spike
/// projected onto the bin (the same kernel as [`ray_reflectance`]).
pub fn binned_reflectance(brdf: &dyn Brdf, theta_deg: f64, theta_o_deg: f64, step_deg: f64) -> f64 {
    binned_reflectance_at(brdf, theta_deg, &view_dir(theta_o_deg), step_deg)
}

/// The reflectance factor of `brdf` in bin `theta_deg` (view `wo`): its
/// average over the bin kernel, without a mirror spike (the priors' grid
/// vectors; see [`binned_reflectance_at`] for why an average).
pub fn binned_factor_at(brdf: &dyn Brdf, theta_deg: f64, wo: &Vector3<f64>, step_deg: f64) -> f64 {
    let theta_o = wo.z.clamp(-1.0, 1.0).acos().to_degrees();
    let f = |t: f64| std::f64::consts::PI * brdf.f_r(&light_dir(t.clamp(-MAX_INCIDENCE_DEG, MAX_INCIDENCE_DEG)), wo);
    bin_kernel_average(f, theta_deg, step_deg, (theta_deg - theta_o).abs())
}

/// [`binned_reflectance`] for a view `wo` anywhere (surface frame, unit):
/// light in the plane of incidence at bin centre `theta_deg`, the mirror
/// spike about the view's own polar angle. The truth at a pixel whose view
/// is not the instrument's nominal one.
///
/// The bin's value is the reflectance factor averaged over the bin kernel
/// (the triangle of half-width `step_deg` the readings' model splits a
/// ray's weight by), not its value at the centre: a glossy lobe narrower
/// than a bin (a specular phenolic's is a few tenths of a degree wide)
/// would otherwise give the bin at the view's exact mirror incidence a
/// spike its neighbours do not share, and a prior learnt from such truths
/// carves a notch into smooth lobes there. The average is taken by the
/// midpoint rule on sub-intervals, finest near the mirror incidence, where
/// lobes are narrowest.
pub fn binned_reflectance_at(brdf: &dyn Brdf, theta_deg: f64, wo: &Vector3<f64>, step_deg: f64) -> f64 {
    let theta_o = wo.z.clamp(-1.0, 1.0).acos().to_degrees();
    binned_factor_at(brdf, theta_deg, wo, step_deg) + spike(brdf, theta_deg, theta_o, step_deg)
}

/// Incidence beyond which the bin kernel's average takes the value at
/// this angle (light at grazing incidence or below the horizon reads nothing useful).
const MAX_INCIDENCE_DEG: f64 = 89.9;

/// Sub-intervals per half of the bin kernel: finer within two bins of the
/// mirror incidence, where lobes are narrowest.
fn kernel_subdivisions(from_mirror_deg: f64, step_deg: f64) -> usize {
    if from_mirror_deg < 2.0 * step_deg {
        32
    } else if from_mirror_deg < 6.0 * step_deg {
        8
    } else {
        3
    }
}

/// `f` averaged over the triangle kernel of half-width `step` centred on
/// `theta` (weights integrated exactly per sub-interval, `f` at its midpoint).
pub fn bin_kernel_average(f: impl Fn(f64) -> f64, theta: f64, step: f64, from_mirror_deg: f64) -> f64 {
    let k = kernel_subdivisions(from_mirror_deg, step);
    let h = 1.0 / k as f64;
    let mut sum = 0.0;
    for i in 0..k {
        // Sub-interval [a, b] of the kernel's half, in units of step from
        // the centre: the triangle's weight there is h (1 - (a + b) / 2).
        let mid = (i as f64 + 0.5) * h;
        let w = h * (1.0 - mid);
        sum += w * (f(theta - mid * step) + f(theta + mid * step));
    }
    sum
}

/// Unit direction towards an in-plane light at incidence `theta_deg` (-x side).
pub fn light_dir(theta_deg: f64) -> Vector3<f64> {
    let t = theta_deg.to_radians();
    Vector3::new(-t.sin(), 0.0, t.cos())
}

/// Unit direction towards an in-plane viewer at `theta_deg` (+x side).
pub fn view_dir(theta_deg: f64) -> Vector3<f64> {
    let t = theta_deg.to_radians();
    Vector3::new(t.sin(), 0.0, t.cos())
}

/// A reflection model as written in instrument, prior and scene files.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "kebab-case", deny_unknown_fields)]
pub enum BrdfSpec {
    /// Isotropic Ward; `rho_s` defaults to 1 - rho_d (the patent profile).
    Ward {
        /// Diffuse albedo.
        rho_d: f64,
        /// Specular albedo (default 1 - rho_d).
        #[serde(default)]
        rho_s: Option<f64>,
        /// Roughness.
        alpha: f64,
    },
    /// Lambertian diffuser.
    Lambertian {
        /// Albedo (1 = perfect diffuser).
        rho: f64,
    },
    /// Cook-Torrance microfacet model with the GGX distribution.
    Ggx {
        /// Diffuse albedo.
        rho_d: f64,
        /// Specular scale.
        k_s: f64,
        /// GGX roughness.
        alpha: f64,
        /// Fresnel reflectance at normal incidence.
        #[serde(default = "Ggx::default_f0")]
        f0: f64,
    },
    /// A measured material of the vendored MERL set (NBRDF network), seen
    /// through the instrument's spectral weights.
    Merl {
        /// Material name, e.g. `"blue-acrylic"` (host-tools/data/merl-nbrdf.json).
        material: String,
    },
    /// A measured material in an NBRDF file (the layout of
    /// `host-tools/data/merl-nbrdf.json`: networks fitted to measured
    /// data), seen through the instrument's spectral weights.
    Nbrdf {
        /// The file, relative to the current directory.
        file: std::path::PathBuf,
        /// The material's name in it.
        material: String,
    },
    /// A measured material in the MERL binary format (`.binary`: the
    /// half-angle table of Matusik et al. 2003), seen through the
    /// instrument's spectral weights.
    MerlBinary {
        /// The file, relative to the current directory.
        file: std::path::PathBuf,
    },
    /// A measured table in ASTM E1392 form (`.astm`; in-plane values, by
    /// reciprocity too), its path relative to the current directory.
    AstmE1392 {
        /// The file.
        file: std::path::PathBuf,
    },
    /// A polished dielectric black behind its surface (the black-glass gloss
    /// standard: n = 1.567): Fresnel reflection only, a mirror spike.
    SmoothDielectric {
        /// Refractive index (default 1.567, black glass at the sodium D line).
        #[serde(default = "black_glass_index")]
        n: f64,
        /// Albedo of a diffuse base under the surface (default 0: black behind it).
        #[serde(default)]
        base_albedo: f64,
    },
}

fn black_glass_index() -> f64 {
    smooth_dielectric::BLACK_GLASS_INDEX
}

/// Why a model description was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("{model}: parameter `{field}`{} is invalid: {why}", if value.is_nan() { String::new() } else { format!(" = {value}") })]
pub struct BrdfParamError {
    /// Model name.
    pub model: &'static str,
    /// Parameter name.
    pub field: &'static str,
    /// Value given.
    pub value: f64,
    /// What is allowed.
    pub why: String,
}

pub(crate) fn check(
    model: &'static str,
    field: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
    why: &'static str,
) -> Result<(), BrdfParamError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(BrdfParamError { model, field, value, why: why.into() })
    }
}

impl BrdfSpec {
    /// Builds the model, validating every parameter (RGB data seen with
    /// luminance weights).
    pub fn build(&self) -> Result<Box<dyn Brdf>, BrdfParamError> {
        self.build_for(nbrdf::LUMINANCE)
    }

    /// Builds the model for a sensor whose spectral weights of R, G, B are `spectral`.
    pub fn build_for(&self, spectral: [f64; 3]) -> Result<Box<dyn Brdf>, BrdfParamError> {
        if let BrdfSpec::Merl { material } = self {
            return NbrdfSet::merl().by_name(material, spectral).map(|b| Box::new(b) as Box<dyn Brdf>).map_err(|_| {
                BrdfParamError {
                    model: "merl",
                    field: "material",
                    value: f64::NAN,
                    why: "not a material of the vendored MERL set (names as in host-tools/data/merl-nbrdf.json)".into(),
                }
            });
        }
        let file_error = |model: &'static str, e: anyhow::Error| BrdfParamError {
            model,
            field: "file",
            value: f64::NAN,
            why: format!("{e:#}"),
        };
        match self {
            BrdfSpec::Nbrdf { file, material } => {
                let set = NbrdfSet::load(file).map_err(|e| file_error("nbrdf", e))?;
                return set.by_name(material, spectral).map(|b| Box::new(b) as Box<dyn Brdf>).map_err(|_| {
                    BrdfParamError {
                        model: "nbrdf",
                        field: "material",
                        value: f64::NAN,
                        why: format!(
                            "no material {material:?} in {}; it has: {}",
                            file.display(),
                            set.names().collect::<Vec<_>>().join(", ")
                        ),
                    }
                });
            }
            BrdfSpec::MerlBinary { file } => {
                let t = merl_binary::MerlTable::load_monochrome(file, spectral)
                    .map_err(|e| file_error("merl-binary", e))?;
                return Ok(Box::new(t));
            }
            _ => {}
        }
        Ok(match *self {
            BrdfSpec::Ward { rho_d, rho_s, alpha } => Box::new(Ward::new(rho_d, rho_s.unwrap_or(1.0 - rho_d), alpha)?),
            BrdfSpec::Lambertian { rho } => Box::new(Lambertian::new(rho)?),
            BrdfSpec::Ggx { rho_d, k_s, alpha, f0 } => Box::new(Ggx::new(rho_d, k_s, alpha, f0)?),
            BrdfSpec::AstmE1392 { ref file } => Box::new(AstmTable::load(file).map_err(|e| BrdfParamError {
                model: "astm-e1392",
                field: "file",
                value: f64::NAN,
                why: format!("{e:#}"),
            })?),
            BrdfSpec::SmoothDielectric { n, base_albedo } => Box::new(SmoothDielectric::over_base(n, base_albedo)?),
            BrdfSpec::Merl { .. } | BrdfSpec::Nbrdf { .. } | BrdfSpec::MerlBinary { .. } => {
                unreachable!("built above")
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_from_toml_and_reject_unknown_models_and_fields() {
        #[derive(Deserialize)]
        struct W {
            b: BrdfSpec,
        }
        let w: W = toml::from_str("b = { model = \"ward\", rho_d = 0.3, alpha = 0.05 }").unwrap();
        assert_eq!(w.b, BrdfSpec::Ward { rho_d: 0.3, rho_s: None, alpha: 0.05 });
        assert!(toml::from_str::<W>("b = { model = \"phong\", n = 3 }").is_err());
        assert!(toml::from_str::<W>("b = { model = \"ward\", rho_d = 0.3, alpha = 0.05, beta = 1 }").is_err());
        let err = BrdfSpec::Ward { rho_d: 0.3, rho_s: None, alpha: -1.0 }.build().unwrap_err();
        assert_eq!(err.field, "alpha");
        let w: W = toml::from_str("b = { model = \"merl\", material = \"white-paint\" }").unwrap();
        let b = w.b.build().unwrap();
        assert!((b.reflectance(45.0, 45.0) - 1.14481).abs() < 1e-4);
        let red_only = w.b.build_for([1.0, 0.0, 0.0]).unwrap();
        assert_ne!(red_only.reflectance(45.0, 45.0), b.reflectance(45.0, 45.0));
        let err = BrdfSpec::Merl { material: "unobtainium".into() }.build().unwrap_err();
        assert_eq!(err.field, "material");
    }

    #[test]
    fn bins_average_over_their_kernel_so_a_narrow_lobe_is_not_a_spike() {
        // Exact for linear functions; a partition of unity over the grid.
        assert!((bin_kernel_average(|t| 3.0 + 0.5 * t, 40.0, 1.0, 10.0) - 23.0).abs() < 1e-12);
        // A lobe much narrower than a bin: the bins share its integral
        // (sum over bins x step), the centre bin no longer carries a spike.
        let lobe = |t: f64| (-((t - 45.0) / 0.1).powi(2)).exp();
        let integral = 0.1 * std::f64::consts::PI.sqrt();
        let bins: Vec<f64> =
            (40..=50).map(|b| bin_kernel_average(lobe, f64::from(b), 1.0, (f64::from(b) - 45.0).abs())).collect();
        let total: f64 = bins.iter().sum();
        assert!((total - integral).abs() < 0.01 * integral, "{total} vs {integral}");
        assert!(bins[5] < 0.25 * lobe(45.0), "{}", bins[5]);
        // A measured specular material at the exact mirror bin: of the
        // order of its neighbours, not tens of times them.
        let m = NbrdfSet::merl().by_name("specular-black-phenolic", [0.2126, 0.7152, 0.0722]).unwrap();
        let wo = view_dir(45.0);
        let at = |t: f64| binned_reflectance_at(&m, t, &wo, 1.0);
        let point = |t: f64| m.reflectance(t, 45.0);
        let ratio = at(45.0) / (0.5 * (at(44.0) + at(46.0)));
        let point_ratio = point(45.0) / (0.5 * (point(44.0) + point(46.0)));
        assert!(ratio < 0.25 * point_ratio, "exact-specular bin {ratio} times its neighbours (points: {point_ratio})");
    }
}
