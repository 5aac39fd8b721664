//! How sure a coverage figure is: a share of bins within k = 2 is counted
//! over thousands of bins, but the bins of one surface err together (one
//! estimate, one prior shape), so the surfaces, not the bins, are the
//! independent draws. The interval resamples the surfaces with replacement
//! (a percentile bootstrap, [`RESAMPLES`] times, seeded so a report is the
//! same every run) and takes the 2.5th and 97.5th percentiles of the
//! pooled share: whether a coverage of 91.9 % over 120 surfaces is below
//! 92 % or only looks so.
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Bootstrap resamples.
pub const RESAMPLES: usize = 2000;

/// The 95 % percentile-bootstrap interval of the pooled share
/// `sum(hits) / sum(total)` over `units` (per surface: bins within, bins
/// counted; or a share of 1), resampling the surfaces; `None` with no bins
/// counted.
pub fn coverage_interval(units: &[(f64, f64)], seed: u64) -> Option<[f64; 2]> {
    let counted: f64 = units.iter().map(|u| u.1).sum();
    if counted.is_nan() || counted <= 0.0 {
        return None;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = units.len();
    let mut shares: Vec<f64> = (0..RESAMPLES)
        .filter_map(|_| {
            let (mut hit, mut all) = (0.0, 0.0);
            for _ in 0..n {
                let u = units[rng.random_range(0..n)];
                hit += u.0;
                all += u.1;
            }
            (all > 0.0).then(|| hit / all)
        })
        .collect();
    shares.sort_by(f64::total_cmp);
    let at = |q: f64| shares[((q * (shares.len() - 1) as f64).round() as usize).min(shares.len() - 1)];
    Some([at(0.025), at(0.975)])
}

/// `97.1 % (96.0-98.0)`: a coverage and its interval (the coverage alone
/// without one).
pub fn percent_with_interval(x: f64, interval: Option<[f64; 2]>) -> String {
    match interval {
        Some([lo, hi]) => format!("{:.1} % ({:.1}-{:.1})", 100.0 * x, 100.0 * lo, 100.0 * hi),
        None => format!("{:.1} %", 100.0 * x),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Surfaces that all cover alike give a narrow interval about their
    /// share; surfaces that differ give a wide one that still holds it;
    /// the same seed gives the same interval.
    #[test]
    fn the_interval_is_as_wide_as_the_surfaces_differ() {
        let alike = vec![(95.0, 100.0); 50];
        let [lo, hi] = coverage_interval(&alike, 1).unwrap();
        assert!((lo - 0.95).abs() < 1e-12 && (hi - 0.95).abs() < 1e-12, "{lo} {hi}");
        // Half the surfaces fully covered, half at 90 %: pooled 95 %.
        let mixed: Vec<(f64, f64)> = (0..50).map(|i| (if i % 2 == 0 { 1.0 } else { 0.9 }, 1.0)).collect();
        let [lo, hi] = coverage_interval(&mixed, 1).unwrap();
        assert!(lo < 0.95 && 0.95 < hi, "{lo} {hi}");
        // About 1.96 x 5 % / sqrt(50) either side, 1.4 points.
        assert!((0.005..0.03).contains(&(hi - lo)), "{lo} {hi}");
        assert_eq!(coverage_interval(&mixed, 1), Some([lo, hi]));
        assert_eq!(coverage_interval(&[(0.0, 0.0)], 1), None);
        assert_eq!(coverage_interval(&[], 1), None);
        assert_eq!(percent_with_interval(0.9712, Some([0.96, 0.98])), "97.1 % (96.0-98.0)");
        assert_eq!(percent_with_interval(0.9712, None), "97.1 %");
    }
}
