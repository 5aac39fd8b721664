//! The one timing and error harness of every evaluation (reproduce,
//! tradeoff, stability): how host time is measured (blocks long enough for
//! the clock, median of 7 after a warm-up; whole runs for fits) and how an
//! estimate's error against the truth is summed.
use nalgebra::DMatrix;
use std::time::{Duration, Instant};

/// The median (sorts `xs`); the mean of the middle two for an even count.
pub fn median(xs: &mut [f64]) -> f64 {
    xs.sort_by(f64::total_cmp);
    let k = xs.len();
    if k % 2 == 1 { xs[k / 2] } else { 0.5 * (xs[k / 2 - 1] + xs[k / 2]) }
}

/// Seconds per point of `f` (which estimates `points` points per call):
/// warm-up, blocks of at least `block`, median of 7.
pub fn time_per_point(points: usize, block: Duration, mut f: impl FnMut()) -> f64 {
    f();
    let mut reps = 1usize;
    loop {
        let t0 = Instant::now();
        for _ in 0..reps {
            f();
        }
        if t0.elapsed() >= block || reps >= 1 << 30 {
            break;
        }
        reps *= 2;
    }
    let mut per = Vec::with_capacity(7);
    for _ in 0..7 {
        let t0 = Instant::now();
        for _ in 0..reps {
            f();
        }
        per.push(t0.elapsed().as_secs_f64() / reps as f64);
    }
    median(&mut per) / points.max(1) as f64
}

/// `f`'s result and its wall time in seconds (one run).
pub fn timed<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t0 = Instant::now();
    let r = std::hint::black_box(f());
    (r, t0.elapsed().as_secs_f64())
}

/// Runs `f` `runs` times (at least once): the last result and the median
/// wall time of a run, seconds. For work too long to repeat in blocks (fits).
pub fn median_of_runs<T, E>(runs: usize, mut f: impl FnMut() -> Result<T, E>) -> Result<(T, f64), E> {
    let mut times = Vec::with_capacity(runs.max(1));
    let mut last = None;
    for _ in 0..runs.max(1) {
        let (r, t) = timed(&mut f);
        times.push(t);
        last = Some(r?);
    }
    Ok((last.expect("at least one run"), median(&mut times)))
}

/// Best and median wall time of `runs` runs of `f` after a warm-up, seconds.
pub fn best_and_median(runs: usize, mut f: impl FnMut()) -> (f64, f64) {
    f();
    let mut t: Vec<f64> = (0..runs).map(|_| timed(&mut f).1).collect();
    let best = t.iter().copied().fold(f64::INFINITY, f64::min);
    (best, median(&mut t))
}

/// (RMSE, max |error|) of estimates `est` (points x n, row-major) against
/// `truth` (n x points).
pub fn errors(est: &[f32], truth: &DMatrix<f64>) -> (f64, f64) {
    let n = truth.nrows();
    let (mut s, mut mx) = (0.0f64, 0.0f64);
    for (p, row) in est.chunks_exact(n).enumerate() {
        for j in 0..n {
            let e = row[j] as f64 - truth[(j, p)];
            s += e * e;
            mx = mx.max(e.abs());
        }
    }
    ((s / est.len() as f64).sqrt(), mx)
}

/// (RMSE, max |error|) of f64 estimates `est` against `truth` (same shape).
pub fn errors_f64(est: &DMatrix<f64>, truth: &DMatrix<f64>) -> (f64, f64) {
    let d = est - truth;
    ((d.norm_squared() / d.len() as f64).sqrt(), d.amax())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medians_and_errors() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
        let truth = DMatrix::from_column_slice(2, 2, &[1.0, 2.0, 3.0, 4.0]);
        // points x n row-major: point 0 = (1, 2), point 1 = (3, 4) + errors.
        let (rmse, mx) = errors(&[1.0, 2.0, 3.0, 6.0], &truth);
        assert_eq!((rmse, mx), (1.0, 2.0));
        let est = DMatrix::from_column_slice(2, 2, &[1.0, 2.0, 3.0, 6.0]);
        assert_eq!(errors_f64(&est, &truth), (1.0, 2.0));
    }

    #[test]
    fn runs_are_counted_and_failures_stop() {
        let mut calls = 0;
        let (r, t) = median_of_runs(3, || -> Result<usize, ()> {
            calls += 1;
            Ok(calls)
        })
        .unwrap();
        assert_eq!((r, calls), (3, 3));
        assert!(t >= 0.0);
        assert!(median_of_runs(2, || Err::<(), _>("no")).is_err());
        let mut n = 0;
        let (best, med) = best_and_median(4, || n += 1);
        assert_eq!(n, 5, "a warm-up and 4 timed runs");
        assert!(best <= med);
        let mut m = 0;
        assert!(time_per_point(10, Duration::from_micros(1), || m += 1) >= 0.0);
        assert!(m >= 8, "a warm-up and at least 7 blocks");
    }
}
