//! The sigma -> 0 limit of eq. 22 in exact arithmetic, for I3's reference.
//!
//! When `B = H L` (m x r) has full rank, the limit has a closed form that
//! needs no SVD and no square root:
//! - `m <= r` (full row rank): `W_lim = L B^T (B B^T)^-1`, whatever the
//!   noise weights (the limit interpolates the readings exactly);
//! - `r < m` (full column rank): `W_lim = L (B^T D^-1 B)^-1 B^T D^-1`, the
//!   D-weighted least-squares inverse.
//!
//! Every f64 is an integer times a power of two, so H, L and D are scaled to
//! integer matrices (a common power of two per matrix; W_lim is invariant to
//! scaling L and D and scales as 1/c with H), the normal matrices are formed
//! exactly in big integers, and the system is solved by fraction-free
//! (Bareiss) elimination with an exact integer back-substitution. The only
//! rounding is the final conversion of each entry to the nearest f64, so the
//! reference is exact for the f64 data H, L and D, and I3 measures the
//! solver's error alone. The f64 SVD route (`weighted_limit`) is itself
//! accurate only to `O(max(m, n) u kappa)`, the same order as I3's tolerance,
//! which made the reference, not the solver, decide the hardest cases.
use nalgebra::{DMatrix, DVector};
use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{Float, ToPrimitive, Zero};

/// Integer matrix (row-major) and the power of two it was scaled by:
/// `value = int / 2^shift`.
struct Scaled {
    rows: usize,
    cols: usize,
    v: Vec<BigInt>,
    shift: i64,
}

fn scaled(rows: usize, cols: usize, at: impl Fn(usize, usize) -> f64) -> Scaled {
    let min_exp = (0..rows)
        .flat_map(|i| (0..cols).map(move |j| (i, j)))
        .map(|(i, j)| at(i, j))
        .filter(|x| *x != 0.0)
        .map(|x| i64::from(Float::integer_decode(x).1))
        .min()
        .unwrap_or(0);
    let shift = -min_exp;
    let mut v = Vec::with_capacity(rows * cols);
    for i in 0..rows {
        for j in 0..cols {
            let x = at(i, j);
            if x == 0.0 {
                v.push(BigInt::zero());
                continue;
            }
            let (mant, exp, sign) = Float::integer_decode(x);
            let z = BigInt::from(mant) << ((i64::from(exp) + shift) as usize);
            v.push(if sign < 0 { -z } else { z });
        }
    }
    Scaled { rows, cols, v, shift }
}

fn mul(a: &[BigInt], ar: usize, ac: usize, b: impl Fn(usize, usize) -> BigInt, bc: usize) -> Vec<BigInt> {
    let mut out = Vec::with_capacity(ar * bc);
    for i in 0..ar {
        for j in 0..bc {
            let mut s = BigInt::zero();
            for t in 0..ac {
                if !a[i * ac + t].is_zero() {
                    s += &a[i * ac + t] * b(t, j);
                }
            }
            out.push(s);
        }
    }
    out
}

/// Solves `A X = R` exactly (A p x p, R p x q, row-major integers). Returns
/// `(Y, det)` with `X = Y / det`, or None when A is singular.
fn bareiss_solve(mut a: Vec<BigInt>, mut rhs: Vec<BigInt>, p: usize, q: usize) -> Option<(Vec<BigInt>, BigInt)> {
    let mut prev = BigInt::from(1);
    for k in 0..p {
        let piv = (k..p).find(|&i| !a[i * p + k].is_zero())?;
        if piv != k {
            for j in 0..p {
                a.swap(piv * p + j, k * p + j);
            }
            for j in 0..q {
                rhs.swap(piv * q + j, k * q + j);
            }
        }
        for i in k + 1..p {
            let (akk, aik) = (a[k * p + k].clone(), a[i * p + k].clone());
            for j in k + 1..p {
                a[i * p + j] = (&akk * &a[i * p + j] - &aik * &a[k * p + j]) / &prev;
            }
            for j in 0..q {
                rhs[i * q + j] = (&akk * &rhs[i * q + j] - &aik * &rhs[k * q + j]) / &prev;
            }
            a[i * p + k] = BigInt::zero();
        }
        prev = a[k * p + k].clone();
    }
    // Back-substitution scaled by det = a[p-1][p-1] (up to sign, the
    // determinant after row swaps): det * x is an integer vector (Cramer), so
    // every division below is exact.
    let det = a[(p - 1) * p + (p - 1)].clone();
    let mut y = vec![BigInt::zero(); p * q];
    for j in 0..q {
        for i in (0..p).rev() {
            let mut s = &det * &rhs[i * q + j];
            for t in i + 1..p {
                s -= &a[i * p + t] * &y[t * q + j];
            }
            y[i * q + j] = s / &a[i * p + i];
        }
    }
    Some((y, det))
}

fn to_f64(num: &BigInt, den: &BigInt, shift: i64) -> f64 {
    let (mut n, mut d) = (num.clone(), den.clone());
    if shift >= 0 {
        n <<= shift as usize;
    } else {
        d <<= (-shift) as usize;
    }
    BigRational::new(n, d).to_f64().unwrap_or(f64::NAN)
}

/// `W_lim` for `B = H L` of full rank, with noise weights `dw` (used only
/// when r < m), computed exactly and rounded once to f64. None when `H L` is
/// exactly singular (the caller then keeps the SVD route).
pub fn exact_limit(h: &DMatrix<f64>, l: &DMatrix<f64>, dw: &DVector<f64>) -> Option<DMatrix<f64>> {
    let (m, n, r) = (h.nrows(), l.nrows(), l.ncols());
    if m == 0 || r == 0 || dw.iter().any(|x| !(*x > 0.0 && x.is_finite())) {
        return None;
    }
    let hs = scaled(m, n, |i, j| h[(i, j)]);
    let ls = scaled(n, r, |i, j| l[(i, j)]);
    debug_assert!(hs.rows == m && ls.cols == r && hs.cols == ls.rows);
    // B_int = H_int L_int = B 2^(sh + sl); W_lim(H) = 2^-sh W_lim(H_int),
    // i.e. W_lim = W_lim(H_int, L_int) * 2^sh.
    let b = mul(&hs.v, m, n, |t, j| ls.v[t * r + j].clone(), r); // m x r
    if m <= r {
        // (B B^T) W^T = B L^T.
        let bbt = mul(&b, m, r, |t, j| b[j * r + t].clone(), m);
        let blt = mul(&b, m, r, |t, j| ls.v[j * r + t].clone(), n); // m x n
        let (y, det) = bareiss_solve(bbt, blt, m, n)?;
        Some(DMatrix::from_fn(n, m, |j, i| to_f64(&y[i * n + j], &det, hs.shift)))
    } else {
        // (B^T G B) X = B^T G, W = L X, with G = diag(g) proportional to D^-1:
        // d_i = a_i 2^e_i, g_i = (prod_j a_j / a_i) 2^(E - e_i), E = max e_i.
        let dec: Vec<(BigInt, i64)> = dw
            .iter()
            .map(|x| {
                let (mant, exp, _) = Float::integer_decode(*x);
                (BigInt::from(mant), i64::from(exp))
            })
            .collect();
        let emax = dec.iter().map(|(_, e)| *e).max().unwrap_or(0);
        let g: Vec<BigInt> = (0..m)
            .map(|i| {
                let mut p = BigInt::from(1) << ((emax - dec[i].1) as usize);
                for (j, (a, _)) in dec.iter().enumerate() {
                    if j != i {
                        p *= a;
                    }
                }
                p
            })
            .collect();
        let btg: Vec<BigInt> =
            (0..r).flat_map(|j| (0..m).map(move |i| (j, i))).map(|(j, i)| &b[i * r + j] * &g[i]).collect();
        let n_mat = mul(&btg, r, m, |t, j| b[t * r + j].clone(), r); // r x r
        let (x, det) = bareiss_solve(n_mat, btg, r, m)?; // r x m
        let w = mul(&ls.v, n, r, |t, j| x[t * m + j].clone(), m); // n x m
        Some(DMatrix::from_fn(n, m, |j, i| to_f64(&w[j * m + i], &det, hs.shift)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_svd_limit_on_a_well_conditioned_case() {
        // Full row rank: W_lim = L B^T (B B^T)^-1 satisfies W_lim B = ... and H W_lim L = L restricted.
        let h = DMatrix::from_row_slice(2, 3, &[1.0, 0.5, 0.25, 0.0, 1.0, 2.0]);
        let l = DMatrix::from_row_slice(3, 3, &[1.0, 0.0, 0.0, 0.2, 0.7, 0.0, 0.1, 0.3, 0.4]);
        let w = exact_limit(&h, &l, &DVector::from_element(2, 1.0)).expect("full rank");
        let b = &h * &l;
        let want = &l * b.clone().pseudo_inverse(1e-14).unwrap();
        assert!((&w - &want).norm() <= 1e-14 * want.norm(), "{w} vs {want}");
        // Full column rank, weighted: (B^T D^-1 B) Y = B^T D^-1 with W = L Y.
        let h2 = DMatrix::from_row_slice(3, 2, &[1.0, 0.5, 0.3, 1.0, 2.0, -1.0]);
        let l2 = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.5, 0.25]);
        let dw = DVector::from_vec(vec![1.0, 4.0, 0.5]);
        let w2 = exact_limit(&h2, &l2, &dw).expect("full rank");
        let b2 = &h2 * &l2;
        let di = DMatrix::from_diagonal(&dw.map(|x| 1.0 / x));
        let nm = b2.transpose() * &di * &b2;
        // The normal equations solved by Cholesky (2 x 2, well conditioned).
        let want2 = &l2 * nm.cholesky().expect("positive definite").solve(&(b2.transpose() * &di));
        assert!((&w2 - &want2).norm() <= 1e-14 * want2.norm(), "{w2} vs {want2}");
    }

    #[test]
    fn singular_product_is_refused() {
        let h = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 4.0]);
        let l = DMatrix::identity(2, 2);
        assert!(exact_limit(&h, &l, &DVector::from_element(2, 1.0)).is_none());
    }
}
