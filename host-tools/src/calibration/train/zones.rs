//! Each zone's estimator (the linear kinds from H or pairs, the scale-free
//! kinds from pairs), the f32 gate's plans, the white reference the gate
//! rescales, and the summary the blob records.

use super::*;

/// The prior as `R_pp` over a zone's pairs (their truths with the
/// criterion's weights): what the H-based kinds predict their
/// uncertainty with.
fn pairs_r_pp(pairs: &Pairs) -> DMatrix<f64> {
    let sw = DVector::from_iterator(pairs.len(), pairs.weights.iter().map(|w| w.sqrt()));
    let mut s = pairs.truth.clone();
    for (j, mut c) in s.column_iter_mut().enumerate() {
        c *= sw[j];
    }
    &s * s.transpose()
}

pub(super) fn linear_zones(
    spec: &TrainSpec<'_>,
    kind: EstimatorKind,
    pairs: &[Pairs],
) -> anyhow::Result<Vec<TrainedZone>> {
    let k = spec.prior.len();
    let mut out = Vec::with_capacity(spec.zones.len());
    for (z, (zo, p)) in spec.zones.iter().zip(pairs).enumerate() {
        let at = || format!("zone {z}: training the {} estimator", kind_name(kind));
        let est = match kind {
            EstimatorKind::Wiener => pairs_wiener::build(p, zo.h(), k, spec.noise_rel).with_context(at)?,
            EstimatorKind::LogWiener => {
                bail!("the log-wiener estimator has no device form; it is evaluated in `tradeoff`")
            }
            _ => {
                let r_pp = pairs_r_pp(p);
                let inputs = EstimatorInputs {
                    h: zo.h(),
                    r_pp: &r_pp,
                    prior_samples: k,
                    noise: NoiseModel::Relative(spec.noise_rel),
                    bins_deg: spec.bins_deg,
                    centres_deg: zo.centres_deg(),
                };
                estimators::build(kind, &inputs).with_context(at)?
            }
        };
        out.push(TrainedZone { first_pixel: zo.first_pixel, h: zo.h().clone(), estimator: ZoneEstimator::Linear(est) });
    }
    Ok(out)
}

pub(super) fn scale_free_zones(spec: &TrainSpec<'_>, pairs: &[Pairs], most: usize) -> anyhow::Result<Vec<TrainedZone>> {
    ensure!(spec.noise_rel > 0.0, "scale-free training needs a noise level > 0 (got {})", spec.noise_rel);
    ensure!(
        spec.false_alarm > 0.0 && spec.false_alarm < 1.0,
        "the out-of-prior false-alarm rate {} must be in (0, 1)",
        spec.false_alarm
    );
    let piecewise = spec.estimator == EstimatorKind::ScaleFreePiecewise;
    let bins32: Vec<f32> = spec.bins_deg.iter().map(|x| *x as f32).collect();
    let opts = ScaleFreeOptions {
        piecewise,
        false_alarm: spec.false_alarm,
        root: spec.root,
        band_bins: Some(&bins32),
        ..Default::default()
    };
    // The counts tried: scored per zone, the ridge with them.
    let counts: Vec<usize> = match (piecewise, spec.clusters) {
        (false, _) => vec![1],
        (true, Some(k)) => {
            ensure!(
                (2..=brdf_meter::blob::MAX_CLUSTERS).contains(&k),
                "{k} clusters: the piecewise kind takes 2..={}",
                brdf_meter::blob::MAX_CLUSTERS
            );
            vec![k]
        }
        (true, None) => scale_free::CLUSTER_COUNTS.iter().copied().filter(|k| *k <= most.max(2)).collect(),
    };
    use rayon::prelude::*;
    let scores: Vec<Vec<scale_free::CountScore>> = pairs
        .par_iter()
        .enumerate()
        .map(|(z, p)| {
            scale_free::score_counts(p, &opts, &counts)
                .with_context(|| format!("zone {z}: cross-validating the scale-free estimator"))
        })
        .collect::<anyhow::Result<_>>()?;
    // The count: the most accurate on random folds of those that read kinds
    // of material held out whole no worse than the fewest clusters do,
    // summed over the zones.
    let best = scale_free::guarded_count(&scores);
    // Each zone's training pixels' views: where their held-out peaks are sought.
    let views: Vec<Vec<f64>> = spec.zones.iter().map(|zo| zo.pixels.iter().map(|p| p.theta_o_deg).collect()).collect();
    let mut trained: Vec<ScaleFreeZone> = pairs
        .par_iter()
        .zip(&scores)
        .enumerate()
        .map(|(z, (p, c))| {
            let opts = ScaleFreeOptions { peak_views_deg: views.get(z).map(Vec::as_slice), ..opts };
            scale_free::train_with(p, &opts, c[best].ridge, counts[best], c[best].random)
                .with_context(|| format!("zone {z}: training the scale-free estimator"))
        })
        .collect::<anyhow::Result<_>>()?;
    // The blob holds one out-of-prior form: the one whose flagged held-out
    // readings were the worse estimated, over all zones.
    let form = crate::calibration::estimators::out_of_prior::choose_form(trained.iter().map(|z| &z.out_of_prior_forms));
    for z in &mut trained {
        z.use_out_of_prior_form(form);
    }
    Ok(spec
        .zones
        .iter()
        .zip(trained)
        .map(|(zo, t)| TrainedZone {
            first_pixel: zo.first_pixel,
            h: zo.h().clone(),
            estimator: ZoneEstimator::ScaleFree(t),
        })
        .collect())
}

/// The f32 gate, per zone: accept (possibly rescaled) or refuse with the reason.
pub(super) fn gate(spec: &TrainSpec<'_>, zones: &[TrainedZone], raw: &[Pairs]) -> anyhow::Result<Vec<F32Plan>> {
    let mut plans = Vec::with_capacity(zones.len());
    for (z, (tz, p)) in zones.iter().zip(raw).enumerate() {
        match &tz.estimator {
            ZoneEstimator::Linear(e) => match f32_gate(&e.w, &p.readings) {
                Ok(plan) => plans.push(plan),
                Err(r) => {
                    let advice = f32_advice(spec, z, &raw[z], r.rel_error);
                    bail!(
                        "zone {z} (first pixel {}): the {} matrix cannot be evaluated in f32 on the device: {r}; {advice}",
                        tz.first_pixel,
                        kind_name(spec.estimator)
                    );
                }
            },
            ZoneEstimator::ScaleFree(sz) => {
                let mut rel = 0.0f64;
                for (c, map) in sz.maps.iter().enumerate() {
                    rel = rel.max(scale_free_gate(map, &p.readings, sz.root).map_err(|e| {
                        anyhow::anyhow!(
                            "zone {z}, cluster {c}: f32 evaluation differs from f64 by {e:.2e} of the estimate's scale \
                             (tolerance {F32_TOLERANCE:.0e}); retrain with more noise (--noise)"
                        )
                    })?);
                }
                let m = p.m();
                plans.push(F32Plan { w32: Vec::new(), exponents: vec![0; m], rel_error: rel, bound: 0.0 });
            }
        }
    }
    Ok(plans)
}

/// The white reference with each zone's f32 exponents folded in.
pub(super) fn rescaled_white(
    spec: &TrainSpec<'_>,
    zones: &[TrainedZone],
    plans: &[F32Plan],
    m: usize,
) -> anyhow::Result<Vec<f32>> {
    let mut white = spec.white.clone().unwrap_or_else(|| vec![1.0; spec.pixels * m]);
    for (z, p) in plans.iter().enumerate() {
        if p.exponents.iter().all(|e| *e == 0) {
            continue;
        }
        let end = zones.get(z + 1).map_or(spec.pixels, |n| n.first_pixel);
        for px in zones[z].first_pixel..end {
            for i in 0..m {
                let x = (f64::from(white[px * m + i]) * 2f64.powi(p.exponents[i])) as f32;
                ensure!(
                    x.is_normal() && x > 0.0,
                    "zone {z}: W leaves f32's range and the power-of-two rescaling 2^{} of reading {i} would make the \
                     white reference of pixel {px} {x:e}, not a normal f32; retrain with more noise (--noise) or a \
                     better-conditioned instrument",
                    p.exponents[i]
                );
                white[px * m + i] = x;
            }
        }
    }
    Ok(white)
}

pub(super) fn summary(
    spec: &TrainSpec<'_>,
    zones: &[TrainedZone],
    clusters: usize,
    f32_rel_error: f64,
) -> TrainingSummary {
    let linear: Vec<&EstimatorSummary> = zones.iter().filter_map(|z| z.linear().map(|e| &e.summary)).collect();
    let sf: Vec<&ScaleFreeZone> = zones.iter().filter_map(|z| z.scale_free()).collect();
    let worst = |f: fn(&EstimatorSummary) -> f64| linear.iter().map(|s| f(s)).fold(0.0, f64::max);
    let n = spec.bins_deg.len() as f64;
    let predicted = if sf.is_empty() {
        linear.iter().map(|s| s.predicted_rmse).sum::<f64>() / linear.len().max(1) as f64
    } else {
        // Each map's tables alike (the sharp and the broad estimates' when it has both).
        let rms = |t: &nalgebra::DVector<f64>| (t.norm_squared() / n).sqrt();
        sf.iter()
            .flat_map(|z| &z.maps)
            .map(|mp| mp.sigma_broad.as_ref().map_or(rms(&mp.sigma_unit), |b| 0.5 * (rms(&mp.sigma_unit) + rms(b))))
            .sum::<f64>()
            / (sf.len() * clusters) as f64
    };
    TrainingSummary {
        prior_samples: spec.prior.len() as u32,
        // Finite in the blob: an infinite (singular) condition is stored as f32::MAX.
        condition: worst(|s| s.condition_system).min(f32::MAX as f64) as f32,
        regularisation: if sf.is_empty() {
            worst(|s| s.regularisation) as f32
        } else {
            sf.iter().map(|z| z.ridge).fold(0.0, f64::max) as f32
        },
        predicted_rmse: predicted as f32,
        f32_rel_error: f32_rel_error as f32,
    }
}

/// What to do when zone `z` is refused: the smallest relative noise (in
/// half-decade steps up to 0.5, rounded up to the three digits it is
/// printed with) at which the Wiener matrix passes the gate with a
/// two-fold margin: a heavily cancelling matrix's f32 error moves with the
/// last digit of its noise, so the advice is not made on the edge.
fn f32_advice(spec: &TrainSpec<'_>, z: usize, raw: &Pairs, err: f64) -> String {
    let zo = &spec.zones[z];
    let mut s = spec.noise_rel.max(1e-6);
    while s <= 0.5 {
        s *= 10f64.sqrt();
        // Printed to three significant digits, rounded up.
        let digits = 10f64.powf(s.log10().floor() - 2.0);
        let printed = (s / digits).ceil() * digits;
        let mut p = raw.weighted(spec.criterion);
        p.noise_var = raw.readings.map(|v| (printed * v).powi(2));
        if let Ok(e) = pairs_wiener::build(&p, zo.h(), spec.prior.len(), printed)
            && let Ok(plan) = f32_gate(&e.w, &raw.readings)
            && plan.rel_error <= 0.5 * F32_TOLERANCE
        {
            return format!(
                "retrain the wiener estimator with --noise {printed:.2e} or more (f32 error {:.1e} there, {err:.1e} now), \
                 or use an instrument whose LEDs are better spread",
                plan.rel_error
            );
        }
    }
    "no Wiener noise level up to 0.5 passes: the optics are too ill-conditioned for the device; spread the LEDs or \
     coarsen the angle grid"
        .into()
}
