//! Piecewise (clustered) Wiener estimation: K matrices, each trained on one
//! part of the prior, and a cheap rule that picks the matrix for a point from
//! its readings alone.
//!
//! - **Feature space**: the readings normalised by their sum, `u = v / sum|v|`
//!   (the shape of the readings, independent of the overall reflectance
//!   level). The prior's samples are mapped there through the noise-free model
//!   `v = H rho`.
//! - **Clusters**: k-means (k-means++ seeding from a fixed seed, Lloyd
//!   iterations to convergence) on the prior's features.
//! - **Matrices**: one Wiener matrix (eq. 22, relative noise) per cluster, from
//!   `R_pp` of the cluster's samples plus those of its neighbours within a
//!   margin (a sample whose distance to the centroid is within `(1 + margin)`
//!   of its distance to its own centroid also trains that cluster), so that a
//!   point near a boundary, misassigned by noise, still meets a matrix that
//!   has seen its kind.
//! - **Selection** (`brdf_meter::kernel::select_cluster`, the device's rule):
//!   nearest centroid in the feature space: m adds, a division, m multiplies,
//!   K*m subtract/multiply-adds and K compares.
//!
//! Cost per point: one n x m mat-vec plus the selection.
use crate::calibration::estimators::{self, BatchEstimator, EstimatorInputs, LinearEstimator, NoiseModel};
use crate::forward::prior::Prior;
use anyhow::Context;
use brdf_meter::blob::EstimatorKind;
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A trained clustered estimator.
#[derive(Clone, Debug)]
pub struct Clustered {
    /// K x m centroids in the normalised-readings space, row-major, f32.
    pub centroids: Vec<f32>,
    /// One estimator per cluster.
    pub estimators: Vec<LinearEstimator>,
    /// The f32 batch form of each.
    pub batch: Vec<BatchEstimator>,
    /// Training samples per cluster (with the margin).
    pub samples_per_cluster: Vec<usize>,
    /// Readings m.
    pub m: usize,
    /// Bins n.
    pub n: usize,
    /// Affine form: per cluster `b_c = mu_c - W_c H mu_c` added to `W_c v`
    /// (empty for the patent's non-centred form).
    pub offsets: Vec<Vec<f32>>,
}

/// Normalised readings `v / sum|v|` (zero stays zero).
pub fn normalise(v: &[f64]) -> Vec<f64> {
    let s: f64 = v.iter().map(|x| x.abs()).sum();
    if s > 0.0 { v.iter().map(|x| x / s).collect() } else { vec![0.0; v.len()] }
}

fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// k-means on `points` (each of the same length): returns (centroids, labels).
/// k-means++ seeding with `seed`, then Lloyd iterations until no label
/// changes (at most 200). `k` is clamped to the number of distinct points.
pub fn kmeans(points: &[Vec<f64>], k: usize, seed: u64) -> (Vec<Vec<f64>>, Vec<usize>) {
    assert!(!points.is_empty() && k >= 1);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut cents: Vec<Vec<f64>> = vec![points[rng.random_range(0..points.len())].clone()];
    while cents.len() < k {
        let d: Vec<f64> =
            points.iter().map(|p| cents.iter().map(|c| dist2(p, c)).fold(f64::INFINITY, f64::min)).collect();
        let total: f64 = d.iter().sum();
        if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            break; // fewer distinct points than k
        }
        let mut r = rng.random_range(0.0..total);
        let mut pick = d.len() - 1;
        for (i, di) in d.iter().enumerate() {
            if r < *di {
                pick = i;
                break;
            }
            r -= di;
        }
        cents.push(points[pick].clone());
    }
    let nearest = |p: &[f64], cents: &[Vec<f64>]| -> usize {
        let mut best = (0, f64::INFINITY);
        for (c, cv) in cents.iter().enumerate() {
            let d = dist2(p, cv);
            if d < best.1 {
                best = (c, d);
            }
        }
        best.0
    };
    let mut labels: Vec<usize> = points.iter().map(|p| nearest(p, &cents)).collect();
    for _ in 0..200 {
        let dim = points[0].len();
        let mut sums = vec![vec![0.0; dim]; cents.len()];
        let mut counts = vec![0usize; cents.len()];
        for (p, &l) in points.iter().zip(&labels) {
            counts[l] += 1;
            for (s, x) in sums[l].iter_mut().zip(p) {
                *s += x;
            }
        }
        for (c, (s, &cnt)) in sums.iter().zip(&counts).enumerate() {
            if cnt > 0 {
                cents[c] = s.iter().map(|x| x / cnt as f64).collect();
            }
        }
        let new: Vec<usize> = points.iter().map(|p| nearest(p, &cents)).collect();
        if new == labels {
            break;
        }
        labels = new;
    }
    (cents, labels)
}

impl Clustered {
    /// Trains K clusters from `prior`'s samples for system `h` (m x n) and
    /// relative noise `noise_rel`; `margin` widens each cluster's training set
    /// (0 = exactly its own samples). With `affine`, each cluster's
    /// matrix is the Wiener matrix of the cluster's covariance about its mean
    /// `mu_c` (noise `s^2 diag(H R_pp H^T)` of its non-centred correlation),
    /// and `b_c = mu_c - W_c H mu_c` is added (the linear minimum-MSE
    /// estimator with a constant term: one mat-vec plus n adds).
    pub fn train_with(
        prior: &Prior,
        h: &DMatrix<f64>,
        noise_rel: f64,
        k: usize,
        margin: f64,
        seed: u64,
        affine: bool,
    ) -> anyhow::Result<Self> {
        let (m, n) = h.shape();
        let samples = &prior.samples;
        let feats: Vec<Vec<f64>> =
            (0..samples.ncols()).map(|s| normalise((h * samples.column(s)).as_slice())).collect();
        let (cents, labels) = kmeans(&feats, k, seed);
        // f32 centroids: the device's selection rule runs on them, so the
        // training assignment below uses the same rule on f32 too.
        let centroids: Vec<f32> = cents.iter().flatten().map(|x| *x as f32).collect();
        let kk = cents.len();
        let mut estimators = Vec::with_capacity(kk);
        let mut batch = Vec::with_capacity(kk);
        let mut samples_per_cluster = Vec::with_capacity(kk);
        let mut offsets = Vec::new();
        for c in 0..kk {
            let cols: Vec<usize> = (0..samples.ncols())
                .filter(|&s| {
                    labels[s] == c || {
                        let own = dist2(&feats[s], &cents[labels[s]]);
                        dist2(&feats[s], &cents[c]) <= (1.0 + margin).powi(2) * own.max(1e-30)
                    }
                })
                .collect();
            let sub = DMatrix::from_fn(n, cols.len(), |j, i| samples[(j, cols[i])]);
            let p = Prior::from_samples(sub.clone()).with_context(|| format!("cluster {c} of {kk}"))?;
            let e = if affine {
                let mu = sub.column_mean();
                let mut cov = &p.r_pp - &mu * mu.transpose();
                cov = (&cov + cov.transpose()) * 0.5;
                let rnn = NoiseModel::Relative(noise_rel).covariance(h, &p.r_pp)?;
                let inputs = EstimatorInputs {
                    h,
                    r_pp: &cov,
                    prior_samples: cols.len(),
                    noise: NoiseModel::Covariance(rnn),
                    bins_deg: &[],
                    centres_deg: &[],
                };
                let e = estimators::build(EstimatorKind::Wiener, &inputs)
                    .with_context(|| format!("affine Wiener matrix of cluster {c}"))?;
                let b = &mu - &e.w * (h * &mu);
                offsets.push(b.iter().map(|x| *x as f32).collect());
                e
            } else {
                let inputs = EstimatorInputs {
                    h,
                    r_pp: &p.r_pp,
                    prior_samples: cols.len(),
                    noise: NoiseModel::Relative(noise_rel),
                    bins_deg: &[],
                    centres_deg: &[],
                };
                estimators::build(EstimatorKind::Wiener, &inputs)
                    .with_context(|| format!("Wiener matrix of cluster {c}"))?
            };
            batch.push(BatchEstimator::from_estimator(&e));
            estimators.push(e);
            samples_per_cluster.push(cols.len());
        }
        Ok(Self { centroids, estimators, batch, samples_per_cluster, m, n, offsets })
    }

    /// Number of clusters.
    pub fn k(&self) -> usize {
        self.estimators.len()
    }

    /// The cluster the device's rule picks for readings `v`.
    pub fn select(&self, v: &[f32]) -> usize {
        brdf_meter::kernel::select_cluster(&self.centroids, v)
    }

    /// Estimates `readings` (points x m, f32) into `out` (points x n).
    ///
    /// Points are selected one by one (the device's rule), then gathered per
    /// cluster so each cluster's matrix runs as one batch; the per-point
    /// arithmetic is the device's either way (`BatchEstimator` is
    /// bit-identical to the kernel), so the grouping changes only the speed.
    pub fn estimate_into(&self, readings: &[f32], out: &mut [f32]) {
        let (m, n) = (self.m, self.n);
        let points = readings.len() / m;
        if points < 64 {
            for (v, o) in readings.chunks_exact(m).zip(out.chunks_exact_mut(n)) {
                let c = self.select(v);
                self.batch[c].estimate_into(v, o);
                self.add_offset(c, o);
            }
            return;
        }
        let sel: Vec<usize> = readings.chunks_exact(m).map(|v| self.select(v)).collect();
        let mut vin = Vec::with_capacity(points * m);
        let mut vout = vec![0.0f32; points * n];
        let mut idx = Vec::with_capacity(points);
        for c in 0..self.k() {
            vin.clear();
            idx.clear();
            for (p, s) in sel.iter().enumerate() {
                if *s == c {
                    idx.push(p);
                    vin.extend_from_slice(&readings[p * m..(p + 1) * m]);
                }
            }
            if idx.is_empty() {
                continue;
            }
            let o = &mut vout[..idx.len() * n];
            self.batch[c].estimate_into(&vin, o);
            for (k, &p) in idx.iter().enumerate() {
                let dst = &mut out[p * n..(p + 1) * n];
                dst.copy_from_slice(&o[k * n..(k + 1) * n]);
                self.add_offset(c, dst);
            }
        }
    }

    fn add_offset(&self, c: usize, o: &mut [f32]) {
        if let Some(b) = self.offsets.get(c) {
            for (x, bj) in o.iter_mut().zip(b) {
                *x += *bj;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kmeans_separates_well_separated_groups() {
        let mut pts = Vec::new();
        for (cx, cy) in [(0.0, 0.0), (10.0, 0.0), (0.0, 10.0)] {
            for k in 0..20 {
                let t = k as f64 * 0.3;
                pts.push(vec![cx + 0.5 * t.sin(), cy + 0.5 * t.cos()]);
            }
        }
        let (cents, labels) = kmeans(&pts, 3, 1);
        assert_eq!(cents.len(), 3);
        for g in 0..3 {
            let l = labels[g * 20];
            assert!(labels[g * 20..(g + 1) * 20].iter().all(|x| *x == l), "group {g} split");
        }
        assert_ne!(labels[0], labels[20]);
        assert_ne!(labels[20], labels[40]);
        assert_ne!(labels[0], labels[40]);
    }

    #[test]
    fn points_clearly_in_a_cluster_select_its_matrix() {
        // A prior of three BRDF families with different shapes (flat, lobe at
        // the start, lobe at the end) on a 1:1 system: the rule must send a
        // fresh member of each family, at any brightness, to its family's
        // cluster, and that cluster's matrix must reproduce it.
        let (m, n) = (4, 4);
        let h = DMatrix::<f64>::identity(m, n);
        let mut cols = Vec::new();
        for k in 0..10 {
            let a = 0.5 + 0.1 * k as f64;
            cols.push(vec![a, a, a, a]);
            cols.push(vec![5.0 * a, a, 0.2 * a, 0.1 * a]);
            cols.push(vec![0.1 * a, 0.2 * a, a, 5.0 * a]);
        }
        let samples = DMatrix::from_fn(n, cols.len(), |j, s| cols[s][j]);
        let prior = Prior::from_samples(samples).unwrap();
        let c = Clustered::train_with(&prior, &h, 0.0, 3, 0.0, 7, false).unwrap();
        assert_eq!(c.k(), 3);
        let fam = |f: usize, a: f32| -> Vec<f32> {
            match f {
                0 => vec![a, a, a, a],
                1 => vec![5.0 * a, a, 0.2 * a, 0.1 * a],
                _ => vec![0.1 * a, 0.2 * a, a, 5.0 * a],
            }
        };
        let picks: Vec<usize> = (0..3).map(|f| c.select(&fam(f, 1.0))).collect();
        assert!(picks[0] != picks[1] && picks[1] != picks[2] && picks[0] != picks[2], "{picks:?}");
        for (f, &pick) in picks.iter().enumerate() {
            for a in [0.01f32, 0.77, 30.0] {
                let v = fam(f, a);
                assert_eq!(c.select(&v), pick, "family {f} at level {a}");
                let mut out = vec![0.0f32; n];
                c.estimate_into(&v, &mut out);
                for j in 0..n {
                    assert!(
                        (out[j] - v[j]).abs() <= 1e-3 * v[j].abs().max(1e-3),
                        "family {f} level {a} bin {j}: {} vs {}",
                        out[j],
                        v[j]
                    );
                }
            }
        }
    }
}
