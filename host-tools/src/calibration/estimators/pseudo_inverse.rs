//! The Moore-Penrose pseudo-inverse of H (claim 4): `W = H^+`.
//!
//! Computed from the SVD `H = U S V^T` as `V S^+ U^T`, where singular values
//! at or below `max(m, n) * eps * s_max` are treated as zero
//! ([`super::rank_tolerance`]; the LAPACK / NumPy `pinv` convention: below it a
//! singular value cannot be told apart from the rounding of the largest one,
//! and inverting it would only amplify rounding). No inverse is formed.
use super::{Built, rank_tolerance};
use nalgebra::DMatrix;

/// `H^+` with the tolerance above; also returns the number of kept directions
/// and the tolerance.
pub fn pinv(h: &DMatrix<f64>) -> (DMatrix<f64>, usize, f64) {
    let (m, n) = h.shape();
    let svd = h.clone().svd(true, true);
    let s = &svd.singular_values;
    let u = svd.u.as_ref().expect("u requested");
    let vt = svd.v_t.as_ref().expect("v requested");
    let smax = s.iter().fold(0.0f64, |a, x| a.max(*x));
    let tol = rank_tolerance(m, n);
    let mut w = DMatrix::zeros(n, m);
    let mut kept = 0;
    for k in 0..s.len() {
        if smax > 0.0 && s[k] > tol * smax {
            kept += 1;
            w += vt.row(k).transpose() * u.column(k).transpose() / s[k];
        }
    }
    (w, kept, tol)
}

pub(crate) fn build(h: &DMatrix<f64>) -> Built {
    let (w, kept, tol) = pinv(h);
    let sv = h.clone().svd(false, false).singular_values;
    let smax = sv.max();
    let smin = sv.min();
    let dropped = kept < sv.len();
    Built {
        w,
        condition_system: if smin > 0.0 { smax / smin } else { f64::INFINITY },
        effective_rank: kept as f64,
        regularisation: if dropped { tol } else { 0.0 },
        tolerance: tol,
        method: format!(
            "claim 4: SVD of H, {kept} of {} singular values above {tol:.1e} s_max, W = V S^+ U^T",
            sv.len()
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::*;

    fn check_penrose(a: &DMatrix<f64>, x: &DMatrix<f64>, tol: f64) {
        let scale = a.amax() * x.amax();
        let e1 = (a * x * a - a).amax() / a.amax();
        let e2 = (x * a * x - x).amax() / x.amax();
        let e3 = (a * x - (a * x).transpose()).amax() / scale.max(1.0);
        let e4 = (x * a - (x * a).transpose()).amax() / scale.max(1.0);
        assert!(e1 < tol, "A X A != A ({e1:e})");
        assert!(e2 < tol, "X A X != X ({e2:e})");
        assert!(e3 < tol, "A X not symmetric ({e3:e})");
        assert!(e4 < tol, "X A not symmetric ({e4:e})");
    }

    #[test]
    fn satisfies_the_four_moore_penrose_conditions() {
        // Wide (the usual n > m), tall, and rank-deficient matrices.
        check_penrose(&blur(7, 81, 3.0), &pinv(&blur(7, 81, 3.0)).0, 1e-9);
        let tall = blur(9, 4, 0.8);
        check_penrose(&tall, &pinv(&tall).0, 1e-9);
        let mut def = blur(6, 20, 1.5);
        let r0 = def.row(0).into_owned();
        let r2 = def.row(2).into_owned();
        def.set_row(4, &(r0 * 0.3 + r2 * 0.7));
        let (x, kept, _) = pinv(&def);
        assert_eq!(kept, 5);
        check_penrose(&def, &x, 1e-9);
    }

    #[test]
    fn a_wrong_inverse_fails_the_conditions() {
        // Guard that the check above can fail: the transpose is no pseudo-inverse.
        let a = blur(4, 10, 1.0);
        let r = std::panic::catch_unwind(|| check_penrose(&a, &a.transpose(), 1e-9));
        assert!(r.is_err());
    }
}
