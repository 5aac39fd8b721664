//! Host batch speed: `BatchEstimator` (the f32 path bit-identical to the
//! device kernel) on one batch of points against numpy's matmul (OpenBLAS
//! sgemm) on the same shape, measured in the same run.
//!
//! The batch is `points` x m readings (uniform 0..300) and a W of n x m
//! (uniform -50..50), n = 81, m = 7, f32, output points x n preallocated. The
//! host kernel is timed single-threaded (best and median of 7 runs after a
//! warm-up) and with the points split over 2 threads; numpy runs
//! `scripts/numpy_matmul.py` with OpenBLAS limited to 1 thread and with its
//! default thread count. Host and numpy alternate for 3 rounds (best of all
//! runs reported), so load from elsewhere on a shared machine hits both.
use crate::calibration::estimators::BatchEstimator;
use crate::evaluation::timing::{best_and_median, median};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::hint::black_box;

/// One timing.
#[derive(Clone, Debug, Serialize)]
pub struct Timing {
    /// What ran.
    pub what: String,
    /// Threads.
    pub threads: Option<usize>,
    /// Best wall time of the runs, seconds.
    pub best_s: f64,
    /// Median, seconds.
    pub median_s: f64,
    /// Best seconds per point.
    pub best_s_per_point: f64,
}

/// The comparison.
#[derive(Clone, Debug, Serialize)]
pub struct SpeedReport {
    /// Points in the batch.
    pub points: usize,
    /// n.
    pub n: usize,
    /// m.
    pub m: usize,
    /// Timings (host kernel 1 and 2 threads, numpy if present).
    pub timings: Vec<Timing>,
    /// numpy's status ("numpy 2.x" or why it is absent).
    pub numpy: String,
    /// Host single-thread best over numpy single-thread best (< 1: host faster).
    pub host_over_numpy_1t: Option<f64>,
    /// Host best (1 or 2 threads) over numpy's best (any thread count).
    pub host_over_numpy_best: Option<f64>,
}

/// Estimates with the points split over `threads` scoped threads.
pub fn estimate_threads(b: &BatchEstimator, readings: &[f32], out: &mut [f32], threads: usize) {
    let (n, m) = (b.n(), b.m());
    let points = readings.len() / m;
    let per = points.div_ceil(threads.max(1));
    std::thread::scope(|s| {
        for (r, o) in readings.chunks(per * m).zip(out.chunks_mut(per * n)) {
            s.spawn(move || b.estimate_into(r, o));
        }
    });
}

/// Runs the comparison.
pub fn run(cfg: &super::Config) -> anyhow::Result<SpeedReport> {
    let (n, m, points) = (81usize, 7usize, cfg.batch_points);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let w: Vec<f32> = (0..n * m).map(|_| rng.random_range(-50.0f32..50.0)).collect();
    let v: Vec<f32> = (0..points * m).map(|_| rng.random_range(0.0f32..300.0)).collect();
    let b = BatchEstimator::from_row_major(&w, n, m);
    let mut out = vec![0.0f32; points * n];
    let runs = 7;
    let has_numpy = cfg.numpy
        && std::process::Command::new("python3")
            .args(["-c", "import numpy"])
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false);
    let mut numpy = if !cfg.numpy {
        "not run (reduced configuration or --no-numpy)".to_string()
    } else if has_numpy {
        String::new()
    } else {
        "numpy not present".to_string()
    };
    // The machine may be shared: alternate host and numpy for `ROUNDS`
    // rounds and keep each one's best (and the median of its medians), so a
    // burst of load elsewhere does not favour one side.
    const ROUNDS: usize = 3;
    // (what, threads, bests, medians)
    type Slot = (String, Option<usize>, Vec<f64>, Vec<f64>);
    let mut slots: Vec<Slot> = Vec::new();
    let mut record = |what: &str, threads: Option<usize>, best: f64, med: f64| {
        if let Some(s) = slots.iter_mut().find(|s| s.0 == what && s.1 == threads) {
            s.2.push(best);
            s.3.push(med);
        } else {
            slots.push((what.to_string(), threads, vec![best], vec![med]));
        }
    };
    for _ in 0..ROUNDS {
        let (best, med) = best_and_median(runs, || b.estimate_into(black_box(&v), black_box(&mut out)));
        record("host BatchEstimator", Some(1), best, med);
        let (best2, med2) = best_and_median(runs, || estimate_threads(&b, black_box(&v), black_box(&mut out), 2));
        record("host BatchEstimator", Some(2), best2, med2);
        black_box(&out);
        if has_numpy {
            let script = cfg.root.join("scripts/numpy_matmul.py");
            for threads in [Some(1usize), None] {
                let mut c = std::process::Command::new("python3");
                c.arg(&script).args([
                    "--points",
                    &points.to_string(),
                    "--n",
                    &n.to_string(),
                    "--m",
                    &m.to_string(),
                    "--runs",
                    &runs.to_string(),
                ]);
                if let Some(t) = threads {
                    c.args(["--threads", &t.to_string()]);
                }
                let o = c.output()?;
                anyhow::ensure!(o.status.success(), "numpy_matmul.py failed: {}", String::from_utf8_lossy(&o.stderr));
                let j: serde_json::Value = serde_json::from_slice(&o.stdout)?;
                numpy = format!(
                    "numpy {} ({})",
                    j["numpy"].as_str().unwrap_or("?"),
                    j["blas"].as_str().unwrap_or("BLAS ?")
                );
                record(
                    "numpy matmul (OpenBLAS sgemm)",
                    threads,
                    j["best_s"].as_f64().unwrap_or(f64::NAN),
                    j["median_s"].as_f64().unwrap_or(f64::NAN),
                );
            }
        }
    }
    let timings: Vec<Timing> = slots
        .into_iter()
        .map(|(what, threads, bests, mut meds)| {
            let best = bests.iter().copied().fold(f64::INFINITY, f64::min);
            Timing { what, threads, best_s: best, median_s: median(&mut meds), best_s_per_point: best / points as f64 }
        })
        .collect();
    let get = |what: &str, t: Option<usize>| {
        timings.iter().find(|x| x.what.starts_with(what) && x.threads == t).map(|x| x.best_s)
    };
    let best = get("host", Some(1)).unwrap_or(f64::NAN);
    let best2 = get("host", Some(2)).unwrap_or(f64::NAN);
    let np1 = get("numpy", Some(1));
    let npbest = match (np1, get("numpy", None)) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    };
    Ok(SpeedReport {
        points,
        n,
        m,
        host_over_numpy_1t: np1.map(|x| best / x),
        host_over_numpy_best: npbest.map(|x| best.min(best2) / x),
        timings,
        numpy,
    })
}
