//! How the estimators do on materials they have not seen: leave-one-material-
//! out over a measured set (the vendored MERL set by default), on the patent
//! profile with proportional noise.
//!
//! For each material: every estimator that learns from samples is trained
//! on the other materials only (hyper-parameters by cross-validation inside
//! those), the held-out material's readings are simulated from its
//! continuous BRDF at each ray's exact direction (as `reproduce` does) with
//! seeded noise draws, and the error is the RMS over bins and draws divided
//! by the material's peak reflectance factor on the grid. The scale-free
//! estimators also give the out-of-prior flag (a material is flagged when
//! most of its draws are) and the predicted error (RMS of the per-bin
//! uncertainty scaled by the point, over the same peak) beside the achieved one.
//!
//! Estimators: the default calibration (Wiener, Table 5 prior), Wiener with
//! the measured prior (the others' R_pp), scale-free, scale-free piecewise,
//! log-domain Wiener (offset chosen by cross-validation in the training
//! materials), and the conventional Ward fit with the light distribution
//! modelled (condition 2), which needs no prior. Last, the scale-free
//! estimator trained on the Table 5 Ward prior: every measured material is
//! new to it, so it shows whether the out-of-prior flag catches the
//! materials such a calibration gets badly wrong.
use crate::calibration::estimators::log_wiener::LogWiener;
use crate::calibration::estimators::scale_free::{ScaleFreeOptions, WeightedSamples, peak_error, train_zone};
use crate::calibration::estimators::{self, EstimatorInputs, NoiseModel};
use crate::evaluation::fitting::{FitOptions, ForwardModel, fit_ward};
use crate::forward::brdf::{Brdf, NbrdfSet};
use crate::forward::grid::AngleGrid;
use crate::forward::optics::{Instrument, simulate_readings, system_matrix};
use crate::forward::prior::PriorSpec;
use crate::forward::prior_measured::{Family, family_models, weighted_prior};
use anyhow::Context;
use brdf_meter::blob::EstimatorKind;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;
use std::path::Path;

/// The estimators compared, in table order.
pub const ESTIMATORS: [&str; 7] = [
    "wiener-table5",
    "wiener-measured",
    "scale-free",
    "scale-free-piecewise",
    "log-wiener",
    "ward-fit-2",
    "scale-free-table5",
];
/// Error above which a material counts as badly estimated (for the flag's hit rate).
pub const BAD_ERROR: f64 = 0.15;
/// Offsets of the log mapping tried by cross-validation.
pub const LOG_EPS: [f64; 4] = [1e-3, 1e-2, 1e-1, 1.0];

/// Settings of a leave-one-material-out run.
#[derive(Clone, Debug)]
pub struct HeldOutConfig {
    /// Relative noise (0.02).
    pub noise_rel: f64,
    /// Noise draws per material.
    pub draws: usize,
    /// Seed.
    pub seed: u64,
    /// False-alarm rate of the flag on held-out prior samples.
    pub false_alarm: f64,
    /// Only the first this many materials are held out (all stay in the
    /// training sets); `None` = every material.
    pub limit: Option<usize>,
    /// Whether to run the Ward fit (slow-ish: one LM fit per draw).
    pub ward_fit: bool,
    /// Extra family mixed into every training prior, with its weight.
    pub mix_with: Option<(Family, f64)>,
}

impl Default for HeldOutConfig {
    fn default() -> Self {
        Self { noise_rel: 0.02, draws: 8, seed: 2024, false_alarm: 0.05, limit: None, ward_fit: true, mix_with: None }
    }
}

/// One material's results.
#[derive(Clone, Debug, Serialize)]
pub struct MaterialRow {
    /// Name.
    pub name: String,
    /// Peak reflectance factor on the grid.
    pub peak: f64,
    /// Peak-normalised error per estimator ([`ESTIMATORS`] order; NaN when not run).
    pub errors: Vec<f64>,
    /// Out-of-prior flag of the scale-free estimator (most draws above the threshold).
    pub flagged: bool,
    /// The same for the scale-free estimator with the Table 5 prior.
    pub flagged_table5: bool,
    /// Median statistic over the draws and the threshold it was compared with.
    pub stat: f64,
    /// Threshold.
    pub threshold: f64,
    /// Predicted peak-normalised error of the scale-free estimator.
    pub predicted: f64,
    /// Truth on the grid.
    pub truth: Vec<f64>,
    /// Scale-free estimate of draw 0 and its per-bin sigma.
    pub estimate: Vec<f64>,
    /// Per-bin sigma of that estimate.
    pub sigma: Vec<f64>,
}

/// Summary per estimator.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Estimator.
    pub estimator: String,
    /// Median of the per-material error.
    pub median: f64,
    /// 90th percentile.
    pub p90: f64,
    /// Worst.
    pub worst: f64,
    /// Of materials with this estimator's error > [`BAD_ERROR`], the fraction flagged.
    pub flag_hit_rate: Option<f64>,
    /// Of the rest, the fraction flagged.
    pub false_alarm_rate: Option<f64>,
    /// Materials above [`BAD_ERROR`].
    pub bad: usize,
    /// Of the worst tenth of materials by this estimator's error, the fraction flagged.
    pub flag_rate_worst_tenth: Option<f64>,
}

/// A run's result.
#[derive(Clone, Debug, Serialize)]
pub struct HeldOutReport {
    /// Bin centres.
    pub bins_deg: Vec<f64>,
    /// Relative noise.
    pub noise_rel: f64,
    /// Draws per material.
    pub draws: usize,
    /// Per-material rows.
    pub materials: Vec<MaterialRow>,
    /// Summary per estimator.
    pub summary: Vec<Summary>,
}

fn percentile(xs: &[f64], q: f64) -> f64 {
    let mut v: Vec<f64> = xs.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    // Nearest rank.
    let r = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[r - 1]
}

fn noisy(v: &DVector<f64>, s: f64, rng: &mut ChaCha8Rng) -> DVector<f64> {
    let nd = Normal::new(0.0, 1.0).unwrap();
    v.map(|x| (x * (1.0 + s * nd.sample(rng))).max(0.0))
}

/// The log-domain estimator with its offset chosen by 5-fold CV on the training samples.
fn log_wiener_cv(h: &DMatrix<f64>, train: &WeightedSamples, noise_rel: f64, seed: u64) -> anyhow::Result<LogWiener> {
    let k = train.samples.ncols();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let reads: Vec<DVector<f64>> = (0..k).map(|s| noisy(&(h * train.samples.column(s)), noise_rel, &mut rng)).collect();
    let mut best = (f64::INFINITY, LOG_EPS[0]);
    for &eps in &LOG_EPS {
        let mut err = 0.0;
        for f in 0..5 {
            let idx: Vec<usize> = (0..k).filter(|s| s % 5 != f).collect();
            let lw = LogWiener::train(&weighted_prior(&train.subset(&idx)), h, noise_rel, eps)?;
            for s in (0..k).filter(|s| s % 5 == f) {
                let v32: Vec<f32> = reads[s].iter().map(|x| *x as f32).collect();
                let mut out = vec![0.0f32; h.ncols()];
                lw.estimate_into(&v32, &mut out);
                let est = DVector::from_iterator(out.len(), out.iter().map(|x| *x as f64));
                let e = peak_error(&est, &train.samples.column(s).into_owned());
                err += if e.is_finite() { e } else { 1e3 };
            }
        }
        if err < best.0 {
            best = (err, eps);
        }
    }
    LogWiener::train(&weighted_prior(train), h, noise_rel, best.1)
}

/// Runs leave-one-material-out over `set` on the patent profile.
pub fn run(set: &NbrdfSet, cfg: &HeldOutConfig) -> anyhow::Result<HeldOutReport> {
    let inst = Instrument::patent_profile();
    let grid: AngleGrid = inst.grid()?;
    let h = system_matrix(&inst, &grid, false)?;
    let (m, n) = h.shape();
    let spectral = inst.spectral_weights;
    let mats: Vec<_> = (0..set.len()).map(|i| set.material(i, spectral)).collect();
    let truth: Vec<DVector<f64>> = mats
        .iter()
        .map(|b| DVector::from_iterator(n, grid.bins_deg().iter().map(|t| b.reflectance(*t, inst.view_deg))))
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let reads: Vec<Vec<DVector<f64>>> = mats
        .iter()
        .map(|b| {
            let clean = simulate_readings(&inst, b, false);
            (0..cfg.draws).map(|_| noisy(&clean, cfg.noise_rel, &mut rng)).collect()
        })
        .collect();
    let extra = match &cfg.mix_with {
        Some((fam, w)) => Some((
            family_models(fam, &grid, inst.view_deg, spectral)?
                .iter()
                .map(|(_, m)| m.on_grid(&grid, inst.view_deg))
                .collect::<Vec<_>>(),
            *w,
        )),
        None => None,
    };
    // The default calibration does not depend on the held-out material.
    let t5 = PriorSpec::patent().build(&grid, inst.view_deg, Path::new("."))?;
    let wiener = |r_pp: &DMatrix<f64>, k: usize| {
        estimators::build(
            EstimatorKind::Wiener,
            &EstimatorInputs {
                h: &h,
                r_pp,
                prior_samples: k,
                noise: NoiseModel::Relative(cfg.noise_rel),
                bins_deg: grid.bins_deg(),
                centres_deg: &inst.centre_angles_deg(),
            },
        )
    };
    let w_t5 = wiener(&t5.r_pp, 16)?;
    let sf_opts = ScaleFreeOptions {
        noise_rel: cfg.noise_rel,
        piecewise: false,
        clusters: None,
        false_alarm: cfg.false_alarm,
        seed: cfg.seed,
        root: false,
        band_bins: None,
        peak_views_deg: None,
    };
    let sf_t5 = train_zone(&h, &WeightedSamples::equal(t5.samples.clone()), &sf_opts)
        .context("scale-free with the Table 5 prior")?;
    let fit_model = ForwardModel::near_field(&inst);
    let fit_opts = FitOptions::default();
    let held = cfg.limit.unwrap_or(set.len()).min(set.len());
    let mut rows = Vec::with_capacity(held);
    for k in 0..held {
        let others: Vec<usize> = (0..set.len()).filter(|i| *i != k).collect();
        let mut cols: Vec<DVector<f64>> = others.iter().map(|i| truth[*i].clone()).collect();
        let mut weights = vec![1.0 / others.len() as f64; others.len()];
        if let Some((ex, w)) = &extra {
            for x in weights.iter_mut() {
                *x *= 1.0 - w;
            }
            weights.extend(std::iter::repeat_n(w / ex.len() as f64, ex.len()));
            cols.extend(ex.iter().cloned());
        }
        let train = WeightedSamples { samples: DMatrix::from_columns(&cols), weights };
        let measured = weighted_prior(&train);
        let w_meas = wiener(&measured.r_pp, train.samples.ncols())?;
        let opts = sf_opts.clone();
        let sf = train_zone(&h, &train, &opts).with_context(|| format!("scale-free without {}", mats[k].name()))?;
        let sfp = train_zone(&h, &train, &ScaleFreeOptions { piecewise: true, ..opts })?;
        let lw = log_wiener_cv(&h, &train, cfg.noise_rel, cfg.seed)?;
        let t = &truth[k];
        let peak = t.amax();
        let mut sq = [0.0f64; 7];
        let mut stats = Vec::new();
        let mut t5_flags = 0usize;
        let mut pred = 0.0;
        let (mut est0, mut sig0) = (Vec::new(), Vec::new());
        for (d, v) in reads[k].iter().enumerate() {
            let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
            let to64 = |o: &[f32]| DVector::from_iterator(n, o.iter().map(|x| *x as f64));
            let mut add = |i: usize, est: &DVector<f64>| sq[i] += (est - t).norm_squared() / n as f64;
            add(0, &w_t5.estimate(v));
            add(1, &w_meas.estimate(v));
            let (e, sigma, stat, _) = sf.estimate_f32(&v32);
            add(2, &to64(&e));
            stats.push(stat as f64);
            pred += sigma.iter().map(|x| (*x as f64).powi(2)).sum::<f64>() / n as f64;
            if d == 0 {
                est0 = e.iter().map(|x| *x as f64).collect();
                sig0 = sigma.iter().map(|x| *x as f64).collect();
            }
            let (e, _, _, _) = sfp.estimate_f32(&v32);
            add(3, &to64(&e));
            let (e, _, st, _) = sf_t5.estimate_f32(&v32);
            add(6, &to64(&e));
            t5_flags += usize::from(st.is_nan() || st > sf_t5.out_of_prior.threshold);
            let mut out = vec![0.0f32; n];
            lw.estimate_into(&v32, &mut out);
            add(4, &to64(&out));
            if cfg.ward_fit {
                let vv: Vec<f64> = v.iter().copied().collect();
                match fit_ward(&fit_model, &vv, &fit_opts) {
                    Ok(r) => {
                        let b = r.params.brdf();
                        add(
                            5,
                            &DVector::from_iterator(
                                n,
                                grid.bins_deg().iter().map(|th| b.reflectance(*th, inst.view_deg)),
                            ),
                        );
                    }
                    Err(_) => sq[5] = f64::INFINITY,
                }
            }
        }
        let dn = cfg.draws as f64;
        let mut errors: Vec<f64> = sq.iter().map(|s| (s / dn).sqrt() / peak).collect();
        if !cfg.ward_fit {
            errors[5] = f64::NAN;
        }
        let thr = sf.out_of_prior.threshold as f64;
        let flagged = stats.iter().filter(|s| **s > thr).count() * 2 > stats.len();
        let _ = m;
        rows.push(MaterialRow {
            name: mats[k].name().to_string(),
            peak,
            errors,
            flagged,
            flagged_table5: t5_flags * 2 > cfg.draws,
            stat: percentile(&stats, 0.5),
            threshold: thr,
            predicted: (pred / dn).sqrt() / peak,
            truth: t.iter().copied().collect(),
            estimate: est0,
            sigma: sig0,
        });
    }
    let summary = ESTIMATORS
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let errs: Vec<f64> = rows.iter().map(|r| r.errors[i]).collect();
            let bad: Vec<&MaterialRow> = rows.iter().filter(|r| r.errors[i] > BAD_ERROR).collect();
            let good: Vec<&MaterialRow> = rows.iter().filter(|r| r.errors[i] <= BAD_ERROR).collect();
            let t5 = *name == "scale-free-table5";
            let flag = |r: &MaterialRow| if t5 { r.flagged_table5 } else { r.flagged };
            let rate = |xs: &[&MaterialRow]| {
                (!xs.is_empty()).then(|| xs.iter().filter(|r| flag(r)).count() as f64 / xs.len() as f64)
            };
            let has_flag = name.starts_with("scale-free");
            let mut by_err: Vec<&MaterialRow> = rows.iter().collect();
            by_err.sort_by(|a, b| b.errors[i].total_cmp(&a.errors[i]));
            by_err.truncate(rows.len().div_ceil(10));
            Summary {
                estimator: name.to_string(),
                median: percentile(&errs, 0.5),
                p90: percentile(&errs, 0.9),
                worst: percentile(&errs, 1.0),
                flag_hit_rate: if has_flag { rate(&bad) } else { None },
                false_alarm_rate: if has_flag { rate(&good) } else { None },
                bad: bad.len(),
                flag_rate_worst_tenth: if has_flag { rate(&by_err) } else { None },
            }
        })
        .collect();
    Ok(HeldOutReport {
        bins_deg: grid.bins_deg().to_vec(),
        noise_rel: cfg.noise_rel,
        draws: cfg.draws,
        materials: rows,
        summary,
    })
}

impl HeldOutReport {
    /// The tables as Markdown.
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        s += &format!(
            "Leave-one-material-out, {} materials, patent profile, {} % noise, {} draws each; error = RMS / material's peak\n\n",
            self.materials.len(),
            self.noise_rel * 100.0,
            self.draws
        );
        s += "| estimator | median | 90 % | worst | > 0.15 | flag hit rate (> 0.15) | false-alarm rate (<= 0.15) | flagged in worst tenth |\n|---|---|---|---|---|---|---|---|\n";
        let pct = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{:.0} %", 100.0 * x));
        for r in &self.summary {
            s += &format!(
                "| {} | {:.4} | {:.4} | {:.4} | {} | {} | {} | {} |\n",
                r.estimator,
                r.median,
                r.p90,
                r.worst,
                r.bad,
                pct(r.flag_hit_rate),
                pct(r.false_alarm_rate),
                pct(r.flag_rate_worst_tenth)
            );
        }
        s += "\nPer material (scale-free: flag, statistic / threshold, predicted vs achieved):\n\n| material | peak | ";
        s += &ESTIMATORS.join(" | ");
        s += " | flag | stat / thr | predicted |\n|---|---|";
        s += &"---|".repeat(ESTIMATORS.len() + 3);
        s += "\n";
        let mut order: Vec<&MaterialRow> = self.materials.iter().collect();
        order.sort_by(|a, b| b.errors[2].total_cmp(&a.errors[2]));
        for r in order {
            s += &format!("| {} | {:.3} | ", r.name, r.peak);
            s += &r.errors.iter().map(|e| format!("{e:.4}")).collect::<Vec<_>>().join(" | ");
            s += &format!(
                " | {}{} | {:.1} / {:.1} | {:.4} |\n",
                if r.flagged { "yes" } else { "" },
                if r.flagged_table5 { " (t5)" } else { "" },
                r.stat,
                r.threshold,
                r.predicted
            );
        }
        s
    }

    /// The worst materials (by the scale-free error), at most `count`.
    pub fn worst(&self, count: usize) -> Vec<&MaterialRow> {
        let mut order: Vec<&MaterialRow> = self.materials.iter().collect();
        order.sort_by(|a, b| b.errors[2].total_cmp(&a.errors[2]));
        order.truncate(count);
        order
    }
}

/// The worst materials' truth vs scale-free estimate with the +-1 sigma band.
pub struct WorstPlot<'a> {
    /// The report.
    pub report: &'a HeldOutReport,
    /// How many panels.
    pub count: usize,
}

impl crate::output::plot::Figure for WorstPlot<'_> {
    fn draw<DB: plotters::prelude::DrawingBackend>(
        &self,
        root: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    ) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        use plotters::prelude::*;
        let e = |x: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("plot: {x:?}");
        root.fill(&WHITE).map_err(e)?;
        let worst = self.report.worst(self.count);
        let cols = 3usize.min(worst.len().max(1));
        let rows = worst.len().div_ceil(cols).max(1);
        let panels = root.split_evenly((rows, cols));
        let bins = &self.report.bins_deg;
        for (r, area) in worst.iter().zip(panels.iter()) {
            let peak = r.peak;
            let hi = r
                .truth
                .iter()
                .chain(&r.estimate)
                .zip(r.sigma.iter().chain(&r.sigma))
                .map(|(x, s)| (x + s) / peak)
                .fold(1.0f64, f64::max);
            let mut ch = ChartBuilder::on(area)
                .caption(
                    format!("{} (err {:.3}{})", r.name, r.errors[2], if r.flagged { ", flagged" } else { "" }),
                    ("sans-serif", 14),
                )
                .margin(8)
                .x_label_area_size(24)
                .y_label_area_size(36)
                .build_cartesian_2d(bins[0]..*bins.last().unwrap(), -0.2f64..hi * 1.05)
                .map_err(e)?;
            ch.configure_mesh()
                .x_desc("incidence, deg")
                .y_desc("rho / peak")
                .label_style(("sans-serif", 10))
                .draw()
                .map_err(e)?;
            let band: Vec<(f64, f64)> = bins
                .iter()
                .zip(r.estimate.iter().zip(&r.sigma))
                .map(|(t, (x, s))| (*t, (x + s) / peak))
                .chain(bins.iter().zip(r.estimate.iter().zip(&r.sigma)).rev().map(|(t, (x, s))| (*t, (x - s) / peak)))
                .collect();
            ch.draw_series(std::iter::once(Polygon::new(band, BLUE.mix(0.2)))).map_err(e)?;
            ch.draw_series(LineSeries::new(
                bins.iter().zip(&r.truth).map(|(t, x)| (*t, x / peak)),
                BLACK.stroke_width(2),
            ))
            .map_err(e)?;
            ch.draw_series(LineSeries::new(
                bins.iter().zip(&r.estimate).map(|(t, x)| (*t, x / peak)),
                BLUE.stroke_width(1),
            ))
            .map_err(e)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduced_leave_one_out_runs_and_scale_free_beats_the_default() {
        let set = NbrdfSet::merl();
        let cfg = HeldOutConfig { draws: 2, limit: Some(12), ward_fit: false, ..Default::default() };
        let r = run(&set, &cfg).unwrap();
        assert_eq!(r.materials.len(), 12);
        let s = |name: &str| r.summary.iter().find(|x| x.estimator == name).unwrap().clone();
        assert!(s("scale-free").median < s("wiener-table5").median, "{}", r.markdown());
        assert!(r.materials.iter().all(|m| m.errors[2].is_finite() && m.predicted > 0.0));
        assert!(r.markdown().contains("| scale-free |"));
    }
}
