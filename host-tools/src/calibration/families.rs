//! The rule every quantile set on held-out training samples follows: each
//! family of samples covered on its own. A prior holds the materials as
//! they are and their variants (rougher finishes, stretches across the
//! plane; `crate::forward::prior_models::PriorModels::variants`), and the
//! gloss rows also the gloss standards. The families err, and are flagged,
//! at different rates, and pooled, an easy family buys a hard one's
//! coverage: a factor or a threshold set on the pool did not hold on the
//! materials the instrument is sold to read. Used by the per-bin band
//! (`crate::calibration::estimators::scale_free`), the gloss readings'
//! uncertainty factors (`crate::calibration::gloss_rows`), the specular
//! peak's (`crate::calibration::peak_factors`) and the out-of-prior
//! flag's threshold (`crate::calibration::estimators::out_of_prior`).

/// Fewest held-out points a family's own quantile is set from (the 95th
/// percentile of 40 points is the third largest); a smaller family still
/// counts in the whole.
pub const MIN_FAMILY_POINTS: usize = 40;

/// The largest of `quantile` over all of `families` together and over each
/// family with at least [`MIN_FAMILY_POINTS`]; `None` when the whole's is.
pub fn covering_each_family<T: Clone>(families: &[Vec<T>], quantile: impl Fn(&[T]) -> Option<f64>) -> Option<f64> {
    let all = quantile(&families.concat())?;
    Some(families.iter().filter(|f| f.len() >= MIN_FAMILY_POINTS).filter_map(|f| quantile(f)).fold(all, f64::max))
}

/// [`covering_each_family`] of the weighted `q` quantile of (value,
/// weight) pairs (`estimators::scale_free::weighted_quantile`), the form
/// the per-bin band and the flag's threshold take; `None` when no family
/// holds a pair.
pub fn weighted_quantile_of_each(families: &[Vec<(f64, f64)>], q: f64) -> Option<f64> {
    covering_each_family(families, |xs| {
        (!xs.is_empty()).then(|| crate::calibration::estimators::scale_free::weighted_quantile(&mut xs.to_vec(), q))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_family_large_enough_sets_its_own_and_a_small_one_only_counts_in_the_whole() {
        let max = |xs: &[f64]| xs.iter().copied().reduce(f64::max);
        // 40 points at 1 and 40 at 3: the larger family's own is 3.
        assert_eq!(covering_each_family(&[vec![1.0; 40], vec![3.0; 40]], max), Some(3.0));
        // A family of 39 at 0.5 cannot lower what the whole gives.
        let mean = |xs: &[f64]| Some(xs.iter().sum::<f64>() / xs.len() as f64);
        assert_eq!(covering_each_family(&[vec![2.0; 40], vec![0.5; 39]], mean), Some(2.0));
        // Nothing at all: no quantile.
        assert_eq!(covering_each_family::<f64>(&[vec![], vec![]], max), None);
    }
}
