//! The inverse of a square H (claim 3): `W = H^-1`.
//!
//! W *is* the inverse here, so it has to be formed; it is computed by an LU
//! solve with partial pivoting of `H X = I`, and only after the SVD has shown
//! that H is numerically non-singular: a condition number at or above
//! `1 / (n eps)` is refused ([`super::EstimatorError::Singular`]) with the
//! advice to use the pseudo-inverse or Wiener estimator instead.
use super::{Built, EstimatorError, rank_tolerance};
use nalgebra::DMatrix;

pub(crate) fn build(h: &DMatrix<f64>) -> Result<Built, EstimatorError> {
    let (m, n) = h.shape();
    if m != n {
        return Err(EstimatorError::NotSquare { m, n });
    }
    let sv = h.clone().svd(false, false).singular_values;
    let (smax, smin) = (sv.max(), sv.min());
    let tol = rank_tolerance(n, n);
    let condition = if smin > 0.0 { smax / smin } else { f64::INFINITY };
    // Also refuses NaN singular values.
    if smin.is_nan() || smin <= tol * smax {
        return Err(EstimatorError::Singular { condition });
    }
    let w = h.clone().lu().solve(&DMatrix::identity(n, n)).ok_or(EstimatorError::Singular { condition })?;
    Ok(Built {
        w,
        condition_system: condition,
        effective_rank: n as f64,
        regularisation: 0.0,
        tolerance: tol,
        method: format!("claim 3: LU solve of H X = I (condition {condition:.3e})"),
    })
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::super::*;

    #[test]
    fn inverse_of_a_square_h() {
        let n = 7;
        let mut h = blur(n, n, 0.7);
        for i in 0..n {
            h[(i, i)] += 0.3;
        }
        let r = correlation(&lobes(n, 20, 1));
        let bins: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let inp = EstimatorInputs {
            h: &h,
            r_pp: &r,
            prior_samples: 20,
            noise: NoiseModel::None,
            bins_deg: &bins,
            centres_deg: &bins,
        };
        let est = build(EstimatorKind::Inverse, &inp).unwrap();
        assert!((&est.w * &h - DMatrix::identity(n, n)).amax() < 1e-12);
        // Noise-free and exact: nothing left to predict.
        assert!(est.summary.predicted_rmse < 1e-6 * r.amax().sqrt());
    }

    #[test]
    fn singular_square_h_is_refused() {
        let n = 5;
        let mut h = blur(n, n, 0.7);
        let r0 = h.row(0).into_owned();
        h.set_row(3, &r0);
        let r = correlation(&lobes(n, 20, 1));
        let inp = EstimatorInputs {
            h: &h,
            r_pp: &r,
            prior_samples: 20,
            noise: NoiseModel::None,
            bins_deg: &[],
            centres_deg: &[],
        };
        match build(EstimatorKind::Inverse, &inp) {
            Err(EstimatorError::Singular { condition }) => assert!(condition > 1e14),
            other => panic!("expected Singular, got {other:?}"),
        }
    }
}
