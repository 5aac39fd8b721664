//! The specular peak's uncertainty factors (`brdf_meter::blob::PeakFactors`):
//! what a resolved peak's first-order standard uncertainties
//! (`crate::output::peak`) are multiplied by so that they cover the peaks of
//! materials held out of training as the per-bin band covers the bins.
//!
//! The first-order height uncertainty is the peak bin's per-bin value, and
//! each bin's table is set to cover [`COVERAGE`] of that bin's held-out
//! errors over every estimate. But a bin is an estimate's peak exactly
//! where the estimate errs most (the lobe's top, where the prior decides
//! how high a narrow lobe is), so the peaks were covered less often than
//! the bins: measured before the factors, 88.7 % of the handheld's resolved
//! held-out MERL peaks and 91.2 % of the patent profile's (widths 88.4 %).
//!
//! Training collects, for every held-out reading the band's tables are set
//! from (kinds of material held out whole, `scale_free`), the estimate's
//! peak with its first-order uncertainties from the final tables and the
//! truth's peak ([`held_out_peak`]). Once the calibration's peak resolution
//! is known, the factors are the weighted [`COVERAGE`] quantile of the
//! standardised errors of the resolved peaks over [`COVERAGE_K`]
//! ([`factors`]), the prior's own weights, as the band's, the largest of
//! the materials as they are and of their variants (rougher finishes,
//! stretches) and of both together, so that each is covered on its own, as
//! the gloss readings' factors are (`crate::calibration::gloss_rows`).
//! Pooled, the patent profile's finishes bought the materials' coverage:
//! the height's factor came out at 1.00 and the materials' peaks never
//! seen were covered 89.0 %. Training data only: the test set never
//! enters it.
use crate::calibration::estimators::scale_free::weighted_quantile;
use crate::calibration::families::covering_each_family;
use crate::calibration::gloss_rows::{COVERAGE, COVERAGE_K};
use crate::output::peak::{Peak, PeakFactors, RESOLVED_WIDTH_FACTOR, specular_peak};

/// One held-out estimate's peak against its truth's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeldOutPeak {
    /// The reading's weight (the prior's own, shared over its draws).
    pub weight: f64,
    /// Which of the zone's training pixels read it (index into them).
    pub pixel: usize,
    /// Whether its sample is a variant of a material (`Pairs::variant`).
    pub variant: bool,
    /// The estimate's full width at half maximum, deg (NaN: none, a wide lobe).
    pub width_deg: f64,
    /// `|height - truth's| / u(height)` (first order).
    pub z_height: f64,
    /// `|width - truth's| / u(width)`; NaN where either has no width.
    pub z_width: f64,
}

/// The peak of the estimate `est` (per-bin standard uncertainties `u`) and
/// of its `truth` on `bins_deg`, about `view_deg`'s mirror incidence; `None`
/// where either has no peak or the estimate's height states no uncertainty.
pub fn held_out_peak(
    bins_deg: &[f32],
    (est, u, truth): (&[f32], &[f32], &[f32]),
    view_deg: f64,
    (weight, pixel, variant): (f64, usize, bool),
) -> Option<HeldOutPeak> {
    let t = specular_peak(bins_deg, truth, &vec![0.0; truth.len()], view_deg);
    let e: Peak = specular_peak(bins_deg, est, u, view_deg);
    if !(t.rf.is_finite() && e.rf.is_finite() && e.u_rf > 0.0) {
        return None;
    }
    let z_width = if t.width_deg.is_finite() && e.width_deg.is_finite() && e.u_width_deg > 0.0 {
        (e.width_deg - t.width_deg).abs() / e.u_width_deg
    } else {
        f64::NAN
    };
    let z_height = (e.rf - t.rf).abs() / e.u_rf;
    Some(HeldOutPeak { weight, pixel, variant, width_deg: e.width_deg, z_height, z_width })
}

/// Fewest resolved held-out peaks (with a width, for the width's factor) a
/// factor is set from, in all or in one family; fewer leave it at 1, or
/// leave the family to the pool.
pub const MIN_PEAKS: usize = 40;

/// The factors from the held-out `peaks`, each with the peak resolution of
/// the pixel that read it (`None`: the calibration records none, and every
/// peak counts as resolved, as `Peak::stated` judges them). `None` when too
/// few peaks are resolved to set the height's.
pub fn factors<'a>(peaks: impl IntoIterator<Item = (&'a HeldOutPeak, Option<f64>)>) -> Option<PeakFactors> {
    // Per family (as they are, variants), the resolved peaks' (z, weight).
    let (mut height, mut width) = ([Vec::new(), Vec::new()], [Vec::new(), Vec::new()]);
    for (p, res) in peaks {
        let resolved = p.width_deg.is_nan() || res.is_none_or(|r| p.width_deg >= RESOLVED_WIDTH_FACTOR * r);
        if !resolved || !p.z_height.is_finite() {
            continue;
        }
        let f = usize::from(p.variant);
        height[f].push((p.z_height, p.weight));
        if p.z_width.is_finite() {
            width[f].push((p.z_width, p.weight));
        }
    }
    let quantile = |xs: &[(f64, f64)]| -> Option<f64> {
        (xs.len() >= MIN_PEAKS).then(|| weighted_quantile(&mut xs.to_vec(), COVERAGE) / COVERAGE_K)
    };
    let factor = |fam: &[Vec<(f64, f64)>; 2]| -> Option<f32> {
        let f = covering_each_family(fam, quantile)? as f32;
        (f.is_finite() && f > 0.0).then_some(f)
    };
    let h = factor(&height)?;
    Some(PeakFactors { height: h, width: factor(&width).unwrap_or(1.0) })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> Vec<f32> {
        (0..81).map(|i| 25.0 + 0.5 * i as f32).collect()
    }

    fn lobe(x: &[f32], height: f32, fwhm: f32) -> Vec<f32> {
        let s = fwhm / 2.354_82;
        x.iter().map(|&a| height * (-0.5 * ((a - 45.0) / s).powi(2)).exp()).collect()
    }

    #[test]
    fn a_peak_read_high_by_two_of_its_uncertainties_has_z_two() {
        let x = grid();
        let u = vec![0.05f32; x.len()];
        let p = held_out_peak(&x, (&lobe(&x, 1.1, 3.0), &u, &lobe(&x, 1.0, 3.0)), 45.0, (0.5, 3, false)).unwrap();
        assert!((p.z_height - 2.0).abs() < 1e-5, "{p:?}");
        assert!(p.z_width < 1e-3 && (p.width_deg - 3.0).abs() < 0.05, "{p:?}");
        assert_eq!((p.weight, p.pixel), (0.5, 3));
        // No peak in the truth (a flat diffuser): nothing to compare.
        let flat = vec![0.3f32; x.len()];
        assert_eq!(held_out_peak(&x, (&lobe(&x, 1.0, 3.0), &u, &flat), 45.0, (1.0, 0, false)), None);
    }

    #[test]
    fn the_factors_cover_the_resolved_peaks_at_k_2_and_skip_the_unresolved() {
        // 100 resolved peaks of equal weight, |z| 0.05 .. 5.0: the 95th
        // percentile is 4.75, so the factor 2.375; the widths' |z| half
        // of that. An unresolved peak with a huge error changes nothing.
        let mut peaks: Vec<HeldOutPeak> = (1..=100)
            .map(|i| HeldOutPeak {
                weight: 1.0,
                pixel: 0,
                variant: false,
                width_deg: 2.0,
                z_height: f64::from(i) / 20.0,
                z_width: f64::from(i) / 40.0,
            })
            .collect();
        peaks.push(HeldOutPeak { weight: 50.0, pixel: 1, variant: false, width_deg: 1.0, z_height: 1e3, z_width: 1e3 });
        let res = |p: &HeldOutPeak| Some(if p.pixel == 1 { 0.9 } else { 1.0 });
        let f = factors(peaks.iter().map(|p| (p, res(p)))).unwrap();
        assert_eq!(f, PeakFactors { height: 2.375, width: 1.1875 });
        // Too few resolved peaks: no factors.
        assert_eq!(factors(peaks[..39].iter().map(|p| (p, Some(1.0)))), None);
        // Twice as many easy variants (|z| 0.1) do not buy the materials'
        // coverage: the pool's 95th percentile would be 3.5.
        let easy = HeldOutPeak { variant: true, z_height: 0.1, z_width: 0.1, ..peaks[0] };
        let with_easy: Vec<HeldOutPeak> = peaks[..100].iter().copied().chain(std::iter::repeat_n(easy, 200)).collect();
        let f = factors(with_easy.iter().map(|p| (p, Some(1.0)))).unwrap();
        assert_eq!(f, PeakFactors { height: 2.375, width: 1.1875 });
    }
}
