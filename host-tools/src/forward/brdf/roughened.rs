//! A material made rougher: the same material's surface with its facets'
//! normals spread by a further isotropic Gaussian of tilts (standard
//! deviation `sigma` per axis), as a finer or coarser finish of one
//! material spreads its lobe. It is how a prior of measured materials, each
//! measured at one finish, also holds the finishes between them
//! (`crate::forward::prior_models::PriorModels::finishes`): the measured sets' glossy lobes are
//! cusps (a polished material's lobe falls off within a few tenths of a
//! degree), and a prior of cusps alone reads a round-topped lobe of a few
//! degrees with a notch at the mirror incidence.
//!
//! Tilting the normal by a small `t` moves the half vector's offset from
//! the normal (a 2-D vector of length `theta_h`) by `t` and leaves the
//! difference angle alone, so near the mirror direction the rougher
//! material is the original convolved over the half vector's offset with
//! the tilts' Gaussian. An isotropic material depends on the offset's
//! length only, and the convolution of a radial function with an isotropic
//! Gaussian is radial, one integral over the original's `theta_h` at the
//! same difference vector:
//!
//! `f'(r0, d) = int f(r, d) (r / s^2) exp(-(r0 - r)^2 / 2 s^2) I0e(r0 r / s^2) dr`
//!
//! (`I0e` the exponentially scaled modified Bessel function), taken by the
//! midpoint rule on nodes squeezed towards `r = 0` when the kernel reaches
//! it, where measured lobes are narrowest. The small-angle model neglects
//! the facets' foreshortening (a few parts in a thousand at a 2 deg tilt,
//! both sides together) and treats the hemisphere's curvature as flat over
//! a few `sigma`; a diffuser stays a diffuser, and the lobe keeps its flux.
use super::Brdf;
use super::nbrdf::half_and_difference;
use nalgebra::Vector3;
use std::sync::Arc;

/// Kernel half-width, in `sigma`.
const REACH: f64 = 6.0;
/// Quadrature nodes when the kernel reaches `theta_h = 0` (squeezed there).
const NODES_AT_PEAK: usize = 32;
/// Quadrature nodes elsewhere (the original is smooth there: one per
/// `sigma`; four per `sigma`, with 96 at the peak, gave the same `accuracy`
/// figures to the digit).
const NODES_ELSEWHERE: usize = 12;

/// `brdf` with its facets' normals spread by a further Gaussian of tilts.
#[derive(Debug)]
pub struct Roughened {
    inner: Arc<dyn Brdf>,
    sigma: f64,
}

impl Roughened {
    /// `inner` with a further isotropic Gaussian of facet tilts, standard
    /// deviation `sigma_deg` (> 0) per axis.
    pub fn new(inner: Arc<dyn Brdf>, sigma_deg: f64) -> Self {
        assert!(sigma_deg > 0.0 && sigma_deg.is_finite(), "tilt spread {sigma_deg} deg must be positive");
        Self { inner, sigma: sigma_deg.to_radians() }
    }
}

/// `exp(-x) I0(x)` for `x >= 0` (Abramowitz and Stegun 9.8.1-9.8.2,
/// relative error below 2e-7).
fn i0e(x: f64) -> f64 {
    if x <= 3.75 {
        let t = (x / 3.75).powi(2);
        let p = 1.0
            + t * (3.515_622_9
                + t * (3.089_942_4 + t * (1.206_749_2 + t * (0.265_973_2 + t * (0.036_076_8 + t * 0.004_581_3)))));
        p * (-x).exp()
    } else {
        let t = 3.75 / x;
        let p = 0.398_942_28
            + t * (0.013_285_92
                + t * (0.002_253_19
                    + t * (-0.001_575_65
                        + t * (0.009_162_81
                            + t * (-0.020_577_06 + t * (0.026_355_37 + t * (-0.016_476_33 + t * 0.003_923_77)))))));
        p / x.sqrt()
    }
}

/// The pair of directions with half-vector angle `theta_h` (half vector in
/// the x-z plane) and difference vector `d`.
fn pair_at(theta_h: f64, d: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let (s, c) = theta_h.sin_cos();
    let wi = Vector3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z);
    let h = Vector3::new(s, 0.0, c);
    (wi, 2.0 * wi.dot(&h) * h - wi)
}

impl Brdf for Roughened {
    fn f_r(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> f64 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let (r0, d) = half_and_difference(wi, wo);
        let s = self.sigma;
        let hi = (r0 + REACH * s).min(std::f64::consts::FRAC_PI_2);
        let lo = (r0 - REACH * s).max(0.0);
        // Nodes r(x), x uniform on [0, 1]: squeezed as x^2 towards 0 when the
        // kernel reaches the mirror direction, uniform otherwise.
        let (nodes, at_peak) = if lo == 0.0 { (NODES_AT_PEAK, true) } else { (NODES_ELSEWHERE, false) };
        let (mut sum, mut mass) = (0.0, 0.0);
        for i in 0..nodes {
            let x = (i as f64 + 0.5) / nodes as f64;
            let (r, dr) = if at_peak { (hi * x * x, 2.0 * hi * x) } else { (lo + (hi - lo) * x, hi - lo) };
            let k = r / (s * s) * (-(r0 - r).powi(2) / (2.0 * s * s)).exp() * i0e(r0 * r / (s * s)) * dr;
            mass += k;
            let (a, b) = pair_at(r, &d);
            if a.z > 0.0 && b.z > 0.0 {
                sum += k * self.inner.f_r(&a, &b);
            }
        }
        // The kernel's mass is 1; dividing by the nodes' sum removes the
        // quadrature's error on it (a diffuser stays exactly a diffuser).
        if mass > 0.0 { sum / mass } else { 0.0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::{Lambertian, Ward, light_dir, view_dir};

    #[test]
    fn the_scaled_bessel_function_matches_its_series() {
        // I0(x) = sum (x/2)^(2k) / (k!)^2.
        for x in [0.0f64, 0.5, 2.0, 3.75, 5.0, 20.0] {
            let (mut term, mut i0) = (1.0f64, 1.0f64);
            for k in 1..200 {
                term *= (x / 2.0).powi(2) / (k as f64).powi(2);
                i0 += term;
            }
            let want = i0 * (-x).exp();
            assert!((i0e(x) - want).abs() < 3e-7 * want, "x {x}: {} against {want}", i0e(x));
        }
    }

    #[test]
    fn a_diffuser_stays_a_diffuser() {
        let r = Roughened::new(Arc::new(Lambertian::new(0.8).unwrap()), 2.0);
        for (ti, to) in [(45.0, 45.0), (10.0, 60.0), (70.0, 20.0)] {
            let f = r.f_r(&light_dir(ti), &view_dir(to));
            assert!((f - 0.8 / std::f64::consts::PI).abs() < 1e-12, "{ti}/{to}: {f}");
        }
    }

    #[test]
    fn a_narrow_lobe_spreads_into_a_round_top_of_the_tilts_width_and_keeps_its_flux() {
        // A Ward lobe of alpha 0.01 (about half a degree) roughened by
        // 1.5 deg of tilts: the mirror incidence reads a round top, no
        // longer a cusp, and 2 theta_h = 2 * 1.5 deg off it the lobe has
        // fallen by about the Gaussian's exp(-1/2) (the half vector moves by
        // half the incidence's change).
        let narrow: Arc<dyn Brdf> = Arc::new(Ward::new(0.0, 1.0, 0.01).unwrap());
        let rough = Roughened::new(narrow.clone(), 1.5);
        let r = |t: f64| rough.reflectance(t, 45.0);
        let top = r(45.0);
        assert!(r(44.5) > 0.95 * top && r(45.5) > 0.95 * top, "{} {top} {}", r(44.5), r(45.5));
        let fall = r(45.0 + 3.0) / top;
        assert!((fall - (-0.5f64).exp()).abs() < 0.05, "3 deg off: {fall}");
        // The flux about the mirror direction (over the half vector's
        // offsets, in-plane and across) is the original's.
        let flux = |b: &dyn Brdf| {
            let (n, step) = (161, 0.1f64.to_radians());
            let mut sum = 0.0;
            for i in 0..n {
                for j in 0..n {
                    let (x, y) = ((i as f64 - 80.0) * step, (j as f64 - 80.0) * step);
                    let h = Vector3::new(x, y, 1.0).normalize();
                    let wo = view_dir(45.0);
                    let wi = 2.0 * wo.dot(&h) * h - wo;
                    sum += b.f_r(&wi, &wo);
                }
            }
            sum
        };
        let (a, b) = (flux(narrow.as_ref()), flux(&rough));
        assert!((b / a - 1.0).abs() < 0.03, "flux {b} against {a}");
    }
}
