//! Log-domain Wiener estimation (after the log mapping of Nielsen, Jensen and
//! Ramamoorthi 2015, "On optimal, minimal BRDF sampling for reflectance
//! acquisition", which estimates in `log(rho + eps)` because BRDF values span
//! orders of magnitude).
//!
//! - **Mapping**: bins `y = ln(rho + eps)`, readings `x = ln(v + eps)`, with
//!   a constant 1 appended to x (an affine estimator).
//! - **Training**: the linear minimum-MSE estimator of y from x over the
//!   prior's samples, `W = <y x^T> (<x x^T> + R_nn)^-1`, with x from the
//!   noise-free model `v = H rho`. The instrument's relative noise
//!   `v (1 + e)`, `e ~ N(0, s^2)`, is additive in the log domain
//!   (`ln(v(1+e)) ~ ln v + e`), so `R_nn = s^2 I` on the log readings (0 on
//!   the constant): the log mapping turns the patent's proportional noise
//!   into the homoscedastic noise Wiener estimation assumes.
//! - **Estimation**: `rho = exp(W [1; ln(v + eps)]) - eps`: m logarithms, one
//!   n x (m + 1) mat-vec, n exponentials per point.
//!
//! It is not linear in the readings, so it has no single W for a blob (the
//! blob's `LogWiener` kind is reserved for it); this module measures whether it
//! earns a place.
use crate::forward::prior::Prior;
use anyhow::ensure;
use nalgebra::{DMatrix, DVector};

/// A trained log-domain Wiener estimator.
#[derive(Clone, Debug)]
pub struct LogWiener {
    /// n x (m + 1): column 0 multiplies the constant 1.
    pub w: DMatrix<f64>,
    /// f32 row-major copy of `w` (n x (m + 1)).
    w32: Vec<f32>,
    /// Offset of the mapping.
    pub eps: f64,
    n: usize,
    m: usize,
}

impl LogWiener {
    /// Trains from `prior` for system `h` (m x n), relative noise `noise_rel`
    /// and offset `eps` (> 0).
    pub fn train(prior: &Prior, h: &DMatrix<f64>, noise_rel: f64, eps: f64) -> anyhow::Result<Self> {
        ensure!(eps > 0.0 && eps.is_finite(), "eps must be > 0, got {eps}");
        let (m, n) = h.shape();
        let s = prior.samples.ncols();
        let mut rxx = DMatrix::<f64>::zeros(m + 1, m + 1);
        let mut ryx = DMatrix::<f64>::zeros(n, m + 1);
        for k in 0..s {
            let rho = prior.samples.column(k);
            let v = h * rho;
            let x = DVector::from_fn(m + 1, |i, _| if i == 0 { 1.0 } else { (v[i - 1].max(0.0) + eps).ln() });
            let y = rho.map(|r| (r.max(0.0) + eps).ln());
            rxx += &x * x.transpose();
            ryx += &y * x.transpose();
        }
        rxx /= s as f64;
        ryx /= s as f64;
        for i in 1..=m {
            rxx[(i, i)] += noise_rel * noise_rel;
        }
        // A relative floor keeps the solve defined when the prior is smaller
        // than m + 1 samples or perfectly collinear.
        let floor = 1e-12 * rxx.diagonal().amax();
        for i in 0..=m {
            rxx[(i, i)] += floor;
        }
        let chol = rxx.cholesky().ok_or_else(|| anyhow::anyhow!("log-Wiener: <x x^T> is not positive definite"))?;
        // W rxx = ryx  <=>  rxx W^T = ryx^T (rxx symmetric).
        let w = chol.solve(&ryx.transpose()).transpose();
        let w32 = (0..n).flat_map(|j| (0..=m).map(move |i| (j, i))).map(|(j, i)| w[(j, i)] as f32).collect();
        Ok(Self { w, w32, eps, n, m })
    }

    /// Estimates `readings` (points x m, f32) into `out` (points x n), in f32.
    pub fn estimate_into(&self, readings: &[f32], out: &mut [f32]) {
        let (m, n) = (self.m, self.n);
        let eps = self.eps as f32;
        let mut x = vec![0.0f32; m + 1];
        x[0] = 1.0;
        for (v, o) in readings.chunks_exact(m).zip(out.chunks_exact_mut(n)) {
            for i in 0..m {
                x[i + 1] = (v[i].max(0.0) + eps).ln();
            }
            brdf_meter::kernel::mat_vec_f32_slice(&self.w32, &x, o);
            for r in o.iter_mut() {
                *r = r.exp() - eps;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_power_law_family_exactly_in_the_log_domain() {
        // rho_j = a * exp(b t_j) is linear in the log domain; with H = I
        // (readings are the bins) and no noise the estimator reproduces
        // members it never saw, which a linear-domain Wiener cannot do for a
        // two-parameter multiplicative family with 3 bins of data... here it
        // must be exact to rounding.
        let n = 3;
        let t = [0.0, 0.5, 1.0];
        let mut cols = Vec::new();
        for a in [0.5, 1.0, 2.0, 4.0] {
            for b in [-1.0, 0.0, 1.5, 3.0] {
                cols.push((0..n).map(|j| a * f64::exp(b * t[j])).collect::<Vec<_>>());
            }
        }
        let samples = DMatrix::from_fn(n, cols.len(), |j, s| cols[s][j]);
        let prior = Prior::from_samples(samples).unwrap();
        let h = DMatrix::identity(n, n);
        let lw = LogWiener::train(&prior, &h, 0.0, 1e-9).unwrap();
        let v: Vec<f32> = (0..n).map(|j| (1.3 * f64::exp(2.2 * t[j])) as f32).collect();
        let mut out = vec![0.0f32; n];
        lw.estimate_into(&v, &mut out);
        for j in 0..n {
            assert!((out[j] - v[j]).abs() < 1e-4 * v[j], "bin {j}: {} vs {}", out[j], v[j]);
        }
    }
}
