//! The number of LEDs: m = 3..15 illuminations spread evenly over the patent
//! profile's arc (centre rays 33..57 deg; each the patent's cluster of 5
//! sources 0.17 cm apart at 10 cm), the same 120 test BRDFs and noise draws.
//! For each m: Wiener with the patent's and the dense prior, the piecewise
//! Wiener (K = 8, dense prior) and the condition-2 fit, with the host time
//! per point (a mat-vec costs n m multiply-accumulates).
use super::{patent_data, priors, wiener};
use crate::calibration::estimators::BatchEstimator;
use crate::calibration::estimators::clustered::Clustered;
use crate::evaluation::fitting::{FitOptions, ForwardModel, fit_ward};
use crate::evaluation::timing::{errors, time_per_point, timed};
use crate::forward::optics::Instrument;
use serde::Serialize;
use std::hint::black_box;

/// One estimator at one LED count.
#[derive(Clone, Debug, Serialize)]
pub struct LedRow {
    /// LEDs m.
    pub m: usize,
    /// Estimator id.
    pub id: String,
    /// RMSE.
    pub rmse: f64,
    /// Host seconds per point.
    pub host_seconds_per_point: f64,
    /// Multiply-accumulates per point (linear rows).
    pub macs_per_point: Option<usize>,
}

/// The patent profile with `m` LEDs over the same arc.
pub fn instrument_with(m: usize) -> Instrument {
    let mut inst = Instrument::patent_profile();
    let proto = inst.leds[0].clone();
    inst.leds = (0..m)
        .map(|i| {
            let mut l = proto.clone();
            l.name = Some(format!("L{}", i + 1));
            l.centre_deg = if m == 1 { 45.0 } else { 33.0 + 24.0 * i as f64 / (m - 1) as f64 };
            l
        })
        .collect();
    inst
}

/// Runs the sweep.
pub fn run(cfg: &super::Config) -> anyhow::Result<Vec<LedRow>> {
    let mut rows = Vec::new();
    for &m in &cfg.leds {
        let inst = instrument_with(m);
        let data = patent_data(&inst, cfg.noise_rel, cfg.seed, cfg.draws)?;
        let n = data.truth.nrows();
        let k = data.points();
        let pri = priors(&data.grid, inst.view_deg, cfg.dense)?;
        let mut out = vec![0.0f32; k * n];
        for (id, prior) in [("wiener-patent16", &pri.patent), ("wiener-dense", &pri.dense)] {
            let b = BatchEstimator::from_estimator(&wiener(&data.h, prior, cfg.noise_rel)?);
            b.estimate_into(&data.readings_f32, &mut out);
            let (rmse, _) = errors(&out, &data.truth);
            let t =
                time_per_point(k, cfg.block, || b.estimate_into(black_box(&data.readings_f32), black_box(&mut out)));
            rows.push(LedRow { m, id: id.into(), rmse, host_seconds_per_point: t, macs_per_point: Some(n * m) });
        }
        let c = Clustered::train_with(&pri.dense, &data.h, cfg.noise_rel, 8, cfg.margin, 1, false)?;
        c.estimate_into(&data.readings_f32, &mut out);
        let (rmse, _) = errors(&out, &data.truth);
        let t = time_per_point(k, cfg.block, || c.estimate_into(black_box(&data.readings_f32), black_box(&mut out)));
        rows.push(LedRow {
            m,
            id: format!("clustered-k{}", c.k()),
            rmse,
            host_seconds_per_point: t,
            macs_per_point: Some(n * m + c.k() * m),
        });
        let model = ForwardModel::near_field(&inst);
        let opts = FitOptions::default();
        let (fits, run_s) =
            timed(|| data.readings.iter().map(|v| fit_ward(&model, v, &opts)).collect::<Result<Vec<_>, _>>());
        let t = run_s / k as f64;
        let fits = fits?;
        for (p, r) in fits.iter().enumerate() {
            let b = r.params.brdf();
            for j in 0..n {
                out[p * n + j] =
                    crate::forward::brdf::Brdf::reflectance(&b, data.grid.bins_deg()[j], inst.view_deg) as f32;
            }
        }
        let (rmse, _) = errors(&out, &data.truth);
        rows.push(LedRow { m, id: "fit-cond2".into(), rmse, host_seconds_per_point: t, macs_per_point: None });
    }
    Ok(rows)
}
