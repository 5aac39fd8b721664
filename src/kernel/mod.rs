//! The estimator kernels: `rho = W v`, one matrix-vector product per point,
//! in the forms the device runs and the host reproduces bit for bit.
//!
//! - [`f32`](mod@self::f32): the f32 kernel (what the firmware runs per point; Cortex-M4F
//!   assembly for m = 7), on nalgebra's fixed-size types and on slices.
//! - [`q15`]: the fixed-point (Q15) kernel, its quantisation and error bound.
//! - [`cluster`]: the clustered estimator's choice of matrix per point.
//!
//! Every form keeps a fixed accumulation order so host and device agree to the
//! bit; the module docs of each say how.
pub mod cluster;
pub mod f32;
pub mod q15;
pub mod scale_free;

pub use self::cluster::select_cluster;
pub use self::f32::{mat_vec_f32, mat_vec_f32_4, mat_vec_f32_into, mat_vec_f32_slice};
pub use self::q15::*;

/// The root form's scales (`crate::blob`'s flag bit 3) for readings of
/// scale `s`: `(sqrt(s), 1 / sqrt(s))`. The kernel's input times the second
/// gives `t / sqrt(s)`, whose square is the estimate `t^2 / s`; readings of
/// no light (`s <= 0`) give `(0, 0)`: an estimate of 0, not a division by zero.
#[inline]
pub fn root_scales(s: f32) -> (f32, f32) {
    if s > 0.0 {
        let r = sqrt0(s);
        (r, 1.0 / r)
    } else {
        (0.0, 0.0)
    }
}

/// The root form's first step: the kernel's input times
/// [`root_scales`]' second (m multiplies, not one per value).
#[inline]
pub fn scale_input(x: &mut [f32], r: f32) {
    for e in x.iter_mut() {
        *e *= r;
    }
}

/// The root form's last step: each of the kernel's outputs squared in
/// place, so no value is negative.
#[inline]
pub fn square_in_place(t: &mut [f32]) {
    for e in t.iter_mut() {
        *e *= *e;
    }
}

/// `sqrt(max(x, 0))`, IEEE-exact on both sides: the M4's `VSQRT` on the
/// device, libm (correctly rounded) elsewhere.
#[inline]
pub fn sqrt0(x: f32) -> f32 {
    let x = if x > 0.0 { x } else { 0.0 };
    #[cfg(all(target_arch = "arm", target_os = "none", target_abi = "eabihf"))]
    {
        // Through core registers: naming an FPU register needs the `vfp2`
        // target feature, which rustc does not expose on stable.
        let bits: u32;
        // SAFETY: one FPU instruction on a register moved in and out, no memory access.
        unsafe {
            core::arch::asm!(
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {r}, s0",
                x = in(reg) x.to_bits(),
                r = lateout(reg) bits,
                out("s0") _,
                options(pure, nomem, nostack)
            )
        };
        f32::from_bits(bits)
    }
    #[cfg(not(all(target_arch = "arm", target_os = "none", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}
