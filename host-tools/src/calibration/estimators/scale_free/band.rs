//! The per-bin uncertainty: per cluster, the quantile over readings of
//! kinds held out whole of the unit uncertainty that covers each error.

use super::*;

/// What one out-of-prior form's flag did on the kinds held out whole: the
/// band-factor evidence (`OutOfPrior::band_ratios`) and its score.
pub(super) type KindsEvidence = (Vec<(f64, f64)>, out_of_prior::FlagOnKinds);

/// One held-out reading: (cluster, weight, per bin the smallest unit
/// uncertainty that covers its error, [`covering_unit`], its pair and draw,
/// its peak-normalised error, whether its estimate is broad).
pub(super) type HeldOutRoot = (usize, f64, DVector<f64>, (usize, usize), f64, bool);

/// Fewest held-out readings a cluster's table for one kind of estimate
/// (sharp or broad) is set from on their own; fewer take that kind's over
/// every cluster of the zone (the 95th percentile of 40 readings is the
/// third largest).
pub(super) const MIN_BAND_READINGS: usize = 40;

/// The smallest uncertainty per unit scale `sigma` whose stated
/// uncertainty `root_uncertainty(sigma, est, s)` covers the error `e` at
/// `COVERAGE_K`: the positive root of `K sigma (2 sqrt(est s) + sqrt(2) s
/// sigma) = e`, in the form that does not cancel.
pub(super) fn covering_unit(est: f64, e: f64, s: f64) -> f64 {
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
pub(super) fn held_out_uncertainty(
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

/// One bin's band from its held-out readings' covering units (value,
/// weight), grouped by family (the materials as they are, their
/// variants): the largest of the pool's `COVERAGE` quantile and each
/// family's with enough readings
/// (`crate::calibration::families::weighted_quantile_of_each`); `None`
/// with no reading at all.
pub(super) fn band_quantile(families: &[Vec<(f64, f64)>]) -> Option<f64> {
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
