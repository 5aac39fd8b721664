//! Host batch speed: `BatchEstimator` (the f32 path bit-identical to the
//! device kernel) on one batch of points against numpy's matmul (OpenBLAS
//! sgemm) on the same shape and against the machine's memory-bandwidth floor,
//! all measured in the same run, at every thread count from 1 to the
//! machine's cores.
//!
//! The batch is `points` x m readings (uniform 0..300) and a W of n x m
//! (uniform -50..50), n = 81, m = 7, f32, output points x n preallocated. At
//! each thread count t the host kernel runs on a rayon pool of t threads
//! (`ThreadPoolBuilder`, `estimate_par_into`; best and median of 7 runs after
//! a warm-up), numpy runs `scripts/numpy_matmul.py` with OpenBLAS limited to t
//! threads, and the STREAM-like copy and triad ([`super::bandwidth`]) run on
//! the same pool. Host, numpy and bandwidth alternate for 3 rounds (best of
//! all runs reported), so load from elsewhere on a shared machine hits all.
//!
//! # The floor
//! A point reads m readings and writes n values (f32): `4 (m + n)` bytes,
//! 352 B for n = 81, m = 7. W (n x m f32, 2.3 KB) stays in L1 and the large
//! batch's output is written with streaming stores (no read for ownership),
//! so that is all the memory traffic. The floor is the bandwidth measured at
//! the same thread count (the better of copy and triad) over those bytes.
//! The kernel's own arithmetic rate is measured too, on a batch that stays
//! in L2 ([`IN_CACHE_POINTS`], one thread): when it is below the floor the
//! kernel is compute-bound there, not memory-bound (it multiplies, then adds,
//! without FMA, so that it stays bit-identical to the device).
use super::bandwidth::{Arrays, Bandwidth};
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
    /// Host best (any thread count) over numpy's best (any thread count).
    pub host_over_numpy_best: Option<f64>,
    /// Memory traffic of one point, bytes (the floor's numerator).
    pub bytes_per_point: usize,
    /// The machine's bandwidth per thread count (STREAM-like copy and triad).
    pub bandwidth: Vec<Bandwidth>,
    /// Host, numpy and floor side by side, per thread count.
    pub per_threads: Vec<ThreadRow>,
    /// The host kernel on [`IN_CACHE_POINTS`] points (in L2), one thread,
    /// points per second (best run): its arithmetic alone, no memory bound.
    pub host_in_cache_points_per_s: f64,
}

/// Points of the in-cache measurement: 1,024 x (81 + 7) f32 = 360 KB.
pub const IN_CACHE_POINTS: usize = 1024;

/// One thread count of the comparison.
#[derive(Clone, Debug, Serialize)]
pub struct ThreadRow {
    /// Threads (rayon pool; OpenBLAS threads for numpy).
    pub threads: usize,
    /// Host batch kernel, points per second (best run).
    pub host_points_per_s: f64,
    /// numpy, points per second (best run), if numpy ran.
    pub numpy_points_per_s: Option<f64>,
    /// Host over numpy in points per second (>= 1: host at least as fast).
    pub host_over_numpy: Option<f64>,
    /// The bandwidth floor: measured bandwidth / bytes per point.
    pub floor_points_per_s: f64,
    /// Host over the floor (1 = at the memory bound; >= 1/1.5 is the target).
    pub host_over_floor: f64,
}

/// The thread counts measured: 1 up to the machine's cores.
pub fn thread_counts() -> Vec<usize> {
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    (1..=cores).collect()
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
    let threads = thread_counts();
    let pools = threads
        .iter()
        .map(|&t| rayon::ThreadPoolBuilder::new().num_threads(t).build())
        .collect::<Result<Vec<_>, _>>()?;
    let mut arrays = Arrays::new(cfg.bandwidth_floats);
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
    // The machine may be shared: alternate host, numpy and bandwidth for
    // `ROUNDS` rounds and keep each one's best (and the median of its
    // medians), so a burst of load elsewhere does not favour one side.
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
    let mut bandwidth: Vec<Bandwidth> = Vec::new();
    let small = IN_CACHE_POINTS.min(points);
    let mut in_cache = f64::INFINITY;
    for _ in 0..ROUNDS {
        let (best, _) = best_and_median(4 * runs, || {
            b.estimate_into(black_box(&v[..small * m]), black_box(&mut out[..small * n]));
        });
        in_cache = in_cache.min(best);
        for (&t, pool) in threads.iter().zip(&pools) {
            let (best, med) =
                best_and_median(runs, || pool.install(|| b.estimate_par_into(black_box(&v), black_box(&mut out))));
            record("host BatchEstimator (rayon)", Some(t), best, med);
            black_box(&out);
            let bw = pool.install(|| arrays.measure(runs));
            match bandwidth.iter_mut().find(|x| x.threads == t) {
                Some(x) => {
                    x.copy_bytes_per_s = x.copy_bytes_per_s.max(bw.copy_bytes_per_s);
                    x.triad_bytes_per_s = x.triad_bytes_per_s.max(bw.triad_bytes_per_s);
                }
                None => bandwidth.push(bw),
            }
            if has_numpy {
                let script = cfg.root.join("scripts/numpy_matmul.py");
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
                    "--threads",
                    &t.to_string(),
                ]);
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
                    Some(t),
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
    let get = |what: &str, t: usize| {
        timings.iter().find(|x| x.what.starts_with(what) && x.threads == Some(t)).map(|x| x.best_s)
    };
    let bytes_per_point = std::mem::size_of::<f32>() * (m + n);
    let per_threads: Vec<ThreadRow> = threads
        .iter()
        .map(|&t| {
            let host = points as f64 / get("host", t).unwrap_or(f64::NAN);
            let np = get("numpy", t).map(|s| points as f64 / s);
            let bw = bandwidth.iter().find(|x| x.threads == t).map_or(f64::NAN, Bandwidth::best_bytes_per_s);
            let floor = bw / bytes_per_point as f64;
            ThreadRow {
                threads: t,
                host_points_per_s: host,
                numpy_points_per_s: np,
                host_over_numpy: np.map(|x| host / x),
                floor_points_per_s: floor,
                host_over_floor: host / floor,
            }
        })
        .collect();
    let best_of = |what: &str| threads.iter().filter_map(|&t| get(what, t)).reduce(f64::min);
    let host1 = get("host", 1).unwrap_or(f64::NAN);
    Ok(SpeedReport {
        points,
        n,
        m,
        host_over_numpy_1t: get("numpy", 1).map(|x| host1 / x),
        host_over_numpy_best: best_of("numpy").map(|x| best_of("host").unwrap_or(f64::NAN) / x),
        timings,
        numpy,
        bytes_per_point,
        bandwidth,
        per_threads,
        host_in_cache_points_per_s: small as f64 / in_cache,
    })
}
