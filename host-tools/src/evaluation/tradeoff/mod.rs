//! What accuracy costs in time: every estimator measured on the same data in
//! one run, accuracy (RMSE) against time per point, with the Pareto front.
//!
//! # The data (the patent profile of method.md, reused from `reproduce`)
//! The 120 test BRDFs of Table 4, readings simulated from the continuous BRDF
//! at every ray's exact direction, 2 % proportional noise; `draws` noise draws
//! of the whole set (seeds `seed..seed+draws`), so the RMSEs rest on
//! `120 * draws` points. Every row below estimates exactly these readings.
//!
//! # The rows (the table in [`rows`])
//! - linear estimators through the device's f32 kernel arithmetic
//!   (`BatchEstimator`): interpolation, pseudo-inverse, Wiener with the
//!   patent's 16-sample prior, with a denser Ward prior over the same ranges,
//!   and with mismatched priors (Ward with the wrong roughness range; GGX);
//! - Ward fits, condition 1 and 2, and condition 2 with more starts and a
//!   finer start scan;
//! - piecewise (clustered) Wiener, K = 1..16 ([`Clustered`](crate::calibration::estimators::clustered::Clustered));
//! - log-domain Wiener ([`LogWiener`](crate::calibration::estimators::log_wiener::LogWiener));
//! - device number formats: f32 and Q15 ([`Q15Estimator`](crate::calibration::estimators::fixed_point::Q15Estimator)), with the error
//!   against f64 evaluation of the same W.
//!
//! Separate tables: zones along the line sensor ([`zones`]) and the number of
//! LEDs ([`led_count`]). The kernels' instruction counts come from QEMU
//! ([`kernel_bench`]); the host batch speed against numpy and the memory-bandwidth floor
//! from [`speed`] (bandwidth measured by [`bandwidth`]).
//!
//! # Timing
//! Host time per point: the estimator runs over all test readings, repeated
//! until a block lasts at least `block`; the median of 7 blocks after a
//! warm-up, divided by the points. Fits: median of `fit_runs` full runs.
//! One thread. Both from [`crate::evaluation::timing`].
pub mod bandwidth;
pub mod kernel_bench;
pub mod led_count;
pub mod report;
pub mod rows;
pub mod speed;
pub mod zones;

use crate::calibration::estimators::{self, EstimatorInputs, NoiseModel};
use crate::forward::brdf::BrdfSpec;
use crate::forward::grid::AngleGrid;
use crate::forward::optics::{Instrument, system_matrix};
use crate::forward::prior::{Prior, PriorSpec, WardGridSpec};
use anyhow::Context;
use brdf_meter::blob::EstimatorKind;
use nalgebra::DMatrix;
use serde::Serialize;
use std::path::Path;
use std::time::Duration;

/// What to run.
#[derive(Clone, Debug)]
pub struct Config {
    /// Reduced configuration (for the test command).
    pub quick: bool,
    /// Noise draws of the 120-pattern test set.
    pub draws: usize,
    /// First noise seed.
    pub seed: u64,
    /// Relative noise (0.02 in the patent).
    pub noise_rel: f64,
    /// Minimum length of one timing block of a linear estimator.
    pub block: Duration,
    /// Full runs of each fit for timing.
    pub fit_runs: usize,
    /// Cluster counts of the piecewise Wiener.
    pub ks: Vec<usize>,
    /// Dense prior: number of rho_d and alpha values over the Table 5 ranges.
    pub dense: (usize, usize),
    /// Training margin of the clusters (see [`Clustered`](crate::calibration::estimators::clustered::Clustered)).
    pub margin: f64,
    /// Zone counts for the line sensor.
    pub zones: Vec<usize>,
    /// Every how many pixels of the line sensor a test point is taken.
    pub zone_pixel_stride: usize,
    /// LED counts.
    pub leds: Vec<usize>,
    /// Points of the host batch speed test (n = 81, m = 7).
    pub batch_points: usize,
    /// f32 elements of each of the three STREAM-like arrays (the bandwidth
    /// floor of the batch speed test); at least 4x the last-level cache.
    pub bandwidth_floats: usize,
    /// Compare with numpy when python3 has it.
    pub numpy: bool,
    /// Run the QEMU kernel bench (scripts/kernel-bench.sh).
    pub qemu: bool,
    /// Repository root (scripts/ and scenes/ are found from here).
    pub root: std::path::PathBuf,
}

impl Config {
    /// The whole measurement.
    pub fn full(root: &Path) -> Self {
        Self {
            quick: false,
            draws: 10,
            seed: 1,
            noise_rel: 0.02,
            block: Duration::from_millis(30),
            fit_runs: 3,
            ks: (1..=16).collect(),
            dense: (18, 60),
            margin: 0.25,
            zones: vec![1, 4, 16, 128],
            zone_pixel_stride: 1,
            leds: (3..=15).collect(),
            batch_points: 1_000_000,
            bandwidth_floats: 1 << 25,
            numpy: true,
            qemu: true,
            root: root.to_path_buf(),
        }
    }

    /// A reduced configuration that runs in seconds (the test command's).
    pub fn quick(root: &Path) -> Self {
        Self {
            quick: true,
            draws: 1,
            block: Duration::from_millis(2),
            fit_runs: 1,
            ks: vec![1, 4, 8],
            dense: (6, 16),
            zones: vec![1, 4],
            zone_pixel_stride: 16,
            leds: vec![3, 7],
            batch_points: 20_000,
            bandwidth_floats: 1 << 20,
            numpy: false,
            qemu: false,
            ..Self::full(root)
        }
    }
}

/// Device cost of a row, from the QEMU kernel bench.
#[derive(Clone, Debug, Serialize)]
pub struct DeviceCost {
    /// Instructions per point, counted exactly in QEMU.
    pub instructions: f64,
    /// Cycle estimate from the Cortex-M4 instruction timings ([`kernel_bench`]).
    pub cycles: f64,
    /// `cycles / 80 MHz`, seconds.
    pub seconds_at_80mhz: f64,
    /// What was counted.
    pub counted: String,
}

/// One estimator on the patent profile.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Stable identifier.
    pub id: String,
    /// Family: `linear`, `prior`, `fit`, `clustered`, `log`, `format`.
    pub group: String,
    /// Human-readable description.
    pub label: String,
    /// RMSE of the reflectance factor over all points and bins.
    pub rmse: f64,
    /// RMSE / RMS of the truth.
    pub nrmse: f64,
    /// Largest absolute error.
    pub max_abs_error: f64,
    /// Host time per point, seconds (measured, one thread).
    pub host_seconds_per_point: f64,
    /// Work per point in the device's terms (what the device would run).
    pub cost: String,
    /// Multiply-accumulates per point of the mat-vec (linear-cost rows).
    pub macs_per_point: Option<usize>,
    /// Device cost (rows whose kernels the QEMU bench runs).
    pub device: Option<DeviceCost>,
    /// Bytes of matrices (and centroids) the device stores for one zone.
    pub flash_bytes: Option<usize>,
    /// Largest |estimate - f64 evaluation of the same estimator| relative to
    /// the largest f64 estimate (number-format rows and f32 rows).
    pub vs_f64: Option<f64>,
    /// On the Pareto front of host time vs RMSE.
    pub pareto: bool,
}

/// Where the accuracy target stands (condition 2's RMSE at 1e5 x its speed).
#[derive(Clone, Debug, Serialize)]
pub struct Target {
    /// Condition 2's RMSE (the bar).
    pub cond2_rmse: f64,
    /// Condition 2's host time per point.
    pub cond2_seconds_per_point: f64,
    /// The linear-cost row with the lowest RMSE.
    pub best_linear_id: String,
    /// Its RMSE.
    pub best_linear_rmse: f64,
    /// Speed-up of that row over condition 2 on the host.
    pub best_linear_speedup: f64,
    /// The fastest linear-cost row with RMSE <= condition 2's, if any.
    pub reaching_id: Option<String>,
    /// Its host speed-up over condition 2.
    pub reaching_speedup: Option<f64>,
    /// Its device speed-up: condition 2's host time over the row's device
    /// time at 80 MHz (a fit on the device would be slower still).
    pub reaching_device_vs_host_fit: Option<f64>,
    /// Speed-up over the patent's own condition-2 time (13.8 s / 120 points).
    pub reaching_speedup_vs_patent_fit: Option<f64>,
    /// One-sentence verdict.
    pub verdict: String,
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Reduced configuration?
    pub quick: bool,
    /// Test points (120 x draws).
    pub points: usize,
    /// Noise draws.
    pub draws: usize,
    /// Relative noise.
    pub noise_rel: f64,
    /// Bins n and LEDs m.
    pub n: usize,
    /// LEDs.
    pub m: usize,
    /// Prior sizes: patent, dense, mismatched range, GGX.
    pub prior_samples: Vec<(String, usize)>,
    /// RMS of the truth.
    pub rms_true: f64,
    /// The estimator rows (the plot).
    pub rows: Vec<Row>,
    /// Zones along the line sensor.
    pub zones: Vec<zones::ZoneRow>,
    /// LED counts.
    pub leds: Vec<led_count::LedRow>,
    /// QEMU kernel counts, if run.
    pub kernels: Option<kernel_bench::KernelCounts>,
    /// Host batch speed and the numpy comparison.
    pub speed: speed::SpeedReport,
    /// The accuracy target.
    pub target: Target,
    /// Notes on what was skipped and why.
    pub notes: Vec<String>,
}

/// The patent-profile data every row estimates.
pub struct Data {
    /// Instrument.
    pub inst: Instrument,
    /// Grid.
    pub grid: AngleGrid,
    /// H (near field).
    pub h: DMatrix<f64>,
    /// Truth, n x points.
    pub truth: DMatrix<f64>,
    /// Readings, points x m (f64).
    pub readings: Vec<Vec<f64>>,
    /// Readings, points x m, f32 row-major.
    pub readings_f32: Vec<f32>,
}

impl Data {
    /// Test points.
    pub fn points(&self) -> usize {
        self.readings.len()
    }
}

/// Builds the test data: `draws` noise draws of the Table 4 set.
pub fn patent_data(inst: &Instrument, noise_rel: f64, seed: u64, draws: usize) -> anyhow::Result<Data> {
    let grid = inst.grid().context("the instrument's grid")?;
    let h = system_matrix(inst, &grid, false).context("system matrix")?;
    let mut cfg = crate::evaluation::reproduce::Config::patent();
    cfg.instrument = inst.clone();
    cfg.noise_rel = noise_rel;
    let mut truth_cols = Vec::new();
    let mut readings = Vec::new();
    for d in 0..draws.max(1) {
        cfg.seed = seed + d as u64;
        let (t, v) = crate::evaluation::reproduce::test_data(&cfg, &grid);
        truth_cols.extend(t.column_iter().map(|c| c.into_owned()));
        readings.extend(v);
    }
    let truth = DMatrix::from_columns(&truth_cols);
    let readings_f32 = readings.iter().flatten().map(|x| *x as f32).collect();
    Ok(Data { inst: inst.clone(), grid, h, truth, readings, readings_f32 })
}

/// The priors compared.
pub struct Priors {
    /// Table 5: 16 Ward samples.
    pub patent: Prior,
    /// A finer Ward grid over Table 5's ranges.
    pub dense: Prior,
    /// Ward with the wrong roughness range (0.1..0.3, rougher than any test BRDF).
    pub wrong_range: Prior,
    /// GGX samples over the same albedo and roughness ranges (another model).
    pub ggx: Prior,
}

fn linspace(a: f64, b: f64, k: usize) -> Vec<f64> {
    if k <= 1 {
        return vec![a];
    }
    (0..k).map(|i| a + (b - a) * i as f64 / (k - 1) as f64).collect()
}

/// Builds the priors on `grid`.
pub fn priors(grid: &AngleGrid, view_deg: f64, dense: (usize, usize)) -> anyhow::Result<Priors> {
    let base = Path::new(".");
    let patent = PriorSpec::patent().build(grid, view_deg, base)?;
    let dense_spec = PriorSpec {
        ward_grid: vec![WardGridSpec { rho_d: linspace(0.1, 0.95, dense.0), alpha: linspace(0.02, 0.1, dense.1) }],
        ..Default::default()
    };
    let wrong = PriorSpec {
        ward_grid: vec![WardGridSpec { rho_d: vec![0.1, 0.95], alpha: linspace(0.1, 0.3, 8) }],
        ..Default::default()
    };
    let mut ggx = Vec::new();
    for d in linspace(0.1, 0.95, 4) {
        for a in linspace(0.02, 0.1, 8) {
            ggx.push(BrdfSpec::Ggx { rho_d: d, k_s: 1.0 - d, alpha: a, f0: 1.0 });
        }
    }
    let ggx_spec = PriorSpec { samples: ggx, ..Default::default() };
    Ok(Priors {
        patent,
        dense: dense_spec.build(grid, view_deg, base).context("dense prior")?,
        wrong_range: wrong.build(grid, view_deg, base).context("wrong-range prior")?,
        ggx: ggx_spec.build(grid, view_deg, base).context("GGX prior")?,
    })
}

fn wiener(h: &DMatrix<f64>, prior: &Prior, noise_rel: f64) -> anyhow::Result<estimators::LinearEstimator> {
    let inputs = EstimatorInputs {
        h,
        r_pp: &prior.r_pp,
        prior_samples: prior.samples.ncols(),
        noise: NoiseModel::Relative(noise_rel),
        bins_deg: &[],
        centres_deg: &[],
    };
    Ok(estimators::build(EstimatorKind::Wiener, &inputs)?)
}

/// Runs everything.
pub fn run(cfg: &Config) -> anyhow::Result<Report> {
    run_observed(cfg, &|_| {})
}

/// [`run`], telling `stage` which part it starts (for a progress display).
pub fn run_observed(cfg: &Config, stage: &dyn Fn(&str)) -> anyhow::Result<Report> {
    stage("estimators on the test set");
    let mut notes = Vec::new();
    let inst = Instrument::patent_profile();
    let data = patent_data(&inst, cfg.noise_rel, cfg.seed, cfg.draws)?;
    let (m, n) = data.h.shape();
    let k = data.points();
    let rms_true = (data.truth.norm_squared() / (n * k) as f64).sqrt();
    let pri = priors(&data.grid, inst.view_deg, cfg.dense)?;
    let mut rows = rows::measure_rows(rows::row_specs(cfg, &data, &pri), cfg, &data, &pri, rms_true)?;

    // Device costs from QEMU.
    let kernels = if cfg.qemu {
        stage("device kernels in QEMU");
        match kernel_bench::run_bench(&cfg.root) {
            Ok(kc) => Some(kc),
            Err(e) => {
                notes.push(format!("QEMU kernel bench not run: {e:#}"));
                None
            }
        }
    } else {
        notes.push("QEMU kernel bench skipped (reduced configuration or --no-qemu)".into());
        None
    };
    if let Some(kc) = &kernels {
        kernel_bench::attach(&mut rows, kc);
    }
    mark_pareto(&mut rows);

    stage("zones");
    let zones = zones::run(cfg, &pri.dense).context("zones")?;
    stage("LED counts");
    let leds = led_count::run(cfg).context("LED counts")?;
    stage("host batch speed");
    let speed = speed::run(cfg).context("batch speed")?;
    let target = target(&rows);
    Ok(Report {
        quick: cfg.quick,
        points: k,
        draws: cfg.draws,
        noise_rel: cfg.noise_rel,
        n,
        m,
        prior_samples: vec![
            ("patent".into(), pri.patent.samples.ncols()),
            ("dense".into(), pri.dense.samples.ncols()),
            ("wrong-range".into(), pri.wrong_range.samples.ncols()),
            ("ggx".into(), pri.ggx.samples.ncols()),
        ],
        rms_true,
        rows,
        zones,
        leds,
        kernels,
        speed,
        target,
        notes,
    })
}

/// Marks the rows no other row beats in both host time and RMSE.
pub fn mark_pareto(rows: &mut [Row]) {
    let pts: Vec<(f64, f64)> = rows.iter().map(|r| (r.host_seconds_per_point, r.rmse)).collect();
    for (i, r) in rows.iter_mut().enumerate() {
        let (t, e) = pts[i];
        r.pareto = !pts.iter().enumerate().any(|(j, &(t2, e2))| j != i && t2 <= t && e2 <= e && (t2 < t || e2 < e));
    }
}

fn target(rows: &[Row]) -> Target {
    let cond2 = rows.iter().find(|r| r.id == "fit-cond2");
    let (c2_rmse, c2_t) = cond2.map_or((f64::NAN, f64::NAN), |r| (r.rmse, r.host_seconds_per_point));
    let linear: Vec<&Row> = rows.iter().filter(|r| r.group != "fit").collect();
    let best = linear.iter().min_by(|a, b| a.rmse.total_cmp(&b.rmse)).copied();
    let reaching = linear
        .iter()
        .filter(|r| r.rmse <= c2_rmse && r.group != "log")
        .min_by(|a, b| a.host_seconds_per_point.total_cmp(&b.host_seconds_per_point))
        .copied();
    let patent_fit_per_point = 13.8 / 120.0;
    let verdict = match reaching {
        Some(r) => {
            let s = c2_t / r.host_seconds_per_point;
            format!(
                "{} reaches condition 2's accuracy (RMSE {:.4} <= {:.4}) at {:.2e} x its host speed; the 1e5 x target is {}",
                r.id,
                r.rmse,
                c2_rmse,
                s,
                if s >= 1e5 {
                    "met".to_string()
                } else {
                    format!(
                        "not met on this host (the fit here takes {:.1} us per point, so 1e5 x would need {:.2} ns per point, below one pass over W); against the patent's own fit time ({:.0} ms per point) it is {:.2e} x",
                        c2_t * 1e6,
                        c2_t / 1e5 * 1e9,
                        patent_fit_per_point * 1e3,
                        patent_fit_per_point / r.host_seconds_per_point
                    )
                }
            )
        }
        None => format!(
            "no linear-cost estimator reaches condition 2's RMSE {:.4}; the best is {} at {:.4}",
            c2_rmse,
            best.map_or("-", |b| b.id.as_str()),
            best.map_or(f64::NAN, |b| b.rmse)
        ),
    };
    Target {
        cond2_rmse: c2_rmse,
        cond2_seconds_per_point: c2_t,
        best_linear_id: best.map_or(String::new(), |b| b.id.clone()),
        best_linear_rmse: best.map_or(f64::NAN, |b| b.rmse),
        best_linear_speedup: best.map_or(f64::NAN, |b| c2_t / b.host_seconds_per_point),
        reaching_id: reaching.map(|r| r.id.clone()),
        reaching_speedup: reaching.map(|r| c2_t / r.host_seconds_per_point),
        reaching_device_vs_host_fit: reaching.and_then(|r| r.device.as_ref().map(|d| c2_t / d.seconds_at_80mhz)),
        reaching_speedup_vs_patent_fit: reaching.map(|r| patent_fit_per_point / r.host_seconds_per_point),
        verdict,
    }
}
