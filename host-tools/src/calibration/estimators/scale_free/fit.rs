//! The maps of a set of pairs: one affine map per cluster of normalised
//! readings, and the same clusters' maps fitted to another target (the
//! gloss rows').

use super::*;

/// Trained maps for a subset of pairs (piecewise: K clusters).
pub(super) struct Fitted {
    pub(super) maps: Vec<ScaleFreeMap>,
    pub(super) centroids: Vec<f32>,
    pub(super) root: bool,
}

impl Fitted {
    pub(super) fn cluster(&self, v: &DVector<f64>) -> usize {
        if self.centroids.is_empty() {
            0
        } else {
            let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
            brdf_meter::kernel::select_cluster(&self.centroids, &v32)
        }
    }

    pub(super) fn estimate(&self, v: &DVector<f64>) -> DVector<f64> {
        self.maps[self.cluster(v)].estimate(v, self.root)
    }
}

pub(super) fn fit(
    nz: &Normalised,
    idx: &[usize],
    seed: u64,
    ridge: f64,
    clusters: usize,
    root: bool,
) -> anyhow::Result<Fitted> {
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
pub(super) fn cluster_maps(
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
