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

/// Per-pair quantities: normalised readings `u = v / s`, the target over
/// the scale, the noise's standard deviations over the scale, the weight
/// of the pair in the fit (the criterion's weight times `s^2`, since an
/// error of `y` is `s` times smaller than the same error of the target).
struct Normalised {
    u: Vec<DVector<f64>>,
    y: Vec<DVector<f64>>,
    sn: Vec<DVector<f64>>,
    w: Vec<f64>,
}

/// How a target is fitted: as it is, or in the root form with each pair's
/// level (its truth's peak; a gloss row's reading) for the weight.
#[derive(Clone, Copy, Debug)]
enum Form<'a> {
    Linear,
    Root(&'a [f64]),
}

fn normalise(pairs: &Pairs, target: &DMatrix<f64>, form: Form<'_>) -> anyhow::Result<Normalised> {
    let mut out = Normalised { u: Vec::new(), y: Vec::new(), sn: Vec::new(), w: Vec::new() };
    for k in 0..pairs.len() {
        let v = pairs.readings.column(k);
        let s: f64 = v.iter().sum();
        ensure!(
            s > 0.0 && s.is_finite(),
            "prior sample {}: its readings sum to {s}; a sample must reflect some light",
            pairs.sample[k]
        );
        out.u.push(v / s);
        out.sn.push(pairs.noise_var.column(k).map(|x| x.max(0.0).sqrt() / s));
        match form {
            Form::Linear => {
                out.y.push(target.column(k) / s);
                out.w.push(pairs.weights[k] * s * s);
            }
            Form::Root(level) => {
                out.y.push(target.column(k).map(|x| (x.max(0.0) / s).sqrt()));
                out.w.push(pairs.weights[k] * s * level[k].max(f64::MIN_POSITIVE));
            }
        }
    }
    Ok(out)
}

/// Each pair's truth's peak: the root form's level of the BRDF target.
fn peaks(pairs: &Pairs) -> Vec<f64> {
    pairs.truth.column_iter().map(|c| c.amax()).collect()
}

/// A pair's level for a gloss target (its gloss row plus one GU, so a matt
/// sample's rows still count).
pub fn gloss_levels(target: &DMatrix<f64>) -> Vec<f64> {
    target.row(0).iter().map(|g| g.max(0.0) + 1.0).collect()
}

/// Mean, centred factor (columns scaled by sqrt(w)) and noise covariance of
/// `u'`, plus the target's mean and factor.
struct Moments {
    mu_u: DVector<f64>,
    mu_y: DVector<f64>,
    su: DMatrix<f64>,
    sy: DMatrix<f64>,
    r_noise: DMatrix<f64>,
}

fn moments(nz: &Normalised, idx: &[usize]) -> Moments {
    moments_scaled(nz, idx, &vec![1.0; idx.len()])
}

fn moments_scaled(nz: &Normalised, idx: &[usize], mult: &[f64]) -> Moments {
    let m1 = nz.u[0].len() - 1;
    let n = nz.y[0].len();
    let wk = |c: usize| nz.w[idx[c]] * mult[c];
    let total: f64 = (0..idx.len()).map(wk).sum();
    let mut mu_u = DVector::zeros(m1);
    let mut mu_y = DVector::zeros(n);
    for (c, &k) in idx.iter().enumerate() {
        let w = wk(c) / total;
        mu_u += nz.u[k].rows(0, m1) * w;
        mu_y += &nz.y[k] * w;
    }
    let mut su = DMatrix::zeros(m1, idx.len());
    let mut sy = DMatrix::zeros(n, idx.len());
    let mut r_noise = DMatrix::zeros(m1, m1);
    for (c, &k) in idx.iter().enumerate() {
        let w = wk(c) / total;
        let sw = w.sqrt();
        su.set_column(c, &((nz.u[k].rows(0, m1) - &mu_u) * sw));
        sy.set_column(c, &((&nz.y[k] - &mu_y) * sw));
        // du = (I - u 1^T) diag(sigma / s) e, e ~ N(0, I); keep rows < m-1.
        let (u, sn) = (&nz.u[k], &nz.sn[k]);
        let mm = u.len();
        let a = DMatrix::from_fn(m1, mm, |i, j| (if i == j { 1.0 } else { 0.0 } - u[i]) * sn[j]);
        r_noise += (&a * a.transpose()) * w;
    }
    Moments { mu_u, mu_y, su, sy, r_noise }
}

fn fit_map(mo: &Moments, ridge: f64) -> anyhow::Result<ScaleFreeMap> {
    let m1 = mo.mu_u.len();
    let cuu = &mo.su * mo.su.transpose() + &mo.r_noise;
    let lam = ridge * (cuu.trace() / m1 as f64).max(f64::MIN_POSITIVE);
    let reg = &cuu + DMatrix::identity(m1, m1) * lam;
    let chol =
        reg.cholesky().context("the normalised readings' covariance is not positive definite; add samples or noise")?;
    let cyu = &mo.sy * mo.su.transpose();
    // W' = C_yu C^-1  <=>  C W'^T = C_yu^T.
    let wp = chol.solve(&cyu.transpose()).transpose();
    let b = &mo.mu_y - &wp * &mo.mu_u;
    let n = mo.mu_y.len();
    let mut w = DMatrix::zeros(n, m1 + 1);
    w.view_mut((0, 0), (n, m1)).copy_from(&wp);
    w.set_column(m1, &b);
    let err = &mo.sy * mo.sy.transpose() - &wp * &cyu.transpose();
    let sigma_unit = DVector::from_fn(n, |j, _| err[(j, j)].max(0.0).sqrt());
    Ok(ScaleFreeMap { w, sigma_unit, err_unit: err, sigma_broad: None })
}

/// Packed `chol(C')^-1` (lower triangular) of the predictive covariance of
/// `u'` (the linear out-of-prior form's model).
fn whitening(mo: &Moments) -> anyhow::Result<Vec<f32>> {
    let m1 = mo.mu_u.len();
    let c = &mo.su * mo.su.transpose() + &mo.r_noise;
    let jitter = 1e-12 * (c.trace() / m1 as f64).max(f64::MIN_POSITIVE);
    let l = (c + DMatrix::identity(m1, m1) * jitter).cholesky().context("the predictive covariance is singular")?.l();
    let g = l.solve_lower_triangular(&DMatrix::identity(m1, m1)).context("whitening")?;
    let mut packed = Vec::with_capacity(whitening_len(m1 + 1));
    for k in 0..m1 {
        for i in 0..=k {
            packed.push(g[(k, i)] as f32);
        }
    }
    Ok(packed)
}

/// Fold of each prior sample: a fixed shuffle, then round robin. Pairs of
/// one sample (at several pixels) share its fold, so a held-out sample is
/// held out at every pixel.
fn folds(pairs: &Pairs, seed: u64) -> Vec<usize> {
    use rand::seq::SliceRandom;
    let samples = pairs.sample.iter().copied().max().map_or(0, |x| x + 1);
    let mut order: Vec<usize> = (0..samples).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let mut of_sample = vec![0; samples];
    let nf = FOLDS.min(samples.max(1));
    for (pos, &s) in order.iter().enumerate() {
        of_sample[s] = pos % nf;
    }
    pairs.sample.iter().map(|&s| of_sample[s]).collect()
}

/// Folds that each hold out one kind of material: the prior's samples
/// grouped into [`FOLDS`] groups by k-means on the shape of their
/// noise-free readings (`nz.u`, `v / sum v`: what the device's clusters and
/// the out-of-prior statistic see), one group per fold, each sample's pairs
/// together. Falls back to [`folds`] for a prior too small to group
/// (fewer than two samples per fold) or whose groups collapse into one.
fn shape_folds(pairs: &Pairs, nz: &Normalised, seed: u64) -> Vec<usize> {
    // Each sample by its first pair (sample ids may have gaps: a prior
    // with some samples held out).
    let mut first: std::collections::BTreeMap<usize, usize> = std::collections::BTreeMap::new();
    for (k, &s) in pairs.sample.iter().enumerate() {
        first.entry(s).or_insert(k);
    }
    if first.len() < 2 * FOLDS {
        return folds(pairs, seed);
    }
    let points: Vec<Vec<f64>> = first.values().map(|&k| nz.u[k].iter().copied().collect()).collect();
    let (_, labels) = kmeans(&points, FOLDS, seed);
    // Numbered 0.. without gaps, so no fold is empty.
    let mut used = labels.clone();
    used.sort_unstable();
    used.dedup();
    if used.len() < 2 {
        return folds(pairs, seed);
    }
    let of_sample: std::collections::BTreeMap<usize, usize> =
        first.keys().zip(&labels).map(|(s, l)| (*s, used.binary_search(l).unwrap_or(0))).collect();
    pairs.sample.iter().map(|s| of_sample[s]).collect()
}

/// One noisy draw of noise-free readings `v` with variances `var` (a
/// reading cannot go below 0 on a real sensor's dark-corrected signal for
/// long: clamped, as the device's readings of a dark pixel are).
fn noisy(v: &DVector<f64>, var: &DVector<f64>, rng: &mut ChaCha8Rng) -> DVector<f64> {
    let nd = Normal::new(0.0, 1.0).unwrap();
    DVector::from_fn(v.len(), |i, _| (v[i] + var[i].max(0.0).sqrt() * nd.sample(rng)).max(0.0))
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

/// Trained maps for a subset of pairs (piecewise: K clusters).
struct Fitted {
    maps: Vec<ScaleFreeMap>,
    centroids: Vec<f32>,
    root: bool,
}

impl Fitted {
    fn cluster(&self, v: &DVector<f64>) -> usize {
        if self.centroids.is_empty() {
            0
        } else {
            let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
            brdf_meter::kernel::select_cluster(&self.centroids, &v32)
        }
    }

    fn estimate(&self, v: &DVector<f64>) -> DVector<f64> {
        self.maps[self.cluster(v)].estimate(v, self.root)
    }
}

fn fit(nz: &Normalised, idx: &[usize], seed: u64, ridge: f64, clusters: usize, root: bool) -> anyhow::Result<Fitted> {
    let m = nz.u[0].len();
    if clusters <= 1 {
        return Ok(Fitted { maps: vec![fit_map(&moments(nz, idx), ridge)?], centroids: Vec::new(), root });
    }
    // Clusters in the selection rule's space (v / sum|v|; the readings are
    // non-negative, so it is u).
    let feats: Vec<Vec<f64>> = idx.iter().map(|&k| nz.u[k].iter().copied().collect()).collect();
    let (cents, _) = kmeans(&feats, clusters, seed);
    let c32: Vec<f32> = cents.iter().flatten().map(|x| *x as f32).collect();
    let maps = cluster_maps(nz, idx, ridge, &c32, m)?;
    Ok(Fitted { maps, centroids: c32, root })
}

/// One map per centroid of `c32` (K x m, the device's selection rule): each
/// trained on the pairs of `idx` the rule sends to it and, so that every
/// cluster has enough pairs for a stable covariance, the nearest others.
fn cluster_maps(
    nz: &Normalised,
    idx: &[usize],
    ridge: f64,
    c32: &[f32],
    m: usize,
) -> anyhow::Result<Vec<ScaleFreeMap>> {
    let feats: Vec<Vec<f64>> = idx.iter().map(|&k| nz.u[k].iter().copied().collect()).collect();
    let cents: Vec<Vec<f64>> = c32.chunks(m).map(|c| c.iter().map(|x| f64::from(*x)).collect()).collect();
    let k_eff = cents.len();
    let min_members = (3 * m).max(idx.len() / k_eff).min(idx.len());
    let mut maps = Vec::with_capacity(k_eff);
    for (c, cent) in cents.iter().enumerate() {
        let mut by_dist: Vec<(f64, usize)> = idx
            .iter()
            .zip(&feats)
            .map(|(&k, f)| (f.iter().zip(cent).map(|(a, b)| (a - b) * (a - b)).sum::<f64>(), k))
            .collect();
        by_dist.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut members: Vec<usize> = idx
            .iter()
            .zip(&feats)
            .filter(|(_, f)| {
                let v32: Vec<f32> = f.iter().map(|x| *x as f32).collect();
                brdf_meter::kernel::select_cluster(c32, &v32) == c
            })
            .map(|(&k, _)| k)
            .collect();
        for (_, k) in &by_dist {
            if members.len() >= min_members {
                break;
            }
            if !members.contains(k) {
                members.push(*k);
            }
        }
        maps.push(fit_map(&moments(nz, &members), ridge)?);
    }
    Ok(maps)
}

/// Maps of another target for the same zone (the gloss readings' linear
/// readings, `r x K`, one column per pair of `pairs`): the zone's ridge and
/// clusters (its centroids, so the device's cluster choice is unchanged),
/// fitted on every pair.
/// In the zone's root form the maps give roots of the target, each pair
/// weighted by its level [`gloss_levels`].
pub fn fit_target(pairs: &Pairs, target: &DMatrix<f64>, zone: &ScaleFreeZone) -> anyhow::Result<Vec<ScaleFreeMap>> {
    let levels = gloss_levels(target);
    let nz = normalise(pairs, target, if zone.root { Form::Root(&levels) } else { Form::Linear })?;
    let all: Vec<usize> = (0..pairs.len()).collect();
    if zone.centroids.is_empty() {
        return Ok(vec![fit_map(&moments(&nz, &all), zone.ridge)?]);
    }
    cluster_maps(&nz, &all, zone.ridge, &zone.centroids, pairs.m())
}

/// `k` centroids (K x m, f32) of the pairs' normalised readings `v / s`,
/// by the k-means the piecewise maps are clustered with: the selection
/// rule's space (`brdf_meter::kernel::select_cluster`), so a set of rows
/// with clusters of its own (the gloss rows) selects as the maps do.
pub fn reading_centroids(pairs: &Pairs, k: usize, seed: u64) -> Vec<f32> {
    let feats: Vec<Vec<f64>> = pairs
        .readings
        .column_iter()
        .map(|v| {
            let s: f64 = v.iter().map(|x| x.abs()).sum();
            v.iter().map(|x| if s > 0.0 { x / s } else { 0.0 }).collect()
        })
        .collect();
    let (mut cents, _) = kmeans(&feats, k, seed);
    // Fewer distinct readings than k: the last centroid again, which the
    // rule never selects (it takes the first of equal distances).
    while cents.len() < k {
        cents.push(cents.last().expect("k-means gives at least one centroid").clone());
    }
    cents.iter().flatten().map(|x| *x as f32).collect()
}

/// Each pair's fold when the pairs' samples are held out by kind of
/// material ([`FOLDS`] groups by the shape of their readings, as the
/// maps' cluster count is guarded with): what reads a material unlike
/// the rest, where random folds leave a near twin of it behind.
pub fn kind_folds(pairs: &Pairs, seed: u64) -> anyhow::Result<Vec<usize>> {
    let nz = normalise(pairs, &pairs.truth, Form::Linear)?;
    Ok(shape_folds(pairs, &nz, seed))
}

/// [`fit_target`] with clusters of the target's own (`centroids`, K x m
/// in the selection rule's space) in place of the zone's.
pub fn fit_target_with(
    pairs: &Pairs,
    target: &DMatrix<f64>,
    zone: &ScaleFreeZone,
    centroids: &[f32],
) -> anyhow::Result<Vec<ScaleFreeMap>> {
    let levels = gloss_levels(target);
    let nz = normalise(pairs, target, if zone.root { Form::Root(&levels) } else { Form::Linear })?;
    let all: Vec<usize> = (0..pairs.len()).collect();
    cluster_maps(&nz, &all, zone.ridge, centroids, pairs.m())
}

/// The noisy held-out readings of every pair (fixed for every candidate
/// setting) and each pair's fold.
struct CrossValidation {
    readings: Vec<Vec<DVector<f64>>>,
    fold: Vec<usize>,
}

const DRAWS: usize = 2;

impl CrossValidation {
    fn new(pairs: &Pairs, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
        let readings = (0..pairs.len())
            .map(|k| {
                let v = pairs.readings.column(k).into_owned();
                let var = pairs.noise_var.column(k).into_owned();
                (0..DRAWS).map(|_| noisy(&v, &var, &mut rng)).collect()
            })
            .collect();
        Self { readings, fold: folds(pairs, seed) }
    }

    /// Mean peak-normalised error over the prior's own weights of every
    /// pair read by a fit without its fold; `None` when a fit fails.
    fn error(
        &self,
        pairs: &Pairs,
        nz: &Normalised,
        opts: &ScaleFreeOptions,
        ridge: f64,
        clusters: usize,
    ) -> Option<f64> {
        let errors = self.held_out_errors(pairs, nz, opts, ridge, clusters).ok()?;
        // Summed fold by fold, in the order the folds are fitted.
        let nf = self.fold.iter().copied().max().map_or(0, |x| x + 1);
        let mut err = 0.0;
        for f in 0..nf {
            for k in (0..pairs.len()).filter(|k| self.fold[*k] == f) {
                for e in &errors[k] {
                    err += pairs.base[k] * e / DRAWS as f64;
                }
            }
        }
        Some(err)
    }

    /// Per pair and noise draw, the peak-normalised error of its reading
    /// estimated by the fit without its fold.
    fn held_out_errors(
        &self,
        pairs: &Pairs,
        nz: &Normalised,
        opts: &ScaleFreeOptions,
        ridge: f64,
        clusters: usize,
    ) -> anyhow::Result<Vec<Vec<f64>>> {
        let nf = self.fold.iter().copied().max().map_or(0, |x| x + 1);
        let mut errors = vec![Vec::new(); pairs.len()];
        for f in 0..nf {
            let train_idx: Vec<usize> = (0..pairs.len()).filter(|k| self.fold[*k] != f).collect();
            let fitted = fit(nz, &train_idx, opts.seed, ridge, clusters, opts.root)?;
            for k in (0..pairs.len()).filter(|k| self.fold[*k] == f) {
                let truth = pairs.truth.column(k).into_owned();
                errors[k] = self.readings[k].iter().map(|v| peak_error(&fitted.estimate(v), &truth)).collect();
            }
        }
        Ok(errors)
    }
}

/// One zone's score of one cluster count ([`score_counts`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CountScore {
    /// The ridge cross-validation on random folds chose.
    pub ridge: f64,
    /// Its mean peak-normalised error on random folds.
    pub random: f64,
    /// At that ridge, the error with each kind of material held out whole
    /// (the folds of `shape_folds`, each one group of samples alike in the
    /// shape of their readings): what guards the count
    /// ([`guarded_count`]). NaN when only one count is scored.
    pub kinds: f64,
}

/// Scores each of `counts` on one zone's pairs: per count, the best ridge
/// of [`RIDGES`] on random folds and its error, and when more than one
/// count is scored, that fit's error on kinds of material held out whole.
/// The noise draws and both sets of folds are made once, for every count.
pub fn score_counts(pairs: &Pairs, opts: &ScaleFreeOptions, counts: &[usize]) -> anyhow::Result<Vec<CountScore>> {
    check_pairs(pairs)?;
    let nz = normalise_truth(pairs, opts)?;
    let mut cv = CrossValidation::new(pairs, opts.seed);
    let kinds = (counts.len() > 1).then(|| shape_folds(pairs, &nz, opts.seed));
    let mut out = Vec::with_capacity(counts.len());
    for &clusters in counts {
        let mut best = (RIDGES[0], f64::INFINITY);
        for &ridge in &RIDGES {
            if let Some(e) = cv.error(pairs, &nz, opts, ridge, clusters)
                && e < best.1
            {
                best = (ridge, e);
            }
        }
        ensure!(best.1.is_finite(), "no ridge gives a positive-definite system; the prior is degenerate");
        let kinds_error = match &kinds {
            Some(folds) => {
                let random = std::mem::replace(&mut cv.fold, folds.clone());
                let e = cv.error(pairs, &nz, opts, best.0, clusters);
                cv.fold = random;
                e.context("no fit of the prior without one of its kinds of material is positive-definite")?
            }
            None => f64::NAN,
        };
        out.push(CountScore { ridge: best.0, random: best.1, kinds: kinds_error });
    }
    Ok(out)
}

/// Which of the cluster counts scored (per zone, [`score_counts`]; the
/// first the fewest) a calibration takes, both errors summed over the
/// zones: the least error on random folds among the counts that read the
/// kinds of material held out whole no worse than the fewest clusters do.
///
/// Random folds leave a near twin of every held-out sample in training, so
/// their error keeps falling as clusters are added (on the patent profile
/// 0.0269 at 2 to 0.0203 at 8); a material unlike the prior's is read by
/// extrapolation, which more clusters, each fitted on fewer samples, do
/// worse where the prior is sparse. Measured: on the handheld's line, whose
/// prior has no finishes, random folds alone pick 6, and the held-out gloss
/// tiles' BRDF error went 0.144 -> 0.178 at the 90th percentile (worst 0.53
/// -> 1.38); there 5 and 6 read the kinds held out worse than 2 and the
/// guard keeps 4. On the patent profile, whose finishes fill the space
/// between polished cusps and smooth lobes, 6 reads them best of all and is
/// taken. The kinds' error alone is no ranking: dominated by one group
/// holding out up to half the prior, it swung between 3 and 4 from one
/// held-out fold of `pixel-map` to the next.
pub fn guarded_count(per_zone: &[Vec<CountScore>]) -> usize {
    let sum = |c: usize, of: fn(&CountScore) -> f64| per_zone.iter().map(|z| of(&z[c])).sum::<f64>();
    let counts = per_zone.first().map_or(0, Vec::len);
    (0..counts)
        .filter(|&c| sum(c, |s| s.kinds) <= sum(0, |s| s.kinds))
        .min_by(|a, b| sum(*a, |s| s.random).total_cmp(&sum(*b, |s| s.random)))
        .unwrap_or(0)
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

/// What one out-of-prior form's flag did on the kinds held out whole: the
/// band-factor evidence (`OutOfPrior::band_ratios`) and its score.
type KindsEvidence = (Vec<(f64, f64)>, out_of_prior::FlagOnKinds);

/// One held-out reading: (cluster, weight, per bin the smallest unit
/// uncertainty that covers its error, [`covering_unit`], its pair and draw,
/// its peak-normalised error, whether its estimate is broad).
type HeldOutRoot = (usize, f64, DVector<f64>, (usize, usize), f64, bool);

/// Fewest held-out readings a cluster's table for one kind of estimate
/// (sharp or broad) is set from on their own; fewer take that kind's over
/// every cluster of the zone (the 95th percentile of 40 readings is the
/// third largest).
const MIN_BAND_READINGS: usize = 40;

/// The smallest uncertainty per unit scale `sigma` whose stated
/// uncertainty `root_uncertainty(sigma, est, s)` covers the error `e` at
/// `COVERAGE_K`: the positive root of `K sigma (2 sqrt(est s) + sqrt(2) s
/// sigma) = e`, in the form that does not cancel.
fn covering_unit(est: f64, e: f64, s: f64) -> f64 {
    let (k, a) = (COVERAGE_K, (est.max(0.0) * s).sqrt());
    let d = k * a + (k * k * a * a + std::f64::consts::SQRT_2 * k * s * e).sqrt();
    if d > 0.0 { e / d } else { 0.0 }
}

/// The root form's uncertainty per unit scale (module doc): per cluster of
/// `fitted` and bin, the `COVERAGE` quantile over the held-out readings of
/// the smallest unit uncertainty that would have covered their error at
/// `COVERAGE_K` (each pair read by the fit without its fold, `fold` being
/// [`shape_folds`], every noise draw of `readings`, the prior's own
/// weights). Each bin's stated uncertainty then covers `COVERAGE` of its
/// held-out errors, in the reflectance factor where coverage is judged.
///
/// Returns, per out-of-prior form, the evidence for a flagged point's
/// band (`out_of_prior::band_factor`): for each held-out reading in that
/// form's `flagged` (pair, draw), per bin, its covering unit over the
/// band's, with its weight shared over the bins; and how that form's flag
/// did on the same readings ([`out_of_prior::FlagOnKinds`]). With
/// `peak_views` (and `band_bins`), also each held-out reading's specular
/// peak against its truth's, read with the tables just set
/// (`crate::calibration::peak_factors`).
#[allow(clippy::too_many_arguments)]
fn held_out_uncertainty(
    pairs: &Pairs,
    nz: &Normalised,
    (readings, fold): (&[Vec<DVector<f64>>], &[usize]),
    (seed, band_bins, peak_views): (u64, Option<&[f32]>, Option<&[f64]>),
    ridge: f64,
    clusters: usize,
    fitted: &mut Fitted,
    flagged: &[Vec<(usize, usize)>; 2],
) -> anyhow::Result<([KindsEvidence; 2], Vec<HeldOutPeak>)> {
    let n = pairs.n();
    let nf = fold.iter().copied().max().map_or(0, |x| x + 1);
    let mut held: Vec<HeldOutRoot> = Vec::new();
    // The held-out estimates and their scales, where their peaks are kept
    // (the views to seek them at, the grid the band's kinds are set on).
    let peak_grid = peak_views.zip(band_bins);
    let mut estimates: Vec<(Vec<f32>, f32)> = Vec::new();
    for f in 0..nf {
        let train_idx: Vec<usize> = (0..pairs.len()).filter(|k| fold[*k] != f).collect();
        let fold_fit = fit(nz, &train_idx, seed, ridge, clusters, true)?;
        for k in (0..pairs.len()).filter(|k| fold[*k] == f) {
            let truth = pairs.truth.column(k).into_owned();
            for (d, v) in readings[k].iter().enumerate() {
                let s: f64 = v.iter().sum();
                if s.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                    continue;
                }
                let est = fold_fit.estimate(v);
                let unit = DVector::from_fn(n, |j, _| covering_unit(est[j], (est[j] - truth[j]).abs(), s));
                let error = peak_error(&est, &truth);
                let est32: Vec<f32> = est.iter().map(|x| *x as f32).collect();
                let broad = band_bins.is_some_and(|b| brdf_meter::band::is_broad(b, &est32));
                held.push((fitted.cluster(v), pairs.base[k] / DRAWS as f64, unit, (k, d), error, broad));
                if peak_grid.is_some() {
                    estimates.push((est32, s as f32));
                }
            }
        }
    }
    // Per cluster and bin: each bin is covered on its own, the lobe's bins
    // (whose errors are heavy-tailed) as well as the dark tails. One factor
    // on all the bins would let the many tail bins' coverage buy the peak's:
    // set to cover 95 % of all the held-out values it came out at 0.77-0.91,
    // and the peak bins of held-out measured materials were covered 70-80 %
    // of the time.
    //
    // With a grid to decide on, each cluster's readings of each kind of
    // estimate (sharp, broad: `brdf_meter::band`) are covered on their own
    // too: a cluster's readings may be read as smooth lobes or as sharp
    // peaks, which err differently at the specular bins.
    //
    // And the prior's materials as they are and their variants (rougher
    // finishes, stretches across the plane) are covered each on its own
    // (`crate::calibration::families`), as every other quantile set on
    // held-out samples is: pooled, by their shared weight, the materials'
    // errors set most of the band and the variants' smooth lobes, the
    // kind of surface no measured set holds, were covered less often.
    let quantile = |c: Option<usize>, broad: Option<bool>, j: usize| -> Option<f64> {
        let family = |variant: bool| -> Vec<(f64, f64)> {
            held.iter()
                .filter(|h| c.is_none_or(|c| h.0 == c) && broad.is_none_or(|b| h.5 == b))
                .filter(|h| (pairs.variant[h.3.0] != 0) == variant)
                .map(|h| (h.2[j], h.1))
                .collect()
        };
        band_quantile(&[family(false), family(true)])
    };
    let count =
        |c: Option<usize>, broad: bool| held.iter().filter(|h| c.is_none_or(|c| h.0 == c) && h.5 == broad).count();
    let pooled = DVector::from_fn(n, |j, _| quantile(None, None, j).unwrap_or(0.0));
    let table = |c: Option<usize>, broad: Option<bool>| {
        (0..n).map(|j| quantile(c, broad, j)).collect::<Option<Vec<f64>>>().map(DVector::from_vec)
    };
    for (c, map) in fitted.maps.iter_mut().enumerate() {
        // A cluster no held-out pair fell in keeps the pooled value.
        let all = table(Some(c), None).unwrap_or_else(|| pooled.clone());
        // A kind with too few readings in the cluster takes the kind's over
        // the zone's clusters, and with too few of those the cluster's.
        let of_kind = |broad: bool| {
            let own = (count(Some(c), broad) >= MIN_BAND_READINGS).then(|| table(Some(c), Some(broad))).flatten();
            own.or_else(|| (count(None, broad) >= MIN_BAND_READINGS).then(|| table(None, Some(broad))).flatten())
                .unwrap_or_else(|| all.clone())
        };
        if band_bins.is_some() {
            map.sigma_broad = Some(of_kind(true));
            map.sigma_unit = of_kind(false);
        } else {
            map.sigma_unit = all;
        }
    }
    // A bin whose band is zero cannot be widened by a factor: it gives no
    // evidence for one.
    let evidence = |flagged: &[(usize, usize)]| {
        let flagged: std::collections::HashSet<(usize, usize)> = flagged.iter().copied().collect();
        let ratios = held
            .iter()
            .filter(|h| flagged.contains(&h.3))
            .flat_map(|h| {
                let map = &fitted.maps[h.0];
                let band = if h.5 { map.sigma_broad.as_ref().unwrap_or(&map.sigma_unit) } else { &map.sigma_unit };
                (0..n).filter(|&j| band[j] > 0.0).map(move |j| (h.2[j] / band[j], h.1 / n as f64))
            })
            .collect();
        let mut on_kinds = out_of_prior::FlagOnKinds::default();
        for h in &held {
            on_kinds.add(h.1, h.4, flagged.contains(&h.3));
        }
        (ratios, on_kinds)
    };
    let peaks = match peak_grid {
        Some((views, bins)) => held
            .iter()
            .zip(&estimates)
            .filter_map(|(h, (est, s))| {
                let map = &fitted.maps[h.0];
                let band = if h.5 { map.sigma_broad.as_ref().unwrap_or(&map.sigma_unit) } else { &map.sigma_unit };
                let u: Vec<f32> = (0..n).map(|j| root_uncertainty(band[j] as f32, est[j], *s)).collect();
                let truth: Vec<f32> = pairs.truth.column(h.3.0).iter().map(|x| *x as f32).collect();
                let pixel = pairs.pixel[h.3.0];
                let variant = pairs.variant[h.3.0] != 0;
                peak_factors::held_out_peak(bins, (est, &u, &truth), views[pixel], (h.1, pixel, variant))
            })
            .collect(),
        None => Vec::new(),
    };
    Ok(([evidence(&flagged[0]), evidence(&flagged[1])], peaks))
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

/// One bin's band from its held-out readings' covering units (value,
/// weight), grouped by family (the materials as they are, their
/// variants): the largest of the pool's `COVERAGE` quantile and each
/// family's with enough readings
/// (`crate::calibration::families::weighted_quantile_of_each`); `None`
/// with no reading at all.
fn band_quantile(families: &[Vec<(f64, f64)>]) -> Option<f64> {
    weighted_quantile_of_each(families, COVERAGE)
}

/// The weighted `q` quantile of `xs` (value, weight): the first value, in
/// ascending order, at which the weights reach `q` of their total
/// (`f64::MAX` when there is none).
pub(crate) fn weighted_quantile(xs: &mut [(f64, f64)], q: f64) -> f64 {
    xs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = xs.iter().map(|x| x.1).sum();
    let mut acc = 0.0;
    for (x, w) in xs.iter() {
        acc += w;
        if acc >= q * total {
            return *x;
        }
    }
    xs.last().map_or(f64::MAX, |x| x.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::grid::AngleGrid;
    use crate::forward::optics::{Instrument, system_matrix};
    use crate::forward::prior::SampleSet;

    fn setup() -> (DMatrix<f64>, WeightedSamples) {
        let grid = AngleGrid::patent();
        let inst = Instrument::patent_profile();
        let h = system_matrix(&inst, &grid, false).unwrap();
        let rho_d: Vec<f64> = (0..6).map(|i| 0.05 + 0.15 * i as f64).collect();
        let alpha: Vec<f64> = (0..6).map(|i| 0.03 + 0.02 * i as f64).collect();
        let set = SampleSet::ward_grid(&rho_d, &alpha);
        // Scale the samples over orders of magnitude, as real materials are.
        let mut s = set.on_grid(&grid, inst.view_deg);
        for (c, mut col) in s.column_iter_mut().enumerate() {
            col *= 10f64.powi(c as i32 % 4 - 1);
        }
        (h, WeightedSamples::equal(s))
    }

    #[test]
    fn the_covering_unit_uncertainty_states_exactly_the_error() {
        for (est, e, s) in [(0.5, 0.1, 2.0), (30.0, 12.0, 0.7), (0.0, 0.3, 1.0), (1e-6, 1e-3, 5.0)] {
            let unit = covering_unit(est, e, s);
            let stated = f64::from(root_uncertainty(unit as f32, est as f32, s as f32));
            assert!((COVERAGE_K * stated - e).abs() <= 1e-5 * e, "est {est} e {e} s {s}: {stated}");
        }
        assert_eq!(covering_unit(2.0, 0.0, 1.0), 0.0);
    }

    #[test]
    fn the_weighted_quantile_counts_weights_not_values() {
        let mut xs = vec![(3.0, 1.0), (1.0, 1.0), (2.0, 2.0)];
        // Sorted 1 (w 1), 2 (w 2), 3 (w 1): a quarter of the weight is at 1,
        // three quarters at or below 2.
        assert_eq!(weighted_quantile(&mut xs, 0.25), 1.0);
        assert_eq!(weighted_quantile(&mut xs, 0.5), 2.0);
        assert_eq!(weighted_quantile(&mut xs, 0.75), 2.0);
        assert_eq!(weighted_quantile(&mut xs, 0.95), 3.0);
        assert_eq!(weighted_quantile(&mut [], 0.5), f64::MAX);
    }

    #[test]
    fn a_bins_band_covers_the_materials_and_their_variants_each_on_its_own() {
        // 100 materials' covering units 1..=100 and 100 variants', the two
        // families of equal weight (a material's variants share half of it).
        let materials: Vec<(f64, f64)> = (1..=100).map(|i| (f64::from(i), 1.0)).collect();
        let easy: Vec<(f64, f64)> = (1..=100).map(|i| (0.01 * f64::from(i), 1.0)).collect();
        let hard: Vec<(f64, f64)> = (1..=100).map(|i| (10.0 * f64::from(i), 1.0)).collect();
        // Pooled, easy variants narrow the band to cover 90 % of the
        // materials, and hard ones are covered at 900 where 95 % of them
        // need 950.
        let pooled = |v: &[(f64, f64)]| weighted_quantile(&mut [materials.clone(), v.to_vec()].concat(), COVERAGE);
        assert_eq!((pooled(&easy), pooled(&hard)), (90.0, 900.0));
        assert_eq!(band_quantile(&[materials.clone(), easy]), Some(95.0), "easy variants do not narrow it");
        assert_eq!(band_quantile(&[materials.clone(), hard]), Some(950.0), "hard variants are covered too");
        // A family too small to set its own (its 95th percentile: 37,000)
        // only counts in the pool (33,000: the 33rd of its 39 completes 95 %
        // of the 139 readings' weight).
        let few: Vec<(f64, f64)> = (1..=39).map(|i| (1e3 * f64::from(i), 1.0)).collect();
        assert_eq!(band_quantile(&[materials.clone(), few]), Some(33_000.0));
        assert_eq!(band_quantile(&[Vec::new(), Vec::new()]), None);
    }

    #[test]
    fn the_uncertaintys_folds_hold_out_each_kind_of_material_whole() {
        let (h, prior) = setup();
        let k = prior.samples.ncols();
        // Every sample twice, the copy eight times brighter: one shape.
        let samples = DMatrix::from_fn(prior.samples.nrows(), 2 * k, |j, c| {
            prior.samples[(j, c % k)] * if c < k { 1.0 } else { 8.0 }
        });
        let noise = ReadingNoise::relative(0.02, h.nrows());
        let pairs = Pairs::in_plane(&h, &samples, &vec![1.0 / (2 * k) as f64; 2 * k], &noise);
        let nz = normalise_truth(&pairs, &ScaleFreeOptions::default()).unwrap();
        let fold = shape_folds(&pairs, &nz, 7);
        let nf = fold.iter().max().unwrap() + 1;
        assert!((2..=FOLDS).contains(&nf), "{fold:?}");
        assert!((0..nf).all(|f| fold.contains(&f)), "no fold empty: {fold:?}");
        for c in 0..k {
            assert_eq!(fold[c], fold[c + k], "sample {c} and its brighter copy: {fold:?}");
        }
        // Random folds split most such pairs, so the copy would be in
        // training when its twin is held out.
        let random = folds(&pairs, 7);
        assert!((0..k).filter(|c| random[*c] != random[c + k]).count() > k / 2, "{random:?}");
        // Too few samples to group: the random folds.
        let few = Pairs::in_plane(&h, &samples.columns(0, 6).into_owned(), &[1.0 / 6.0; 6], &noise);
        let nz_few = normalise_truth(&few, &ScaleFreeOptions::default()).unwrap();
        assert_eq!(shape_folds(&few, &nz_few, 7), folds(&few, 7));
    }

    #[test]
    fn host_f64_and_device_f32_agree_and_scaled_copies_scale() {
        let (h, prior) = setup();
        let z = train_zone(&h, &prior, &ScaleFreeOptions::default()).unwrap();
        for k in [0, 7, 20] {
            let v = &h * prior.samples.column(k);
            let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
            let (est, sigma, _, _) = z.estimate_f32(&v32);
            let e64 = z.maps[0].estimate(&v.map(|x| x as f32 as f64), false);
            let scale = e64.amax();
            for j in 0..est.len() {
                assert!((est[j] as f64 - e64[j]).abs() <= 1e-4 * scale, "{k} {j}");
            }
            // A scaled copy: the estimate and its uncertainty scale with it, bit for bit for 2^3.
            let v8: Vec<f32> = v32.iter().map(|x| x * 8.0).collect();
            let (est8, sigma8, stat8, _) = z.estimate_f32(&v8);
            for j in 0..est.len() {
                assert_eq!(est8[j], est[j] * 8.0);
                assert_eq!(sigma8[j], sigma[j] * 8.0);
            }
            assert_eq!(stat8, z.out_of_prior.stat(&v32));
            // Close to the truth (the prior's own sample, noise-free).
            let truth = prior.samples.column(k).into_owned();
            let e = peak_error(&DVector::from_iterator(est.len(), est.iter().map(|x| *x as f64)), &truth);
            assert!(e < 0.1, "sample {k}: peak-normalised error {e}");
        }
    }

    #[test]
    fn flag_rate_on_the_priors_own_samples_and_far_materials() {
        let (h, prior) = setup();
        let z = train_zone(&h, &prior, &ScaleFreeOptions::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(99);
        let (mut flagged, mut total) = (0, 0);
        for k in 0..prior.samples.ncols() {
            for _ in 0..5 {
                let v0 = &h * prior.samples.column(k);
                let v = noisy(&v0, &v0.map(|x| (0.02 * x).powi(2)), &mut rng);
                let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
                flagged += usize::from(z.out_of_prior.stat(&v32) > z.out_of_prior.threshold);
                total += 1;
            }
        }
        // The threshold was set for 5 % on held-out samples; the prior's own
        // samples (seen in training) are flagged at most that often.
        assert!((flagged as f64) <= 0.05 * total as f64 + 1.0, "{flagged} of {total}");
        // A material unlike any Ward sample: light only from one LED.
        let mut v = vec![1e-4f32; h.nrows()];
        v[0] = 1.0;
        assert!(z.out_of_prior.stat(&v) > z.out_of_prior.threshold);
    }

    #[test]
    fn the_cluster_count_is_the_most_accurate_that_reads_kinds_held_out_no_worse_than_two() {
        let (h, prior) = setup();
        let noise = ReadingNoise::relative(0.02, h.nrows());
        let pairs = Pairs::in_plane(&h, &prior.samples, &prior.weights, &noise);
        let opts = ScaleFreeOptions { piecewise: true, ..Default::default() };
        let scored = score_counts(&pairs, &opts, &CLUSTER_COUNTS).unwrap();
        let (random, kinds): (Vec<f64>, Vec<f64>) = scored.iter().map(|s| (s.random, s.kinds)).unzip();
        for (k, (r, kind)) in CLUSTER_COUNTS.iter().zip(random.iter().zip(&kinds)) {
            // A kind held out whole has no near twin left in training.
            assert!(kind > r, "{k} clusters: kinds held out {kind}, random folds {r}");
        }
        let z = train_pairs(&pairs, &opts).unwrap();
        let c = guarded_count(std::slice::from_ref(&scored));
        assert_eq!(z.maps.len(), CLUSTER_COUNTS[c]);
        assert!(kinds[c] <= kinds[0]);
        for (i, (r, k)) in random.iter().zip(&kinds).enumerate() {
            assert!(
                *k > kinds[0] || *r >= random[c],
                "{} clusters would have been taken: {random:?} {kinds:?}",
                CLUSTER_COUNTS[i]
            );
        }
    }

    #[test]
    fn the_guarded_count_sums_the_zones_and_drops_counts_that_read_kinds_held_out_worse() {
        // Random folds prefer the most clusters; kinds held out say the
        // last count extrapolates worse than the first: the middle one.
        let zones = |random: &[&[f64]], kinds: &[&[f64]]| -> Vec<Vec<CountScore>> {
            random
                .iter()
                .zip(kinds)
                .map(|(r, k)| {
                    r.iter().zip(*k).map(|(r, k)| CountScore { ridge: 1e-8, random: *r, kinds: *k }).collect()
                })
                .collect()
        };
        let random: [&[f64]; 2] = [&[0.05, 0.04, 0.03], &[0.05, 0.04, 0.03]];
        assert_eq!(guarded_count(&zones(&random, &[&[0.25, 0.125, 0.5], &[0.25, 0.25, 0.25]])), 1);
        // Summed over the zones, the last one reads kinds as well as the first.
        assert_eq!(guarded_count(&zones(&random, &[&[0.25, 0.25, 0.5], &[0.25, 0.25, 0.0]])), 2);
        // Nothing better on random folds than the fewest: the fewest.
        assert_eq!(guarded_count(&zones(&[&[0.02, 0.04]], &[&[0.3, 0.1]])), 0);
        assert_eq!(guarded_count(&[]), 0);
    }

    #[test]
    fn with_a_grid_broad_and_sharp_estimates_each_take_their_own_band() {
        // Ward lobes from near-mirrors (alpha 0.005) to broad ones, scaled
        // over orders of magnitude as in `setup`.
        let (grid, inst) = (AngleGrid::patent(), Instrument::patent_profile());
        let h = system_matrix(&inst, &grid, false).unwrap();
        let rho_d: Vec<f64> = (0..6).map(|i| 0.05 + 0.15 * i as f64).collect();
        let alpha = [0.005, 0.01, 0.02, 0.05, 0.09, 0.13];
        let mut samples = SampleSet::ward_grid(&rho_d, &alpha).on_grid(&grid, inst.view_deg);
        for (c, mut col) in samples.column_iter_mut().enumerate() {
            col *= 10f64.powi(c as i32 % 4 - 1);
        }
        let prior = WeightedSamples::equal(samples);
        let bins: Vec<f32> = grid.bins_deg().iter().map(|x| *x as f32).collect();
        let opts = ScaleFreeOptions { root: true, band_bins: Some(&bins), ..Default::default() };
        let two = train_zone(&h, &prior, &opts).unwrap();
        let one = train_zone(&h, &prior, &ScaleFreeOptions { band_bins: None, ..opts }).unwrap();
        // Without the grid, one table as before; the estimates are the same either way.
        assert!(one.band_bins.is_none() && one.maps.iter().all(|m| m.sigma_broad.is_none()));
        assert!(two.band_bins.is_some() && two.maps.iter().all(|m| m.sigma_broad.is_some()));
        assert!(one.maps.iter().zip(&two.maps).all(|(a, b)| a.w == b.w));
        // Every prior sample's reading states the table its estimate takes,
        // and both kinds occur (the narrowest Ward lobes read sharp, the
        // widest broad) with tables that differ.
        let mut kinds = [false; 2];
        for k in 0..prior.samples.ncols() {
            let v: Vec<f32> = (&h * prior.samples.column(k)).iter().map(|x| *x as f32).collect();
            let (est, sigma, _, c) = two.estimate_f32(&v);
            let broad = brdf_meter::band::is_broad(&bins, &est);
            kinds[usize::from(broad)] = true;
            let map = &two.maps[c];
            let table = if broad { map.sigma_broad.as_ref().unwrap() } else { &map.sigma_unit };
            let s: f32 = v.iter().sum();
            for j in 0..est.len() {
                assert_eq!(sigma[j], root_uncertainty(table[j] as f32, est[j], s), "sample {k} bin {j}");
            }
        }
        assert_eq!(kinds, [true, true]);
        assert!(two.maps.iter().any(|m| m.sigma_broad.as_ref().unwrap() != &m.sigma_unit));
    }

    #[test]
    fn piecewise_trains_clusters_and_is_at_least_as_good_in_cross_validation() {
        let (h, prior) = setup();
        let plain = train_zone(&h, &prior, &ScaleFreeOptions::default()).unwrap();
        let pw = train_zone(&h, &prior, &ScaleFreeOptions { piecewise: true, ..Default::default() }).unwrap();
        assert!(pw.maps.len() >= 2 && pw.centroids.len() == pw.maps.len() * h.nrows());
        assert!(plain.cv_error.is_finite() && pw.cv_error.is_finite());
        assert!(
            train_zone(
                &h,
                &WeightedSamples::equal(prior.samples.columns(0, 4).into_owned()),
                &ScaleFreeOptions::default()
            )
            .is_err()
        );
    }
}
