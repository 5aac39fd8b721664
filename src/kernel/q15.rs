//! Fixed point (Q15): the device's integer kernel.
//!
//! # Format
//! - **W** (n x m, f32 in the blob) is quantised at load time, row by row:
//!   `wq_ji = round(w_ji * s_j)` with `s_j = min(65000 / L1_j, 32767 / max_i |w_ji|)`
//!   (`L1_j = sum_i |w_ji|`), so every element fits i16 and every row's L1
//!   norm is at most `65000 + m/2 < 65535`. The blob stays f32 (format
//!   version 1): the device quantises when it loads a calibration, with the
//!   same f32 arithmetic as the host ([`quantise_w_q15`]), so both hold the
//!   same integers.
//! - **v** (m readings) is quantised per point in block floating point: with
//!   `E` the binary exponent of `max_i |v_i|`, `k = 14 - E` and
//!   `vq_i = min(round(v_i 2^k), 32767)` (ties away from zero): the largest
//!   reading uses 15 bits ([`quantise_v_q15`]).
//! - **Accumulation**: `acc_j = sum_i wq_ji vq_i` in i32, two products per
//!   SMLAD on the Cortex-M4 (portable integer code elsewhere; integer sums are
//!   exact, so any order gives the same bits).
//! - **Output**: `rho_j = (acc_j as f32 * inv_s_j) * 2^-k` ([`dequantise_q15`]);
//!   the device may also stream `acc_j` and `k` and leave this to the host.
//!
//! # Overflow bound (why a 32-bit accumulator is safe)
//! `|acc_j| <= sum_i |wq_ji| |vq_i| <= (sum_i |wq_ji|) * 32767 <= 65534 * 32767
//! = 2_147_385_378 < 2^31 - 1`, and every partial sum (including the two
//! products SMUAD/SMLAD add at once) is bounded by the same sum, so no step
//! overflows and SMLAD's Q flag never sets. Elements are clamped to
//! [-32767, 32767] (never -32768), so each single product is below 2^30.
//!
//! # Error bound against exact arithmetic
//! With `d_ji = wq_ji / s_j - w_ji` (|d_ji| <= 0.5 / s_j) and
//! `e_i = vq_i 2^-k - v_i` (|e_i| <= 2^-k: half an LSB, one at the clamp),
//! `|rho_j - W_j v| <= sum_i |d_ji| |v_i| + sum_i |wq_ji / s_j| |e_i| + r_j`
//! where `r_j <= 3 * 2^-24 |rho_j|` covers the i32 -> f32 conversion and the
//! two f32 products ([`q15_error_bound`]; tested against f64).
//!
//! # Packed layout of W (what the SMLAD kernel loads with one LDM per row pair)
//! Rows are taken in pairs (a = 2r, b = 2r + 1; an odd n gets a zero row b).
//! Each pair is `m` 32-bit words: the `floor(m/2)` words of row a, each two
//! i16 `(w_2k | w_2k+1 << 16)`, then the `floor(m/2)` words of row b, then for
//! odd m one word holding both rows' last elements `(a_m-1 | b_m-1 << 16)`.
//! The readings are packed the same way: `ceil(m/2)` words `(v_2k | v_2k+1 << 16)`,
//! the last one `(v_m-1 | 0)` for odd m.

/// Largest magnitude of a Q15 element (-32768 is never used).
pub const Q15_MAX: i32 = 32767;
/// Target L1 norm of a quantised W row (see the overflow bound).
pub const Q15_ROW_L1: f32 = 65000.0;

/// Words of the packed Q15 matrix for n bins and m readings.
pub const fn q15_w_words(n: usize, m: usize) -> usize {
    n.div_ceil(2) * m
}

/// Words of the packed Q15 readings for m readings.
pub const fn q15_v_words(m: usize) -> usize {
    m.div_ceil(2)
}

/// Length of the accumulator buffer for n bins (n rounded up to even; the
/// padding entry of an odd n is always 0).
pub const fn q15_acc_len(n: usize) -> usize {
    n.div_ceil(2) * 2
}

#[inline(always)]
fn round_half_away(x: f32) -> i32 {
    // x is below 2^23 in magnitude here, so adding 0.5 is exact; `as` truncates
    // towards zero (VCVT.S32.F32 on the M4), giving ties away from zero.
    (if x >= 0.0 { x + 0.5 } else { x - 0.5 }) as i32
}

#[inline(always)]
fn pack(lo: i32, hi: i32) -> u32 {
    (lo as u16 as u32) | ((hi as u16 as u32) << 16)
}

/// `2^e` as f32 (for `-126 <= e <= 127`), built from its bits.
#[inline(always)]
pub fn pow2_f32(e: i32) -> f32 {
    f32::from_bits(((e + 127) as u32) << 23)
}

/// Quantises W (row-major n x m, the blob layout) into the packed Q15 layout
/// (`packed.len() == q15_w_words(n, m)`) and writes `inv_scale[j] = 1 / s_j`
/// (0 for an all-zero row). f32 arithmetic only, so the device and the host
/// produce the same integers.
///
/// # Panics
/// If a length disagrees or W holds a non-finite value.
pub fn quantise_w_q15(w: &[f32], n: usize, m: usize, packed: &mut [u32], inv_scale: &mut [f32]) {
    assert!(m > 0 && w.len() == n * m, "W must be n x m row-major");
    assert_eq!(packed.len(), q15_w_words(n, m), "packed W has the wrong length");
    assert_eq!(inv_scale.len(), n, "one scale per row");
    let row_q = |j: usize, i: usize, s: f32| -> i32 {
        if j >= n {
            return 0;
        }
        round_half_away(w[j * m + i] * s).clamp(-Q15_MAX, Q15_MAX)
    };
    let mut scales = [0.0f32; 2];
    for r in 0..n.div_ceil(2) {
        for (h, sc) in scales.iter_mut().enumerate() {
            let j = 2 * r + h;
            *sc = 0.0;
            if j >= n {
                continue;
            }
            let row = &w[j * m..(j + 1) * m];
            assert!(row.iter().all(|x| x.is_finite()), "W row {j} is not finite");
            let (mut l1, mut mx) = (0.0f32, 0.0f32);
            for x in row {
                l1 += x.abs();
                mx = mx.max(x.abs());
            }
            if mx > 0.0 {
                let s = (Q15_ROW_L1 / l1).min(Q15_MAX as f32 / mx);
                *sc = s;
                inv_scale[j] = 1.0 / s;
            } else {
                inv_scale[j] = 0.0;
            }
        }
        let out = &mut packed[r * m..(r + 1) * m];
        let half = m / 2;
        for (h, base) in [(0usize, 0usize), (1, half)] {
            let j = 2 * r + h;
            for k in 0..half {
                out[base + k] = pack(row_q(j, 2 * k, scales[h]), row_q(j, 2 * k + 1, scales[h]));
            }
        }
        if m % 2 == 1 {
            out[m - 1] = pack(row_q(2 * r, m - 1, scales[0]), row_q(2 * r + 1, m - 1, scales[1]));
        }
    }
}

/// Quantises one point's readings into `packed` (`q15_v_words(m)` words) and
/// returns the block exponent `k` (`vq_i ~ v_i 2^k`). All-zero readings give
/// `k = 0` and zeros.
///
/// # Panics
/// If a length disagrees or a reading is not finite.
#[inline]
pub fn quantise_v_q15(v: &[f32], packed: &mut [u32]) -> i32 {
    let m = v.len();
    assert_eq!(packed.len(), q15_v_words(m), "packed v has the wrong length");
    // For finite floats the order of |x| is the order of their bits without
    // the sign: the maximum is an integer maximum (no libm call on the M4).
    let mut mx = 0u32;
    for x in v {
        let b = x.to_bits() & 0x7fff_ffff;
        assert!(b < 0x7f80_0000, "reading is not finite");
        mx = mx.max(b);
    }
    if mx == 0 {
        packed.fill(0);
        return 0;
    }
    // Binary exponent of the largest reading (subnormals count as -126).
    let e = (((mx >> 23) & 0xff) as i32 - 127).max(-126);
    let k = (14 - e).clamp(-126, 127);
    let s = pow2_f32(k);
    let q = |i: usize| if i < m { round_half_away(v[i] * s).clamp(-Q15_MAX, Q15_MAX) } else { 0 };
    for (k2, p) in packed.iter_mut().enumerate() {
        *p = pack(q(2 * k2), q(2 * k2 + 1));
    }
    k
}

#[inline(always)]
fn lo(x: u32) -> i32 {
    x as u16 as i16 as i32
}
#[inline(always)]
fn hi(x: u32) -> i32 {
    (x >> 16) as u16 as i16 as i32
}

/// The Q15 kernel: `acc_j = sum_i wq_ji vq_i` for every bin, `acc.len() ==
/// q15_acc_len(n)` (the padding entry of an odd n is 0). Integer arithmetic,
/// so every target gives the same bits; on the Cortex-M4 with m = 7 it runs
/// the SMLAD assembly kernel (one LDM per row pair, two MACs per SMLAD).
///
/// # Panics
/// If the lengths disagree (`w.len() == q15_w_words(n, m)`, `v.len() ==
/// q15_v_words(m)`).
#[inline]
pub fn mat_vec_q15(w: &[u32], v: &[u32], m: usize, acc: &mut [i32]) {
    assert!(m > 0 && v.len() == q15_v_words(m), "packed v has the wrong length");
    let pairs = acc.len() / 2;
    assert!(acc.len().is_multiple_of(2) && w.len() == pairs * m, "packed W and acc disagree");
    #[cfg(all(target_arch = "arm", target_os = "none", target_abi = "eabihf"))]
    if m == 7 {
        // SAFETY: lengths checked above: `pairs` row pairs of 7 words each in
        // `w`, 4 words in `v`, `2 * pairs` i32 in `acc`.
        unsafe { arm::q15_m7(w.as_ptr(), v.as_ptr(), acc.as_mut_ptr(), pairs) };
        return;
    }
    mat_vec_q15_portable(w, v, m, acc);
}

/// The portable form of [`mat_vec_q15`] (same integers on every target).
pub fn mat_vec_q15_portable(w: &[u32], v: &[u32], m: usize, acc: &mut [i32]) {
    let half = m / 2;
    for (r, out) in acc.chunks_exact_mut(2).enumerate() {
        let p = &w[r * m..(r + 1) * m];
        let (mut a, mut b) = (0i32, 0i32);
        for k in 0..half {
            a = a.wrapping_add(lo(p[k]) * lo(v[k]) + hi(p[k]) * hi(v[k]));
            b = b.wrapping_add(lo(p[half + k]) * lo(v[k]) + hi(p[half + k]) * hi(v[k]));
        }
        if m % 2 == 1 {
            a = a.wrapping_add(lo(p[m - 1]) * lo(v[half]));
            b = b.wrapping_add(hi(p[m - 1]) * lo(v[half]));
        }
        out[0] = a;
        out[1] = b;
    }
}

/// `rho_j = (acc_j as f32 * inv_scale_j) * 2^-k` for `j < out.len()`.
#[inline]
pub fn dequantise_q15(acc: &[i32], inv_scale: &[f32], k: i32, out: &mut [f32]) {
    let f = pow2_f32((-k).clamp(-126, 127));
    for ((o, a), s) in out.iter_mut().zip(acc).zip(inv_scale) {
        *o = (*a as f32 * *s) * f;
    }
}

/// Upper bound on `|rho_j - (W v)_j|` of the Q15 path for one point (exact
/// arithmetic on the f32 inputs `w`, `v`), per the derivation above:
/// quantisation of W and v plus three f32 roundings of the result.
pub fn q15_error_bound(w: &[f32], v: &[f32], inv_scale: &[f32], k: i32, rho_j: f32, j: usize) -> f64 {
    let m = v.len();
    let row = &w[j * m..(j + 1) * m];
    let inv_s = inv_scale[j] as f64;
    let lsb_v = pow2_f64(-k);
    let mut b = 0.0;
    for (wi, vi) in row.iter().zip(v) {
        // |d| <= 0.5 / s, plus the f32 roundings of s, w s and 1/s (each
        // 2^-24 relative, together below 2^-22 |w|).
        b += (0.5 * inv_s + pow2_f64(-22) * (*wi as f64).abs()) * (*vi as f64).abs();
        b += ((*wi as f64).abs() + 0.5 * inv_s) * lsb_v;
    }
    b + 3.0 * pow2_f64(-24) * (rho_j as f64).abs() + f64::MIN_POSITIVE
}

fn pow2_f64(e: i32) -> f64 {
    f64::from_bits(((e + 1023) as u64) << 52)
}
#[cfg(all(target_arch = "arm", target_os = "none", target_abi = "eabihf"))]
mod arm {
    //! The Cortex-M4 Q15 kernel for m = 7: per row pair one `LDM` of the 7
    //! packed words, 3 `SMUAD/SMLAD` + 1 `SMLABB` for row a, the same with
    //! `SMLATB` for row b, one `STRD`; eight pairs per loop iteration.

    /// One row pair: W words in r4..r10, v in r3 (v0|v1), r12 (v2|v3),
    /// lr (v4|v5), r11 (v6); results to [r1], r1 += 8.
    macro_rules! pair {
        () => {
            "ldmia r0!, {{r4-r10}}\n\
             smuad r4, r4, r3\n\
             smuad r7, r7, r3\n\
             smlad r4, r5, r12, r4\n\
             smlad r7, r8, r12, r7\n\
             smlad r4, r6, lr, r4\n\
             smlad r7, r9, lr, r7\n\
             smlabb r4, r10, r11, r4\n\
             smlatb r7, r10, r11, r7\n\
             strd r4, r7, [r1], #8\n"
        };
    }

    /// # Safety
    /// `w` holds `pairs * 7` words, `v` 4 words, `acc` `2 * pairs` i32.
    // Inlined into its caller, so a non-inlined caller (the firmware's
    // per-point function) is the one symbol that holds the whole kernel.
    #[inline(always)]
    pub(super) unsafe fn q15_m7(w: *const u32, v: *const u32, acc: *mut i32, pairs: usize) {
        // SAFETY: the caller guarantees the buffers; r6/r7 (reserved by LLVM)
        // are saved and restored around their use; everything else used is
        // declared clobbered.
        unsafe {
            core::arch::asm!(
                "push {{r6, r7}}",
                "ldr r12, [r3, #4]",
                "ldr lr, [r3, #8]",
                "ldr r11, [r3, #12]",
                "ldr r3, [r3]",
                "subs r2, r2, #8",          // r2 = pairs left - 8
                "blo 2f",
                "1:",                       // blocks of 8 pairs
                pair!(), pair!(), pair!(), pair!(), pair!(), pair!(), pair!(), pair!(),
                "subs r2, r2, #8",
                "bhs 1b",
                "2:",
                "adds r2, r2, #8",          // remaining pairs, 0..7
                "beq 4f",
                "3:",
                pair!(),
                "subs r2, r2, #1",
                "bne 3b",
                "4:",
                "pop {{r6, r7}}",
                inout("r0") w => _,
                inout("r1") acc => _,
                inout("r2") pairs => _,
                inout("r3") v => _,
                out("r4") _, out("r5") _, out("r8") _, out("r9") _, out("r10") _,
                out("r11") _, out("r12") _, out("lr") _,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> f32 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }

    /// Unpacks the packed Q15 W back to n x m integers (independent of the kernel).
    fn unpack_w(p: &[u32], n: usize, m: usize) -> std::vec::Vec<i32> {
        let mut out = std::vec![0; n * m];
        let half = m / 2;
        for j in 0..n {
            let (r, b) = (j / 2, j % 2);
            let words = &p[r * m..(r + 1) * m];
            for i in 0..m {
                let word = if m % 2 == 1 && i == m - 1 { words[m - 1] } else { words[b * half + i / 2] };
                let take_hi = if m % 2 == 1 && i == m - 1 { b == 1 } else { i % 2 == 1 };
                out[j * m + i] = if take_hi { hi(word) } else { lo(word) };
            }
        }
        out
    }

    #[test]
    fn q15_kernel_equals_exact_integer_dot_products() {
        let mut seed = 7;
        for (n, m) in [(81usize, 7usize), (80, 7), (9, 3), (10, 8), (5, 1), (33, 15), (1, 2)] {
            let w: std::vec::Vec<f32> = (0..n * m).map(|_| lcg(&mut seed) * 40.0).collect();
            let v: std::vec::Vec<f32> = (0..m).map(|_| lcg(&mut seed).abs() * 300.0).collect();
            let mut pw = std::vec![0u32; q15_w_words(n, m)];
            let mut inv = std::vec![0f32; n];
            quantise_w_q15(&w, n, m, &mut pw, &mut inv);
            let mut pv = std::vec![0u32; q15_v_words(m)];
            let k = quantise_v_q15(&v, &mut pv);
            let vq: std::vec::Vec<i64> =
                (0..m).map(|i| if i % 2 == 0 { lo(pv[i / 2]) } else { hi(pv[i / 2]) } as i64).collect();
            let wq = unpack_w(&pw, n, m);
            let mut acc = std::vec![0i32; q15_acc_len(n)];
            mat_vec_q15(&pw, &pv, m, &mut acc);
            for j in 0..n {
                let l1: i64 = (0..m).map(|i| (wq[j * m + i] as i64).abs()).sum();
                assert!(l1 <= 65534, "row {j} L1 {l1}");
                let exact: i64 = (0..m).map(|i| wq[j * m + i] as i64 * vq[i]).sum();
                assert_eq!(acc[j] as i64, exact, "n={n} m={m} row {j}");
                // The quantised value is the row scaled, within half an LSB.
                for i in 0..m {
                    let back = wq[j * m + i] as f64 * inv[j] as f64;
                    let tol = 0.5 * inv[j] as f64 + 2f64.powi(-22) * (w[j * m + i] as f64).abs();
                    assert!((back - w[j * m + i] as f64).abs() <= tol, "W[{j}][{i}]");
                }
            }
            if n % 2 == 1 {
                assert_eq!(acc[n], 0, "padding row");
            }
            for i in 0..m {
                assert!((vq[i] as f64 * 2f64.powi(-k) - v[i] as f64).abs() <= 2f64.powi(-k));
            }
        }
    }

    #[test]
    fn q15_worst_case_does_not_overflow() {
        // Every element at the bound, same sign, readings at full scale: the
        // largest possible accumulator.
        for m in [1usize, 2, 3, 7, 8, 15] {
            let n = 3;
            let w = std::vec![1.0f32; n * m];
            let v = std::vec![1.9999999f32; m];
            let mut pw = std::vec![0u32; q15_w_words(n, m)];
            let mut inv = std::vec![0f32; n];
            quantise_w_q15(&w, n, m, &mut pw, &mut inv);
            let mut pv = std::vec![0u32; q15_v_words(m)];
            quantise_v_q15(&v, &mut pv);
            let mut acc = std::vec![0i32; q15_acc_len(n)];
            mat_vec_q15(&pw, &pv, m, &mut acc);
            let wq = unpack_w(&pw, n, m);
            let exact: i64 = (0..m).map(|i| wq[i] as i64 * 32767).sum();
            assert_eq!(acc[0] as i64, exact);
            assert!(exact > 2_000_000_000 || m < 3, "m={m}: the bound is tight ({exact})");
            let mut rho = std::vec![0f32; n];
            dequantise_q15(&acc, &inv, 0, &mut rho);
            // sum_i 1 * 2 = 2m, scaled back.
            let k = quantise_v_q15(&v, &mut pv);
            dequantise_q15(&acc, &inv, k, &mut rho);
            assert!((rho[0] as f64 - 2.0 * m as f64).abs() < 1e-3 * m as f64, "m={m}: {}", rho[0]);
        }
    }

    #[test]
    fn q15_error_is_within_the_derived_bound() {
        let mut seed = 99;
        let (n, m) = (81, 7);
        for trial in 0..200 {
            // Wiener-like rows: mixed signs, a few large coefficients.
            let w: std::vec::Vec<f32> =
                (0..n * m).map(|_| lcg(&mut seed) * if trial % 3 == 0 { 500.0 } else { 3.0 }).collect();
            let scale = if trial % 2 == 0 { 1.0 } else { 1e-3 };
            let v: std::vec::Vec<f32> = (0..m).map(|_| (lcg(&mut seed).abs() + 0.01) * 200.0 * scale).collect();
            let mut pw = std::vec![0u32; q15_w_words(n, m)];
            let mut inv = std::vec![0f32; n];
            quantise_w_q15(&w, n, m, &mut pw, &mut inv);
            let mut pv = std::vec![0u32; q15_v_words(m)];
            let k = quantise_v_q15(&v, &mut pv);
            let mut acc = std::vec![0i32; q15_acc_len(n)];
            mat_vec_q15(&pw, &pv, m, &mut acc);
            let mut rho = std::vec![0f32; n];
            dequantise_q15(&acc, &inv, k, &mut rho);
            let mut worst = 0.0f64;
            for j in 0..n {
                let exact: f64 = (0..m).map(|i| w[j * m + i] as f64 * v[i] as f64).sum();
                let err = (rho[j] as f64 - exact).abs();
                let bound = q15_error_bound(&w, &v, &inv, k, rho[j], j);
                assert!(err <= bound, "trial {trial} row {j}: error {err:e} > bound {bound:e}");
                worst = worst.max(err / bound);
            }
            // The bound is not vacuous: errors reach a visible part of it.
            if trial == 0 {
                assert!(worst > 0.01, "bound far too loose: {worst}");
            }
        }
    }
}
