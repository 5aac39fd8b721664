//! The specular peak of a point's estimate: its height (reflectance factor),
//! its incidence and its full width at half maximum, with the standard
//! uncertainties (k = 1) of the height and the width, computed on the host
//! from the point's bins and their per-bin uncertainties.
//!
//! # Definition
//! The estimate is `R(theta)`, the reflectance factor at incidence theta for
//! the fixed view, taken as the piecewise-linear interpolation of the bins
//! (as `forward::gloss` defines the gloss readings on it). Its maximum is
//! therefore at a bin: the peak is the highest bin within the specular
//! aperture, the receptor's 8 deg in-plane aperture
//! (`forward::gloss::SPECULAR_APERTURE_DEG`) about the view's mirror
//! incidence (the view angle is a parameter: the instrument's nominal 45
//! deg unless the point's own view is known). Its width is where `R` crosses
//! half the peak on each side, by linear interpolation between the two bins
//! the crossing lies between, searched over the whole grid (a lobe may be
//! wider than the aperture).
//!
//! No peak (every field NaN): a bin needed is not finite, the highest bin in
//! the aperture is not above zero, or it is no maximum (not at or above the
//! bins beside it and above at least one of them: the estimate is flat there,
//! or still rising at the aperture's edge, or the bin has no neighbour on the
//! grid). No width (the width and its uncertainty NaN, the height kept): the
//! estimate does not fall to half the peak on both sides within the grid (a
//! lobe on a diffuse level above half its height, or wider than the grid).
//!
//! # Uncertainty: first-order propagation
//! The bins are taken as independent (the calibration holds one standard
//! uncertainty per bin, no covariance between bins), and the GUM's law of
//! propagation is applied to the functions above: the height is the peak
//! bin, so `u(peak) = u_k`; the width is `theta_R - theta_L`, each crossing
//! `theta = x_a + (h - R_a) / (R_b - R_a) (x_b - x_a)` with `h = R_k / 2`,
//! whose partial derivatives in `R_a`, `R_b` and `R_k` are exact, so
//! `u(width)^2 = sum_j (d width / d R_j)^2 u_j^2`.
//!
//! Why first order and not a Monte Carlo: it is exact for the quantities as
//! defined at the estimate, deterministic to the bit (the files are pinned
//! by a golden file), linear in the bins' u (twice the u, twice the
//! width's), and costs a few operations per point. A Monte Carlo of 256
//! draws would carry its own sampling error (about 1 / sqrt(2 x 256) = 4 %
//! of the u it states), would pin a random-number stream into the files, and
//! would have to say what a draw without a crossing means. What first order
//! leaves out, and a reader should know: the peak bin is taken as fixed
//! (noise that moves the maximum to another bin is not propagated; the
//! highest of noisy bins is biased upwards by a fraction of u), the
//! crossings are taken as staying between the same bins, and correlation
//! between the bins' errors (an estimator's errors are correlated across
//! neighbouring bins) is not in the per-bin u the calibration holds. A test
//! checks the first-order u against a seeded Monte Carlo where its
//! assumptions hold.
//!
//! # Resolution
//! A calibration puts out no lobe narrower than its estimate of a mirror
//! spike (its peak resolution, `crate::calibration::peak_resolution`,
//! recorded in the blob, per pixel where the pixels differ): below that width the readings do not say how
//! narrow a lobe is, or how high, and the estimate's shape there is the
//! prior's. A peak is *resolved* when its width is at least
//! [`RESOLVED_WIDTH_FACTOR`] times the resolution: widths of a lobe and of
//! the calibration's response add about in quadrature, so a lobe as wide as
//! the resolution comes out `sqrt 2` times as wide, and one that comes out
//! narrower is narrower than the resolution itself. An unresolved peak
//! keeps its height and width (what the estimate shows), but no uncertainty
//! is stated for either (NaN): its errors are not the readings' noise but
//! what the prior assumes, which the per-bin uncertainty does not hold (on
//! the patent profile the gloss standards' mirror spikes come out 45 %
//! below their height, 6 standard uncertainties). A peak without a width
//! (a lobe on a level above half its height) is resolved: it is wide.
//!
//! # The calibration's factors
//! A resolved peak's first-order uncertainties are multiplied by the
//! factors a calibration records (`brdf_meter::blob::PeakFactors`, flag
//! bit 12; [`Peak::stated`]). The height's first-order value is its bin's
//! per-bin uncertainty, which training sets to cover that bin's held-out
//! errors over every estimate; a bin is an estimate's peak where its
//! errors are largest, so on held-out materials the peaks were covered
//! less often than the bins. Training sets the factors on the resolved
//! peaks of the samples it holds out (`crate::calibration::peak_factors`).
use crate::forward::gloss::SPECULAR_APERTURE_DEG;
pub use brdf_meter::blob::PeakFactors;

/// A peak narrower than this times its pixel's peak resolution is not
/// resolved (module docs).
pub const RESOLVED_WIDTH_FACTOR: f64 = std::f64::consts::SQRT_2;

/// Slack on the aperture's edges (deg): the grid is stored in f32, so a bin
/// meant to be on the edge may lie a rounding error outside it.
const EDGE_SLACK_DEG: f64 = 1e-4;

/// A point's specular peak. NaN fields: no peak, or no width (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Peak {
    /// Height: the reflectance factor of the highest bin.
    pub rf: f64,
    /// Its standard uncertainty (k = 1).
    pub u_rf: f64,
    /// Its incidence (deg).
    pub deg: f64,
    /// Full width at half maximum (deg).
    pub width_deg: f64,
    /// Its standard uncertainty (k = 1, deg).
    pub u_width_deg: f64,
    /// Whether the calibration resolves it (module docs); `None`: no peak,
    /// or the calibration records no resolution.
    pub resolved: Option<bool>,
}

impl Peak {
    /// No peak.
    pub const NONE: Self = Self {
        rf: f64::NAN,
        u_rf: f64::NAN,
        deg: f64::NAN,
        width_deg: f64::NAN,
        u_width_deg: f64::NAN,
        resolved: None,
    };

    /// The peak as a calibration states it at a pixel of peak resolution
    /// `resolution_deg` (`None`: the calibration records none, and the peak
    /// is as it was): an unresolved peak's uncertainties are not stated; a
    /// resolved one's are the first-order values times the calibration's
    /// `factors` (`None`: as they are; module docs).
    pub fn stated(self, resolution_deg: Option<f64>, factors: Option<PeakFactors>) -> Self {
        let Some(res) = resolution_deg.filter(|_| self.rf.is_finite()) else { return self };
        // No width (NaN): a lobe on a level above half its height, wide.
        let resolved = self.width_deg.is_nan() || self.width_deg >= RESOLVED_WIDTH_FACTOR * res;
        if !resolved {
            return Self { u_rf: f64::NAN, u_width_deg: f64::NAN, resolved: Some(false), ..self };
        }
        let f = factors.unwrap_or(PeakFactors { height: 1.0, width: 1.0 });
        Self {
            u_rf: self.u_rf * f64::from(f.height),
            u_width_deg: self.u_width_deg * f64::from(f.width),
            resolved: Some(true),
            ..self
        }
    }
}

/// Where `R` crosses `h` between the outer bin `a` (at or below `h`) and the
/// inner bin `b` (above it), and the crossing's derivatives in `R_a`, `R_b`
/// and `h`.
struct Crossing {
    deg: f64,
    d_a: f64,
    d_b: f64,
    d_h: f64,
}

fn crossing(x: &[f64], r: &[f64], a: usize, b: usize, h: f64) -> Crossing {
    let (dx, dr) = (x[b] - x[a], r[b] - r[a]);
    Crossing {
        deg: x[a] + (h - r[a]) / dr * dx,
        d_a: dx * (h - r[b]) / (dr * dr),
        d_b: -dx * (h - r[a]) / (dr * dr),
        d_h: dx / dr,
    }
}

/// The outer bin of the first crossing of `h` walking from the peak `k` by
/// `step` (-1 or +1); `None` when the grid ends first or a bin is not finite.
fn outer_bin(r: &[f64], k: usize, step: isize, h: f64) -> Option<usize> {
    let mut j = k;
    loop {
        j = j.checked_add_signed(step).filter(|&j| j < r.len())?;
        if !r[j].is_finite() {
            return None;
        }
        if r[j] <= h {
            return Some(j);
        }
    }
}

/// The specular peak of an estimate `rho` on the bins `bins_deg`
/// (ascending) with per-bin standard uncertainties `u`, the view at
/// `view_deg` (module docs).
///
/// # Panics
/// If the three slices differ in length.
pub fn specular_peak(bins_deg: &[f32], rho: &[f32], u: &[f32], view_deg: f64) -> Peak {
    assert!(bins_deg.len() == rho.len() && rho.len() == u.len(), "one value and one uncertainty per bin");
    let x: Vec<f64> = bins_deg.iter().map(|&v| f64::from(v)).collect();
    let r: Vec<f64> = rho.iter().map(|&v| f64::from(v)).collect();
    let half = SPECULAR_APERTURE_DEG / 2.0 + EDGE_SLACK_DEG;
    let aperture: Vec<usize> = (0..x.len()).filter(|&j| (x[j] - view_deg).abs() <= half).collect();
    if aperture.is_empty() || aperture.iter().any(|&j| !r[j].is_finite()) {
        return Peak::NONE;
    }
    // The first of the highest bins.
    let k = aperture.iter().copied().fold(aperture[0], |best, j| if r[j] > r[best] { j } else { best });
    let (Some(left), Some(right)) = (k.checked_sub(1), Some(k + 1).filter(|&j| j < r.len())) else {
        return Peak::NONE;
    };
    let (top, l, rt) = (r[k], r[left], r[right]);
    let is_max = l.is_finite() && rt.is_finite() && top >= l && top >= rt && (top > l || top > rt);
    if !(top > 0.0 && is_max) {
        return Peak::NONE;
    }
    let mut peak = Peak { rf: top, u_rf: f64::from(u[k]), deg: x[k], ..Peak::NONE };
    let h = top / 2.0;
    let (Some(a_l), Some(a_r)) = (outer_bin(&r, k, -1, h), outer_bin(&r, k, 1, h)) else {
        return peak;
    };
    let (cl, cr) = (crossing(&x, &r, a_l, a_l + 1, h), crossing(&x, &r, a_r, a_r - 1, h));
    // d width / d R_j over the bins the width depends on (the peak may be
    // the inner bin of a crossing, so contributions add up).
    let mut grad = vec![0.0f64; r.len()];
    for (c, a, b, sign) in [(&cr, a_r, a_r - 1, 1.0), (&cl, a_l, a_l + 1, -1.0)] {
        grad[a] += sign * c.d_a;
        grad[b] += sign * c.d_b;
        grad[k] += sign * c.d_h * 0.5;
    }
    let var: f64 = grad.iter().zip(u).map(|(g, &u)| (g * f64::from(u)).powi(2)).sum();
    peak.width_deg = cr.deg - cl.deg;
    peak.u_width_deg = var.sqrt();
    peak
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn a_peak_within_sqrt_2_of_the_resolution_states_no_uncertainty() {
        let x = grid();
        let u = vec![0.02f32; x.len()];
        let at = |fwhm: f64, res: Option<f64>| {
            specular_peak(&x, &gaussian(&x, 1.0, fwhm, 45.0, 0.0), &u, 45.0).stated(res, None)
        };
        // Without a recorded resolution nothing changes.
        let bare = specular_peak(&x, &gaussian(&x, 1.0, 1.2, 45.0, 0.0), &u, 45.0);
        assert_eq!(at(1.2, None), bare);
        assert_eq!(bare.resolved, None);
        // 1.2 deg wide against a resolution of 1: below sqrt 2, so not resolved,
        // the values kept, their uncertainties not stated.
        let narrow = at(1.2, Some(1.0));
        assert_eq!(narrow.resolved, Some(false));
        assert_eq!((narrow.rf, narrow.deg, narrow.width_deg), (bare.rf, bare.deg, bare.width_deg));
        assert!(narrow.u_rf.is_nan() && narrow.u_width_deg.is_nan());
        // 1.6 deg: resolved, as it was.
        let wide = at(1.6, Some(1.0));
        assert_eq!(wide.resolved, Some(true));
        assert!(wide.u_rf.is_finite() && wide.u_width_deg.is_finite());
        // A lobe on a level above half its height has no width: it is wide.
        let flat = specular_peak(&x, &gaussian(&x, 0.5, 3.0, 45.0, 0.6), &u, 45.0).stated(Some(1.0), None);
        assert!(flat.width_deg.is_nan());
        assert_eq!(flat.resolved, Some(true));
        // No peak stays no peak.
        assert_eq!(Peak::NONE.stated(Some(1.0), None).resolved, None);
    }

    #[test]
    fn a_resolved_peak_states_its_uncertainties_times_the_calibrations_factors() {
        let x = grid();
        let u = vec![0.02f32; x.len()];
        let f = Some(PeakFactors { height: 1.5, width: 2.0 });
        let peak = |fwhm: f64| specular_peak(&x, &gaussian(&x, 1.0, fwhm, 45.0, 0.0), &u, 45.0);
        let (plain, scaled) = (peak(1.6).stated(Some(1.0), None), peak(1.6).stated(Some(1.0), f));
        assert_eq!((scaled.rf, scaled.width_deg, scaled.resolved), (plain.rf, plain.width_deg, Some(true)));
        assert!((scaled.u_rf - 1.5 * plain.u_rf).abs() <= 1e-15 && plain.u_rf > 0.0);
        assert!((scaled.u_width_deg - 2.0 * plain.u_width_deg).abs() <= 1e-15 && plain.u_width_deg > 0.0);
        // An unresolved peak still states none.
        let narrow = peak(1.2).stated(Some(1.0), f);
        assert!(narrow.u_rf.is_nan() && narrow.u_width_deg.is_nan());
    }

    /// 0.5 deg bins over 25..65 deg, the instrument's grid.
    fn grid() -> Vec<f32> {
        (0..81).map(|i| 25.0 + 0.5 * i as f32).collect()
    }

    /// A Gaussian lobe of `height` and full width at half maximum `fwhm`
    /// centred at `centre` over a level `base`.
    fn gaussian(x: &[f32], height: f64, fwhm: f64, centre: f64, base: f64) -> Vec<f32> {
        let c = 4.0 * std::f64::consts::LN_2 / (fwhm * fwhm);
        x.iter().map(|&t| (base + height * (-c * (f64::from(t) - centre).powi(2)).exp()) as f32).collect()
    }

    #[test]
    fn a_gaussian_lobe_gives_back_its_height_and_width() {
        let x = grid();
        let u = vec![0.01f32; x.len()];
        for (height, fwhm) in [(2.0, 4.0), (30.0, 1.5), (0.8, 9.0)] {
            let p = specular_peak(&x, &gaussian(&x, height, fwhm, 45.0, 0.0), &u, 45.0);
            assert!((p.rf - height).abs() <= 1e-6 * height, "{p:?}");
            assert_eq!(p.deg, 45.0);
            // Linear interpolation between 0.5 deg bins: the chord of a
            // Gaussian at half maximum, within 2.5 % of the width down to a
            // lobe three bins wide (2.0 % there).
            assert!((p.width_deg - fwhm).abs() <= 0.025 * fwhm, "height {height} fwhm {fwhm}: {p:?}");
            assert_eq!(p.u_rf, 0.01f32 as f64);
            assert!(p.u_width_deg > 0.0 && p.u_width_deg.is_finite());
        }
    }

    #[test]
    fn a_triangle_has_its_width_exactly() {
        // Linear between the bins, so the interpolated crossings are exact:
        // a triangle 1 high, 3 deg from peak to foot, is 3 deg wide at half height.
        let x = grid();
        let rho: Vec<f32> = x.iter().map(|&t| (1.0 - (t - 44.0).abs() / 3.0).max(0.0)).collect();
        let p = specular_peak(&x, &rho, &vec![0.02; x.len()], 45.0);
        assert_eq!((p.rf, p.deg), (1.0, 44.0));
        assert!((p.width_deg - 3.0).abs() < 1e-6, "{p:?}");
    }

    #[test]
    fn the_uncertainty_grows_with_the_bins_and_matches_a_monte_carlo() {
        let x = grid();
        let rho = gaussian(&x, 2.0, 3.0, 45.0, 0.1);
        let u1: Vec<f32> = (0..x.len()).map(|j| 0.002 + 0.0001 * (j % 5) as f32).collect();
        let u2: Vec<f32> = u1.iter().map(|u| 2.0 * u).collect();
        let (p1, p2) = (specular_peak(&x, &rho, &u1, 45.0), specular_peak(&x, &rho, &u2, 45.0));
        assert_eq!((p1.rf, p1.width_deg), (p2.rf, p2.width_deg), "u does not move the values");
        assert!((p2.u_rf - 2.0 * p1.u_rf).abs() <= 1e-12);
        assert!((p2.u_width_deg - 2.0 * p1.u_width_deg).abs() <= 1e-9 * p1.u_width_deg);
        assert!(p1.u_width_deg > 0.0);
        // Small u (the crossings stay between the same bins): a seeded Monte
        // Carlo of the same definition agrees with first order within its
        // own sampling error (2000 draws: about 1.6 % of u).
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let n01 = Normal::new(0.0, 1.0).unwrap();
        let draws: Vec<f64> = (0..2000)
            .map(|_| {
                let noisy: Vec<f32> = rho.iter().zip(&u1).map(|(r, u)| r + u * n01.sample(&mut rng) as f32).collect();
                specular_peak(&x, &noisy, &u1, 45.0).width_deg
            })
            .collect();
        let mean = draws.iter().sum::<f64>() / draws.len() as f64;
        let sd = (draws.iter().map(|w| (w - mean).powi(2)).sum::<f64>() / (draws.len() - 1) as f64).sqrt();
        assert!((sd / p1.u_width_deg - 1.0).abs() < 0.06, "Monte Carlo {sd}, first order {}", p1.u_width_deg);
    }

    #[test]
    fn no_peak_when_flat_negative_or_rising_out_of_the_aperture() {
        let x = grid();
        let u = vec![0.01f32; x.len()];
        let none = |rho: &[f32], view: f64| {
            let p = specular_peak(&x, rho, &u, view);
            [p.rf, p.u_rf, p.deg, p.width_deg, p.u_width_deg].iter().all(|v| v.is_nan())
        };
        assert!(none(&vec![0.3; x.len()], 45.0), "flat");
        assert!(none(&gaussian(&x, -1.0, 3.0, 45.0, 0.0), 45.0), "a dip below zero");
        assert!(none(&gaussian(&x, 1.0, 3.0, 45.0, -2.0), 45.0), "a peak below zero");
        // A lobe at 52 deg rises through the aperture 41..49 to its edge.
        assert!(none(&gaussian(&x, 1.0, 3.0, 52.0, 0.0), 45.0), "rising at the edge");
        let mut nan = gaussian(&x, 1.0, 3.0, 45.0, 0.0);
        nan[40] = f32::NAN;
        assert!(none(&nan, 45.0), "a bin without a value");
        // The aperture follows the view: the same lobe seen from 52 deg is a peak.
        let p = specular_peak(&x, &gaussian(&x, 1.0, 3.0, 52.0, 0.0), &u, 52.0);
        assert_eq!((p.rf, p.deg), (1.0, 52.0));
        // A grid that ends at the peak: no neighbour there, no peak.
        let cut = 41;
        assert!(specular_peak(&x[..cut], &gaussian(&x, 1.0, 3.0, 45.0, 0.0)[..cut], &u[..cut], 45.0).rf.is_nan());
    }

    #[test]
    fn a_lobe_on_a_high_level_has_a_height_but_no_width() {
        let x = grid();
        let u = vec![0.01f32; x.len()];
        let p = specular_peak(&x, &gaussian(&x, 0.5, 3.0, 45.0, 0.6), &u, 45.0);
        assert!((p.rf - 1.1).abs() < 1e-6 && p.deg == 45.0, "{p:?}");
        assert!(p.width_deg.is_nan() && p.u_width_deg.is_nan(), "{p:?}");
    }
}
