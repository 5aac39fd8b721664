//! The estimator kernel: `rho = W v`, one matrix-vector product per point.
//!
//! `W` is stored row-major as `n` rows of `m` (each output bin's weights are
//! contiguous), which on the Cortex-M4F gives one load and one VMLA per
//! multiply-accumulate. The accumulation order is fixed (`acc = 0; acc += w*v`
//! for i = 0..m, unfused) and rustc never contracts to FMA on either target, so
//! the host and the device produce bit-identical f32 results. Keep it so: do not
//! reorder, unroll across rows or use `mul_add` here.

/// Estimates one point: `out[j] = sum_i w[j*m + i] * v[i]`, for `j < out.len()`.
///
/// `w` is row-major `out.len()` x `v.len()`.
///
/// # Panics
/// If `w.len() != out.len() * v.len()`.
#[inline]
pub fn estimate_into(w: &[f32], v: &[f32], out: &mut [f32]) {
    let m = v.len();
    assert_eq!(w.len(), out.len() * m, "W must be n x m row-major");
    if m == 0 {
        out.fill(0.0);
        return;
    }
    for (row, o) in w.chunks_exact(m).zip(out.iter_mut()) {
        *o = dot(row, v);
    }
}

/// Fixed-size form of [`estimate_into`]: `N` bins from `M` readings.
#[inline]
pub fn estimate<const N: usize, const M: usize>(w: &[[f32; M]; N], v: &[f32; M]) -> [f32; N] {
    let mut out = [0.0f32; N];
    for (row, o) in w.iter().zip(out.iter_mut()) {
        *o = dot(row, v);
    }
    out
}

/// The one accumulation both targets share. Sequential and unfused on purpose.
#[inline(always)]
fn dot(row: &[f32], v: &[f32]) -> f32 {
    let mut acc = 0.0f32;
    for (w, x) in row.iter().zip(v.iter()) {
        acc += *w * *x;
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slice_and_fixed_forms_agree_bit_for_bit() {
        let mut w = [[0.0f32; 3]; 4];
        for (j, row) in w.iter_mut().enumerate() {
            for (i, x) in row.iter_mut().enumerate() {
                *x = (j as f32 + 1.0) * 0.37 - i as f32 * 1.13;
            }
        }
        let v = [0.25f32, -3.5, 7.125];
        let fixed = estimate(&w, &v);
        let flat: [f32; 12] = bytemuck::cast(w);
        let mut out = [0.0f32; 4];
        estimate_into(&flat, &v, &mut out);
        assert_eq!(fixed.map(f32::to_bits), out.map(f32::to_bits));
        // Against an explicit f64 evaluation, within f32 rounding.
        for j in 0..4 {
            let exact: f64 = (0..3).map(|i| w[j][i] as f64 * v[i] as f64).sum();
            assert!((fixed[j] as f64 - exact).abs() <= 1e-5 * exact.abs().max(1.0));
        }
    }

    #[test]
    fn identity_matrix_returns_readings() {
        let w = [[1.0, 0.0], [0.0, 1.0]];
        assert_eq!(estimate(&w, &[3.0, -2.0]), [3.0, -2.0]);
    }

    #[test]
    #[should_panic(expected = "n x m")]
    fn wrong_shape_panics() {
        let mut out = [0.0; 2];
        estimate_into(&[1.0; 5], &[1.0, 2.0], &mut out);
    }
}
