//! Wiener estimation (patent eqs. 20 and 22, claims 1, 2 and 5).
//!
//! ```text
//! W = R_pp H^T (H R_pp H^T + R_nn)^-1          (eq. 22; eq. 20 with R_nn = 0)
//! ```
//!
//! # How it is computed (square-root form, no inverse)
//! On the patent profile `H R_pp H^T` has a condition number near 1e10, so
//! forming it and inverting (or even Cholesky-solving) it throws away about
//! ten of f64's sixteen digits. Instead:
//!
//! 1. `R_pp = L L^T` from its symmetric eigendecomposition (eigenvalues at or
//!    below `n eps lambda_max` dropped: the prior's numerical rank r).
//! 2. `B = H L` (m x r) and its SVD `B = U S V^T`. Singular values at or below
//!    `max(m, r) eps s_max` are rounding noise of a rank-deficient B and are
//!    removed (the pseudo-inverse tolerance). `cond(B) = sqrt(cond(H R_pp H^T))`.
//! 3. Noise-free (eq. 20): `W = L V S^-1 U^T`, which is `R_pp H^T (H R_pp H^T)^+`,
//!    the minimum-norm solution when `H R_pp H^T` is singular.
//! 4. With noise and `R_nn` positive definite (eq. 22): whiten first,
//!    `T = R_nn^-1/2`, `G = T H L = P Sig Q^T` (SVD, directions at or below
//!    `max(m, r) eps sig_max` dropped), then `W = L Q diag(sig / (sig^2 + 1)) P^T T`.
//!    The rank is decided in the whitened frame, so per-reading gains cancel
//!    exactly (`W(G H) = W(H) G^-1`).
//!    This is eq. 22 exactly (`(B B^T + R_nn)^-1 = T (G G^T + I)^-1 T`), its
//!    gains `sig/(sig^2+1) <= 1/2` never blow up, and as `R_nn -> 0` it tends
//!    to step 3's minimum-norm solution when the noise is isotropic (with
//!    anisotropic noise and more readings than the prior's rank, to the
//!    noise-weighted generalised inverse, the statistically right limit).
//! 5. With noise but `R_nn` singular (some readings noise-free): `A = M M^T`
//!    with `M = [U S, R_nn^1/2]`; `A^+` from the SVD of M truncated at
//!    `max(m, cols) eps s_max`; `W = L V S U^T A^+` (minimum-norm).
//!
//! The condition number recorded is that of `H R_pp H^T + R_nn`, from the
//! singular values of its square-root factor (accurate even beyond 1e16).
use super::{Built, EstimatorError, PsdFactor, rank_tolerance};
use nalgebra::{DMatrix, DVector};

pub(crate) fn build(
    h: &DMatrix<f64>,
    prior: &PsdFactor,
    _r_nn: &DMatrix<f64>,
    noise: &PsdFactor,
) -> Result<Built, EstimatorError> {
    let m = h.nrows();
    let b = h * &prior.l; // m x r
    let r = b.ncols();
    let svd = super::checked_svd::svd(&b);
    let s = svd.singular_values.clone();
    let u = svd.u.expect("u requested");
    let vt = svd.v_t.expect("v requested");
    let smax = s.iter().fold(0.0f64, |a, x| a.max(*x));
    if smax == 0.0 {
        return Err(EstimatorError::NotPsd {
            what: "H R_pp H^T",
            detail: "zero: the readings see none of the prior's variation".into(),
        });
    }
    let tol = rank_tolerance(m, r);
    // nalgebra's `svd` sorts singular values in descending order.
    let k = s.iter().take_while(|x| **x > tol * smax).count();
    let truncated = k < s.len();
    let uk = u.columns(0, k).into_owned(); // m x k
    let sk = s.rows(0, k).into_owned();
    let lv = &prior.l * vt.rows(0, k).transpose(); // n x k: L V_k

    if noise.rank == 0 {
        // Eq. 20. W = L V S^-1 U^T.
        let mut x = uk.transpose(); // k x m
        for (row, sv) in sk.iter().enumerate() {
            x.row_mut(row).scale_mut(1.0 / sv);
        }
        let w = &lv * x;
        let smin_all = if s.len() == m { s[m - 1] } else { 0.0 };
        let condition_system = if smin_all > 0.0 { (smax / smin_all).powi(2) } else { f64::INFINITY };
        return Ok(Built {
            w,
            condition_system,
            effective_rank: k as f64,
            regularisation: if truncated { tol } else { 0.0 },
            tolerance: tol,
            method: format!(
                "eq. 20 in square-root form: SVD of H L (R_pp = L L^T), {k} of {} directions kept \
                 (cutoff {tol:.1e} s_max), W = L V S^-1 U^T (minimum-norm)",
                s.len()
            ),
        });
    }

    // Condition of H R_pp H^T + R_nn = M M^T, M = [U_k S_k, R_nn^1/2].
    let us = {
        let mut us = uk.clone();
        for (c, sv) in sk.iter().enumerate() {
            us.column_mut(c).scale_mut(*sv);
        }
        us
    };
    let mut mm = DMatrix::zeros(m, k + noise.rank);
    mm.columns_mut(0, k).copy_from(&us);
    mm.columns_mut(k, noise.rank).copy_from(&noise.l);
    let mm_cols = mm.ncols();
    let msvd = mm.svd(noise.rank < m, false);
    let ms = msvd.singular_values.clone();
    let ms_max = ms.iter().fold(0.0f64, |a, x| a.max(*x));
    let ms_min = if ms.len() == m { ms[m - 1] } else { 0.0 };
    let condition_system = if ms_min > 0.0 { (ms_max / ms_min).powi(2) } else { f64::INFINITY };

    if noise.rank == m {
        // Eq. 22, whitened *before* any rank decision: T = R_nn^-1/2 =
        // Q diag(lambda^-1/2) Q^T from noise.l = Q diag(lambda^1/2), and
        // G = T H L = P Sig Q^T. Deciding the rank on H L instead would drop
        // the directions of weakly scaled readings (per-LED gains 1e-6 vs
        // 1e6 put them below max(m, r) eps s_max) although the noise model
        // says they are informative; in the whitened frame the result is
        // exactly gain-covariant, W(G H) = W(H) G^-1 (stability family `gain`).
        let t = whitening(&noise.l);
        let g = &t * (h * &prior.l); // m x r
        let gsvd = super::checked_svd::svd(&g);
        let sig_all = gsvd.singular_values.clone();
        let sig_max = sig_all.iter().fold(0.0f64, |a, x| a.max(*x));
        let kw = sig_all.iter().take_while(|x| **x > tol * sig_max).count();
        let sig = sig_all.rows(0, kw);
        let p = gsvd.u.expect("u requested").columns(0, kw).into_owned(); // m x kw
        let qt = gsvd.v_t.expect("v requested").rows(0, kw).into_owned(); // kw x r
        let gain = DVector::from_iterator(kw, sig.iter().map(|x| x / (x * x + 1.0)));
        let mut x = p.transpose() * &t; // kw x m
        for (row, gn) in gain.iter().enumerate() {
            x.row_mut(row).scale_mut(*gn);
        }
        let w = &prior.l * (qt.transpose() * x);
        let dof: f64 = sig.iter().map(|x| x * x / (x * x + 1.0)).sum();
        return Ok(Built {
            w,
            condition_system,
            effective_rank: dof,
            regularisation: if kw < sig_all.len() { tol } else { 0.0 },
            tolerance: tol,
            method: format!(
                "eq. 22 in square-root form: G = R_nn^-1/2 H L (R_pp = L L^T), SVD G = P S Q^T, {kw} of {} \
                 directions above {tol:.1e} s_max, W = L Q diag(s/(s^2+1)) P^T R_nn^-1/2",
                sig_all.len()
            ),
        });
    }

    // Singular, non-zero R_nn: A^+ from the truncated SVD of M.
    let pm = msvd.u.expect("u requested");
    let tol2 = rank_tolerance(m, mm_cols);
    let kept: Vec<usize> = (0..ms.len()).filter(|&i| ms[i] > tol2 * ms_max).collect();
    let mut a_pinv = DMatrix::zeros(m, m);
    for &i in &kept {
        let col = pm.column(i);
        a_pinv += (col * col.transpose()) / (ms[i] * ms[i]);
    }
    // W = L V S U^T A^+ = lv * (us^T A^+)
    let w = &lv * (us.transpose() * &a_pinv);
    let dropped = kept.len() < ms.len();
    let effective_rank = (h * &w).trace();
    Ok(Built {
        w,
        condition_system,
        effective_rank,
        regularisation: if dropped || truncated { tol2.max(tol) } else { 0.0 },
        tolerance: tol2,
        method: format!(
            "eq. 22 with singular R_nn (rank {} of {m}): A = M M^T, M = [H L, R_nn^1/2], \
             A^+ by SVD truncated at {tol2:.1e} s_max ({} of {} kept), W = L V S U^T A^+",
            noise.rank,
            kept.len(),
            ms.len()
        ),
    })
}

/// `R_nn^-1/2 = Q diag(lambda^-1/2) Q^T` from the factor `l = Q diag(lambda^1/2)`
/// (full rank).
fn whitening(l: &DMatrix<f64>) -> DMatrix<f64> {
    let m = l.nrows();
    let mut t = DMatrix::zeros(m, m);
    for c in 0..l.ncols() {
        let col = l.column(c);
        let lam = col.norm_squared(); // lambda_i (q_i is unit)
        // q_i q_i^T / sqrt(lambda_i) = col col^T / lambda_i^{3/2}
        t += (col * col.transpose()) / (lam * lam.sqrt());
    }
    t
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::super::*;
    use nalgebra::DMatrix;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    fn inputs<'a>(h: &'a DMatrix<f64>, r: &'a DMatrix<f64>, noise: NoiseModel) -> EstimatorInputs<'a> {
        EstimatorInputs { h, r_pp: r, prior_samples: 0, noise, bins_deg: &[], centres_deg: &[] }
    }

    /// The textbook formula with a Cholesky solve, for well-conditioned cases.
    fn reference(h: &DMatrix<f64>, r: &DMatrix<f64>, rnn: &DMatrix<f64>) -> DMatrix<f64> {
        let a = h * r * h.transpose() + rnn;
        let rhs = h * r; // A W^T = H R_pp
        a.cholesky().expect("SPD").solve(&rhs).transpose()
    }

    #[test]
    fn matches_the_textbook_formula_when_well_conditioned() {
        let (m, n) = (5, 20);
        let h = blur(m, n, 2.5);
        let r = correlation(&lobes(n, 50, 7));
        for s in [0.3, 0.05, 0.01] {
            let noise = NoiseModel::Relative(s);
            let rnn = noise.covariance(&h, &r).unwrap();
            let est = build(EstimatorKind::Wiener, &inputs(&h, &r, noise)).unwrap();
            let want = reference(&h, &r, &rnn);
            let err = (&est.w - &want).amax() / want.amax();
            assert!(err < 1e-8, "noise {s}: relative difference {err:e}");
        }
    }

    #[test]
    fn error_covariance_is_r_pp_minus_w_h_r_pp() {
        // The patent's form holds only for the optimal W: this fails if W is
        // not the Wiener solution.
        let (m, n) = (6, 30);
        let h = blur(m, n, 2.0);
        let r = correlation(&lobes(n, 60, 8));
        let noise = NoiseModel::Relative(0.02);
        let rnn = noise.covariance(&h, &r).unwrap();
        let est = build(EstimatorKind::Wiener, &inputs(&h, &r, noise)).unwrap();
        let general = error_covariance(&est.w, &h, &r, &rnn);
        let patent = &r - &est.w * &h * &r;
        assert!((&general - &patent).amax() < 1e-9 * r.amax());
        for j in 0..n {
            assert!((est.uncertainty[j].powi(2) - patent[(j, j)]).abs() < 1e-9 * r.amax());
        }
    }

    #[test]
    fn square_well_conditioned_h_gives_the_inverse_as_noise_vanishes() {
        let n = 6;
        let mut h = blur(n, n, 0.6);
        for i in 0..n {
            h[(i, i)] += 0.5;
        }
        let h_inv = h.clone().lu().solve(&DMatrix::identity(n, n)).unwrap();
        let r = correlation(&lobes(n, 40, 3)) + DMatrix::identity(n, n) * 0.1;
        let mut last = f64::INFINITY;
        for s in [1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8] {
            let est = build(EstimatorKind::Wiener, &inputs(&h, &r, NoiseModel::Relative(s))).unwrap();
            let err = (&est.w - &h_inv).amax() / h_inv.amax();
            assert!(err <= last * 1.0001, "not converging: {err:e} after {last:e}");
            last = err;
        }
        assert!(last < 1e-9, "W - H^-1 = {last:e} at noise 1e-8");
        let nf = build(EstimatorKind::WienerNoiseFree, &inputs(&h, &r, NoiseModel::None)).unwrap();
        assert!((&nf.w - &h_inv).amax() / h_inv.amax() < 1e-10);
    }

    #[test]
    fn singular_noise_free_system_gives_the_minimum_norm_solution() {
        // Two identical LEDs and more LEDs than the prior's rank: H R_pp H^T singular.
        let n = 12;
        let mut h = blur(5, n, 1.5);
        let row = h.row(1).into_owned();
        h.set_row(3, &row);
        let s = lobes(n, 3, 9); // rank 3 < m = 5
        let r = correlation(&s);
        let est = build(EstimatorKind::WienerNoiseFree, &inputs(&h, &r, NoiseModel::None)).unwrap();
        assert!(est.w.iter().all(|x| x.is_finite()));
        assert!(est.summary.condition_system.is_infinite());
        assert_eq!(est.summary.effective_rank, 3.0);
        // W = R_pp H^T A^+ with A^+ the Moore-Penrose inverse (independent route).
        let a = &h * &r * h.transpose();
        let a_pinv = a.clone().pseudo_inverse(1e-10 * a.amax()).unwrap();
        let want = &r * h.transpose() * a_pinv;
        assert!((&est.w - &want).amax() < 1e-6 * want.amax(), "{:e}", (&est.w - &want).amax());
        // Tiny isotropic noise converges to it instead of blowing up. (With
        // anisotropic noise the limit is the noise-weighted generalised
        // inverse, which differs when H L has more rows than rank.)
        let scale = a.amax();
        for sgm in [1e-6, 1e-9, 1e-12] {
            let rnn = DMatrix::identity(5, 5) * (sgm * sgm * scale);
            let e = build(EstimatorKind::Wiener, &inputs(&h, &r, NoiseModel::Covariance(rnn))).unwrap();
            let d = (&e.w - &want).amax() / want.amax();
            assert!(d < 1e-3, "noise {sgm}: {d:e}");
        }
    }

    #[test]
    fn singular_noise_covariance_uses_the_fallback() {
        let (m, n) = (4, 15);
        let h = blur(m, n, 2.0);
        let r = correlation(&lobes(n, 30, 4));
        let mut rnn = DMatrix::zeros(m, m);
        rnn[(0, 0)] = 0.01;
        rnn[(2, 2)] = 0.02;
        let est = build(EstimatorKind::Wiener, &inputs(&h, &r, NoiseModel::Covariance(rnn.clone()))).unwrap();
        assert!(est.summary.method.contains("singular R_nn"));
        let want = reference(&h, &r, &rnn);
        assert!((&est.w - &want).amax() < 1e-7 * want.amax());
    }

    #[test]
    fn wiener_beats_the_pseudo_inverse_on_brdfs_from_the_prior() {
        // Draw test BRDFs from the same family as the prior (fresh samples),
        // simulate noisy readings and compare empirical MSE.
        let (m, n) = (7, 60);
        let h = blur(m, n, 2.0);
        let train = lobes(n, 200, 11);
        let r = correlation(&train);
        let noise = NoiseModel::Relative(0.02);
        let wien = build(EstimatorKind::Wiener, &inputs(&h, &r, noise.clone())).unwrap();
        let pinv = build(EstimatorKind::PseudoInverse, &inputs(&h, &r, noise)).unwrap();
        let test = lobes(n, 300, 12);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (mut ew, mut ep) = (0.0, 0.0);
        for c in 0..test.ncols() {
            let rho = test.column(c).into_owned();
            let mut v = &h * &rho;
            for x in v.iter_mut() {
                *x += Normal::new(0.0, 0.02 * x.abs()).unwrap().sample(&mut rng);
            }
            ew += (&wien.w * &v - &rho).norm_squared();
            ep += (&pinv.w * &v - &rho).norm_squared();
        }
        assert!(ew < 0.5 * ep, "Wiener MSE {ew} not well below pseudo-inverse MSE {ep}");
        // And the prediction says so too.
        assert!(wien.summary.predicted_rmse < pinv.summary.predicted_rmse);
    }

    #[test]
    fn wiener_is_optimal_and_finite_in_hard_cases() {
        // H with singular values spread over 14 decades, duplicate LEDs, a
        // rank-deficient prior, noise from 1e-12 to 0.2. W and its predicted
        // uncertainty stay finite, and the Wiener W's predicted MSE is never
        // above that of another linear W under the same prior and noise
        // (it is the minimiser), nor above the trivial W = 0 (which predicts
        // trace(R_pp)).
        let (m, n) = (6, 40);
        let base = blur(m, n, 1.2);
        let svd = base.clone().svd(true, true);
        let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
        let spread = DMatrix::from_diagonal(&nalgebra::DVector::from_fn(m, |i, _| {
            10f64.powf(-14.0 * i as f64 / (m - 1) as f64)
        }));
        let mut hard = &u * spread * &vt; // cond 1e14
        let r0 = base.row(0).into_owned();
        let mut dup = base.clone();
        dup.set_row(5, &r0); // duplicate LED
        hard.iter_mut().for_each(|x| *x = x.abs()); // non-negative like an H
        let prior_full = correlation(&lobes(n, 60, 21));
        let prior_def = correlation(&lobes(n, 4, 22)); // rank 4 < m
        for h in [&hard, &dup, &base] {
            for r in [&prior_full, &prior_def] {
                for s in [1e-12, 1e-8, 1e-4, 0.02, 0.2] {
                    let noise = NoiseModel::Relative(s);
                    let rnn = noise.covariance(h, r).unwrap();
                    let w = build(EstimatorKind::Wiener, &inputs(h, r, noise.clone())).unwrap();
                    assert!(w.w.iter().all(|x| x.is_finite()), "non-finite W at noise {s}");
                    assert!(w.uncertainty.iter().all(|x| x.is_finite()));
                    let mse = |wm: &DMatrix<f64>| error_covariance(wm, h, r, &rnn).trace();
                    let ours = mse(&w.w);
                    let tol = 1e-6 * r.trace();
                    assert!(ours <= r.trace() + tol, "worse than W = 0 at noise {s}");
                    let p = build(EstimatorKind::PseudoInverse, &inputs(h, r, noise.clone())).unwrap();
                    assert!(ours <= mse(&p.w) + tol, "pinv beats Wiener at noise {s}: {ours} > {}", mse(&p.w));
                    // A perturbed Wiener matrix is worse (W is a minimiser).
                    let bumped =
                        &w.w + DMatrix::from_fn(n, m, |j, i| 1e-3 * w.w.amax() * (((j * 7 + i * 3) % 5) as f64 - 2.0));
                    assert!(ours <= mse(&bumped) + tol, "perturbed W is better at noise {s}");
                }
            }
        }
    }
}
