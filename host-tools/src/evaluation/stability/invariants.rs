//! The invariants every hard case must satisfy, each with its stated
//! tolerance and why. All are computed against references that do not use
//! the solver under test, so a broken solver fails them (shown in
//! `host-tools/tests/stability.rs` for every invariant).
//!
//! Notation: `R_pp = L L^T` (eigen-factor, eigenvalues at or below
//! `n eps lambda_max` dropped, the documented floor), `B = H L` (m x r),
//! `D = diag(H R_pp H^T)`, `R_nn = s^2 diag(D)` (the relative noise model),
//! `A = H R_pp H^T + R_nn`, u = unit roundoff (2^-53 for f64, 2^-24 for f32).
//!
//! | invariant | passes when | constant and why |
//! |---|---|---|
//! | I1 finite | W, the summary's uncertainty/rank/regularisation are finite (condition may be +inf, never NaN) | - |
//! | I2 error | `mmse/F - floor <= achieved <= F mmse + floor` | [`ERROR_FACTOR`] F = 2, [`ERROR_FLOOR_C`] |
//! | I2' prediction | the solver's own predicted RMSE^2 n is within [`PREDICTION_REL_TOL`] mmse + 2 sqrt(mmse floor) + floor of mmse | first-order effect of the floor's rounding on a sum of squares |
//! | I3 continuity | `|W(sigma) - W_lim| / |W_lim| <= tol_c` at the smallest sigma, and never grows by more than tol_c as sigma falls; eq. 20 = `L (H L)^+`; `W_lim` exact (rational arithmetic, `super::exact_limit`) when `H L` has full rank, else by SVD | [`CONTINUITY_C`] |
//! | I4 f32 | device result within `gamma_{m+2} (|W||v|)_j` of f64 per bin; training's f32 gate accepts only what meets [`crate::calibration::train::F32_TOLERANCE`] and refuses only what does not | rigorous rounding bound |
//! | I5 backward | `|W A - R_pp H^T|_F / (|W|_F |A|_F + |R_pp H^T|_F) <= c u` | [`BACKWARD_C`] |
//! | I6 gain | gain family: `|W(G H) G - W(H)| / |W(H)| <= tol_c` (eq. 22 with relative noise is exactly gain-covariant) | [`CONTINUITY_C`] |
//!
//! `mmse` is the minimum ensemble error, computed in information form from
//! the SVD of the whitened `R_nn^-1/2 B = P S Q^T`:
//! `mmse = |L Q (I + S^2)^-1/2|_F^2 + |L (I - Q Q^T)|_F^2`, a sum of positive
//! terms with no cancellation and no W. `achieved` is a Monte Carlo average of
//! `|rho - W v|^2` over the prior's own samples (projected on the span of L:
//! components below R_pp's eigenvalue floor `n eps lambda_max` are rounding
//! noise of R_pp and unknowable to a solver given R_pp; their effect is
//! reported separately as `raw_achieved_over_mmse`) with fresh noise
//! (`v_i + N(0, (s v_i)^2)`), at least [`MC_MIN_DRAWS`] draws: in-sample, its
//! expectation is exactly `tr E(W) >= mmse`, with equality for the Wiener W.
// `!(err <= bound)` on purpose throughout: a NaN error must fail a check,
// which `err > bound` would let pass.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
use super::exact_limit::exact_limit;
use super::families::Case;
use super::solvers::{DeviceKernel, Solver};
use crate::calibration::estimators::{NoiseModel, rank_tolerance};
use crate::calibration::train::{F32_TOLERANCE, f32_gate};
use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// f64 unit roundoff.
pub const U64: f64 = f64::EPSILON / 2.0;
/// f32 unit roundoff.
pub const U32: f64 = f32::EPSILON as f64 / 2.0;

/// I2: the achieved ensemble error must be within this factor of the
/// predicted minimum. The Monte Carlo noise term is a chi-square with at
/// least [`MC_MIN_REPLICATES`] degrees of freedom (see there); the signal
/// term is exact in-sample.
pub const ERROR_FACTOR: f64 = 2.0;
/// Monte Carlo draws (samples x replicates) per case for I2, at least.
pub const MC_MIN_DRAWS: usize = 256;
/// Noise replicates per sample, at least: the noise is proportional to the
/// reading, so one sample can dominate the noise term; with 128 replicates
/// even then it is a chi-square with 128 degrees of freedom, outside
/// [1/2, 2] of its mean with probability below 1e-6 (Wilson-Hilferty z > 4.9).
pub const MC_MIN_REPLICATES: usize = 128;
/// I2 rounding floor: `floor = mean over draws of sum_j (C m u (|W||v|)_j)^2`.
/// `m u (|W||v|)_j` is the first-order bound on evaluating `(W v)_j` in f64;
/// C covers W's own rounding (a backward-stable W is exact for data perturbed
/// by O(max(m, n) u), whose effect on `W v` is of the same form), hence
/// C = 4 max(m, n) / m, expressed here as the constant 4 times max(m, n).
pub const ERROR_FLOOR_C: f64 = 4.0;
/// I2': relative agreement between the solver's own predicted RMSE and the
/// independent information-form mmse (both are sums of squares of
/// well-conditioned factors; 1e-6 leaves room for eq. 22 at cond 1e14).
pub const PREDICTION_REL_TOL: f64 = 1e-6;
/// I3/I6: `tol_c = CONTINUITY_C max(m, n) u kappa + 2 (sigma / s_min)^2`, with
/// `kappa = cond(C) phi`: C the whitened, truncated `B` whose pseudo-inverse
/// Y gives the limit `W = L Y`, and `phi = |L| |Y| / |L Y|` the amplification
/// of Y's relative error by the product with L. First-order perturbation
/// theory of the pseudo-inverse gives `|dY| / |Y| <= c cond(C) |dC| / |C|`, a
/// backward-stable SVD gives `|dC| / |C| = O(max(m, n) u)`, and
/// `|L dY| / |L Y| <= phi |dY| / |Y|`; the second term is the exact distance
/// `sigma^2 / (s^2 + sigma^2)` of the last step from the limit. The bound is
/// for the solver's rounding only, so the reference must be far more
/// accurate: at full rank `W_lim` is computed exactly from the f64 H and L
/// (an f64 SVD of C would itself carry an error of this bound's order).
pub const CONTINUITY_C: f64 = 64.0;
/// I3 is only checked to the precision f64 can resolve: a case whose `tol_c`
/// exceeds this is recorded as unresolved (W is then finite and bounded but
/// its last digits are rounding), not as passed.
pub const CONTINUITY_RESOLVABLE: f64 = 0.1;
/// I5: normwise backward error bound `BACKWARD_C max(m, n) u`. The SVD-based
/// solution satisfies the normal equations `W A = R_pp H^T` up to the rank
/// cut-off `max(m, r) u s_max` (dropped directions) plus the rounding of the
/// products, each O(max(m, n) u) relative to `|W||A|`.
pub const BACKWARD_C: f64 = 16.0;

/// What one case measured.
#[derive(Clone, Debug, Serialize)]
pub struct CaseReport {
    /// Family name.
    pub family: &'static str,
    /// Seed.
    pub seed: u64,
    /// Parameters.
    pub label: String,
    /// m, n, K.
    pub m: usize,
    /// Bins.
    pub n: usize,
    /// Prior samples.
    pub k: usize,
    /// Relative noise.
    pub noise: f64,
    /// cond(H R_pp H^T) from the reference SVD (inf when singular).
    pub cond_hrh: f64,
    /// cond(H R_pp H^T + R_nn).
    pub cond_system: f64,
    /// I2: achieved / mmse.
    pub achieved_over_mmse: f64,
    /// Diagnostic, not an invariant: achieved / mmse on the raw samples,
    /// including their components below R_pp's eigenvalue floor, which a
    /// solver given only R_pp cannot know.
    pub raw_achieved_over_mmse: f64,
    /// I2: max(achieved / (F mmse + floor), (mmse / F - floor) / achieved); <= 1 passes.
    pub error_bound_ratio: f64,
    /// I3: worst measured / tolerance over the sigma -> 0 checks; <= 1 passes.
    pub continuity_ratio: f64,
    /// I3: whether f64 resolves the limit (tol_c <= CONTINUITY_RESOLVABLE).
    pub continuity_resolved: bool,
    /// I4: worst f32 error / rounding bound; <= 1 passes.
    pub f32_bound_ratio: f64,
    /// I4: worst |f32 - f64| relative to the estimate's scale.
    pub f32_rel_error: f64,
    /// I4: whether training's f32 gate accepted the matrix.
    pub f32_accepted: bool,
    /// I5: normwise backward error.
    pub backward_error: f64,
    /// I5: backward error / bound; <= 1 passes.
    pub backward_ratio: f64,
    /// I6 (gain family): measured / tolerance.
    pub gain_ratio: Option<f64>,
    /// Which invariants failed and how.
    pub failures: Vec<String>,
}

/// Solver-independent quantities of a case.
struct Reference {
    l: DMatrix<f64>,
    /// The samples projected on span(L): n x K.
    resolvable: DMatrix<f64>,
    b: DMatrix<f64>,
    /// B's singular values (descending).
    s: DVector<f64>,
    /// Directions of B above the rank tolerance.
    kept: usize,
    d: DVector<f64>,
    a: DMatrix<f64>,
    rht: DMatrix<f64>,
    rnn_norm: f64,
    mmse: f64,
    cond_hrh: f64,
    cond_system: f64,
}

fn reference(case: &Case) -> Reference {
    let n = case.n();
    let m = case.m();
    let e = ((&case.r_pp + case.r_pp.transpose()) * 0.5).symmetric_eigen();
    let lmax = e.eigenvalues.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let keep: Vec<usize> = (0..n).filter(|&i| e.eigenvalues[i] > n as f64 * f64::EPSILON * lmax).collect();
    let mut l = DMatrix::zeros(n, keep.len());
    let mut ek = DMatrix::zeros(n, keep.len());
    for (c, &i) in keep.iter().enumerate() {
        l.set_column(c, &(e.eigenvectors.column(i) * e.eigenvalues[i].sqrt()));
        ek.set_column(c, &e.eigenvectors.column(i));
    }
    // The test BRDFs: the samples within the prior's resolvable span.
    let resolvable = &ek * (ek.transpose() * &case.samples);
    let b = &case.h * &l;
    let r = b.ncols();
    let svd = b.clone().svd(false, true);
    let (s, vt) = (svd.singular_values, svd.v_t.expect("v"));
    let smax = s.iter().fold(0.0f64, |a, x| a.max(*x));
    let kept = s.iter().filter(|x| **x > rank_tolerance(m, r) * smax).count();
    let d = DVector::from_fn(m, |i, _| b.row(i).norm_squared());
    let s2 = case.noise * case.noise;
    let rnn = DMatrix::from_diagonal(&d.map(|x| s2 * x));
    let a = &case.h * &case.r_pp * case.h.transpose() + &rnn;
    let rht = &case.r_pp * case.h.transpose();
    let smin_m = if s.len() >= m { s[m - 1] } else { 0.0 };
    let cond_hrh = if smin_m > 0.0 { (smax / smin_m).powi(2) } else { f64::INFINITY };
    // cond(A) from the factor [B, R_nn^1/2].
    let mut f = DMatrix::zeros(m, r + m);
    f.columns_mut(0, r).copy_from(&b);
    for i in 0..m {
        f[(i, r + i)] = case.noise * d[i].sqrt();
    }
    let fs = f.svd(false, false).singular_values;
    let fmin = fs.iter().take(m).fold(f64::INFINITY, |a, x| a.min(*x));
    let cond_system = if fmin > 0.0 { (fs.max() / fmin).powi(2) } else { f64::INFINITY };
    // mmse in information form over the readings that carry signal.
    let active: Vec<usize> = (0..m).filter(|&i| d[i] > 0.0).collect();
    let mmse = if case.noise > 0.0 && !active.is_empty() {
        let c = DMatrix::from_fn(active.len(), r, |ii, j| b[(active[ii], j)] / (case.noise * d[active[ii]].sqrt()));
        let cs = c.svd(false, true);
        let q = cs.v_t.expect("v").transpose(); // r x p
        let mut lq = &l * &q;
        for (j, sg) in cs.singular_values.iter().enumerate() {
            lq.column_mut(j).scale_mut(1.0 / (1.0 + sg * sg).sqrt());
        }
        let resid = &l - &l * &q * q.transpose();
        lq.norm_squared() + resid.norm_squared()
    } else {
        // Noise-free: the part of the prior H cannot see.
        let vk = vt.rows(0, kept).transpose();
        (&l - &l * &vk * vk.transpose()).norm_squared()
    };
    let rnn_norm = rnn.norm();
    Reference { l, resolvable, b, s, kept, d, a, rht, rnn_norm, mmse, cond_hrh, cond_system }
}

/// Checks every invariant on `case` for `solver`, with the device evaluating
/// `rho = W v` through `kernel`.
pub fn check_case(case: &Case, solver: &dyn Solver, kernel: DeviceKernel) -> CaseReport {
    let (m, n) = (case.m(), case.n());
    let rf = reference(case);
    let mut rep = CaseReport {
        family: case.family.name(),
        seed: case.seed,
        label: case.label.clone(),
        m,
        n,
        k: case.k(),
        noise: case.noise,
        cond_hrh: rf.cond_hrh,
        cond_system: rf.cond_system,
        achieved_over_mmse: f64::NAN,
        raw_achieved_over_mmse: f64::NAN,
        error_bound_ratio: f64::NAN,
        continuity_ratio: f64::NAN,
        continuity_resolved: false,
        f32_bound_ratio: f64::NAN,
        f32_rel_error: f64::NAN,
        f32_accepted: false,
        backward_error: f64::NAN,
        backward_ratio: f64::NAN,
        gain_ratio: None,
        failures: Vec::new(),
    };
    let solved = match solver.solve(&case.h, &case.r_pp, &NoiseModel::Relative(case.noise)) {
        Ok(s) => s,
        Err(e) => {
            rep.failures.push(format!("I1 finite: the solver refused a valid case: {e}"));
            return rep;
        }
    };
    let w = &solved.w;

    // I1: finite.
    let finite = w.iter().all(|x| x.is_finite());
    if !finite {
        rep.failures.push("I1 finite: W has NaN or infinity".into());
    }
    if let Some(s) = &solved.summary {
        let ok = s.predicted_rmse.is_finite()
            && s.effective_rank.is_finite()
            && s.regularisation.is_finite()
            && !s.condition_h.is_nan()
            && !s.condition_system.is_nan();
        if !ok {
            rep.failures.push(format!("I1 finite: summary has a NaN/inf field: {s:?}"));
        }
    }
    if !finite {
        return rep;
    }

    // I2: achieved error vs mmse, Monte Carlo on the prior's samples.
    let mut rng = ChaCha8Rng::seed_from_u64(case.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x5EED);
    let reps = MC_MIN_DRAWS.div_ceil(case.k()).max(MC_MIN_REPLICATES);
    let wabs = w.abs();
    let (mut achieved, mut floor, mut raw) = (0.0, 0.0, 0.0);
    let mut noisy = Vec::with_capacity(case.k());
    let fc = ERROR_FLOOR_C * m.max(n) as f64 * U64;
    for c in 0..case.k() {
        let rho = rf.resolvable.column(c);
        let v0: DVector<f64> = &case.h * rho;
        let rho_raw = case.samples.column(c);
        let v_raw: DVector<f64> = &case.h * rho_raw;
        for r in 0..reps {
            let z = DVector::from_fn(m, |_, _| gauss(&mut rng));
            let v = v0.zip_map(&z, |x, g| x + case.noise * x * g);
            achieved += (rho - w * &v).norm_squared();
            floor += (&wabs * v.abs()).map(|x| (fc * x).powi(2)).sum();
            let vr = v_raw.zip_map(&z, |x, g| x + case.noise * x * g);
            raw += (rho_raw - w * &vr).norm_squared();
            if r == 0 {
                noisy.push(vr);
            }
        }
    }
    let draws = (case.k() * reps) as f64;
    achieved /= draws;
    floor /= draws;
    raw /= draws;
    rep.raw_achieved_over_mmse = raw / rf.mmse;
    let mmse = rf.mmse;
    rep.achieved_over_mmse = achieved / mmse;
    let hi = achieved / (ERROR_FACTOR * mmse + floor);
    let lo = if achieved > 0.0 {
        (mmse / ERROR_FACTOR - floor) / achieved
    } else if mmse / ERROR_FACTOR > floor {
        f64::INFINITY
    } else {
        0.0
    };
    rep.error_bound_ratio = hi.max(lo);
    if !(rep.error_bound_ratio <= 1.0) {
        rep.failures.push(format!(
            "I2 error: achieved {achieved:.3e} vs predicted minimum {mmse:.3e} (factor {ERROR_FACTOR}, floor {floor:.1e})"
        ));
    }
    if let Some(s) = &solved.summary {
        let pred = s.predicted_rmse.powi(2) * n as f64;
        // The prediction is a sum of squares of residuals `L - W H L` whose
        // rounding is of the size the floor measures: first order in it.
        if !((pred - mmse).abs() <= PREDICTION_REL_TOL * mmse + 2.0 * (mmse * floor).sqrt() + floor) {
            rep.failures.push(format!("I2 prediction: solver predicts {pred:.6e}, reference mmse {mmse:.6e}"));
        }
    }

    // I5: normwise backward error of the normal equations W A = R_pp H^T
    // with respect to the data R_pp and R_nn (H exact): the smallest relative
    // perturbation of them for which W is exact is, to first order, the
    // residual over |R_pp||H| (1 + |W||H|) + |W||R_nn|.
    let resid = (w * &rf.a - &rf.rht).norm();
    let (hn, wn) = (case.h.norm(), w.norm());
    let eta = resid / (case.r_pp.norm() * hn * (1.0 + wn * hn) + wn * rf.rnn_norm);
    rep.backward_error = eta;
    rep.backward_ratio = eta / (BACKWARD_C * m.max(n) as f64 * U64);
    if !(rep.backward_ratio <= 1.0) {
        rep.failures.push(format!("I5 backward: error {eta:.2e} > {:.2e}", BACKWARD_C * m.max(n) as f64 * U64));
    }

    // I4: f32 device evaluation.
    f32_invariant(case, w, &noisy, kernel, &mut rep);

    // I3: continuity as the noise vanishes.
    continuity(case, &rf, solver, &mut rep);

    // I6: gain covariance.
    if let Some((g, h0)) = &case.gains {
        match solver.solve(h0, &case.r_pp, &NoiseModel::Relative(case.noise)) {
            Ok(s0) => {
                let wg = DMatrix::from_fn(n, m, |j, i| w[(j, i)] * g[i]);
                let d = (&wg - &s0.w).norm() / s0.w.norm();
                let dw =
                    if rf.d.iter().all(|x| *x > 0.0) { rf.d.clone() } else { DVector::from_element(m, rf.d.max()) };
                let kappa = weighted_limit(&rf, &dw).1;
                let tol = CONTINUITY_C * m.max(n) as f64 * U64 * kappa;
                rep.gain_ratio = Some(d / tol);
                if !(d <= tol) {
                    rep.failures.push(format!("I6 gain: |W(GH) G - W(H)| / |W(H)| = {d:.2e} > {tol:.2e}"));
                }
            }
            Err(e) => rep.failures.push(format!("I6 gain: the solver refused the un-gained case: {e}")),
        }
    }
    rep
}

/// The sigma -> 0 limit of eq. 22 with `R_nn = sigma^2 diag(dw)`, computed
/// independently of the solver: `C = diag(dw)^-1/2 B = P S Q^T` truncated at
/// the product's rank tolerance, `W_lim = L Q_k S_k^-1 P_k^T diag(dw)^-1/2`
/// (the dw-weighted generalised inverse; for isotropic dw, `L (H L)^+`).
/// Returns `(W_lim, kappa, s_k)` where `kappa = (s_max / s_k) phi` and
/// `phi = |L| |Y| / |L Y|` (`Y = C_k^+ diag(dw)^-1/2`) is the amplification of
/// Y's relative error by the product with L (large when Y's big entries fall
/// in L's small directions, as they do for ill-conditioned H).
fn weighted_limit(rf: &Reference, dw: &DVector<f64>) -> (DMatrix<f64>, f64, f64) {
    let (m, r) = rf.b.shape();
    let c = DMatrix::from_fn(m, r, |i, j| rf.b[(i, j)] / dw[i].sqrt());
    let svd = crate::calibration::estimators::checked_svd::svd(&c);
    let (p, sv, qt) = (svd.u.expect("u"), svd.singular_values, svd.v_t.expect("v"));
    let smax = sv.iter().fold(0.0f64, |a, x| a.max(*x));
    let k = sv.iter().take_while(|x| **x > rank_tolerance(m, r) * smax).count();
    if k == 0 {
        return (DMatrix::zeros(rf.l.nrows(), m), f64::INFINITY, 0.0);
    }
    let mut qs = qt.rows(0, k).transpose(); // r x k
    for c in 0..k {
        qs.column_mut(c).scale_mut(1.0 / sv[c]);
    }
    let mut pt = p.columns(0, k).transpose(); // k x m
    for i in 0..m {
        pt.column_mut(i).scale_mut(1.0 / dw[i].sqrt());
    }
    let y = qs * pt; // r x m
    let w = &rf.l * &y;
    let phi = rf.l.norm() * y.norm() / w.norm();
    (w, smax / sv[k - 1] * phi, sv[k - 1])
}

fn f32_invariant(case: &Case, w: &DMatrix<f64>, noisy: &[DVector<f64>], kernel: DeviceKernel, rep: &mut CaseReport) {
    let (n, m) = w.shape();
    let w32: Vec<f32> = (0..n).flat_map(|j| (0..m).map(move |i| (j, i))).map(|(j, i)| w[(j, i)] as f32).collect();
    let wabs = w.abs();
    let gamma = (m + 2) as f64 * U32 / (1.0 - (m + 2) as f64 * U32);
    let tiny = 2.0 * (m + 1) as f64 * f64::from(f32::from_bits(1)); // underflow: one subnormal ulp per operation
    let mut out = vec![0.0f32; n];
    let (mut worst_ratio, mut worst_abs, mut scale) = (0.0f64, 0.0f64, 0.0f64);
    let clean: Vec<DVector<f64>> = (0..case.k()).map(|c| &case.h * case.samples.column(c)).collect();
    for v in clean.iter().chain(noisy.iter()) {
        let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
        kernel(&w32, &v32, &mut out);
        let e64 = w * v;
        let bound = &wabs * v.abs();
        for j in 0..n {
            let err = (out[j] as f64 - e64[j]).abs();
            let ratio = if err.is_finite() { err / (gamma * bound[j] + tiny) } else { f64::INFINITY };
            worst_ratio = worst_ratio.max(ratio);
            worst_abs = worst_abs.max(err);
            scale = scale.max(e64[j].abs());
        }
    }
    rep.f32_bound_ratio = worst_ratio;
    rep.f32_rel_error = if scale > 0.0 { worst_abs / scale } else { worst_abs };
    if !(worst_ratio <= 1.0) {
        rep.failures
            .push(format!("I4 f32: device error exceeds the rounding bound gamma_(m+2) |W||v| by {worst_ratio:.2e}x"));
    }
    // Training's gate: accepted => within tolerance on every test reading
    // (clean and noisy, through the gate's own scaling); refused => the
    // unscaled device path really misses the tolerance on the prior.
    match f32_gate(w, &(&case.h * &case.samples)) {
        Ok(plan) => {
            rep.f32_accepted = true;
            let (mut worst, mut sc) = (0.0f64, 0.0f64);
            let mut bad = false;
            for v in clean.iter().chain(noisy.iter()) {
                kernel(&plan.w32, &plan.readings(v), &mut out);
                let e64 = w * v;
                for j in 0..n {
                    bad |= !out[j].is_finite();
                    worst = worst.max((out[j] as f64 - e64[j]).abs());
                    sc = sc.max(e64[j].abs());
                }
            }
            let rel = if sc > 0.0 { worst / sc } else { worst };
            if bad || !(rel <= 2.0 * F32_TOLERANCE) {
                rep.failures.push(format!(
                    "I4 f32: the gate accepted a matrix whose device error is {rel:.2e} (tolerance {F32_TOLERANCE:.0e}, 2x allowed off-prior){}",
                    if bad { ", with non-finite output" } else { "" }
                ));
            }
        }
        Err(refusal) => {
            if refusal.rel_error.is_finite() && refusal.rel_error <= F32_TOLERANCE {
                rep.failures.push(format!("I4 f32: the gate refused a matrix within tolerance: {refusal}"));
            }
        }
    }
}

fn continuity(case: &Case, rf: &Reference, solver: &dyn Solver, rep: &mut CaseReport) {
    let (m, n) = (case.m(), case.n());
    if rf.kept == 0 {
        rep.failures.push("I3 continuity: H sees none of the prior".into());
        return;
    }
    let c_u = CONTINUITY_C * m.max(n) as f64 * U64;
    let mut worst = 0.0f64;
    let mut resolved = true;

    // Eq. 20 is the minimum-norm solution L (H L)^+, with the pseudo-inverse
    // by nalgebra at the product's rank tolerance (an independent route).
    let smax = rf.s.max();
    let r = rf.b.ncols();
    let pinv = rf.b.clone().pseudo_inverse(rank_tolerance(m, r) * smax).expect("eps >= 0");
    let w_mn = &rf.l * &pinv;
    let mean_d = rf.d.sum() / m as f64;
    let iso = DVector::from_element(m, mean_d);
    // kappa of B times the amplification by L (see `weighted_limit`).
    let kappa_b = smax / rf.s[rf.kept - 1] * (rf.l.norm() * pinv.norm() / w_mn.norm());
    let tol0 = c_u * kappa_b;
    match solver.solve(&case.h, &case.r_pp, &NoiseModel::None) {
        Ok(nf) => {
            let d = (&nf.w - &w_mn).norm() / w_mn.norm();
            if !d.is_finite() {
                rep.failures.push("I3 continuity: eq. 20 W is not finite".into());
            } else if tol0 <= CONTINUITY_RESOLVABLE {
                worst = worst.max(d / tol0);
                if !(d <= tol0) {
                    rep.failures
                        .push(format!("I3 continuity: eq. 20 differs from L (H L)^+ by {d:.2e} (tol {tol0:.2e})"));
                }
            } else {
                resolved = false;
            }
        }
        Err(e) => rep.failures.push(format!("I3 continuity: eq. 20 refused: {e}")),
    }

    // W(sigma) -> W_lim for isotropic and relative noise, sigma from 0.1 down
    // to 1e-8 s_k (where the exact distance sigma^2 / (s_k^2 + sigma^2) is
    // 1e-16, below rounding).
    let models: Vec<(&str, DVector<f64>)> = if rf.d.iter().all(|x| *x > 0.0) {
        vec![("isotropic", iso), ("relative", rf.d.clone())]
    } else {
        vec![("isotropic", iso)]
    };
    for (name, dw) in models {
        let (w_svd, kappa, smin) = weighted_limit(rf, &dw);
        // The reference itself must be well below the tolerance: at full
        // rank the limit is built exactly (see `exact_limit`); the SVD route
        // carries an error of the tolerance's own order.
        let w_lim = if rf.kept == m.min(rf.b.ncols()) {
            exact_limit(&case.h, &rf.l, &dw).unwrap_or_else(|| w_svd.clone())
        } else {
            w_svd.clone()
        };
        let w_lim_norm = w_lim.norm();
        let sigma_end = (1e-8 * smin).max(1e-150);
        let mut sigmas = vec![0.1];
        while *sigmas.last().unwrap() > sigma_end * 1e3 && sigmas.len() < 9 {
            let next = sigmas.last().unwrap() * 1e-3;
            sigmas.push(next);
        }
        sigmas.push(sigma_end.min(*sigmas.last().unwrap() * 1e-3));
        let last_sigma = *sigmas.last().unwrap();
        let tol = c_u * kappa + 2.0 * (last_sigma / smin).powi(2);
        let mut d_last = f64::NAN;
        for &sg in &sigmas {
            let noise = if name == "relative" {
                NoiseModel::Relative(sg)
            } else {
                NoiseModel::Covariance(DMatrix::from_diagonal(&dw.map(|x| sg * sg * x)))
            };
            let wsg = match solver.solve(&case.h, &case.r_pp, &noise) {
                Ok(s) => s.w,
                Err(e) => {
                    rep.failures.push(format!("I3 continuity ({name}): refused at sigma {sg:.1e}: {e}"));
                    return;
                }
            };
            d_last = (&wsg - &w_lim).norm() / w_lim_norm;
            if !d_last.is_finite() {
                rep.failures.push(format!("I3 continuity ({name}): W not finite at sigma {sg:.1e}"));
                return;
            }
        }
        if tol <= CONTINUITY_RESOLVABLE {
            worst = worst.max(d_last / tol);
            if !(d_last <= tol) {
                rep.failures.push(format!(
                    "I3 continuity ({name}): |W(sigma={last_sigma:.1e}) - W_lim| / |W_lim| = {d_last:.2e} > {tol:.2e} (kappa {kappa:.1e})"
                ));
            }
        } else {
            resolved = false;
        }
    }
    rep.continuity_ratio = worst;
    rep.continuity_resolved = resolved;
}

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}
