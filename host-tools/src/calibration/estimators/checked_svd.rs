//! A thin SVD that is backward stable on every input.
//!
//! nalgebra's Golub-Kahan SVD is usually backward stable, but on some
//! ill-conditioned inputs (singular values spread over 8 or more decades, e.g.
//! the whitened `R_nn^-1/2 H L` as the noise vanishes) it returns orthonormal
//! factors whose product misses the matrix by 1e-11 to 1e-6 relative instead
//! of O(max(m, n) u); the resulting W was off by up to 3e-2 (stability family
//! runs, continuity as the noise vanishes). The factors are therefore checked,
//! and when the check fails the SVD is recomputed by one-sided (Hestenes)
//! Jacobi, which is backward stable by construction (each rotation is
//! orthogonal and applied exactly once to the data). Inputs nalgebra handles
//! well keep nalgebra's result bit for bit.
use super::rank_tolerance;
use nalgebra::{DMatrix, DVector, SVD};

/// Thin SVD of `a` with U and V^T, backward stable: `|A - U S V^T|_F` and
/// the orthogonality defects are at most `rank_tolerance |A|_F` (resp.
/// `rank_tolerance`), i.e. `max(m, n) eps`.
pub(crate) fn svd(a: &DMatrix<f64>) -> SVD<f64, nalgebra::Dyn, nalgebra::Dyn> {
    let first = a.clone().svd(true, true);
    if acceptable(a, &first) {
        return first;
    }
    jacobi(a)
}

fn acceptable(a: &DMatrix<f64>, s: &SVD<f64, nalgebra::Dyn, nalgebra::Dyn>) -> bool {
    let (Some(u), Some(vt)) = (&s.u, &s.v_t) else { return false };
    let tol = rank_tolerance(a.nrows(), a.ncols());
    let k = s.singular_values.len();
    let mut us = u.clone();
    for (c, sv) in s.singular_values.iter().enumerate() {
        us.column_mut(c).scale_mut(*sv);
    }
    let rec = (a - us * vt).norm();
    let eye = DMatrix::<f64>::identity(k, k);
    let ortho = (u.transpose() * u - &eye).norm().max((vt * vt.transpose() - &eye).norm());
    rec.is_finite() && rec <= tol * a.norm() && ortho <= tol
}

/// One-sided Jacobi on the columns of the taller orientation.
fn jacobi(a: &DMatrix<f64>) -> SVD<f64, nalgebra::Dyn, nalgebra::Dyn> {
    let wide = a.nrows() < a.ncols();
    let mut x = if wide { a.transpose() } else { a.clone() }; // p x q, p >= q
    let (p, q) = x.shape();
    let mut v = DMatrix::<f64>::identity(q, q);
    for _sweep in 0..80 {
        let mut rotated = false;
        for i in 0..q {
            for j in i + 1..q {
                let alpha = x.column(i).norm_squared();
                let beta = x.column(j).norm_squared();
                let gamma = x.column(i).dot(&x.column(j));
                if gamma == 0.0 || gamma.abs() <= f64::EPSILON * (alpha * beta).sqrt() {
                    continue;
                }
                rotated = true;
                let zeta = (beta - alpha) / (2.0 * gamma);
                let t = zeta.signum() / (zeta.abs() + zeta.hypot(1.0));
                let c = 1.0 / t.hypot(1.0);
                let s = c * t;
                for (mat, rows) in [(&mut x, p), (&mut v, q)] {
                    for r in 0..rows {
                        let (xi, xj) = (mat[(r, i)], mat[(r, j)]);
                        mat[(r, i)] = c * xi - s * xj;
                        mat[(r, j)] = s * xi + c * xj;
                    }
                }
            }
        }
        if !rotated {
            break;
        }
    }
    let mut order: Vec<usize> = (0..q).collect();
    let norms: Vec<f64> = (0..q).map(|c| x.column(c).norm()).collect();
    order.sort_by(|&i, &j| norms[j].total_cmp(&norms[i]));
    let mut u = DMatrix::zeros(p, q);
    let mut vv = DMatrix::zeros(q, q);
    let sv = DVector::from_fn(q, |c, _| norms[order[c]]);
    for (c, &o) in order.iter().enumerate() {
        if norms[o] > 0.0 {
            u.set_column(c, &(x.column(o) / norms[o]));
        }
        vv.set_column(c, &v.column(o));
    }
    // A (or A^T) = U S V^T.
    if wide {
        SVD { u: Some(vv), v_t: Some(u.transpose()), singular_values: sv }
    } else {
        SVD { u: Some(u), v_t: Some(vv.transpose()), singular_values: sv }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobi_is_backward_stable_on_a_graded_matrix() {
        // Singular values over 12 decades, both orientations.
        let q = DMatrix::from_fn(5, 5, |i, j| ((i * 7 + j * 3) as f64).sin());
        let qr = q.qr();
        let (o1, o2) = (qr.q(), DMatrix::from_fn(5, 9, |i, j| ((i + 2 * j) as f64).cos()).transpose().qr().q());
        let s = DMatrix::from_diagonal(&DVector::from_fn(5, |i, _| 10f64.powi(-3 * i as i32)));
        let a = &o1 * s * o2.transpose(); // 5 x 9
        for m in [a.clone(), a.transpose()] {
            let d = jacobi(&m);
            assert!(acceptable(&m, &d), "{:?}", d.singular_values);
            for i in 0..5 {
                let want = 10f64.powi(-3 * i as i32);
                assert!(
                    (d.singular_values[i] - want).abs() <= 1e-14, // normwise: |d sigma| <= |dA| (rounding of forming A, |A| = 1)
                    "{i}: {}",
                    d.singular_values[i]
                );
            }
        }
    }

    #[test]
    fn an_inaccurate_factorisation_is_rejected() {
        let a = DMatrix::from_row_slice(2, 3, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.5]);
        let mut s = a.clone().svd(true, true);
        assert!(acceptable(&a, &s));
        s.singular_values[1] *= 1.0 + 1e-9;
        assert!(!acceptable(&a, &s));
        assert!(acceptable(&a, &svd(&a)));
    }
}
