//! The f32 kernel: `rho = W v`, one matrix-vector product per point.
//!
//! `W` (n x m) is held as its transpose, an nalgebra `SMatrix<f32, M, N>`
//! (column-major, so column j of the transpose, W's row j, is contiguous):
//! the memory layout is the blob's row-major n x m, which on the Cortex-M4F
//! gives one load and one VMLA per multiply-accumulate. The accumulation
//! order is fixed (`acc = 0; acc += w*v` for i = 0..m, unfused) and rustc
//! never contracts to FMA on either target, so the host and the device
//! produce bit-identical f32 results. Keep it so: do not reorder, unroll
//! across rows, use `mul_add` or nalgebra's own products (their summation
//! order is theirs) here.
use nalgebra::{SMatrix, SMatrixView, SVector};

/// `out[j] = sum_i w[j*m + i] * v[i]`, for `j < out.len()`, on slices: `w` is
/// row-major `out.len()` x `v.len()` (the blob layout). For shapes known only
/// at run time (host tools, tests).
///
/// # Panics
/// If `w.len() != out.len() * v.len()`.
#[inline]
pub fn mat_vec_f32_slice(w: &[f32], v: &[f32], out: &mut [f32]) {
    let m = v.len();
    assert_eq!(w.len(), out.len() * m, "W must be n x m row-major");
    if m == 0 {
        out.fill(0.0);
        return;
    }
    #[cfg(all(target_arch = "arm", target_os = "none", target_abi = "eabihf"))]
    if m == 7 {
        // SAFETY: lengths checked above.
        unsafe { arm_f32::f32_m7(w.as_ptr(), v.as_ptr(), out.as_mut_ptr(), out.len()) };
        return;
    }
    for (row, o) in w.chunks_exact(m).zip(out.iter_mut()) {
        *o = dot(row, v);
    }
}

/// `W v` for N bins from M readings, `W` given as its transpose `wt`
/// (M x N, see the module docs).
#[inline]
pub fn mat_vec_f32<const N: usize, const M: usize>(wt: &SMatrix<f32, M, N>, v: &SVector<f32, M>) -> SVector<f32, N> {
    let mut out = SVector::<f32, N>::zeros();
    mat_vec_f32_into(wt.as_view(), v, &mut out);
    out
}

/// [`mat_vec_f32`] into a caller's vector, from a view of the transpose (a
/// matrix in RAM or one read in place from a flash slot): no copy of W or of
/// the result, what the firmware runs per point.
#[inline]
pub fn mat_vec_f32_into<const N: usize, const M: usize>(
    wt: SMatrixView<'_, f32, M, N>,
    v: &SVector<f32, M>,
    out: &mut SVector<f32, N>,
) {
    // SAFETY: an `SMatrixView<f32, M, N>` has strides (1, M) by its type: its
    // N columns of M are M * N contiguous f32 from its first element.
    // (nalgebra's `as_slice` cannot prove that for generic M, N.)
    let w: &[f32] = unsafe { core::slice::from_raw_parts(wt.as_ptr(), M * N) };
    // The Cortex-M4F (thumbv7em-none-eabihf) runs the assembly form for the
    // instrument's m = 7: the same accumulation per bin, ~1.2 instructions
    // per multiply-accumulate instead of ~2 (VLDM of two rows, VSTM of eight).
    #[cfg(all(target_arch = "arm", target_os = "none", target_abi = "eabihf"))]
    if M == 7 {
        // SAFETY: `w` is N columns of 7 contiguous f32, `v` 7, `out` N.
        unsafe { arm_f32::f32_m7(w.as_ptr(), v.as_ptr(), out.as_mut_ptr(), N) };
        return;
    }
    for (row, o) in w.chunks_exact(M.max(1)).zip(out.iter_mut()) {
        *o = dot(row, v.as_slice());
    }
}

/// `out[r] = sum_i w[r*m + i] * v[i]` for four rows (the gloss readings'
/// rows, `crate::gloss`): the same accumulation as [`mat_vec_f32_slice`],
/// with a four-row assembly form on the Cortex-M4F for m = 7 (two VLDM of
/// two rows, 28 VMLA, one VSTM) instead of the general kernel's row-by-row
/// tail.
///
/// # Panics
/// If `w.len() != 4 * v.len()`.
#[inline]
pub fn mat_vec_f32_4(w: &[f32], v: &[f32], out: &mut [f32; 4]) {
    let m = v.len();
    assert_eq!(w.len(), 4 * m, "four rows of m");
    #[cfg(all(target_arch = "arm", target_os = "none", target_abi = "eabihf"))]
    if m == 7 {
        // SAFETY: lengths checked above.
        unsafe { arm_f32::f32_m7_x4(w.as_ptr(), v.as_ptr(), out.as_mut_ptr()) };
        return;
    }
    for (row, o) in w.chunks_exact(m.max(1)).zip(out.iter_mut()) {
        *o = dot(row, v);
    }
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

#[cfg(all(target_arch = "arm", target_os = "none", target_abi = "eabihf"))]
mod arm_f32 {
    //! The Cortex-M4F f32 kernel for m = 7 (the instrument's LED count). The
    //! same sequence as [`super::dot`] for every bin, `acc = 0; acc += w_i
    //! v_i` for i = 0..7 with VMLA.F32 (multiply rounded, then added: unfused),
    //! so the bits are those of the portable code. v stays in s0-s6; eight
    //! rows per iteration: two rows (14 words) per VLDM, accumulators zeroed
    //! two at a time from a zero core register, eight results per VSTM.

    /// Four rows: `out[r] = sum_i w[7r + i] v[i]`, each accumulated in i
    /// order by VMLA from 0, as [`super::dot`].
    ///
    /// # Safety
    /// `w` holds 28 f32, `v` 7, `out` 4.
    #[inline(always)]
    pub(super) unsafe fn f32_m7_x4(w: *const f32, v: *const f32, out: *mut f32) {
        // SAFETY: the caller guarantees the buffers; every register written is declared.
        unsafe {
            core::arch::asm!(
                "vldmia {v}, {{s0-s6}}",
                "movs {v}, #0",
                "vmov s8, s9, {v}, {v}",
                "vmov s10, s11, {v}, {v}",
                "vldmia {w}!, {{s16-s29}}",
                "vmla.f32 s8, s16, s0",
                "vmla.f32 s9, s23, s0",
                "vmla.f32 s8, s17, s1",
                "vmla.f32 s9, s24, s1",
                "vmla.f32 s8, s18, s2",
                "vmla.f32 s9, s25, s2",
                "vmla.f32 s8, s19, s3",
                "vmla.f32 s9, s26, s3",
                "vmla.f32 s8, s20, s4",
                "vmla.f32 s9, s27, s4",
                "vmla.f32 s8, s21, s5",
                "vmla.f32 s9, s28, s5",
                "vmla.f32 s8, s22, s6",
                "vmla.f32 s9, s29, s6",
                "vldmia {w}!, {{s16-s29}}",
                "vmla.f32 s10, s16, s0",
                "vmla.f32 s11, s23, s0",
                "vmla.f32 s10, s17, s1",
                "vmla.f32 s11, s24, s1",
                "vmla.f32 s10, s18, s2",
                "vmla.f32 s11, s25, s2",
                "vmla.f32 s10, s19, s3",
                "vmla.f32 s11, s26, s3",
                "vmla.f32 s10, s20, s4",
                "vmla.f32 s11, s27, s4",
                "vmla.f32 s10, s21, s5",
                "vmla.f32 s11, s28, s5",
                "vmla.f32 s10, s22, s6",
                "vmla.f32 s11, s29, s6",
                "vstmia {o}, {{s8-s11}}",
                w = inout(reg) w => _,
                v = inout(reg) v => _,
                o = in(reg) out,
                out("s0") _, out("s1") _, out("s2") _, out("s3") _, out("s4") _, out("s5") _, out("s6") _, out("s8") _, out("s9") _, out("s10") _, out("s11") _, out("s16") _, out("s17") _, out("s18") _, out("s19") _, out("s20") _, out("s21") _, out("s22") _, out("s23") _, out("s24") _, out("s25") _, out("s26") _, out("s27") _, out("s28") _, out("s29") _,
                options(nostack),
            );
        }
    }

    /// # Safety
    /// `w` holds `rows * 7` f32, `v` 7, `out` `rows`.
    // Inlined into its caller, so `estimate::point_kernel` (not inlined)
    // stays the one symbol holding the whole kernel (scripts/qemu-icount.sh).
    #[inline(always)]
    pub(super) unsafe fn f32_m7(w: *const f32, v: *const f32, out: *mut f32, rows: usize) {
        // SAFETY: the caller guarantees the buffers; every register written is
        // declared clobbered (s16-s31 are callee-saved: the compiler saves them).
        unsafe {
            core::arch::asm!(
                "vldmia r3, {{s0-s6}}",
                "movs r3, #0",
                "subs r2, r2, #8",
                "blo 2f",
                "1:",
                "vmov s8, s9, r3, r3",
                "vmov s10, s11, r3, r3",
                "vmov s12, s13, r3, r3",
                "vmov s14, s15, r3, r3",
                "vldmia r0!, {{s16-s29}}",
                "vmla.f32 s8, s16, s0",
                "vmla.f32 s9, s23, s0",
                "vmla.f32 s8, s17, s1",
                "vmla.f32 s9, s24, s1",
                "vmla.f32 s8, s18, s2",
                "vmla.f32 s9, s25, s2",
                "vmla.f32 s8, s19, s3",
                "vmla.f32 s9, s26, s3",
                "vmla.f32 s8, s20, s4",
                "vmla.f32 s9, s27, s4",
                "vmla.f32 s8, s21, s5",
                "vmla.f32 s9, s28, s5",
                "vmla.f32 s8, s22, s6",
                "vmla.f32 s9, s29, s6",
                "vldmia r0!, {{s16-s29}}",
                "vmla.f32 s10, s16, s0",
                "vmla.f32 s11, s23, s0",
                "vmla.f32 s10, s17, s1",
                "vmla.f32 s11, s24, s1",
                "vmla.f32 s10, s18, s2",
                "vmla.f32 s11, s25, s2",
                "vmla.f32 s10, s19, s3",
                "vmla.f32 s11, s26, s3",
                "vmla.f32 s10, s20, s4",
                "vmla.f32 s11, s27, s4",
                "vmla.f32 s10, s21, s5",
                "vmla.f32 s11, s28, s5",
                "vmla.f32 s10, s22, s6",
                "vmla.f32 s11, s29, s6",
                "vldmia r0!, {{s16-s29}}",
                "vmla.f32 s12, s16, s0",
                "vmla.f32 s13, s23, s0",
                "vmla.f32 s12, s17, s1",
                "vmla.f32 s13, s24, s1",
                "vmla.f32 s12, s18, s2",
                "vmla.f32 s13, s25, s2",
                "vmla.f32 s12, s19, s3",
                "vmla.f32 s13, s26, s3",
                "vmla.f32 s12, s20, s4",
                "vmla.f32 s13, s27, s4",
                "vmla.f32 s12, s21, s5",
                "vmla.f32 s13, s28, s5",
                "vmla.f32 s12, s22, s6",
                "vmla.f32 s13, s29, s6",
                "vldmia r0!, {{s16-s29}}",
                "vmla.f32 s14, s16, s0",
                "vmla.f32 s15, s23, s0",
                "vmla.f32 s14, s17, s1",
                "vmla.f32 s15, s24, s1",
                "vmla.f32 s14, s18, s2",
                "vmla.f32 s15, s25, s2",
                "vmla.f32 s14, s19, s3",
                "vmla.f32 s15, s26, s3",
                "vmla.f32 s14, s20, s4",
                "vmla.f32 s15, s27, s4",
                "vmla.f32 s14, s21, s5",
                "vmla.f32 s15, s28, s5",
                "vmla.f32 s14, s22, s6",
                "vmla.f32 s15, s29, s6",
                "vstmia r1!, {{s8-s15}}",
                "subs r2, r2, #8",
                "bhs 1b",
                "2:",
                "adds r2, r2, #8",
                "beq 4f",
                "3:",
                "vmov s8, r3",
                "vldmia r0!, {{s16-s22}}",
                "vmla.f32 s8, s16, s0", "vmla.f32 s8, s17, s1", "vmla.f32 s8, s18, s2", "vmla.f32 s8, s19, s3", "vmla.f32 s8, s20, s4", "vmla.f32 s8, s21, s5", "vmla.f32 s8, s22, s6",
                "vstmia r1!, {{s8}}",
                "subs r2, r2, #1",
                "bne 3b",
                "4:",
                inout("r0") w => _,
                inout("r1") out => _,
                inout("r2") rows => _,
                inout("r3") v => _,
                out("s0") _, out("s1") _, out("s2") _, out("s3") _, out("s4") _, out("s5") _, out("s6") _, out("s7") _, out("s8") _, out("s9") _, out("s10") _, out("s11") _, out("s12") _, out("s13") _, out("s14") _, out("s15") _, out("s16") _, out("s17") _, out("s18") _, out("s19") _, out("s20") _, out("s21") _, out("s22") _, out("s23") _, out("s24") _, out("s25") _, out("s26") _, out("s27") _, out("s28") _, out("s29") _,
                options(nostack),
            );
        }
    }
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
        // The transpose's columns are W's rows: the same memory.
        let wt = SMatrix::<f32, 3, 4>::from_data(nalgebra::ArrayStorage(w));
        let fixed = mat_vec_f32(&wt, &SVector::from(v));
        let flat: [f32; 12] = bytemuck::cast(w);
        let mut out = [0.0f32; 4];
        mat_vec_f32_slice(&flat, &v, &mut out);
        assert_eq!(fixed.map(f32::to_bits).as_slice(), out.map(f32::to_bits).as_slice());
        // Against an explicit f64 evaluation, within f32 rounding.
        for j in 0..4 {
            let exact: f64 = (0..3).map(|i| w[j][i] as f64 * v[i] as f64).sum();
            assert!((fixed[j] as f64 - exact).abs() <= 1e-5 * exact.abs().max(1.0));
        }
    }

    #[test]
    fn identity_matrix_returns_readings() {
        let wt = SMatrix::<f32, 2, 2>::identity();
        assert_eq!(mat_vec_f32(&wt, &SVector::from([3.0, -2.0])), SVector::from([3.0, -2.0]));
    }

    #[test]
    #[should_panic(expected = "n x m")]
    fn wrong_shape_panics() {
        let mut out = [0.0; 2];
        mat_vec_f32_slice(&[1.0; 5], &[1.0, 2.0], &mut out);
    }
}
