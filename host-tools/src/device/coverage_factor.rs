//! The coverage factor of a result's expanded uncertainty, from its
//! effective degrees of freedom (GUM, JCGM 100:2008, G.4 and G.6).
//!
//! A result's budget mixes contributions known to many degrees of freedom
//! (the calibration's, set from thousands of held-out readings; the
//! standards', stated by their certificates) with one evaluated from the
//! points themselves (the repeatability, `n - 1` degrees of freedom). When
//! few points vary much, the repeatability is itself uncertain and
//! `value +- 2 u_c` holds the truth less often than 95 %. The
//! Welch-Satterthwaite formula gives the combined uncertainty's effective
//! degrees of freedom, `nu_eff = u_c^4 / sum(u_i^4 / nu_i)`, and the
//! coverage factor is Student's t at the coverage probability for `nu_eff`
//! (GUM Table G.2): 2 with many degrees of freedom, 2.87 with 4, 13.97 with
//! one. A result over dozens of points whose spread is small beside the
//! calibration's uncertainty keeps k = 2 to the second decimal.
use statrs::distribution::{ContinuousCDF, StudentsT};

/// The coverage probability of an expanded uncertainty: that of k = 2 for a
/// normal distribution, `erf(sqrt(2))` (GUM G.1.3 and Table G.1), so that
/// infinitely many degrees of freedom give k = 2 exactly.
pub const COVERAGE_PROBABILITY: f64 = 0.954_499_736_103_641_6;

/// The coverage factor with infinitely many degrees of freedom.
pub const LARGE_DOF_FACTOR: f64 = 2.0;

/// The effective degrees of freedom of the root sum of squares of
/// `parts`, each a standard uncertainty and its degrees of freedom (`None`:
/// infinitely many, as for a type B evaluation known well): the
/// Welch-Satterthwaite formula (GUM G.4.1). `None` when no part with
/// finite degrees of freedom contributes (a repeatability of 0, as from one
/// point, contributes nothing).
pub fn effective_dof(parts: &[(f64, Option<f64>)]) -> Option<f64> {
    let u_c2: f64 = parts.iter().map(|(u, _)| u * u).sum();
    let denominator: f64 =
        parts.iter().filter_map(|&(u, dof)| dof.filter(|_| u > 0.0).map(|nu| u.powi(4) / nu.max(1.0))).sum();
    (denominator > 0.0 && u_c2 > 0.0).then(|| u_c2 * u_c2 / denominator)
}

/// Degrees of freedom from which the coverage factor is the expansion of
/// Student's t in `1 / nu` rather than statrs's inverse: there the
/// incomplete beta function loses accuracy (1.9996 at 10^6, below the
/// limit of 2) and, at 10^8, does not return.
pub const ASYMPTOTIC_DOF: f64 = 1e4;

/// The coverage factor for `dof` effective degrees of freedom (`None`:
/// infinitely many): Student's t quantile at `(1 + p) / 2` for
/// [`COVERAGE_PROBABILITY`] `p`, as GUM G.6.4 takes it (degrees of freedom
/// below 1 as 1). From [`ASYMPTOTIC_DOF`] on, the quantile's expansion
/// about the normal's `z = 2` (Abramowitz and Stegun 26.7.5), `z + (z^3 +
/// z) / (4 nu) + (5 z^5 + 16 z^3 + 3 z) / (96 nu^2)`: `2 + 2.5 / nu +
/// 3.0625 / nu^2`, within 10^-11 of the quantile there.
pub fn coverage_factor(dof: Option<f64>) -> f64 {
    match dof {
        Some(nu) if nu.is_finite() && nu >= ASYMPTOTIC_DOF => LARGE_DOF_FACTOR + 2.5 / nu + 3.0625 / (nu * nu),
        Some(nu) if nu.is_finite() => StudentsT::new(0.0, 1.0, nu.max(1.0))
            .map(|t| t.inverse_cdf(0.5 * (1.0 + COVERAGE_PROBABILITY)))
            .ok()
            .filter(|k| k.is_finite())
            .map_or(LARGE_DOF_FACTOR, |k| k.max(LARGE_DOF_FACTOR)),
        _ => LARGE_DOF_FACTOR,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_factors_are_the_gums_table_g2() {
        // GUM Table G.2, p = 95.45 %.
        for (nu, k) in [(1.0, 13.97), (2.0, 4.53), (3.0, 3.31), (4.0, 2.87), (5.0, 2.65), (10.0, 2.28), (20.0, 2.13)] {
            assert!(
                (coverage_factor(Some(nu)) - k).abs() < 0.006,
                "nu {nu}: {} against {k}",
                coverage_factor(Some(nu))
            );
        }
        for (nu, k) in [(50.0, 2.05), (100.0, 2.025)] {
            assert!((coverage_factor(Some(nu)) - k).abs() < 0.003, "nu {nu}: {}", coverage_factor(Some(nu)));
        }
        assert_eq!(coverage_factor(None), 2.0);
        assert_eq!(coverage_factor(Some(f64::INFINITY)), 2.0);
        // Many degrees of freedom tend to 2 from above, without a jump
        // where the expansion takes over, and return at any size (2
        // itself once 2.5 / nu is below f64's resolution).
        let below = coverage_factor(Some(ASYMPTOTIC_DOF * (1.0 - 1e-9)));
        let above = coverage_factor(Some(ASYMPTOTIC_DOF));
        assert!((below - above).abs() < 1e-10 && (above - 2.00025003).abs() < 1e-8, "{below} {above}");
        for nu in [1e6, 1e8, 1e30] {
            let k = coverage_factor(Some(nu));
            assert!((2.0..=2.0 + 3.0 / nu).contains(&k), "{nu}: {k}");
        }
        assert_eq!(coverage_factor(Some(0.2)), coverage_factor(Some(1.0)));
    }

    #[test]
    fn welch_satterthwaite_weighs_each_part_by_its_share() {
        // One part alone keeps its degrees of freedom.
        assert_eq!(effective_dof(&[(0.3, Some(7.0))]), Some(7.0));
        // A type B part of equal size: u_c^4 = 4 u^4, so 4 nu.
        let nu = effective_dof(&[(0.5, None), (0.5, Some(3.0))]).unwrap();
        assert!((nu - 12.0).abs() < 1e-12, "{nu}");
        // Three equal parts: the finite ones summed, the type B one
        // adding to u_c only.
        let nu = effective_dof(&[(1.0, Some(4.0)), (1.0, Some(9.0)), (1.0, None)]).unwrap();
        assert!((nu - 9.0 / (0.25 + 1.0 / 9.0)).abs() < 1e-12, "{nu}");
        // Nothing finite, or only zero parts with finite degrees of freedom.
        assert_eq!(effective_dof(&[(0.4, None)]), None);
        assert_eq!(effective_dof(&[(0.4, None), (0.0, Some(0.0))]), None);
        assert_eq!(effective_dof(&[]), None);
    }
}
