//! The estimator rows of the trade-off, as a table: [`row_specs`] lists
//! every row (identifier, family, what it runs) in the report's order, and
//! [`measure_rows`] builds and measures each one the same way (accuracy
//! against the truth, host time per point, device cost terms).
use super::{Config, Data, Priors, Row, wiener};
use crate::calibration::estimators::clustered::Clustered;
use crate::calibration::estimators::fixed_point::{Q15Estimator, max_rel_diff};
use crate::calibration::estimators::log_wiener::LogWiener;
use crate::calibration::estimators::{self, BatchEstimator, EstimatorInputs, LinearEstimator, NoiseModel};
use crate::evaluation::fitting::{FitOptions, ForwardModel, fit_ward};
use crate::evaluation::timing::{errors, median_of_runs, time_per_point};
use crate::forward::prior::Prior;
use anyhow::Context;
use brdf_meter::blob::EstimatorKind;
use nalgebra::DMatrix;
use std::collections::HashMap;
use std::hint::black_box;

/// What a row runs.
pub enum RowEstimator<'a> {
    /// A linear estimator of this kind with the patent's prior; the label.
    Linear(EstimatorKind, &'static str),
    /// Wiener (eq. 22) with `prior`; the label.
    Wiener(&'a Prior, String),
    /// A Ward fit with this forward model and options; the label.
    Fit(ForwardModel, FitOptions, &'static str),
    /// Piecewise Wiener with `k` clusters on the dense prior; `affine` adds
    /// a constant term per cluster.
    Clustered { k: usize, affine: bool },
    /// Log-domain Wiener with `prior`; the label.
    LogWiener(&'a Prior, &'static str),
    /// The Wiener row `id` in the device's Q15 format.
    WienerQ15(&'static str),
    /// The most accurate piecewise row so far in Q15 (named after it).
    BestClusteredQ15,
}

/// One row of the table.
pub struct RowSpec<'a> {
    /// Stable identifier; `None` when the row is named by what it picks
    /// ([`RowEstimator::BestClusteredQ15`]).
    pub id: Option<String>,
    /// Family: `linear`, `prior`, `fit`, `clustered`, `log`, `format`.
    pub group: &'static str,
    /// What it runs.
    pub estimator: RowEstimator<'a>,
}

fn spec<'a>(id: &str, group: &'static str, estimator: RowEstimator<'a>) -> RowSpec<'a> {
    RowSpec { id: Some(id.into()), group, estimator }
}

/// Every row, in the report's order.
pub fn row_specs<'a>(cfg: &Config, data: &Data, pri: &'a Priors) -> Vec<RowSpec<'a>> {
    use RowEstimator as E;
    let inst = &data.inst;
    let more = FitOptions { alpha_grid: 96, starts: 4, ftol: 1e-12, xtol: 1e-12, gtol: 1e-12, ..FitOptions::default() };
    let mut rows = vec![
        spec("interpolation", "linear", E::Linear(EstimatorKind::Interpolation, "linear interpolation [0004]")),
        spec("pseudo-inverse", "linear", E::Linear(EstimatorKind::PseudoInverse, "pseudo-inverse (claim 4)")),
        spec("wiener-patent16", "linear", E::Wiener(&pri.patent, "Wiener eq. 22, patent prior (16 Ward)".into())),
        spec(
            "wiener-dense",
            "prior",
            E::Wiener(&pri.dense, format!("Wiener, dense Ward prior ({})", pri.dense.samples.ncols())),
        ),
        spec(
            "wiener-wrong-range",
            "prior",
            E::Wiener(&pri.wrong_range, "Wiener, Ward prior alpha 0.1..0.3 (mismatched)".into()),
        ),
        spec(
            "wiener-ggx",
            "prior",
            E::Wiener(&pri.ggx, format!("Wiener, GGX prior ({}, mismatched model)", pri.ggx.samples.ncols())),
        ),
        spec(
            "fit-cond1",
            "fit",
            E::Fit(
                ForwardModel::far_field(inst),
                FitOptions::default(),
                "Ward fit, light distribution ignored (cond. 1)",
            ),
        ),
        spec(
            "fit-cond2",
            "fit",
            E::Fit(
                ForwardModel::near_field(inst),
                FitOptions::default(),
                "Ward fit, light distribution modelled (cond. 2)",
            ),
        ),
        spec(
            "fit-cond2-more",
            "fit",
            E::Fit(ForwardModel::near_field(inst), more, "Ward fit cond. 2, 96-alpha scan, 4 starts, tol 1e-12"),
        ),
    ];
    for &k in &cfg.ks {
        rows.push(spec(&format!("clustered-k{k}"), "clustered", E::Clustered { k, affine: false }));
    }
    for &k in cfg.ks.iter().filter(|k| [4usize, 8, 12, 16].contains(k)) {
        rows.push(spec(&format!("clustered-affine-k{k}"), "clustered", E::Clustered { k, affine: true }));
    }
    rows.push(RowSpec { id: None, group: "format", estimator: E::BestClusteredQ15 });
    rows.push(spec("log-wiener-dense", "log", E::LogWiener(&pri.dense, "log-domain Wiener, dense prior")));
    rows.push(spec("log-wiener-patent16", "log", E::LogWiener(&pri.patent, "log-domain Wiener, patent prior")));
    // Number formats: Q15 on the device path; f32 is every row above.
    rows.push(spec("wiener-patent16-q15", "format", E::WienerQ15("wiener-patent16")));
    rows.push(spec("wiener-dense-q15", "format", E::WienerQ15("wiener-dense")));
    rows
}

/// f64 evaluation of a linear W on the readings (points x n row-major).
fn f64_estimates(w: &DMatrix<f64>, readings: &[Vec<f64>]) -> Vec<f64> {
    let n = w.nrows();
    let mut out = Vec::with_capacity(readings.len() * n);
    for v in readings {
        for j in 0..n {
            out.push(w.row(j).iter().zip(v).map(|(a, b)| a * b).sum::<f64>());
        }
    }
    out
}

/// What a built row costs and how it is compared with f64.
struct Costs {
    label: String,
    cost: String,
    macs: Option<usize>,
    flash: Option<usize>,
}

/// The rows measured so far that later rows build on.
struct Built {
    wieners: HashMap<String, (LinearEstimator, Vec<f64>)>,
    best_clustered: Option<(f64, Clustered)>,
}

/// Builds and measures every row of `specs` on `data`.
pub fn measure_rows(
    specs: Vec<RowSpec<'_>>,
    cfg: &Config,
    data: &Data,
    pri: &Priors,
    rms_true: f64,
) -> anyhow::Result<Vec<Row>> {
    let (m, n) = data.h.shape();
    let nm = n * m;
    let matvec = |extra: &str| format!("mat-vec {n}x{m}{extra}");
    let f32_bytes = 4 * nm;
    let centres = data.inst.centre_angles_deg();
    let base_inputs = EstimatorInputs {
        h: &data.h,
        r_pp: &pri.patent.r_pp,
        prior_samples: pri.patent.samples.ncols(),
        noise: NoiseModel::Relative(cfg.noise_rel),
        bins_deg: data.grid.bins_deg(),
        centres_deg: &centres,
    };
    let mut built = Built { wieners: HashMap::new(), best_clustered: None };
    let mut rows = Vec::new();
    for s in specs {
        let id = s.id.clone();
        let row = |id: String, c: Costs, est: &dyn Fn(&[f32], &mut [f32]), vs: Option<&[f64]>| {
            linear_row(data, cfg, rms_true, id, s.group, c, est, vs)
        };
        let lin = |label: String| Costs { label, cost: matvec(""), macs: Some(nm), flash: Some(f32_bytes) };
        match &s.estimator {
            RowEstimator::Linear(kind, label) => {
                let e = estimators::build(*kind, &base_inputs)?;
                let b = BatchEstimator::from_estimator(&e);
                let r64 = f64_estimates(&e.w, &data.readings);
                rows.push(row(id.expect("named"), lin(label.to_string()), &|v, o| b.estimate_into(v, o), Some(&r64)).0);
            }
            RowEstimator::Wiener(prior, label) => {
                let id = id.expect("named");
                let e = wiener(&data.h, prior, cfg.noise_rel).with_context(|| format!("training {id}"))?;
                let b = BatchEstimator::from_estimator(&e);
                let r64 = f64_estimates(&e.w, &data.readings);
                rows.push(row(id.clone(), lin(label.clone()), &|v, o| b.estimate_into(v, o), Some(&r64)).0);
                built.wieners.insert(id, (e, r64));
            }
            RowEstimator::Fit(model, opts, label) => {
                rows.push(fit_row(data, cfg, rms_true, id.expect("named"), model, opts, label)?)
            }
            RowEstimator::Clustered { k, affine } => {
                let c = Clustered::train_with(&pri.dense, &data.h, cfg.noise_rel, *k, cfg.margin, 1, *affine)
                    .with_context(|| format!("{}clustered K = {k}", if *affine { "affine " } else { "" }))?;
                let got = c.k();
                let costs = if *affine {
                    Costs {
                        label: format!("piecewise affine Wiener (mean + covariance), K = {got}, dense prior"),
                        cost: matvec(&format!(" + {n} adds + select K={got}")),
                        macs: Some(nm + got * m),
                        flash: Some(got * (f32_bytes + 4 * n + 4 * m)),
                    }
                } else {
                    Costs {
                        label: format!("piecewise Wiener, K = {got}, dense prior"),
                        cost: matvec(&format!(" + select K={got}")),
                        macs: Some(nm + got * m),
                        flash: Some(got * (f32_bytes + 4 * m)),
                    }
                };
                let (r, out) = row(id.expect("named"), costs, &|v, o| c.estimate_into(v, o), None);
                let (rmse, _) = errors(&out, &data.truth);
                rows.push(r);
                if built.best_clustered.as_ref().is_none_or(|(best, _)| rmse < *best) {
                    built.best_clustered = Some((rmse, c));
                }
            }
            RowEstimator::BestClusteredQ15 => {
                let Some((_, c)) = &built.best_clustered else { continue };
                let qs: Vec<Q15Estimator> =
                    c.estimators.iter().map(|e| Q15Estimator::from_row_major(&e.w_f32_row_major(), n, m)).collect();
                let kk = c.k();
                let affine = !c.offsets.is_empty();
                let kind = if affine { "clustered-affine" } else { "clustered" };
                let costs = Costs {
                    label: format!("{kind} K = {kk} in Q15"),
                    cost: format!(
                        "select K={kk} + quantise v + Q15 mat-vec {n}x{m} + scale{}",
                        if affine { " + offset" } else { "" }
                    ),
                    macs: Some(nm + kk * m),
                    flash: Some(
                        qs.iter().map(|q| q.bytes()).sum::<usize>() + 4 * kk * m + if affine { 4 * kk * n } else { 0 },
                    ),
                };
                let est = |v: &[f32], o: &mut [f32]| {
                    for (vv, oo) in v.chunks_exact(m).zip(o.chunks_exact_mut(n)) {
                        let sel = c.select(vv);
                        qs[sel].estimate_into(vv, oo);
                        if let Some(b) = c.offsets.get(sel) {
                            for (x, bj) in oo.iter_mut().zip(b) {
                                *x += *bj;
                            }
                        }
                    }
                };
                rows.push(row(id.unwrap_or(format!("{kind}-k{kk}-q15")), costs, &est, None).0);
            }
            RowEstimator::LogWiener(prior, label) => {
                let lw = LogWiener::train(prior, &data.h, cfg.noise_rel, 0.01)?;
                let costs = Costs {
                    label: label.to_string(),
                    cost: format!("{m} ln + mat-vec {n}x{} + {n} exp", m + 1),
                    macs: Some(n * (m + 1)),
                    flash: Some(4 * n * (m + 1)),
                };
                rows.push(row(id.expect("named"), costs, &|v, o| lw.estimate_into(v, o), None).0);
            }
            RowEstimator::WienerQ15(of) => {
                let (e, r64) =
                    built.wieners.get(*of).with_context(|| format!("the Q15 row needs the row {of} before it"))?;
                let q = Q15Estimator::from_row_major(&e.w_f32_row_major(), n, m);
                let costs = Costs {
                    label: format!("{of} in Q15 (SMLAD kernel)"),
                    cost: format!("quantise v + Q15 mat-vec {n}x{m} + scale"),
                    macs: Some(nm),
                    flash: Some(q.bytes()),
                };
                rows.push(row(id.expect("named"), costs, &|v, o| q.estimate_into(v, o), Some(r64)).0);
            }
        }
    }
    Ok(rows)
}

/// Measures a row that estimates every point at linear cost: its estimates
/// (returned beside the row), errors, f64 comparison and host time.
#[allow(clippy::too_many_arguments)]
fn linear_row(
    data: &Data,
    cfg: &Config,
    rms_true: f64,
    id: String,
    group: &str,
    c: Costs,
    est: &dyn Fn(&[f32], &mut [f32]),
    vs_f64: Option<&[f64]>,
) -> (Row, Vec<f32>) {
    let n = data.truth.nrows();
    let mut out = vec![0.0f32; data.points() * n];
    est(&data.readings_f32, &mut out);
    let (rmse, max_abs) = errors(&out, &data.truth);
    let vs = vs_f64.map(|r| max_rel_diff(&out, r));
    let mut scratch = vec![0.0f32; data.points() * n];
    let t = time_per_point(data.points(), cfg.block, || est(black_box(&data.readings_f32), black_box(&mut scratch)));
    let row = Row {
        id,
        group: group.into(),
        label: c.label,
        rmse,
        nrmse: rmse / rms_true,
        max_abs_error: max_abs,
        host_seconds_per_point: t,
        cost: c.cost,
        macs_per_point: c.macs,
        device: None,
        flash_bytes: c.flash,
        vs_f64: vs,
        pareto: false,
    };
    (row, out)
}

/// Measures a Ward fit row: every point fitted, median of `fit_runs` runs.
fn fit_row(
    data: &Data,
    cfg: &Config,
    rms_true: f64,
    id: String,
    model: &ForwardModel,
    opts: &FitOptions,
    label: &str,
) -> anyhow::Result<Row> {
    let (k, n) = (data.points(), data.truth.nrows());
    let (results, run_s) = median_of_runs(cfg.fit_runs, || {
        data.readings.iter().map(|v| fit_ward(model, v, opts)).collect::<Result<Vec<_>, _>>()
    })
    .context("fitting")?;
    let mut est = vec![0.0f32; k * n];
    for (p, r) in results.iter().enumerate() {
        let b = r.params.brdf();
        for j in 0..n {
            est[p * n + j] =
                crate::forward::brdf::Brdf::reflectance(&b, data.grid.bins_deg()[j], data.inst.view_deg) as f32;
        }
    }
    let (rmse, max_abs) = errors(&est, &data.truth);
    let evals = results.iter().map(|r| r.residual_evals + r.jacobian_evals).sum::<usize>() as f64 / k as f64;
    Ok(Row {
        id,
        group: "fit".into(),
        label: label.into(),
        rmse,
        nrmse: rmse / rms_true,
        max_abs_error: max_abs,
        host_seconds_per_point: run_s / k as f64,
        cost: format!("LM, {evals:.0} evaluations + {}-alpha scan, {} starts", opts.alpha_grid, opts.starts),
        macs_per_point: None,
        device: None,
        flash_bytes: None,
        vs_f64: None,
        pareto: false,
    })
}
