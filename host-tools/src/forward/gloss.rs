//! The gloss readings' definitions on the instrument's angle grid: the
//! weights `a_r` of the linear readings `L_r = a_r^T rho` that
//! `brdf_meter::gloss` combines into specular gloss (GU), haze (HU) and
//! distinctness (%), the black-glass standard's value, and the readings of
//! a true BRDF by the same definition (what tests compare the device with).
//!
//! The instrument is in-plane: it estimates `R(theta)`, the reflectance
//! factor for light at incidence theta and the view fixed at `theta_o` (45
//! deg), on bins 0.5 deg apart, `R` taken as the piecewise-linear
//! interpolation of the bins (how the optics split a ray between bins).
//! By reciprocity, integrating over incidence at a fixed view is
//! integrating over the receptor's in-plane aperture at a fixed source.
//! Every window below is centred on the specular incidence `theta_o`:
//!
//! - `L_0` specular: `int R` over the receptor's in-plane aperture, 8.0 deg
//!   (ASTM D2457 / ASTM C346, the 45 deg geometry; the aperture across the
//!   plane, 10.0 deg, enters through the black glass's in-plane weight,
//!   `brdf::mirror_area_deg`). Gloss `G = 100 L_0 / L_0(black glass)`.
//! - `L_1` haze: `int R` over `theta_o +- [2, 3]` deg, both sides (after
//!   ASTM E430's haze at 2 deg from specular; 2 deg is twice the LEDs'
//!   ~1 deg source spacing, so the shoulder of a peak the instrument cannot
//!   resolve has fallen, and 3 deg keeps it inside the 8 deg aperture).
//!   `H = 100 L_1 / L_0(black glass)`.
//! - `L_2` peak: `int R` over `theta_o +- 0.5` deg (one bin each side: the
//!   finest the grid resolves); `L_3` shoulders: the mean of `int R` over
//!   `theta_o +- [0.5, 1.5]` deg (the same width each side). Distinctness
//!   `D = 100 (L_2 - L_3) / L_2` (after E430's distinctness of image,
//!   which compares the specular peak with 0.3 deg off it: 0.3 deg is below
//!   what 0.5 deg bins and ~1 deg sources resolve, so the shoulders are
//!   taken at 0.5..1.5 deg).
//!
//! A mirror reads `D = 100`, a flat `R` reads `D = 0`, and so does a
//! peak no higher than its shoulders (a fabric's dip at the mirror
//! direction): distinctness is 0 to 100 % by definition
//! (`brdf_meter::gloss::DOMAINS`), as the device reads it, so the truth
//! it is judged against is cut to the same range.
//!
//! # The definitions in three dimensions
//! A gloss meter's receptor has an extent across the plane of incidence
//! too (10.0 deg for the 45 deg geometry): what it receives is a flux,
//! `L = int f_r cos(theta_i) d omega_i` over the window (by reciprocity,
//! over the light's directions for the fixed view), and the black glass's
//! `L_0` is all of its Fresnel reflection, `F(theta_o)`. That is the
//! definition [`model_readings`] computes from a reflection model, every
//! window `u` (in-plane offset from the specular direction, as above) x `w`
//! (across it, +-5 deg), numerically. The in-plane definition above is the
//! same for a BRDF that does not change across the window (a diffuser reads
//! 8.27 GU either way); for a lobe narrower than the window it is not (an
//! isotropic lobe is as narrow across as in-plane, so its in-plane integral
//! over-counts its flux by the window's width over the lobe's). The
//! calibration's gloss rows are fitted to the three-dimensional readings of
//! every sample a model is known for (`calibration::gloss_rows`); a profile
//! known only in-plane takes the in-plane definition.
use crate::forward::brdf::smooth_dielectric::fresnel_unpolarised;
use crate::forward::brdf::{Brdf, binned_reflectance, mirror_area_deg};
use brdf_meter::gloss::LINEAR;
use nalgebra::{DMatrix, DVector, Vector3};

/// The receptor's in-plane aperture of the 45 deg gloss geometry, degrees.
pub const SPECULAR_APERTURE_DEG: f64 = 8.0;
/// Haze window: offsets from the specular incidence, degrees (both sides).
pub const HAZE_OFFSETS_DEG: (f64, f64) = (2.0, 3.0);
/// Peak window half-width, degrees.
pub const PEAK_HALF_WIDTH_DEG: f64 = 0.5;
/// Shoulder windows: offsets from the specular incidence, degrees (both sides).
pub const SHOULDER_OFFSETS_DEG: (f64, f64) = (0.5, 1.5);
/// The black-glass standard's assigned specular gloss, GU.
pub const ASSIGNED_GU: f64 = 100.0;

/// `int_lo^hi R(theta) d theta` for `R` the piecewise-linear interpolation of
/// the bins: the weight of each bin (exact; 0 outside the grid).
fn window(bins: &[f64], lo: f64, hi: f64) -> DVector<f64> {
    let n = bins.len();
    // Integral over [lo, hi] of the linear ramp from (a, ya) to (b, yb).
    let ramp = |a: f64, b: f64, ya: f64, yb: f64| {
        let (l, h) = (lo.max(a), hi.min(b));
        if h <= l {
            return 0.0;
        }
        let y = |t: f64| ya + (yb - ya) * (t - a) / (b - a);
        0.5 * (y(l) + y(h)) * (h - l)
    };
    DVector::from_fn(n, |j, _| {
        let mut w = 0.0;
        if j > 0 {
            w += ramp(bins[j - 1], bins[j], 0.0, 1.0);
        }
        if j + 1 < n {
            w += ramp(bins[j], bins[j + 1], 1.0, 0.0);
        }
        w
    })
}

/// The weights `A` (LINEAR x n) of the linear readings on `bins`, the
/// specular incidence at `theta_o_deg`. `None` when the grid does not
/// cover the specular aperture.
pub fn reading_weights(bins: &[f64], theta_o_deg: f64) -> Option<DMatrix<f64>> {
    let half = SPECULAR_APERTURE_DEG / 2.0;
    if bins.first()? > &(theta_o_deg - half) || bins.last()? < &(theta_o_deg + half) {
        return None;
    }
    let t = theta_o_deg;
    let (h0, h1) = HAZE_OFFSETS_DEG;
    let (s0, s1) = SHOULDER_OFFSETS_DEG;
    let rows = [
        window(bins, t - half, t + half),
        window(bins, t - h1, t - h0) + window(bins, t + h0, t + h1),
        window(bins, t - PEAK_HALF_WIDTH_DEG, t + PEAK_HALF_WIDTH_DEG),
        (window(bins, t - s1, t - s0) + window(bins, t + s0, t + s1)) * 0.5,
    ];
    Some(DMatrix::from_fn(LINEAR, bins.len(), |r, j| rows[r][j]))
}

/// The black-glass standard's specular linear reading `L_0` by the
/// definition: its in-plane mirror weight (the aperture holds the whole spike).
pub fn black_glass_specular(theta_o_deg: f64) -> f64 {
    mirror_area_deg(
        fresnel_unpolarised(theta_o_deg, crate::forward::brdf::smooth_dielectric::BLACK_GLASS_INDEX),
        theta_o_deg,
    )
}

/// The readings (gloss GU, haze HU, distinctness %) of linear readings
/// `l`, on the scale where the black glass's `L_0` is `reference`.
pub fn readings_of(l: &[f64], reference: f64) -> [f64; 3] {
    let q = ASSIGNED_GU / reference;
    let (lowest, highest) = brdf_meter::gloss::DOMAINS[brdf_meter::gloss::DISTINCTNESS];
    let d =
        if l[2] > 0.0 { (100.0 * (l[2] - l[3]) / l[2]).clamp(f64::from(lowest), f64::from(highest)) } else { f64::NAN };
    [q * l[0], q * l[1], d]
}

/// Offsets from the specular direction in the plane of incidence at which
/// [`model_linear_readings`] evaluates the BRDF, degrees (every window's
/// edge is one of them).
const U_STEP_DEG: f64 = 0.25;
/// Offsets across the plane of incidence, degrees (finer near the plane,
/// where a sharp lobe is).
const W_NODES_DEG: [f64; 15] = [-5.0, -3.0, -2.0, -1.5, -1.0, -0.5, -0.25, 0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 5.0];

/// The four linear readings of the definitions in three dimensions (module
/// docs): `int f_r cos(theta_i) d omega_i` over each window about the
/// specular direction of the view `wo` (surface frame, unit), trapezoid
/// rules over `U_STEP_DEG` in-plane and `W_NODES_DEG` across, plus a
/// mirror spike's Fresnel reflectance in the windows that hold the
/// specular direction.
pub fn model_linear_readings(brdf: &dyn Brdf, wo: &Vector3<f64>) -> [f64; LINEAR] {
    let theta_o = wo.z.clamp(-1.0, 1.0).acos();
    // The plane of incidence holds the normal and the view; the light is on
    // the other side: in-plane unit `e` (towards the view, along the
    // surface) and across unit `a`.
    let horiz = Vector3::new(wo.x, wo.y, 0.0);
    let e = if horiz.norm() > 1e-12 { horiz.normalize() } else { Vector3::x() };
    let a = Vector3::z().cross(&e);
    let half = SPECULAR_APERTURE_DEG / 2.0;
    let nu = (2.0 * half / U_STEP_DEG).round() as usize;
    let (h0, h1) = HAZE_OFFSETS_DEG;
    let (s0, s1) = SHOULDER_OFFSETS_DEG;
    // Trapezoid weight of node u (degrees) in a window [lo, hi] whose edges are nodes.
    let in_window = |u: f64, lo: f64, hi: f64| -> f64 {
        let eps = 1e-9;
        if u < lo - eps || u > hi + eps {
            0.0
        } else if (u - lo).abs() < eps || (u - hi).abs() < eps {
            0.5
        } else {
            1.0
        }
    };
    let mut l = [0.0; LINEAR];
    for i in 0..=nu {
        let u = -half + i as f64 * U_STEP_DEG;
        let w_u = [
            in_window(u, -half, half),
            in_window(u, -h1, -h0) + in_window(u, h0, h1),
            in_window(u, -PEAK_HALF_WIDTH_DEG, PEAK_HALF_WIDTH_DEG),
            0.5 * (in_window(u, -s1, -s0) + in_window(u, s0, s1)),
        ];
        if w_u.iter().all(|x| *x == 0.0) {
            continue;
        }
        let ti = theta_o + u.to_radians();
        let mut f = 0.0;
        for (j, w) in W_NODES_DEG.iter().enumerate() {
            let dw_lo = if j > 0 { w - W_NODES_DEG[j - 1] } else { 0.0 };
            let dw_hi = if j + 1 < W_NODES_DEG.len() { W_NODES_DEG[j + 1] - w } else { 0.0 };
            let weight = 0.5 * (dw_lo + dw_hi) * std::f64::consts::PI / 180.0;
            let wr = w.to_radians();
            // Light on the side opposite the view: -e in-plane.
            let wi = (-e * ti.sin() + Vector3::z() * ti.cos()) * wr.cos() + a * wr.sin();
            if wi.z <= 0.0 {
                continue;
            }
            f += brdf.f_r(&wi, wo) * wi.z * wr.cos() * weight;
        }
        for (r, x) in l.iter_mut().enumerate() {
            *x += w_u[r] * f * U_STEP_DEG.to_radians();
        }
    }
    let mirror = brdf.mirror_reflectance(theta_o.to_degrees());
    l[0] += mirror;
    l[2] += mirror;
    l
}

/// The black glass's `L_0` in three dimensions: all its Fresnel reflection.
pub fn black_glass_flux(theta_o_deg: f64) -> f64 {
    fresnel_unpolarised(theta_o_deg, crate::forward::brdf::smooth_dielectric::BLACK_GLASS_INDEX)
}

/// The readings (gloss GU, haze HU, distinctness %) of a reflection model
/// seen along `wo`, by the definitions in three dimensions.
pub fn model_readings(brdf: &dyn Brdf, wo: &Vector3<f64>) -> [f64; 3] {
    let theta_o = wo.z.clamp(-1.0, 1.0).acos().to_degrees();
    readings_of(&model_linear_readings(brdf, wo), black_glass_flux(theta_o))
}

/// A profile's linear readings on the black glass's three-dimensional
/// scale (`L / L_0,bg x 100`, the rows' target) by the in-plane definition
/// (the profile is all that is known); `None` when the grid does not cover
/// the specular aperture.
pub fn profile_scaled_readings(rho: &DVector<f64>, bins: &[f64], theta_o_deg: f64) -> Option<[f64; LINEAR]> {
    let a = reading_weights(bins, theta_o_deg)?;
    let l = (&a * rho) * (ASSIGNED_GU / black_glass_specular(theta_o_deg));
    Some(core::array::from_fn(|r| l[r]))
}

/// The true binned BRDF of `brdf` on `bins` (view `theta_o_deg`, grid step
/// `step_deg`; a mirror spike projected onto its bins).
pub fn true_rho(brdf: &dyn Brdf, bins: &[f64], theta_o_deg: f64, step_deg: f64) -> DVector<f64> {
    DVector::from_iterator(bins.len(), bins.iter().map(|t| binned_reflectance(brdf, *t, theta_o_deg, step_deg)))
}

/// The readings of a true BRDF by the definition, on the standard's own
/// scale (the black glass's `L_0` from [`black_glass_specular`]).
pub fn true_readings(rho: &DVector<f64>, bins: &[f64], theta_o_deg: f64) -> Option<[f64; 3]> {
    let a = reading_weights(bins, theta_o_deg)?;
    let l = &a * rho;
    Some(readings_of(l.as_slice(), black_glass_specular(theta_o_deg)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::{Lambertian, SmoothDielectric};
    use crate::forward::grid::AngleGrid;

    #[test]
    fn distinctness_is_0_to_100_percent_by_definition() {
        // A peak above its shoulders, a flat R, a dip at the mirror
        // direction (shoulders above the peak), and no peak at all.
        assert_eq!(readings_of(&[1.0, 1.0, 4.0, 1.0], 1.0)[2], 75.0);
        assert_eq!(readings_of(&[1.0, 1.0, 2.0, 2.0], 1.0)[2], 0.0);
        assert_eq!(readings_of(&[1.0, 1.0, 2.0, 2.02], 1.0)[2], 0.0, "a dip reads no distinctness, not -1 %");
        assert!(readings_of(&[1.0, 1.0, 0.0, 1.0], 1.0)[2].is_nan());
        // Gloss and haze are not cut (the linear readings of a BRDF are
        // never negative).
        assert_eq!(readings_of(&[2.0, 3.0, 4.0, 1.0], 4.0)[..2], [50.0, 75.0]);
    }

    #[test]
    fn windows_integrate_the_interpolated_brdf() {
        let g = AngleGrid::patent();
        let a = reading_weights(g.bins_deg(), 45.0).unwrap();
        // A constant R integrates to the windows' widths.
        let ones = DVector::from_element(g.n(), 1.0);
        let l = &a * ones;
        for (got, want) in l.iter().zip([8.0, 2.0, 1.0, 1.0]) {
            assert!((got - want).abs() < 1e-12, "{got} {want}");
        }
        // A linear R: the integral of theta over [41, 49] is 8 * 45.
        let lin = DVector::from_iterator(g.n(), g.bins_deg().iter().copied());
        assert!(((&a * lin)[0] - 360.0).abs() < 1e-9);
        assert!(reading_weights(g.bins_deg(), 62.0).is_none());
    }

    #[test]
    fn black_glass_reads_100_and_a_mirror_is_perfectly_distinct() {
        let g = AngleGrid::patent();
        let rho = true_rho(&SmoothDielectric::black_glass(), g.bins_deg(), 45.0, g.step_deg());
        let r = true_readings(&rho, g.bins_deg(), 45.0).unwrap();
        assert!((r[0] - 100.0).abs() < 1e-9 && r[1] == 0.0 && (r[2] - 100.0).abs() < 1e-12, "{r:?}");
        let flat = true_rho(&Lambertian::perfect(), g.bins_deg(), 45.0, g.step_deg());
        assert!(true_readings(&flat, g.bins_deg(), 45.0).unwrap()[2].abs() < 1e-12);
    }

    /// The perfect diffuser's gloss, computed independently: the flux a
    /// Lambertian surface sends into the 3-D receptor (8.0 x 10.0 deg about
    /// the 45 deg specular direction, numerically integrated over solid
    /// angle) over the flux the black glass mirrors into it (all of it:
    /// Fresnel reflectance times the incident flux).
    #[test]
    fn a_perfect_diffuser_reads_the_3d_flux_ratio() {
        let g = AngleGrid::patent();
        let flat = true_rho(&Lambertian::perfect(), g.bins_deg(), 45.0, g.step_deg());
        let gu = true_readings(&flat, g.bins_deg(), 45.0).unwrap()[0];
        // Receptor: a rectangle of angles about the specular direction, in-plane
        // polar offset u in [-4, 4] deg, across-plane angle w in [-5, 5] deg.
        // Direction (sin(45+u) cos w, sin w, cos(45+u) cos w); solid angle cos w du dw.
        let k = 400;
        let (du, dw) = (8.0f64.to_radians() / k as f64, 10.0f64.to_radians() / k as f64);
        let mut flux = 0.0;
        for i in 0..k {
            for j in 0..k {
                let u = -4f64.to_radians() + (i as f64 + 0.5) * du;
                let w = -5f64.to_radians() + (j as f64 + 0.5) * dw;
                let cos_theta = (45f64.to_radians() + u).cos() * w.cos();
                // Lambertian radiance E / pi per unit irradiance; projected solid angle.
                flux += cos_theta / std::f64::consts::PI * w.cos() * du * dw;
            }
        }
        let mirror = fresnel_unpolarised(45.0, 1.567);
        let want = 100.0 * flux / mirror;
        assert!((gu - want).abs() < 0.01 * want, "definition {gu}, 3-D integration {want}");
        // The three-dimensional definition of a model agrees with both.
        let wo = crate::forward::brdf::view_dir(45.0);
        let g3 = model_readings(&Lambertian::perfect(), &wo)[0];
        assert!((g3 - want).abs() < 0.005 * want, "model {g3}, 3-D integration {want}");
    }

    #[test]
    fn the_black_glass_is_100_gu_and_a_narrow_lobe_is_read_by_its_flux() {
        for view in [41.5f64, 45.0, 48.1] {
            let wo = crate::forward::brdf::view_dir(view);
            let r = model_readings(&SmoothDielectric::black_glass(), &wo);
            assert!((r[0] - 100.0).abs() < 1e-9 && r[1] == 0.0 && (r[2] - 100.0).abs() < 1e-12, "{view}: {r:?}");
        }
        // An isotropic lobe much narrower than the window: its flux is its
        // albedo (times Fresnel-free Ward's rho_s), whatever its width,
        // while the in-plane integral grows as it narrows.
        let wo = crate::forward::brdf::view_dir(45.0);
        let f = |alpha: f64| model_readings(&crate::forward::brdf::Ward::new(0.0, 0.05, alpha).unwrap(), &wo)[0];
        let (a, b) = (f(0.01), f(0.02));
        assert!((a - b).abs() < 0.05 * b, "{a} {b}");
        let g = AngleGrid::patent();
        let inplane = |alpha: f64| {
            let rho =
                true_rho(&crate::forward::brdf::Ward::new(0.0, 0.05, alpha).unwrap(), g.bins_deg(), 45.0, g.step_deg());
            true_readings(&rho, g.bins_deg(), 45.0).unwrap()[0]
        };
        assert!(inplane(0.01) > 1.5 * inplane(0.02));
    }
}
