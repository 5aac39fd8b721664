//! Training of the scale-free estimators and of the out-of-prior statistic
//! (the device side, which the host also runs, is `brdf_meter::kernel::scale_free`).
//!
//! For each prior sample rho_k (weight w_k): readings `v` (its pair's,
//! `crate::forward::pairs`: a reflection model's by its rays, a profile's
//! `H rho`), scale
//! `s = sum v`, normalised readings `u = v / s`, shape `y = rho / s`. The
//! prior is factored from its samples, `C = S S^T` with `S = [sqrt(w_k)
//! (x_k - mean)]` (L = S / sqrt(K) for equal weights), never from an
//! eigen-floored correlation matrix. Because `sum u = 1`, the last reading
//! carries no information once the others are known: that is the singular
//! direction of `cov(u)`, removed explicitly by working with `u'` (the first
//! m-1 coordinates).
//!
//! - Noise: proportional, `v_i (1 + e_i)`, `e ~ N(0, sigma^2)`; to first
//!   order `du = (I - u 1^T) diag(u) e`, so `R' = sigma^2 sum_k w_k P (I - u_k
//!   1^T) diag(u_k)^2 (I - 1 u_k^T) P^T` (P keeps the first m-1 rows).
//! - Predictive covariance `C' = S_u' S_u'^T + R'`; the affine Wiener map
//!   `W' = S_y S_u'^T (C' + lambda tr(C')/(m-1) I)^-1`, `b = mu_y - W' mu'`;
//!   the blob's matrix is `[W' | b]`.
//! - Uncertainty per unit scale: `sqrt(diag(S_y S_y^T - W' S_u' S_y^T))`.
//! - Out-of-prior ([`out_of_prior`]): two forms, each a `G = chol(C)^-1`
//!   and a mean. Linear: `C = C'`, the predictive covariance of `u'` above,
//!   statistic `|G (u' - mu')|^2`. Log-ratio: the covariance of the centred
//!   log shares of the prior's noisy readings. Each zone's threshold is the
//!   `1 - alpha` quantile of the statistic of held-out prior samples (the
//!   cross-validation's folds, each scored by a model without it, with
//!   noise draws), folded into G; training keeps the form whose flagged
//!   held-out estimates are the worse.
//! - lambda (and the piecewise estimator's cluster count) is chosen by k-fold
//!   cross-validation inside the prior, on the error normalised by each
//!   sample's peak: never on a material the evaluation holds out.
//!
//! The root form (`brdf_meter::blob`'s flag bit 3) fits the same affine map
//! to the roots `y = sqrt(rho / s)` instead of `rho / s`; the device
//! squares, so no estimate is negative, and a lobe's sharp peak and its
//! dark tails are nearer one scale for a linear map. Each pair's weight is
//! multiplied by `peak / s`, so an error of the root at the peak counts as
//! the reflectance factor's error relative to the peak would (`d rho = 2 s y
//! dy`). Its uncertainty per unit scale is, per bin and cluster, the
//! `COVERAGE` quantile over held-out readings (each pair read by the fold's
//! map trained without it, with noise draws) of the smallest unit
//! uncertainty whose stated uncertainty (`root_uncertainty`, what the
//! device states) would have covered the reading's error at `COVERAGE_K`;
//! the linear form keeps the in-sample posterior. So each bin is covered
//! on its own, in the reflectance factor where coverage is judged. A
//! quantile and not the RMS: a lobe's bins err with heavy tails (most
//! held-out lobes close, a few far off), so an RMS scaled to cover all the
//! bins together covered the dark bins nearly always and the peak's too
//! rarely (`host-tools accuracy`: peak heights within k = 2 50 % of the
//! time on measured materials, 38 % on the gloss standards; 55 % and 64 %
//! with the quantile of the roots' errors and one factor on every bin,
//! which let the many dark bins' coverage buy the peak's; 61 % and 68 %
//! with each bin's own quantile, and 97 % on the measured materials once
//! their training readings were the rays' rather than `H rho`,
//! `crate::forward::pairs`). Given the grid (`ScaleFreeOptions::band_bins`,
//! as `train` gives it), each cluster has two tables, one from its
//! held-out readings whose estimate is sharp and one from those whose
//! estimate is broad (`brdf_meter::band`; a kind with fewer than
//! `MIN_BAND_READINGS` in the cluster takes the kind's over the zone): a
//! cluster's readings may be read either way, and a smooth lobe's specular
//! bins do not err as a mirror's read as the prior's idea of one does.
//! Each quantile also covers the prior's materials as they are and their
//! variants (rougher finishes, stretches across the plane) each on its
//! own (`crate::calibration::families`), so the variants' smooth lobes are
//! not covered at the rate the materials' errors set.
//!
//! The folds of that uncertainty hold out whole *kinds* of material
//! (`shape_folds`: the prior's samples grouped by the shape of their
//! readings), not random samples. A material the instrument reads in the
//! field is often unlike anything in the prior, and a fold of random
//! samples almost always leaves a near twin of each held-out sample in
//! training, so the uncertainty it learns holds only for materials the
//! prior already has. Holding out a whole group makes the fit extrapolate
//! as it must for a new kind of surface, still from training data alone.
//!
//! A point the out-of-prior flag raises may be read worse than the band
//! says, so the same held-out kinds are each scored by the flag's model
//! fitted without them, and those it raises say how much wider a flagged
//! point's band must be to cover them as the band covers all
//! (`out_of_prior::band_factor`, one factor per calibration, at least 1;
//! the device applies it through the point's `sigma_scale`,
//! `brdf_meter::kernel::scale_free::flagged_sigma_scale`). On the MERL
//! prior the flagged held-out kinds are covered about as the rest are
//! (factor 1.02 on the patent profile, 1.00 on the handheld since the
//! band covers each family on its own; 1.08 there before it held its
//! materials stretched across the plane).
//!
//! Where it lives: this file, the trained zone and [`train_pairs`], the
//! path from pairs to it; `normalised`, the pairs over their scale and the
//! affine map's fit; `fit`, the maps of a set of pairs, per cluster;
//! `cross_validation`, the folds and the choice of ridge and cluster count;
//! `band`, the per-bin uncertainty from the kinds held out whole.

mod band;
mod cross_validation;
mod fit;
mod normalised;
#[cfg(test)]
mod tests;

pub(crate) use band::weighted_quantile;
pub use cross_validation::{CountScore, guarded_count, score_counts};
pub use fit::{fit_target, fit_target_with, kind_folds, reading_centroids};
pub use normalised::gloss_levels;

use band::held_out_uncertainty;
use cross_validation::{CrossValidation, DRAWS, shape_folds};
use fit::{Fitted, fit};
use normalised::{Form, Normalised, fit_map, moments, normalise, peaks, whitening};

use crate::calibration::estimators::clustered::kmeans;
use crate::calibration::estimators::out_of_prior;
use crate::calibration::families::weighted_quantile_of_each;
use crate::calibration::gloss_rows::{COVERAGE, COVERAGE_K};
use crate::calibration::peak_factors::{self, HeldOutPeak};
use crate::forward::pairs::{Criterion, Pairs};
use crate::forward::reading_noise::ReadingNoise;
use anyhow::{Context, ensure};
use brdf_meter::kernel::scale_free::{
    OutOfPriorForm, estimate_scale_free, estimate_scale_free_root, root_uncertainty, whitening_len,
};
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Relative ridges tried by cross-validation.
pub const RIDGES: [f64; 7] = [1e-8, 1e-6, 1e-4, 1e-3, 1e-2, 3e-2, 1e-1];
/// Cluster counts tried for the piecewise form: up to 6, which the product's
/// calibration slot holds for the handheld's 16 zones with room to spare
/// (273 KB of the 320 KiB; 7 would take about 318 KB). Which one a
/// calibration takes: [`guarded_count`], among those whose blob the device's
/// slot takes (`calibration::train::TrainSpec::max_blob_len`).
pub const CLUSTER_COUNTS: [usize; 5] = [2, 3, 4, 5, 6];

/// Default false-alarm rate of the out-of-prior flag on held-out prior samples.
pub const DEFAULT_FALSE_ALARM: f64 = 0.05;
/// Folds of the cross-validation.
pub const FOLDS: usize = 5;

/// Prior samples with weights (summing to 1).
#[derive(Clone, Debug)]
pub struct WeightedSamples {
    /// n x K, one sample per column.
    pub samples: DMatrix<f64>,
    /// K weights, summing to 1.
    pub weights: Vec<f64>,
}

impl WeightedSamples {
    /// Equal weights.
    pub fn equal(samples: DMatrix<f64>) -> Self {
        let k = samples.ncols();
        Self { samples, weights: vec![1.0 / k as f64; k] }
    }

    /// The subset `idx`, weights renormalised.
    pub fn subset(&self, idx: &[usize]) -> Self {
        let cols: Vec<DVector<f64>> = idx.iter().map(|&k| self.samples.column(k).into_owned()).collect();
        let total: f64 = idx.iter().map(|&k| self.weights[k]).sum();
        Self { samples: DMatrix::from_columns(&cols), weights: idx.iter().map(|&k| self.weights[k] / total).collect() }
    }
}

/// One affine scale-free map, as the blob stores it.
#[derive(Clone, Debug)]
pub struct ScaleFreeMap {
    /// `[W' | b]`, n x m.
    pub w: DMatrix<f64>,
    /// Predicted standard uncertainty per unit scale, per bin (n).
    pub sigma_unit: DVector<f64>,
    /// The full error covariance per unit scale (n x n): its diagonal is
    /// `sigma_unit` squared; the gloss readings' covariance is taken from it.
    pub err_unit: DMatrix<f64>,
    /// With the grid a band is decided on ([`ScaleFreeOptions::band_bins`]),
    /// the uncertainty per unit scale of the points whose estimate is broad
    /// (`brdf_meter::band`); `sigma_unit` is then the sharp ones'.
    pub sigma_broad: Option<DVector<f64>>,
}

impl ScaleFreeMap {
    /// Row-major f32 copy (the blob's matrix).
    pub fn w_f32(&self) -> Vec<f32> {
        self.w.transpose().iter().map(|x| *x as f32).collect()
    }

    /// f64 estimate (the reference the f32 path is checked against); in
    /// the root form the map's outputs over `sqrt(s)`, squared.
    pub fn estimate(&self, v: &DVector<f64>, root: bool) -> DVector<f64> {
        let m = v.len();
        let s: f64 = v.iter().sum();
        let mut x = v.clone();
        x[m - 1] = s;
        if root {
            let r = if s > 0.0 { 1.0 / s.sqrt() } else { 0.0 };
            (&self.w * (x * r)).map(|t| t * t)
        } else {
            &self.w * x
        }
    }
}

pub use crate::calibration::estimators::out_of_prior::OutOfPrior;

/// A trained scale-free estimator for one zone.
#[derive(Clone, Debug)]
pub struct ScaleFreeZone {
    /// One map (plain) or K (piecewise).
    pub maps: Vec<ScaleFreeMap>,
    /// K x m centroids, f32 (piecewise only; empty otherwise).
    pub centroids: Vec<f32>,
    /// The out-of-prior model the zone flags with (one of
    /// `out_of_prior_forms`).
    pub out_of_prior: OutOfPrior,
    /// Both forms' models, linear then log-ratio, with their held-out
    /// evidence (`out_of_prior::choose_form`).
    pub out_of_prior_forms: [OutOfPrior; 2],
    /// Relative ridge chosen by cross-validation.
    pub ridge: f64,
    /// Cross-validated mean peak-normalised error of the chosen setting.
    pub cv_error: f64,
    /// Whether the maps are in the root form.
    pub root: bool,
    /// The grid the band's table is decided on, when the maps have the
    /// broad estimates' table (`ScaleFreeMap::sigma_broad`).
    pub band_bins: Option<Vec<f32>>,
    /// The specular peaks of the held-out readings the band was set from,
    /// against their truths' (with `ScaleFreeOptions::peak_views_deg`; else
    /// empty): what the peaks' uncertainty factors are set on
    /// (`crate::calibration::peak_factors`).
    pub held_out_peaks: Vec<HeldOutPeak>,
}

impl ScaleFreeZone {
    /// Estimates one point exactly as the device does: f32, the library's
    /// functions, and the per-bin uncertainty as the host states it (the
    /// table the estimate takes, `brdf_meter::band`). Returns (estimate,
    /// per-bin sigma, statistic, cluster).
    pub fn estimate_f32(&self, v: &[f32]) -> (Vec<f32>, Vec<f32>, f32, usize) {
        let n = self.maps[0].w.nrows();
        let mut out = vec![0.0f32; n];
        let c = if self.centroids.is_empty() { 0 } else { brdf_meter::kernel::select_cluster(&self.centroids, v) };
        let mut sigma = vec![0.0f32; n];
        let s = if self.root {
            let (s, _) = estimate_scale_free_root(&self.maps[c].w_f32(), v, &mut out);
            let unit: Vec<f32> = self.band_of(c, &out).iter().map(|x| *x as f32).collect();
            for j in 0..n {
                sigma[j] = root_uncertainty(unit[j], out[j], s);
            }
            s
        } else {
            let s = estimate_scale_free(&self.maps[c].w_f32(), v, &mut out);
            let unit: Vec<f32> = self.band_of(c, &out).iter().map(|x| *x as f32).collect();
            brdf_meter::kernel::scale_free::scaled_uncertainty(&unit, s, &mut sigma);
            s
        };
        let o = &self.out_of_prior;
        (out, sigma, o.form.stat(&o.g, &o.mean, v, s), c)
    }

    /// Cluster `c`'s uncertainty per unit scale for the estimate `est`: the
    /// broad estimates' table when the zone has one and `est` is broad on
    /// its grid, else `sigma_unit`.
    pub fn band_of(&self, c: usize, est: &[f32]) -> &DVector<f64> {
        let map = &self.maps[c];
        match (&map.sigma_broad, &self.band_bins) {
            (Some(broad), Some(bins)) if brdf_meter::band::is_broad(bins, est) => broad,
            _ => &map.sigma_unit,
        }
    }

    /// Flags with `form`'s model (a calibration's zones share one form).
    pub fn use_out_of_prior_form(&mut self, form: OutOfPriorForm) {
        let i = usize::from(form == OutOfPriorForm::LogRatio);
        self.out_of_prior = self.out_of_prior_forms[i].clone();
    }
}

/// Peak-normalised RMS error.
pub fn peak_error(est: &DVector<f64>, truth: &DVector<f64>) -> f64 {
    let peak = truth.amax().max(f64::MIN_POSITIVE);
    ((est - truth).norm_squared() / truth.len() as f64).sqrt() / peak
}

/// Settings of [`train_pairs`].
#[derive(Clone, Debug)]
pub struct ScaleFreeOptions<'a> {
    /// Relative noise, for [`train_zone`]'s in-plane pairs only (pairs
    /// carry their own noise model).
    pub noise_rel: f64,
    /// Piecewise (cluster count chosen by cross-validation unless
    /// `clusters` fixes it) or not.
    pub piecewise: bool,
    /// Piecewise: the cluster count, fixed (every zone of a calibration
    /// must have the same); `None` chooses it by cross-validation.
    pub clusters: Option<usize>,
    /// False-alarm rate of the flag on held-out prior samples.
    pub false_alarm: f64,
    /// Seed of folds and noise draws.
    pub seed: u64,
    /// The root form (every estimate non-negative).
    pub root: bool,
    /// The grid (deg) a held-out estimate's band table is decided on
    /// (`brdf_meter::band`): with it (and the root form), training sets a
    /// second table per cluster for the broad estimates, `sigma_unit`
    /// then being the sharp ones'; without it, one table for every point.
    pub band_bins: Option<&'a [f32]>,
    /// Each of the pairs' pixels' view (deg, by `Pairs::pixel`): with it
    /// (and `band_bins`, the root form), training keeps the held-out
    /// readings' specular peaks (`ScaleFreeZone::held_out_peaks`).
    pub peak_views_deg: Option<&'a [f64]>,
}

impl Default for ScaleFreeOptions<'_> {
    fn default() -> Self {
        Self {
            noise_rel: 0.02,
            piecewise: false,
            clusters: None,
            false_alarm: DEFAULT_FALSE_ALARM,
            seed: 7,
            root: false,
            band_bins: None,
            peak_views_deg: None,
        }
    }
}

/// The pairs' truths normalised in the options' form.
fn normalise_truth(pairs: &Pairs, opts: &ScaleFreeOptions) -> anyhow::Result<Normalised> {
    let levels = peaks(pairs);
    normalise(pairs, &pairs.truth, if opts.root { Form::Root(&levels) } else { Form::Linear })
}

fn check_pairs(pairs: &Pairs) -> anyhow::Result<()> {
    let m = pairs.m();
    ensure!(m >= 2, "scale-free estimation needs at least 2 readings, got {m}");
    let samples = pairs.sample.iter().collect::<std::collections::BTreeSet<_>>().len();
    ensure!(samples >= 2 * FOLDS, "scale-free training needs at least {} prior samples, got {samples}", 2 * FOLDS);
    Ok(())
}

/// Trains one zone from its pairs (weighted for the training criterion):
/// chooses the ridge (and K, unless fixed) by cross-validation over the
/// prior's samples, fits on every pair, sets the out-of-prior threshold
/// from held-out samples.
pub fn train_pairs(pairs: &Pairs, opts: &ScaleFreeOptions) -> anyhow::Result<ScaleFreeZone> {
    check_pairs(pairs)?;
    let clusters: Vec<usize> = match (opts.piecewise, opts.clusters) {
        (false, _) => vec![1],
        (true, Some(k)) => vec![k],
        (true, None) => CLUSTER_COUNTS.to_vec(),
    };
    let scored = score_counts(pairs, opts, &clusters)?;
    let best = guarded_count(std::slice::from_ref(&scored));
    train_with(pairs, opts, scored[best].ridge, clusters[best], scored[best].random)
}

/// Trains one zone with a given ridge and cluster count (chosen by
/// [`score_counts`]); `cv_error` is recorded.
pub fn train_with(
    pairs: &Pairs,
    opts: &ScaleFreeOptions,
    ridge: f64,
    clusters: usize,
    cv_error: f64,
) -> anyhow::Result<ScaleFreeZone> {
    check_pairs(pairs)?;
    let nz = normalise_truth(pairs, opts)?;
    let all: Vec<usize> = (0..pairs.len()).collect();
    let mut fitted = fit(&nz, &all, opts.seed, ridge, clusters, opts.root)?;
    let cv = CrossValidation::new(pairs, opts.seed);
    // Out-of-prior: both forms' models and thresholds from held-out
    // readings, and how badly the readings each flags are estimated.
    let error = cv.held_out_errors(pairs, &nz, opts, ridge, clusters)?;
    let weight: Vec<f64> = pairs.base.iter().map(|b| b / DRAWS as f64).collect();
    let linear_model = |idx: &[usize]| {
        let mo = moments(&nz, idx);
        Ok((mo.mu_u.iter().map(|x| *x as f32).collect(), whitening(&mo)?))
    };
    let held = out_of_prior::HeldOut {
        readings: &cv.readings,
        weight: &weight,
        fold: &cv.fold,
        variant: &pairs.variant,
        error: &error,
        linear_model: &linear_model,
    };
    let mut out_of_prior_forms = out_of_prior::train(&held, opts.false_alarm)?;
    let mut held_out_peaks = Vec::new();
    if opts.root {
        // The band and what a flag adds to it, both from kinds of material
        // held out whole, each flagged as a kind the prior lacks would be.
        let by_shape = shape_folds(pairs, &nz, opts.seed);
        let by_kind = out_of_prior::HeldOut { fold: &by_shape, ..held };
        let flagged = [
            out_of_prior::held_out_flagged(&by_kind, &out_of_prior_forms[0])?,
            out_of_prior::held_out_flagged(&by_kind, &out_of_prior_forms[1])?,
        ];
        let (ratios, peaks) = held_out_uncertainty(
            pairs,
            &nz,
            (&cv.readings, &by_shape),
            (opts.seed, opts.band_bins, opts.peak_views_deg),
            ridge,
            clusters,
            &mut fitted,
            &flagged,
        )?;
        for (o, (r, on_kinds)) in out_of_prior_forms.iter_mut().zip(ratios) {
            o.band_ratios = r;
            o.on_kinds = on_kinds;
        }
        held_out_peaks = peaks;
    }
    let band_bins = opts.band_bins.filter(|_| fitted.maps.iter().all(|m| m.sigma_broad.is_some())).map(<[f32]>::to_vec);
    let mut zone = ScaleFreeZone {
        maps: fitted.maps,
        centroids: fitted.centroids,
        out_of_prior: out_of_prior_forms[1].clone(),
        out_of_prior_forms,
        ridge,
        cv_error,
        root: opts.root,
        band_bins,
        held_out_peaks,
    };
    zone.use_out_of_prior_form(out_of_prior::choose_form([&zone.out_of_prior_forms]));
    Ok(zone)
}

/// Trains one zone of in-plane optics `h` on samples on the grid (the
/// readings `H rho`, relative noise `opts.noise_rel`, each sample's error
/// relative to its readings' scale): the scale-free estimator as the
/// evaluation of measured materials runs it.
pub fn train_zone(h: &DMatrix<f64>, prior: &WeightedSamples, opts: &ScaleFreeOptions) -> anyhow::Result<ScaleFreeZone> {
    ensure!(prior.samples.nrows() == h.ncols(), "the prior has {} bins, H {}", prior.samples.nrows(), h.ncols());
    let noise = ReadingNoise::relative(opts.noise_rel, h.nrows());
    let pairs = Pairs::in_plane(h, &prior.samples, &prior.weights, &noise).weighted(Criterion::ScaleRelative);
    train_pairs(&pairs, opts)
}
