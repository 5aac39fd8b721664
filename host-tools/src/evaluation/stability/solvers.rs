//! The solvers the invariants judge: the product's ([`Production`]) and
//! deliberately broken ones, which exist only to show that every invariant
//! can fail (each is flagged by at least one invariant on hard cases; tested
//! in `host-tools/tests/stability.rs`).
use crate::calibration::estimators::{self, EstimatorInputs, EstimatorSummary, NoiseModel};
use brdf_meter::blob::EstimatorKind;
use nalgebra::DMatrix;

/// What a solver returns.
#[derive(Clone, Debug)]
pub struct Solved {
    /// W, n x m.
    pub w: DMatrix<f64>,
    /// The solver's own summary, if it makes one.
    pub summary: Option<EstimatorSummary>,
}

/// A Wiener solver under test.
pub trait Solver: Sync {
    /// Name for reports.
    fn name(&self) -> &'static str;
    /// W for system `h`, prior `r_pp` and `noise` (`NoiseModel::None`: eq. 20).
    fn solve(&self, h: &DMatrix<f64>, r_pp: &DMatrix<f64>, noise: &NoiseModel) -> Result<Solved, String>;
}

/// The product: `estimators::build` (square-root SVD form), eq. 22, or eq. 20
/// when there is no noise.
pub struct Production;

impl Solver for Production {
    fn name(&self) -> &'static str {
        "production"
    }
    fn solve(&self, h: &DMatrix<f64>, r_pp: &DMatrix<f64>, noise: &NoiseModel) -> Result<Solved, String> {
        let kind =
            if matches!(noise, NoiseModel::None) { EstimatorKind::WienerNoiseFree } else { EstimatorKind::Wiener };
        let inputs =
            EstimatorInputs { h, r_pp, prior_samples: 0, noise: noise.clone(), bins_deg: &[], centres_deg: &[] };
        let e = estimators::build(kind, &inputs).map_err(|e| e.to_string())?;
        Ok(Solved { w: e.w, summary: Some(e.summary) })
    }
}

/// BROKEN on purpose: the textbook formula with an explicit f64 inverse,
/// `R_pp H^T (H R_pp H^T + R_nn)^-1` (`try_inverse`, LU). Loses
/// `log10 cond` digits; returns NaN when the LU gives up.
pub struct ExplicitInverse;

impl Solver for ExplicitInverse {
    fn name(&self) -> &'static str {
        "explicit-inverse"
    }
    // The one explicit inverse in the project, kept to show the invariants
    // catch it (clippy.toml forbids it everywhere else).
    #[allow(clippy::disallowed_methods)]
    fn solve(&self, h: &DMatrix<f64>, r_pp: &DMatrix<f64>, noise: &NoiseModel) -> Result<Solved, String> {
        let rnn = noise.covariance(h, r_pp).map_err(|e| e.to_string())?;
        let a = h * r_pp * h.transpose() + rnn;
        let w = match a.try_inverse() {
            Some(inv) => r_pp * h.transpose() * inv,
            None => DMatrix::from_element(h.ncols(), h.nrows(), f64::NAN),
        };
        Ok(Solved { w, summary: None })
    }
}

/// BROKEN on purpose: the same formula solved entirely in f32 (LU of the
/// f32 normal matrix), as a naive port to the device would.
pub struct F32Only;

impl Solver for F32Only {
    fn name(&self) -> &'static str {
        "f32-only"
    }
    fn solve(&self, h: &DMatrix<f64>, r_pp: &DMatrix<f64>, noise: &NoiseModel) -> Result<Solved, String> {
        let rnn = noise.covariance(h, r_pp).map_err(|e| e.to_string())?;
        let h32 = h.map(|x| x as f32);
        let r32 = r_pp.map(|x| x as f32);
        let a = &h32 * &r32 * h32.transpose() + rnn.map(|x| x as f32);
        let rhs = &h32 * &r32; // A W^T = H R_pp
        let w = match a.lu().solve(&rhs) {
            Some(wt) => wt.transpose().map(|x| x as f64),
            None => DMatrix::from_element(h.ncols(), h.nrows(), f64::NAN),
        };
        Ok(Solved { w, summary: None })
    }
}

/// BROKEN on purpose: a fixed Tikhonov floor, `(H R_pp H^T + R_nn + d I)^-1`
/// with `d = 1e-6 * ||H R_pp H^T||`, solved stably by Cholesky. Finite and
/// accurate at high noise, but W does not tend to the minimum-norm solution
/// as the noise vanishes (a floor that is not documented as part of the model).
pub struct FixedFloor;

impl Solver for FixedFloor {
    fn name(&self) -> &'static str {
        "fixed-floor"
    }
    fn solve(&self, h: &DMatrix<f64>, r_pp: &DMatrix<f64>, noise: &NoiseModel) -> Result<Solved, String> {
        let rnn = noise.covariance(h, r_pp).map_err(|e| e.to_string())?;
        let hrh = h * r_pp * h.transpose();
        let d = 1e-6 * hrh.norm();
        let m = h.nrows();
        let a = hrh + rnn + DMatrix::identity(m, m) * d;
        let rhs = h * r_pp;
        let w = a.cholesky().ok_or("not positive definite")?.solve(&rhs).transpose();
        Ok(Solved { w, summary: None })
    }
}

/// BROKEN on purpose: ignores the noise and always uses eq. 20 (the
/// noise-free minimum-norm solution), which amplifies noise on ill-conditioned
/// optics. Numerically impeccable, statistically wrong.
pub struct IgnoresNoise;

impl Solver for IgnoresNoise {
    fn name(&self) -> &'static str {
        "ignores-noise"
    }
    fn solve(&self, h: &DMatrix<f64>, r_pp: &DMatrix<f64>, _noise: &NoiseModel) -> Result<Solved, String> {
        Production.solve(h, r_pp, &NoiseModel::None)
    }
}

/// How the device evaluates `rho = W v` (the f32 invariant judges this).
pub type DeviceKernel = fn(w: &[f32], v: &[f32], out: &mut [f32]);

/// The device's kernel, `brdf_meter::kernel::mat_vec_f32_slice`.
pub fn device_kernel(w: &[f32], v: &[f32], out: &mut [f32]) {
    brdf_meter::kernel::mat_vec_f32_slice(w, v, out)
}

/// BROKEN on purpose: a kernel that keeps only 8 mantissa bits of W
/// (bfloat16 storage, as a flash-saving shortcut would).
pub fn bf16_kernel(w: &[f32], v: &[f32], out: &mut [f32]) {
    let w16: Vec<f32> = w.iter().map(|x| f32::from_bits(x.to_bits() & 0xFFFF_0000)).collect();
    brdf_meter::kernel::mat_vec_f32_slice(&w16, v, out)
}

/// BROKEN on purpose: eq. 22 with the rank decided on the un-whitened
/// `B = H L` and readings whose noise variance is below `m eps` of the
/// largest treated as noise-free (dropped from the whitening) - the product's
/// algorithm before the gain-covariant whitening. Fine for gains of one order, but per-reading
/// gains 1e-6..1e6 push whole readings below the cut-off, so W is not
/// gain-covariant and is far from optimal.
pub struct TruncateThenWhiten;

impl Solver for TruncateThenWhiten {
    fn name(&self) -> &'static str {
        "truncate-then-whiten"
    }
    fn solve(&self, h: &DMatrix<f64>, r_pp: &DMatrix<f64>, noise: &NoiseModel) -> Result<Solved, String> {
        let rnn = noise.covariance(h, r_pp).map_err(|e| e.to_string())?;
        let (m, n) = h.shape();
        let e = r_pp.clone().symmetric_eigen();
        let lmax = e.eigenvalues.amax();
        let keep: Vec<usize> = (0..n).filter(|&i| e.eigenvalues[i] > n as f64 * f64::EPSILON * lmax).collect();
        let l = DMatrix::from_fn(n, keep.len(), |j, c| e.eigenvectors[(j, keep[c])] * e.eigenvalues[keep[c]].sqrt());
        let b = h * &l;
        let r = b.ncols();
        let svd = b.svd(true, true);
        let (u, s, vt) = (svd.u.expect("u"), svd.singular_values, svd.v_t.expect("v"));
        let smax = s.amax();
        let k = s.iter().filter(|x| **x > estimators::rank_tolerance(m, r) * smax).count();
        let rmax = (0..m).map(|i| rnn[(i, i)]).fold(0.0f64, f64::max);
        let noisy: Vec<usize> = (0..m).filter(|&i| rnn[(i, i)] > m as f64 * f64::EPSILON * rmax).collect();
        if noisy.is_empty() {
            return Production.solve(h, r_pp, &NoiseModel::None);
        }
        // Whiten only the noisy readings; noise-free ones get the minimum-norm treatment (ignored here).
        let us = DMatrix::from_fn(noisy.len(), k, |a, c| u[(noisy[a], c)] * s[c] / rnn[(noisy[a], noisy[a])].sqrt());
        let g = us.svd(true, true);
        let (p, sig, qt) = (g.u.expect("u"), g.singular_values, g.v_t.expect("v"));
        let mut x = p.transpose(); // k' x noisy
        for (row, sg) in sig.iter().enumerate() {
            x.row_mut(row).scale_mut(sg / (sg * sg + 1.0));
        }
        let core = qt.transpose() * x; // k x noisy
        let lv = &l * vt.rows(0, k).transpose();
        let part = lv * core; // n x noisy
        let mut w = DMatrix::zeros(n, m);
        for (a, &i) in noisy.iter().enumerate() {
            w.set_column(i, &(part.column(a) / rnn[(i, i)].sqrt()));
        }
        Ok(Solved { w, summary: None })
    }
}
