//! Batch estimation on the host: `rho_p = W v_p` for many points, in f32.
//!
//! W is stored transposed (m contiguous columns of n), and each point's
//! output is accumulated as `out = 0; out += W[:, i] * v_i` for i = 0..m.
//! Per output element that is exactly the library kernel's sequence
//! (`acc = 0; acc += w_ji * v_i`, i ascending, unfused), so the results are
//! bit-identical to `brdf_meter::kernel::estimate_into` (tested) and to the
//! device, while the inner loop runs over n contiguous outputs and
//! vectorises.
use super::LinearEstimator;

/// An f32 estimator laid out for batches.
#[derive(Clone, Debug)]
pub struct BatchEstimator {
    n: usize,
    m: usize,
    /// `wt[i * n + j] = W[j][i]`.
    wt: Vec<f32>,
}

impl BatchEstimator {
    /// From W row-major n x m (the blob and kernel layout).
    ///
    /// # Panics
    /// If `w.len() != n * m`.
    pub fn from_row_major(w: &[f32], n: usize, m: usize) -> Self {
        assert_eq!(w.len(), n * m, "W must be n x m row-major");
        let mut wt = vec![0.0f32; n * m];
        for j in 0..n {
            for i in 0..m {
                wt[i * n + j] = w[j * m + i];
            }
        }
        Self { n, m, wt }
    }

    /// From a trained estimator (rounded to f32).
    pub fn from_estimator(e: &LinearEstimator) -> Self {
        Self::from_row_major(&e.w_f32_row_major(), e.n(), e.m())
    }

    /// Bins n.
    pub fn n(&self) -> usize {
        self.n
    }
    /// Readings m.
    pub fn m(&self) -> usize {
        self.m
    }

    /// Estimates `readings.len() / m` points: `readings` is points x m
    /// (row-major), `out` points x n.
    ///
    /// # Panics
    /// If the lengths do not agree.
    pub fn estimate_into(&self, readings: &[f32], out: &mut [f32]) {
        let (n, m) = (self.n, self.m);
        assert!(m > 0 && readings.len() % m == 0, "readings must be points x m");
        let points = readings.len() / m;
        assert_eq!(out.len(), points * n, "out must be points x n");
        for (v, o) in readings.chunks_exact(m).zip(out.chunks_exact_mut(n)) {
            o.fill(0.0);
            for (i, &vi) in v.iter().enumerate() {
                let col = &self.wt[i * n..(i + 1) * n];
                for (acc, w) in o.iter_mut().zip(col) {
                    *acc += *w * vi;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn bit_identical_to_the_device_kernel() {
        let (n, m, p) = (81, 7, 500);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let w: Vec<f32> = (0..n * m).map(|_| rng.random_range(-50.0f32..50.0)).collect();
        let v: Vec<f32> = (0..p * m).map(|_| rng.random_range(-1.0f32..300.0)).collect();
        let b = BatchEstimator::from_row_major(&w, n, m);
        let mut out = vec![0.0f32; p * n];
        b.estimate_into(&v, &mut out);
        let mut one = vec![0.0f32; n];
        for k in 0..p {
            brdf_meter::kernel::estimate_into(&w, &v[k * m..(k + 1) * m], &mut one);
            for j in 0..n {
                assert_eq!(out[k * n + j].to_bits(), one[j].to_bits(), "point {k} bin {j}");
            }
        }
    }
}
