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

/// Output bins computed together in registers.
const LANES: usize = 16;

/// An f32 estimator laid out for batches.
#[derive(Clone, Debug)]
pub struct BatchEstimator {
    n: usize,
    m: usize,
    /// n rounded up to a multiple of [`LANES`].
    n_pad: usize,
    /// `wt[i * n_pad + j] = W[j][i]`, zero in the padding.
    wt: Vec<f32>,
}

impl BatchEstimator {
    /// From W row-major n x m (the blob and kernel layout).
    ///
    /// # Panics
    /// If `w.len() != n * m`.
    pub fn from_row_major(w: &[f32], n: usize, m: usize) -> Self {
        assert_eq!(w.len(), n * m, "W must be n x m row-major");
        let n_pad = n.div_ceil(LANES) * LANES;
        let mut wt = vec![0.0f32; n_pad * m];
        for j in 0..n {
            for i in 0..m {
                wt[i * n_pad + j] = w[j * m + i];
            }
        }
        Self { n, m, n_pad, wt }
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
    /// Blocks of [`LANES`] outputs are accumulated in registers over the m
    /// readings (`acc = 0; acc += w * v_i`, i ascending) and stored once.
    ///
    /// # Panics
    /// If the lengths do not agree.
    pub fn estimate_into(&self, readings: &[f32], out: &mut [f32]) {
        let m = self.m;
        assert!(m > 0 && readings.len() % m == 0, "readings must be points x m");
        let points = readings.len() / m;
        assert_eq!(out.len(), points * self.n, "out must be points x n");
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above). AVX2 only
            // widens the vectors; FMA is not enabled, so each element's
            // arithmetic (unfused multiply, then add) is unchanged.
            unsafe { self.run_avx2(readings, out) };
            return;
        }
        self.run(readings, out);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn run_avx2(&self, readings: &[f32], out: &mut [f32]) {
        self.run(readings, out);
    }

    #[inline(always)]
    fn run(&self, readings: &[f32], out: &mut [f32]) {
        let (n, m, np) = (self.n, self.m, self.n_pad);
        let full = n / LANES;
        for (v, o) in readings.chunks_exact(m).zip(out.chunks_exact_mut(n)) {
            // Full blocks: fixed-size stores, no call in the loop, so the
            // out-of-order core overlaps the blocks' dependency chains.
            for b in 0..full {
                let acc = self.block(v, b * LANES, np);
                o[b * LANES..(b + 1) * LANES].copy_from_slice(&acc);
            }
            if full * LANES < n {
                let acc = self.block(v, full * LANES, np);
                for (dst, src) in o[full * LANES..].iter_mut().zip(acc.iter()) {
                    *dst = *src;
                }
            }
        }
    }

    /// Outputs `j0..j0 + LANES` of one point: `acc = 0; acc += W[j][i] * v_i`, i ascending.
    #[inline(always)]
    fn block(&self, v: &[f32], j0: usize, np: usize) -> [f32; LANES] {
        let mut acc = [0.0f32; LANES];
        for (i, &vi) in v.iter().enumerate() {
            let col: &[f32; LANES] = self.wt[i * np + j0..i * np + j0 + LANES].try_into().expect("padded");
            for l in 0..LANES {
                acc[l] += col[l] * vi;
            }
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn bit_identical_to_the_device_kernel() {
        for (n, m, p) in [(81, 7, 300), (16, 3, 20), (3, 1, 5), (33, 9, 10)] {
            let mut rng = ChaCha8Rng::seed_from_u64(n as u64);
            let w: Vec<f32> = (0..n * m).map(|_| rng.random_range(-50.0f32..50.0)).collect();
            let v: Vec<f32> = (0..p * m).map(|_| rng.random_range(-1.0f32..300.0)).collect();
            let b = BatchEstimator::from_row_major(&w, n, m);
            let mut out = vec![0.0f32; p * n];
            b.estimate_into(&v, &mut out);
            let mut one = vec![0.0f32; n];
            for k in 0..p {
                brdf_meter::kernel::estimate_into(&w, &v[k * m..(k + 1) * m], &mut one);
                for j in 0..n {
                    assert_eq!(out[k * n + j].to_bits(), one[j].to_bits(), "n={n} m={m} point {k} bin {j}");
                }
            }
        }
    }
}
