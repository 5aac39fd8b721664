//! Host side of the device's number formats: a W quantised to Q15 exactly as
//! the device quantises it when it loads a blob (`brdf_meter::kernel::
//! quantise_w_q15`), and the per-point path the device runs (quantise the
//! readings, integer kernel, scale back). The integer arithmetic is the
//! library's, so these results are the device's bits (the QEMU bench checks).
use brdf_meter::kernel;

/// A W in the device's Q15 format.
#[derive(Clone, Debug)]
pub struct Q15Estimator {
    packed: Vec<u32>,
    inv_scale: Vec<f32>,
    n: usize,
    m: usize,
}

impl Q15Estimator {
    /// Quantises `w` (row-major n x m f32, the blob layout).
    pub fn from_row_major(w: &[f32], n: usize, m: usize) -> Self {
        let mut packed = vec![0u32; kernel::q15_w_words(n, m)];
        let mut inv_scale = vec![0.0f32; n];
        kernel::quantise_w_q15(w, n, m, &mut packed, &mut inv_scale);
        Self { packed, inv_scale, n, m }
    }

    /// Bytes the quantised matrix takes (packed W plus one f32 scale per row).
    pub fn bytes(&self) -> usize {
        4 * self.packed.len() + 4 * self.inv_scale.len()
    }

    /// Estimates `readings` (points x m) into `out` (points x n) on the
    /// device's Q15 path.
    pub fn estimate_into(&self, readings: &[f32], out: &mut [f32]) {
        let (m, n) = (self.m, self.n);
        let mut vq = vec![0u32; kernel::q15_v_words(m)];
        let mut acc = vec![0i32; kernel::q15_acc_len(n)];
        for (v, o) in readings.chunks_exact(m).zip(out.chunks_exact_mut(n)) {
            let k = kernel::quantise_v_q15(v, &mut vq);
            kernel::mat_vec_q15(&self.packed, &vq, m, &mut acc);
            kernel::dequantise_q15(&acc[..n], &self.inv_scale, k, o);
        }
    }
}

/// Largest `|a - b|` over two equal-length slices, relative to `max |b|`.
pub fn max_rel_diff(a: &[f32], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |s, x| s.max(x.abs())).max(f64::MIN_POSITIVE);
    a.iter().zip(b).map(|(x, y)| (*x as f64 - y).abs()).fold(0.0, f64::max) / scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn q15_estimates_stay_within_the_kernel_bound_of_f64() {
        // A Wiener-like W (mixed signs) and readings over four decades.
        let (n, m) = (81, 7);
        let w: Vec<f32> = (0..n * m).map(|k| ((k as f32 * 0.37).sin() * 12.0) - 2.0).collect();
        let q = Q15Estimator::from_row_major(&w, n, m);
        assert_eq!(q.bytes(), 4 * 41 * 7 + 4 * 81);
        for scale in [0.01f32, 1.0, 100.0] {
            let v: Vec<f32> = (0..m).map(|i| scale * (1.0 + i as f32 * 0.3)).collect();
            let mut out = vec![0.0f32; n];
            q.estimate_into(&v, &mut out);
            let mut vq = vec![0u32; kernel::q15_v_words(m)];
            let k = kernel::quantise_v_q15(&v, &mut vq);
            let mut inv = vec![0.0f32; n];
            let mut packed = vec![0u32; kernel::q15_w_words(n, m)];
            kernel::quantise_w_q15(&w, n, m, &mut packed, &mut inv);
            for j in 0..n {
                let exact: f64 = (0..m).map(|i| w[j * m + i] as f64 * v[i] as f64).sum();
                let bound = kernel::q15_error_bound(&w, &v, &inv, k, out[j], j);
                assert!((out[j] as f64 - exact).abs() <= bound, "scale {scale} bin {j}");
                // And the bound itself is small: about 1e-4 of the row's scale.
                let row_l1: f64 = (0..m).map(|i| (w[j * m + i] as f64).abs()).sum();
                assert!(bound < 2e-4 * row_l1 * scale as f64 * 3.0, "bound {bound} too loose");
            }
        }
    }
}
