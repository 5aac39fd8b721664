//! Training's part of the gloss readings (`brdf_meter::gloss`): per zone
//! and cluster, the rows `A W` of the linear readings and their error
//! covariance `A E A^T`, and the calibration on the gloss standard: each
//! zone's reading `S_z` of the simulated black glass through its own
//! estimator, by the device's own function, so a black glass reads the
//! standard's assigned value (100 GU) on the device.
//!
//! `A` is `crate::forward::gloss::reading_weights` (the definitions); `E`
//! the estimator's error covariance (per unit scale for the scale-free
//! kinds, whose `[W' | b]` takes the readings with the last replaced by
//! their scale: the same kernel input the device uses for the rows).
//!
//! # The rows' own prior
//! No prior of the BRDF estimators holds a mirror, so an estimator trained
//! on one misreads the black glass (the definition's `L_0` over the
//! estimate was 0.55 for Wiener on the Ward prior, 0.74 and 0.80 for the
//! scale-free kinds on MERL), and calibrating on the standard then rescales
//! every reading by that factor. The rows are therefore trained from their
//! own estimator (W for the BRDF stays as it is): the same kind, on the
//! same optics and noise, with the prior augmented by [`gloss_standards`]
//! (the black glass and other smooth dielectrics, bare and over a diffuse
//! base). Weight, on principle: the readings are defined against the
//! standard, so the standards are a family of their own beside the prior,
//! the two mixed at equal weight ([`STANDARDS_WEIGHT`], [`augmented_r_pp`],
//! [`augmented_samples`]); the rows' covariance is that same augmented
//! estimator's.
//!
//! # The stated uncertainty
//! The posterior covariance is too small for materials outside the prior and
//! leaves out the standard's own misreading, which every gloss and haze
//! reading inherits through `q`. Training holds the prior's samples out in
//! [`HELD_OUT_FOLDS`] folds, trains each fold's rows (and their reading of
//! the standard) on the others, reads the held-out samples by the device's
//! function and scales the covariance per reading so that [`COVERAGE`] of
//! them fall within [`COVERAGE_K`] u ([`uncertainty_factors`],
//! [`scale_block`]). Training data only: the test set never enters it.
use crate::calibration::estimators::scale_free::WeightedSamples;
use crate::forward::brdf::smooth_dielectric::{BLACK_GLASS_INDEX, fresnel_unpolarised};
use crate::forward::brdf::{Lambertian, SmoothDielectric};
use crate::forward::gloss::{ASSIGNED_GU, reading_weights, true_rho};
use anyhow::Context;
use brdf_meter::gloss::{LINEAR, block_len, cov_index};
use nalgebra::{DMatrix, DVector};

/// What `train` says when a calibration carries no gloss readings.
pub const NO_GLOSS_NOTE: &str = "no gloss readings in this calibration (the device streams NaN): the angle grid does not \
     cover the 8 deg specular aperture about the view, or no zone sees the black-glass standard's mirror \
     reflection (no LED ray within a bin of the specular direction from any zone)";

/// What `train` says about the zones of a calibration with gloss readings
/// that have none (empty when every zone has them).
pub fn zones_without_reading_note(view: &brdf_meter::blob::BlobView<'_>) -> Option<String> {
    let mut block = vec![0.0f32; block_len(view.dims().m)];
    let none: Vec<String> = (0..view.dims().zones)
        .filter(|z| view.copy_gloss(*z, 0, &mut block).is_some_and(|(_, _, s)| s.is_nan()))
        .map(|z| z.to_string())
        .collect();
    (!none.is_empty()).then(|| {
        format!(
            "no gloss reading in zone(s) {} of {} (the device streams NaN for their points): they do not see the \
             black-glass standard's mirror reflection (no LED ray within a bin of the specular direction)",
            none.join(", "),
            view.dims().zones
        )
    })
}

/// The gloss section training writes.
#[derive(Clone, Debug, PartialEq)]
pub struct GlossSection {
    /// Per zone, the standard's specular linear reading (Z).
    pub reference: Vec<f32>,
    /// Per zone and cluster, the block (rows then packed covariance).
    pub blocks: Vec<f32>,
}

impl GlossSection {
    /// Appends a zone without a reading (it cannot see the standard): its
    /// reference and its `values` block values NaN, the blob's marker
    /// (`brdf_meter::blob`, format version 3), so the device streams NaN
    /// readings for its points.
    pub fn push_no_reading(&mut self, values: usize) {
        self.reference.push(f32::NAN);
        self.blocks.extend(std::iter::repeat_n(f32::NAN, values));
    }

    /// The section, or `None` when no zone has a reading (nothing to carry).
    pub fn if_any_reading(self) -> Option<Self> {
        self.reference.iter().any(|s| !s.is_nan()).then_some(self)
    }

    /// The blob's view of it.
    pub fn data(&self) -> brdf_meter::blob::GlossData<'_> {
        brdf_meter::blob::GlossData {
            assigned_gu: ASSIGNED_GU as f32,
            refractive_index: BLACK_GLASS_INDEX as f32,
            reference: &self.reference,
            blocks: &self.blocks,
        }
    }
}

/// One zone and cluster's block: rows `A W` (LINEAR x m), the packed
/// `A E A^T` and the square roots of its first two diagonal entries.
pub fn block(a: &DMatrix<f64>, w: &DMatrix<f64>, e: &DMatrix<f64>) -> Vec<f32> {
    let m = w.ncols();
    let rows = a * w;
    let cov = a * e * a.transpose();
    let mut out = Vec::with_capacity(block_len(m));
    out.extend(rows.transpose().iter().map(|x| *x as f32));
    let mut packed = vec![0.0f32; brdf_meter::gloss::COV_LEN];
    for i in 0..LINEAR {
        for j in i..LINEAR {
            let c = 0.5 * (cov[(i, j)] + cov[(j, i)]);
            packed[cov_index(i, j)] = if i == j { c.max(0.0) as f32 } else { c as f32 };
        }
    }
    out.extend(packed);
    out.extend([cov[(0, 0)].max(0.0).sqrt() as f32, cov[(1, 1)].max(0.0).sqrt() as f32]);
    out
}

/// The black glass's corrected readings through zone optics `h`.
pub fn black_glass_readings(h: &DMatrix<f64>, bins: &[f64], view_deg: f64) -> DVector<f64> {
    let step = if bins.len() > 1 { bins[1] - bins[0] } else { 1.0 };
    h * true_rho(&SmoothDielectric::black_glass(), bins, view_deg, step)
}

/// The zone's reading `S_z` of the standard: the device's own linear
/// reading `L_0` (f32, `brdf_meter::gloss::readings` with q = 1) of the
/// black glass's readings `v` (already the kernel input `x`), through
/// `block`. `None` for a reading that is not positive: the zone does not
/// see the standard's mirror reflection (no LED ray near the specular
/// direction from where it looks), so no gloss scale can be set and the
/// zone has no gloss reading ([`GlossSection::push_no_reading`]).
pub fn standard_reading(block: &[f32], x: &[f32]) -> Option<f32> {
    let (r, _) = brdf_meter::gloss::readings(block, x, 1.0, 1.0);
    let s = r[brdf_meter::gloss::SPECULAR_GU];
    (s.is_finite() && s > 0.0).then_some(s)
}

/// The weights of the definitions, or why the grid cannot carry them.
pub fn weights(bins: &[f64], view_deg: f64) -> anyhow::Result<DMatrix<f64>> {
    reading_weights(bins, view_deg).with_context(|| {
        format!(
            "the angle grid {:?}..{:?} deg does not cover the 8 deg specular aperture about {view_deg} deg",
            bins.first(),
            bins.last()
        )
    })
}

/// Refractive indices of the smooth dielectrics in the rows' prior (glass,
/// lacquers and plastics, the black-glass standard among them).
pub const STANDARD_INDICES: [f64; 4] = [1.45, 1.5, BLACK_GLASS_INDEX, 1.7];
/// Albedos of the diffuse base under the dielectric surface (0: bare, as
/// the black glass; then dark to white glossy paints).
pub const STANDARD_BASE_ALBEDOS: [f64; 4] = [0.0, 0.05, 0.3, 0.9];

/// The samples added to the rows' prior (n x K, on `bins`, view `view_deg`):
/// for every index of [`STANDARD_INDICES`] and albedo of
/// [`STANDARD_BASE_ALBEDOS`], the smooth dielectric's Fresnel spike plus
/// the light it transmits, `1 - F(theta_o)`, returned by a Lambertian base.
pub fn gloss_standards(bins: &[f64], view_deg: f64) -> DMatrix<f64> {
    let step = if bins.len() > 1 { bins[1] - bins[0] } else { 1.0 };
    let mut cols = Vec::new();
    for n in STANDARD_INDICES {
        let spike = true_rho(&SmoothDielectric::new(n).expect("indices in range"), bins, view_deg, step);
        let transmitted = 1.0 - fresnel_unpolarised(view_deg, n);
        for a in STANDARD_BASE_ALBEDOS {
            let base = true_rho(&Lambertian::new(a * transmitted).expect("albedo in range"), bins, view_deg, step);
            cols.push(&spike + base);
        }
    }
    DMatrix::from_columns(&cols)
}

/// The weight of the standards' family in the rows' prior: the prior and
/// the standards are mixed as two families of equal weight (as
/// `prior_measured::PriorMix` mixes families, `a@0.5+b@0.5`), each
/// family's samples equally weighted within it.
pub const STANDARDS_WEIGHT: f64 = 0.5;

/// `(1 - w) R_pp + w S S^T / K` with `w` [`STANDARDS_WEIGHT`]: the prior
/// correlation mixed with the K columns of `extra`.
pub fn augmented_r_pp(r_pp: &DMatrix<f64>, extra: &DMatrix<f64>) -> DMatrix<f64> {
    let k = extra.ncols().max(1) as f64;
    r_pp * (1.0 - STANDARDS_WEIGHT) + extra * extra.transpose() * (STANDARDS_WEIGHT / k)
}

/// The weighted samples with the columns of `extra` appended: the prior's
/// weights times `1 - w`, each of the K added samples `w / K` (`w`
/// [`STANDARDS_WEIGHT`]).
pub fn augmented_samples(prior: &WeightedSamples, extra: &DMatrix<f64>) -> WeightedSamples {
    let n = prior.samples.ncols();
    let mut cols: Vec<DVector<f64>> = (0..n).map(|k| prior.samples.column(k).into_owned()).collect();
    cols.extend((0..extra.ncols()).map(|k| extra.column(k).into_owned()));
    let total: f64 = prior.weights.iter().sum();
    let mut weights: Vec<f64> = prior.weights.iter().map(|w| w / total * (1.0 - STANDARDS_WEIGHT)).collect();
    weights.extend(std::iter::repeat_n(STANDARDS_WEIGHT / extra.ncols().max(1) as f64, extra.ncols()));
    WeightedSamples { samples: DMatrix::from_columns(&cols), weights }
}

/// Folds of the held-out check that sets the uncertainty's scale factors.
pub const HELD_OUT_FOLDS: usize = 5;
/// Noise draws per held-out sample.
pub const HELD_OUT_DRAWS: usize = 4;
/// The coverage factor the stated uncertainty is calibrated for (U = k u,
/// the GUM's ~95 % convention).
pub const COVERAGE_K: f64 = 2.0;
/// The coverage it must reach on held-out training samples.
pub const COVERAGE: f64 = 0.95;

/// The standardised errors `(reading - truth) / u` of one point's readings
/// (gloss, haze, distinctness), from the device's own function; NaN where
/// either side has no reading.
pub fn z_scores(block: &[f32], x: &[f32], q: f32, s: f32, truth: &[f64; 3]) -> [f64; 3] {
    let (r, u) = brdf_meter::gloss::readings(block, x, q, s);
    std::array::from_fn(|i| (f64::from(r[i]) - truth[i]) / f64::from(u[i]))
}

/// Per reading, the factor on the stated uncertainty that makes `COVERAGE`
/// of the held-out training points fall within `COVERAGE_K` of it: the
/// 95th percentile of `|z|` over `COVERAGE_K` (1 when there is none).
/// Set on training data only (each point's rows trained without it), so
/// the test set never enters the calibration.
pub fn uncertainty_factors(z: &[[f64; 3]]) -> [f64; 3] {
    std::array::from_fn(|r| {
        let mut a: Vec<f64> = z.iter().map(|x| x[r].abs()).filter(|x| x.is_finite()).collect();
        if a.is_empty() {
            return 1.0;
        }
        a.sort_by(f64::total_cmp);
        let i = ((COVERAGE * a.len() as f64).ceil() as usize).clamp(1, a.len()) - 1;
        let f = a[i] / COVERAGE_K;
        if f.is_finite() && f > 0.0 { f } else { 1.0 }
    })
}

/// Scales a block's covariance and standard deviations by the factors
/// `f` (gloss, haze, distinctness: the distinctness factor on both the peak
/// and the shoulders), so the device's stated `u` is `f u`.
pub fn scale_block(block: &mut [f32], m: usize, f: [f64; 3]) {
    let fl = [f[0], f[1], f[2], f[2]];
    let c = &mut block[LINEAR * m..];
    for i in 0..LINEAR {
        for j in i..LINEAR {
            c[cov_index(i, j)] = (f64::from(c[cov_index(i, j)]) * fl[i] * fl[j]) as f32;
        }
    }
    let sd = &mut c[brdf_meter::gloss::COV_LEN..];
    sd[0] = (f64::from(sd[0]) * f[0]) as f32;
    sd[1] = (f64::from(sd[1]) * f[1]) as f32;
}

/// One noisy draw of readings `v` (relative noise `noise_rel`).
pub fn noisy(v: &DVector<f64>, noise_rel: f64, rng: &mut rand_chacha::ChaCha8Rng) -> DVector<f64> {
    use rand_distr::{Distribution, Normal};
    let nd = Normal::new(0.0, 1.0).expect("unit normal");
    v.map(|x| x * (1.0 + noise_rel * nd.sample(rng)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::grid::AngleGrid;

    #[test]
    fn the_standards_hold_the_black_glass_and_mix_at_the_stated_weight() {
        let g = AngleGrid::patent();
        let s = gloss_standards(g.bins_deg(), 45.0);
        assert_eq!(s.ncols(), STANDARD_INDICES.len() * STANDARD_BASE_ALBEDOS.len());
        let bg = true_rho(&SmoothDielectric::black_glass(), g.bins_deg(), 45.0, g.step_deg());
        assert!((0..s.ncols()).any(|k| (s.column(k) - &bg).amax() == 0.0), "the bare black glass is a sample");
        let prior = WeightedSamples::equal(DMatrix::from_element(g.n(), 3, 0.5));
        let aug = augmented_samples(&prior, &s);
        assert!((aug.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let extra: f64 = aug.weights[3..].iter().sum();
        assert!((extra - STANDARDS_WEIGHT).abs() < 1e-12, "{extra}");
        let r = augmented_r_pp(&(&prior.samples * prior.samples.transpose() / 3.0), &s);
        let want = prior.samples.column(0) * prior.samples.column(0).transpose() * (1.0 - STANDARDS_WEIGHT)
            + &s * s.transpose() * (STANDARDS_WEIGHT / s.ncols() as f64);
        assert!((r - want).amax() < 1e-9);
    }

    #[test]
    fn uncertainty_factors_reach_the_coverage_and_scale_the_block() {
        // |z| = 0.1, 0.2, ... 10.0 (100 points): the 95th is 9.5, over k = 2.
        let z: Vec<[f64; 3]> = (1..=100).map(|i| [f64::from(i) / 10.0, -f64::from(i) / 20.0, f64::NAN]).collect();
        let f = uncertainty_factors(&z);
        assert_eq!(f, [9.5 / COVERAGE_K, 4.75 / COVERAGE_K, 1.0]);
        let m = 2;
        let mut block = vec![1.0f32; brdf_meter::gloss::block_len(m)];
        scale_block(&mut block, m, [2.0, 3.0, 0.5]);
        let c = &block[LINEAR * m..];
        assert_eq!(c[cov_index(0, 0)], 4.0);
        assert_eq!(c[cov_index(0, 1)], 6.0);
        assert_eq!(c[cov_index(2, 3)], 0.25);
        assert_eq!(c[cov_index(1, 3)], 1.5);
        assert_eq!(&c[brdf_meter::gloss::COV_LEN..], &[2.0, 3.0]);
        assert_eq!(&block[..LINEAR * m], &[1.0; 8], "the rows are untouched");
    }
}
