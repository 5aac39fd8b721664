//! The patent's experiment (Table 6) on the patent profile of method.md.
//!
//! 1. Optics: H (m x n) of the instrument with its near-field light
//!    distribution; the far-field H for the Wiener-without-distribution row.
//! 2. Prior: R_pp from the training set (Table 5, 16 Ward BRDFs).
//! 3. Test set (Table 4, 120 Ward BRDFs): readings simulated from the
//!    continuous BRDF at each ray's exact direction, plus seeded noise of
//!    `noise_rel` times the value, `v_i + N(0, (s v_i)^2)`.
//! 4. Every method estimates the n-bin BRDF from the same noisy readings:
//!    Ward fits under condition 1 (model ignores the light distribution) and
//!    condition 2 (model integrates it), the Wiener estimator (eq. 22; the
//!    f32 matrix through the device's kernel arithmetic), the noise-free
//!    Wiener (eq. 20), the pseudo-inverse (claim 4) and linear interpolation
//!    (\[0004\]).
//! 5. Error: `RMSE = sqrt(mean over patterns and bins of (est - true)^2)` of
//!    the reflectance factor on the grid; `NRMSE = RMSE / sqrt(mean true^2)`.
//! 6. Time: the estimation of all test patterns from their readings (the
//!    training of W is offline and excluded, as in the patent). Linear
//!    estimators take microseconds, so they are timed over repeated runs
//!    (median of 7 blocks of at least 20 ms); the fits over at least 3 full
//!    runs (median). Single thread.
use crate::calibration::estimators::{
    self, BatchEstimator, EstimatorInputs, EstimatorSummary, LinearEstimator, NoiseModel,
};
use crate::evaluation::fitting::{FitOptions, ForwardModel, fit_ward};
use crate::evaluation::timing::{errors_f64, median_of_runs, time_per_point};
use crate::forward::brdf::Brdf;
use crate::forward::optics::{Instrument, simulate_readings, system_matrix};
use crate::forward::prior::{Prior, PriorSpec, SampleSet};
use anyhow::Context;
use brdf_meter::blob::EstimatorKind;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

/// The patent's Table 6 (Pentium 4 2 GHz, Matlab R13): `(id, seconds for 120 patterns, RMSE)`.
pub const PATENT_TABLE6: [(&str, f64, f64); 3] =
    [("fit-no-distribution", 2.07, 0.633), ("fit-distribution", 13.8, 0.073), ("wiener", 1.5e-5, 0.179)];

/// What to run.
#[derive(Debug)]
pub struct Config {
    /// The instrument (optics and grid).
    pub instrument: Instrument,
    /// The prior's description.
    pub prior: PriorSpec,
    /// Directory relative to which the prior's CSV paths resolve.
    pub prior_base: std::path::PathBuf,
    /// The test BRDFs.
    pub test: SampleSet,
    /// Relative measurement noise (0.02 in the patent).
    pub noise_rel: f64,
    /// Seed of the noise.
    pub seed: u64,
    /// Fit settings.
    pub fit: FitOptions,
    /// Minimum wall time of one timing block of a linear estimator.
    pub block: Duration,
    /// Full runs of each fit for timing (the median is reported).
    pub fit_runs: usize,
}

impl Config {
    /// The patent profile: Table 5 prior, Table 4 test set, 2 % noise.
    pub fn patent() -> Self {
        Self {
            instrument: Instrument::patent_profile(),
            prior: PriorSpec::patent(),
            prior_base: ".".into(),
            test: SampleSet::patent_test(),
            noise_rel: 0.02,
            seed: 1,
            fit: FitOptions::default(),
            block: Duration::from_millis(20),
            fit_runs: 3,
        }
    }

    /// The patent profile on every `stride`-th test BRDF, with short timing:
    /// for tests.
    pub fn reduced(stride: usize) -> Self {
        let mut c = Self::patent();
        let all = SampleSet::patent_test();
        let keep = |k: &usize| k.is_multiple_of(stride.max(1));
        c.test = SampleSet {
            names: all.names.iter().enumerate().filter(|(k, _)| keep(k)).map(|(_, n)| n.clone()).collect(),
            brdfs: all.brdfs.into_iter().enumerate().filter(|(k, _)| keep(k)).map(|(_, b)| b).collect(),
        };
        c.block = Duration::from_millis(2);
        c.fit_runs = 1;
        c
    }
}

/// One row of the table.
#[derive(Clone, Debug, Serialize)]
pub struct MethodResult {
    /// Stable identifier.
    pub id: String,
    /// Human-readable name.
    pub label: String,
    /// The patent's condition number (1, 2, 3) where the row is one of Table 6's.
    pub patent_condition: Option<u8>,
    /// Whether the method models the light distribution.
    pub models_distribution: bool,
    /// RMSE of the reflectance factor over all patterns and bins.
    pub rmse: f64,
    /// RMSE / RMS of the true reflectance factor.
    pub nrmse: f64,
    /// Largest absolute error over all patterns and bins.
    pub max_abs_error: f64,
    /// Wall time to estimate all test patterns, seconds.
    pub seconds: f64,
    /// `seconds / wiener seconds`.
    pub slowdown_vs_wiener: f64,
    /// RMSE the method's error covariance predicts over the prior (linear methods).
    pub predicted_rmse: Option<f64>,
    /// RMSE the error covariance predicts with the test set's own correlation
    /// (linear methods): what remains is H's discretisation error.
    pub predicted_rmse_test_stats: Option<f64>,
    /// The patent's RMSE for this row.
    pub patent_rmse: Option<f64>,
    /// The patent's time for this row, seconds.
    pub patent_seconds: Option<f64>,
    /// Fit statistics (fits only).
    pub fit: Option<FitStats>,
    /// How the matrix was trained (linear methods only).
    pub training: Option<EstimatorSummary>,
}

/// Cost of the fits.
#[derive(Clone, Debug, Serialize)]
pub struct FitStats {
    /// Mean LM residual evaluations per fit (all starts).
    pub residual_evals_per_fit: f64,
    /// Mean LM Jacobian evaluations (= iterations) per fit (all starts).
    pub jacobian_evals_per_fit: f64,
    /// Forward-model evaluations of the start scan per fit.
    pub scan_evals_per_fit: f64,
    /// Mean starts refined per fit.
    pub starts_per_fit: f64,
    /// Fraction of fits whose best start converged.
    pub converged_fraction: f64,
    /// Mean time per fit, seconds.
    pub seconds_per_fit: f64,
}

/// The whole experiment's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Instrument name.
    pub instrument: String,
    /// Bins n.
    pub n: usize,
    /// Readings m.
    pub m: usize,
    /// Bin range, degrees.
    pub bins_deg: [f64; 2],
    /// Test BRDFs.
    pub test_patterns: usize,
    /// Prior samples.
    pub prior_samples: usize,
    /// Relative noise.
    pub noise_rel: f64,
    /// Noise seed.
    pub seed: u64,
    /// RMS of the true reflectance factor (the NRMSE denominator).
    pub rms_true: f64,
    /// One row per method.
    pub methods: Vec<MethodResult>,
    /// The Wiener estimator's training summary.
    pub wiener: EstimatorSummary,
    /// The per-bin predicted standard uncertainty of the Wiener estimator.
    pub wiener_uncertainty: Vec<f64>,
    /// Largest |f32 - f64| of the Wiener estimates over the test readings,
    /// relative to the largest f64 estimate.
    pub f32_rel_error: f64,
}

impl Report {
    /// The row with `id`.
    pub fn method(&self, id: &str) -> Option<&MethodResult> {
        self.methods.iter().find(|m| m.id == id)
    }
}

/// Runs the experiment.
pub fn run(cfg: &Config) -> anyhow::Result<Report> {
    let inst = &cfg.instrument;
    let grid = inst.grid().context("the instrument's angle grid")?;
    let (n, m) = (grid.n(), inst.m());
    anyhow::ensure!(!cfg.test.is_empty(), "the test set is empty");
    anyhow::ensure!(
        cfg.noise_rel.is_finite() && cfg.noise_rel >= 0.0,
        "noise must be finite and >= 0, got {}",
        cfg.noise_rel
    );
    let h = system_matrix(inst, &grid, false).context("system matrix (near field)")?;
    let prior: Prior = cfg.prior.build(&grid, inst.view_deg, &cfg.prior_base).context("building the prior")?;

    // Truth and readings.
    let (truth, noisy) = test_data(cfg, &grid);
    let k = truth.ncols();
    let rms_true = (truth.norm_squared() / (n * k) as f64).sqrt();

    // Linear estimators.
    let centres = inst.centre_angles_deg();
    let noise = NoiseModel::Relative(cfg.noise_rel);
    let inputs = EstimatorInputs {
        h: &h,
        r_pp: &prior.r_pp,
        prior_samples: prior.samples.ncols(),
        noise: noise.clone(),
        bins_deg: grid.bins_deg(),
        centres_deg: &centres,
    };
    let r_test = &truth * truth.transpose() / k as f64;
    let rnn_test = noise.covariance(&h, &r_test)?;
    let readings_f32: Vec<f32> = noisy.iter().flatten().map(|x| *x as f32).collect();

    let mut rows = Vec::new();
    let mut wiener_est: Option<LinearEstimator> = None;
    let mut f32_rel_error = 0.0;
    for (id, label, kind) in [
        ("wiener", "Wiener estimation, eq. 22", EstimatorKind::Wiener),
        ("wiener-noise-free", "Wiener, noise-free eq. 20", EstimatorKind::WienerNoiseFree),
        ("pseudo-inverse", "pseudo-inverse (claim 4)", EstimatorKind::PseudoInverse),
        ("interpolation", "linear interpolation [0004]", EstimatorKind::Interpolation),
    ] {
        let est = estimators::build(kind, &inputs).with_context(|| format!("training the {id} estimator"))?;
        let batch = BatchEstimator::from_estimator(&est);
        let mut out = vec![0.0f32; k * n];
        batch.estimate_into(&readings_f32, &mut out);
        let estimate = DMatrix::from_fn(n, k, |j, c| out[c * n + j] as f64);
        if kind == EstimatorKind::Wiener {
            let v64 = DMatrix::from_fn(m, k, |i, c| noisy[c][i]);
            let e64 = &est.w * v64;
            f32_rel_error = (&estimate - &e64).amax() / e64.amax().max(f64::MIN_POSITIVE);
        }
        let seconds =
            time_per_point(1, cfg.block, || batch.estimate_into(black_box(&readings_f32), black_box(&mut out)));
        let pred_test =
            estimators::error_covariance(&est.w, &h, &r_test, &rnn_test).diagonal().map(|x| x.max(0.0)).mean().sqrt();
        let (rmse, max_abs) = errors_f64(&estimate, &truth);
        rows.push(MethodResult {
            id: id.into(),
            label: label.into(),
            patent_condition: (kind == EstimatorKind::Wiener).then_some(3),
            models_distribution: kind != EstimatorKind::Interpolation,
            rmse,
            nrmse: rmse / rms_true,
            max_abs_error: max_abs,
            seconds,
            slowdown_vs_wiener: f64::NAN,
            predicted_rmse: Some(est.summary.predicted_rmse),
            predicted_rmse_test_stats: Some(pred_test),
            patent_rmse: None,
            patent_seconds: None,
            fit: None,
            training: Some(est.summary.clone()),
        });
        if kind == EstimatorKind::Wiener {
            wiener_est = Some(est);
        }
    }
    let wiener = wiener_est.expect("Wiener row built");

    // Ward fits.
    for (id, label, cond, model) in [
        ("fit-no-distribution", "Ward fit, distribution ignored", 1u8, ForwardModel::far_field(inst)),
        ("fit-distribution", "Ward fit, distribution modelled", 2u8, ForwardModel::near_field(inst)),
    ] {
        let (results, seconds) = median_of_runs(cfg.fit_runs, || {
            noisy.iter().map(|v| fit_ward(&model, v, &cfg.fit)).collect::<Result<Vec<_>, _>>()
        })
        .context("fitting")?;
        let estimate =
            DMatrix::from_fn(n, k, |j, c| results[c].params.brdf().reflectance(grid.bins_deg()[j], inst.view_deg));
        let (rmse, max_abs) = errors_f64(&estimate, &truth);
        let kf = k as f64;
        rows.push(MethodResult {
            id: id.into(),
            label: label.into(),
            patent_condition: Some(cond),
            models_distribution: cond == 2,
            rmse,
            nrmse: rmse / rms_true,
            max_abs_error: max_abs,
            seconds,
            slowdown_vs_wiener: f64::NAN,
            predicted_rmse: None,
            predicted_rmse_test_stats: None,
            patent_rmse: None,
            patent_seconds: None,
            fit: Some(FitStats {
                residual_evals_per_fit: results.iter().map(|r| r.residual_evals as f64).sum::<f64>() / kf,
                jacobian_evals_per_fit: results.iter().map(|r| r.jacobian_evals as f64).sum::<f64>() / kf,
                scan_evals_per_fit: results.iter().map(|r| r.scan_evals as f64).sum::<f64>() / kf,
                starts_per_fit: results.iter().map(|r| r.starts as f64).sum::<f64>() / kf,
                converged_fraction: results.iter().filter(|r| r.converged).count() as f64 / kf,
                seconds_per_fit: seconds / kf,
            }),
            training: None,
        });
    }

    // Order like Table 6, then the extra rows; fill ratios and the patent's figures.
    let order =
        ["fit-no-distribution", "fit-distribution", "wiener", "wiener-noise-free", "pseudo-inverse", "interpolation"];
    rows.sort_by_key(|r| order.iter().position(|o| *o == r.id).unwrap_or(order.len()));
    let tw = rows.iter().find(|r| r.id == "wiener").map(|r| r.seconds).unwrap_or(f64::NAN);
    for r in &mut rows {
        r.slowdown_vs_wiener = r.seconds / tw;
        if let Some((_, s, e)) = PATENT_TABLE6.iter().find(|(id, _, _)| *id == r.id) {
            r.patent_seconds = Some(*s);
            r.patent_rmse = Some(*e);
        }
    }
    let bins = grid.bins_deg();
    Ok(Report {
        instrument: inst.name.clone(),
        n,
        m,
        bins_deg: [bins[0], bins[n - 1]],
        test_patterns: k,
        prior_samples: prior.samples.ncols(),
        noise_rel: cfg.noise_rel,
        seed: cfg.seed,
        rms_true,
        methods: rows,
        wiener_uncertainty: wiener.uncertainty.iter().copied().collect(),
        wiener: wiener.summary,
        f32_rel_error,
    })
}

/// The test set on the grid (n x K truth) and its simulated noisy readings
/// (K x m): the continuous BRDF at every ray's exact direction, plus seeded
/// noise `N(0, (noise_rel v_i)^2)`, clamped at 0.
pub fn test_data(cfg: &Config, grid: &crate::forward::grid::AngleGrid) -> (DMatrix<f64>, Vec<Vec<f64>>) {
    let inst = &cfg.instrument;
    let truth = cfg.test.on_grid(grid, inst.view_deg);
    let clean: Vec<DVector<f64>> = cfg.test.brdfs.iter().map(|b| simulate_readings(inst, b.as_ref(), false)).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let noisy = clean
        .iter()
        .map(|v| {
            v.iter()
                .map(|x| {
                    let sd = cfg.noise_rel * x.abs();
                    let e = if sd > 0.0 { Normal::new(0.0, sd).expect("finite sd").sample(&mut rng) } else { 0.0 };
                    (x + e).max(0.0)
                })
                .collect()
        })
        .collect();
    (truth, noisy)
}

/// The fitting problem of the experiment as JSON, for an external fitter
/// (`scripts/fit_scipy.py`): per condition the rays of each reading as
/// `[weight, weight / (4 sqrt(cos_i cos_o)), tan^2 delta]`, the noisy
/// readings, the truth on the grid and the fit's bounds.
pub fn fit_problem_json(cfg: &Config) -> anyhow::Result<serde_json::Value> {
    let inst = &cfg.instrument;
    let grid = inst.grid().context("the instrument's angle grid")?;
    let (truth, noisy) = test_data(cfg, &grid);
    let cos_o = inst.view_deg.to_radians().cos();
    Ok(serde_json::json!({
        "bins_deg": grid.bins_deg(),
        "view_deg": inst.view_deg,
        "cos_o": cos_o,
        "readings": noisy,
        "truth": truth.column_iter().map(|c| c.iter().copied().collect::<Vec<f64>>()).collect::<Vec<_>>(),
        "rays": {
            "fit-no-distribution": ForwardModel::far_field(inst).terms(),
            "fit-distribution": ForwardModel::near_field(inst).terms(),
        },
        "bounds": { "lo": cfg.fit.bounds.lo, "hi": cfg.fit.bounds.hi },
        "alpha_grid": cfg.fit.alpha_grid,
        "starts": cfg.fit.starts,
        "noise_rel": cfg.noise_rel,
        "seed": cfg.seed,
    }))
}

/// The table, formatted for a terminal.
pub fn format_table(r: &Report) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Reproduction of JP2005-259009A Table 6 on the {} profile: m = {} LEDs, n = {} bins ({}..{} deg), \
         {} test BRDFs, prior of {} samples, noise {} % (seed {})",
        r.instrument,
        r.m,
        r.n,
        r.bins_deg[0],
        r.bins_deg[1],
        r.test_patterns,
        r.prior_samples,
        r.noise_rel * 100.0,
        r.seed
    );
    let _ = writeln!(
        s,
        "{:<5} {:<33} {:>9} {:>8} {:>8} {:>12} {:>12} | {:>10} {:>10} | {:>11} {:>11}",
        "cond",
        "method",
        "distrib.",
        "RMSE",
        "NRMSE",
        "time [s]",
        "x Wiener",
        "pred.prior",
        "pred.test",
        "patent RMSE",
        "patent [s]"
    );
    let opt = |x: Option<f64>, prec: usize| x.map_or("-".to_string(), |v| format!("{v:.prec$}"));
    for m in &r.methods {
        let _ = writeln!(
            s,
            "{:<5} {:<33} {:>9} {:>8.4} {:>8.4} {:>12.3e} {:>12.3e} | {:>10} {:>10} | {:>11} {:>11}",
            m.patent_condition.map_or("".to_string(), |c| c.to_string()),
            m.label,
            if m.models_distribution { "modelled" } else { "ignored" },
            m.rmse,
            m.nrmse,
            m.seconds,
            m.slowdown_vs_wiener,
            opt(m.predicted_rmse, 4),
            opt(m.predicted_rmse_test_stats, 4),
            opt(m.patent_rmse, 3),
            m.patent_seconds.map_or("-".to_string(), |v| format!("{v:.3e}")),
        );
    }
    let _ = writeln!(
        s,
        "pred.prior: RMSE the error covariance (I-WH)R_pp(I-WH)^T + W R_nn W^T predicts over the prior (Table 5); \
         pred.test: the same with the test set's own correlation; the gap to the achieved RMSE is H's discretisation error and the finite noise draw"
    );
    let _ = writeln!(s);
    for m in &r.methods {
        if let Some(f) = &m.fit {
            let _ = writeln!(
                s,
                "{}: {:.1} LM residual + {:.1} Jacobian evaluations per fit ({:.2} starts, {} scan points), \
                 {:.1} us per fit, {:.0} % converged",
                m.id,
                f.residual_evals_per_fit,
                f.jacobian_evals_per_fit,
                f.starts_per_fit,
                f.scan_evals_per_fit,
                f.seconds_per_fit * 1e6,
                f.converged_fraction * 100.0
            );
        }
    }
    if let Some(w) = r.method("wiener") {
        let _ = writeln!(
            s,
            "wiener: predicted RMSE {:.4} over the prior, {:.4} with the test set's own statistics \
             (the rest is H's discretisation error), achieved {:.4}; f32 vs f64 {:.1e}",
            w.predicted_rmse.unwrap_or(f64::NAN),
            w.predicted_rmse_test_stats.unwrap_or(f64::NAN),
            w.rmse,
            r.f32_rel_error
        );
    }
    for m in &r.methods {
        if let Some(ws) = &m.training {
            let _ = writeln!(
                s,
                "{} training: cond(H) {:.3e}, cond(system) {:.3e}, prior rank {}, effective rank {:.2}, \
                 regularisation {:.1e}; {}",
                m.id,
                ws.condition_h,
                ws.condition_system,
                ws.prior_rank,
                ws.effective_rank,
                ws.regularisation,
                ws.method
            );
        }
    }
    if let (Some(c1), Some(c2), Some(w)) =
        (r.method("fit-no-distribution"), r.method("fit-distribution"), r.method("wiener"))
    {
        let _ = writeln!(
            s,
            "speed-up of Wiener: {:.2e} x over condition 1, {:.2e} x over condition 2 (patent: {:.1e} and {:.1e}); \
             ordering cond 1 > Wiener > cond 2 in RMSE: {}",
            c1.seconds / w.seconds,
            c2.seconds / w.seconds,
            2.07 / 1.5e-5,
            13.8 / 1.5e-5,
            if c1.rmse > w.rmse && w.rmse > c2.rmse { "holds" } else { "DOES NOT HOLD" }
        );
    }
    s
}

/// Writes the report as JSON (atomically).
pub fn write_json(path: &Path, r: &Report) -> anyhow::Result<()> {
    crate::output::io::write_json(path, r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ordering_holds_on_a_reduced_configuration() {
        // 12 of the 120 test BRDFs, short timing.
        let r = run(&Config::reduced(10)).unwrap();
        let get = |id: &str| r.method(id).unwrap_or_else(|| panic!("row {id} missing"));
        let (c1, c2, w) = (get("fit-no-distribution"), get("fit-distribution"), get("wiener"));
        assert_eq!(r.test_patterns, 12);
        assert!(c1.rmse > w.rmse, "cond 1 {} should be worse than Wiener {}", c1.rmse, w.rmse);
        assert!(w.rmse > c2.rmse, "Wiener {} should be worse than cond 2 {}", w.rmse, c2.rmse);
        assert!(w.rmse - c2.rmse < c1.rmse - w.rmse, "Wiener should be far closer to cond 2 than to cond 1");
        // Wiener beats the estimators that ignore the prior.
        assert!(w.rmse < get("pseudo-inverse").rmse);
        assert!(w.rmse < get("interpolation").rmse);
        // Linear estimation is much faster than fitting.
        assert!(c2.seconds > 100.0 * w.seconds, "fit {} s vs Wiener {} s", c2.seconds, w.seconds);
        for id in ["fit-no-distribution", "fit-distribution", "wiener", "pseudo-inverse", "interpolation"] {
            let m = get(id);
            assert!(m.rmse.is_finite() && m.nrmse.is_finite() && m.seconds > 0.0, "{id}");
        }
        assert!(r.f32_rel_error < 1e-4, "{}", r.f32_rel_error);
        let table = format_table(&r);
        assert!(table.contains("holds"), "{table}");
    }

    #[test]
    fn noise_is_seeded() {
        let mut a = Config::reduced(40);
        a.fit_runs = 1;
        let r1 = run(&a).unwrap();
        let r2 = run(&a).unwrap();
        assert_eq!(r1.method("wiener").unwrap().rmse, r2.method("wiener").unwrap().rmse);
        a.seed = 2;
        let r3 = run(&a).unwrap();
        assert_ne!(r1.method("wiener").unwrap().rmse, r3.method("wiener").unwrap().rmse);
    }
}
