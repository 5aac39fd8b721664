//! Wiener estimation from sample pairs (the patent's eq. 16-18):
//!
//! ```text
//! W = R_tv (R_vv + R_nn)^-1,   R_tv = sum_k w_k t_k v_k^T,   R_vv = sum_k w_k v_k v_k^T,
//! R_nn = sum_k w_k diag(var(v_k))
//! ```
//!
//! for any target `t` of the pairs (the BRDF on the grid, or the gloss
//! readings' linear readings) and any weights (the training criterion,
//! `crate::forward::pairs::Criterion`). With in-plane pairs `v = H rho` and
//! the prior's own weights it is eq. 22, `R_pp H^T (H R_pp H^T + R_nn)^-1`
//! (tested against [`super::wiener`] to 1e-9). The system is m x m and
//! symmetric positive definite whenever there is noise; it is solved by
//! Cholesky, never inverted. Without noise and with fewer independent
//! readings than LEDs it is singular: a ridge of `rel * tr / m`, the smallest
//! of 1e-14, 1e-12, ... that Cholesky accepts, is added and recorded.
//!
//! The error second moment is computed from the residuals, so it is
//! positive semi-definite by construction:
//! `E = sum_k w_k (t_k - W v_k)(t_k - W v_k)^T + W R_nn W^T`.
use super::{EstimatorSummary, LinearEstimator};
use crate::forward::pairs::Pairs;
use anyhow::{Context, bail};
use brdf_meter::blob::EstimatorKind;
use nalgebra::{DMatrix, DVector};

/// A linear map of the readings onto a target, fitted on pairs.
#[derive(Clone, Debug)]
pub struct LinearMap {
    /// The map, r x m.
    pub g: DMatrix<f64>,
    /// The error's second moment over the pairs, noise included, r x r.
    pub err: DMatrix<f64>,
    /// Condition number of `R_vv + R_nn` (before any ridge).
    pub condition: f64,
    /// Relative ridge added (0 when none was needed).
    pub ridge: f64,
}

/// The Wiener map of the readings of `pairs` onto `target` (r x K, one
/// column per pair), with the pairs' weights.
pub fn linear_map(pairs: &Pairs, target: &DMatrix<f64>) -> anyhow::Result<LinearMap> {
    let (m, k) = (pairs.m(), pairs.len());
    if target.ncols() != k {
        bail!("the target has {} columns for {k} pairs", target.ncols());
    }
    let sw = DVector::from_iterator(k, pairs.weights.iter().map(|w| w.max(0.0).sqrt()));
    let sv = scale_columns(&pairs.readings, &sw);
    let st = scale_columns(target, &sw);
    let r_nn = pairs.noise_covariance();
    let c = &sv * sv.transpose() + &r_nn;
    let c = (&c + c.transpose()) * 0.5;
    let eig = c.clone().symmetric_eigenvalues();
    let (lmax, lmin) = (eig.max(), eig.min());
    let condition = if lmin > 0.0 { lmax / lmin } else { f64::INFINITY };
    let rhs = &sv * st.transpose(); // m x r
    let trace = c.trace().max(f64::MIN_POSITIVE);
    let mut ridge = 0.0;
    let chol = loop {
        let reg = &c + DMatrix::identity(m, m) * (ridge * trace / m as f64);
        if let Some(ch) = reg.cholesky() {
            break ch;
        }
        ridge = if ridge == 0.0 { 1e-14 } else { ridge * 100.0 };
        if ridge > 1e-2 {
            bail!("the readings' covariance is singular even with a ridge of 1e-2: the LEDs read no independent light");
        }
    };
    let g = chol.solve(&rhs).transpose();
    let resid = &st - &g * &sv;
    let gn = &g * &r_nn * g.transpose();
    let err = &resid * resid.transpose() + gn;
    Ok(LinearMap { g, err, condition, ridge })
}

fn scale_columns(a: &DMatrix<f64>, s: &DVector<f64>) -> DMatrix<f64> {
    let mut out = a.clone();
    for (j, mut col) in out.column_iter_mut().enumerate() {
        col *= s[j];
    }
    out
}

/// The Wiener estimator of the BRDF from `pairs` (weighted for the training
/// criterion); its uncertainty is the error over the pairs' own weights.
/// `h` (the zone's in-plane system matrix) only fills the summary.
pub fn build(
    pairs: &Pairs,
    h: &DMatrix<f64>,
    prior_samples: usize,
    noise_level: f64,
) -> anyhow::Result<LinearEstimator> {
    let map = linear_map(pairs, &pairs.truth).context("the Wiener map from sample pairs")?;
    // The per-bin uncertainty a blob carries is over the prior's own
    // ensemble (absolute reflectance factors), whatever the criterion.
    let plain = Pairs { weights: pairs.base.clone(), ..pairs.clone() };
    let err = residual_moment(&plain, &map.g);
    let n = pairs.n();
    let var = err.diagonal().map(|x| x.max(0.0));
    let predicted_rmse = (var.sum() / n as f64).sqrt();
    let sv_h = h.clone().svd(false, false).singular_values;
    let (smax, smin) = (sv_h.max(), sv_h.min());
    let tol = super::rank_tolerance(h.nrows(), h.ncols());
    Ok(LinearEstimator {
        kind: EstimatorKind::Wiener,
        uncertainty: var.map(f64::sqrt),
        summary: EstimatorSummary {
            kind: super::kind_name(EstimatorKind::Wiener).to_string(),
            n,
            m: pairs.m(),
            prior_samples,
            prior_rank: numerical_rank(&pairs.truth),
            condition_h: if smin > 0.0 { smax / smin } else { f64::INFINITY },
            rank_h: sv_h.iter().filter(|s| **s > tol * smax).count(),
            condition_system: map.condition,
            effective_rank: pairs.m() as f64,
            regularisation: map.ridge,
            tolerance: tol,
            noise_rel: noise_level,
            predicted_rmse,
            method: format!(
                "Wiener from {} sample pairs (eq. 16-18): W = R_pv (R_vv + R_nn)^-1 by Cholesky{}",
                pairs.len(),
                if map.ridge > 0.0 { format!(", ridge {:.0e}", map.ridge) } else { String::new() }
            ),
        },
        w: map.g,
    })
}

/// `sum_k w_k (t_k - G v_k)(..)^T + G R_nn G^T` of a map `g` over `pairs`.
pub fn residual_moment(pairs: &Pairs, g: &DMatrix<f64>) -> DMatrix<f64> {
    let k = pairs.len();
    let sw = DVector::from_iterator(k, pairs.weights.iter().map(|w| w.max(0.0).sqrt()));
    let resid = scale_columns(&(&pairs.truth - g * &pairs.readings), &sw);
    &resid * resid.transpose() + g * pairs.noise_covariance() * g.transpose()
}

fn numerical_rank(a: &DMatrix<f64>) -> usize {
    let sv = a.clone().svd(false, false).singular_values;
    let tol = super::rank_tolerance(a.nrows(), a.ncols()) * sv.max();
    sv.iter().filter(|s| **s > tol).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::estimators::{EstimatorInputs, NoiseModel};
    use crate::forward::optics::{Instrument, system_matrix};
    use crate::forward::pairs::{Criterion, Pairs};
    use crate::forward::prior::PriorSpec;
    use crate::forward::reading_noise::ReadingNoise;

    #[test]
    fn in_plane_pairs_give_the_patents_eq_22_matrix() {
        let inst = Instrument::patent_profile();
        let grid = inst.grid().unwrap();
        let h = system_matrix(&inst, &grid, false).unwrap();
        let prior = PriorSpec::patent().build(&grid, 45.0, std::path::Path::new(".")).unwrap();
        let k = prior.samples.ncols();
        let pairs = Pairs::in_plane(&h, &prior.samples, &vec![1.0; k], &ReadingNoise::relative(0.02, 7))
            .weighted(Criterion::Plain);
        let from_pairs = build(&pairs, &h, k, 0.02).unwrap();
        let inputs = EstimatorInputs {
            h: &h,
            r_pp: &prior.r_pp,
            prior_samples: k,
            noise: NoiseModel::Relative(0.02),
            bins_deg: grid.bins_deg(),
            centres_deg: &inst.centre_angles_deg(),
        };
        let classic = crate::calibration::estimators::build(EstimatorKind::Wiener, &inputs).unwrap();
        let d = (&from_pairs.w - &classic.w).amax() / classic.w.amax();
        assert!(d < 1e-9, "relative difference {d:e}");
        let du = (&from_pairs.uncertainty - &classic.uncertainty).amax() / classic.uncertainty.amax();
        assert!(du < 1e-9, "uncertainty differs by {du:e}");
    }

    #[test]
    fn a_singular_noise_free_system_gets_the_smallest_ridge_that_works() {
        // Two identical readings: R_vv is singular without noise.
        let truth = DMatrix::from_fn(3, 6, |j, k| ((j + 1) * (k + 2)) as f64);
        let v = DMatrix::from_fn(2, 6, |_, k| truth.column(k).sum());
        let pairs = Pairs::in_plane(&DMatrix::identity(3, 3), &truth, &[1.0; 6], &ReadingNoise::relative(0.0, 3));
        let pairs = Pairs { readings: v, noise_var: DMatrix::zeros(2, 6), ..pairs };
        let map = linear_map(&pairs, &pairs.truth).unwrap();
        assert!(map.ridge > 0.0 && map.ridge <= 1e-10, "{}", map.ridge);
        assert!(map.g.iter().all(|x| x.is_finite()));
        assert!(map.err.diagonal().iter().all(|x| *x >= 0.0));
    }
}
