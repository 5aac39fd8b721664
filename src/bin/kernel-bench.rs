//! Kernel bench firmware for QEMU (b-l475e-iot01a): runs the device's
//! estimation kernels on fixed inputs and prints inputs and results over
//! semihosting, so that `scripts/kernel-bench.sh` can count each kernel's
//! instructions exactly from QEMU's execution trace and `host-tools tradeoff`
//! can check the results bit for bit against the host.
//!
//! Each measured call sits between two calls of [`mark`]; the script counts
//! the instructions executed between consecutive marks (the mark function's
//! own instructions excluded). The order of the segments is printed as
//! `SEG <name>` lines before the run.
//!
//! Build and run: `scripts/kernel-bench.sh` (feature `kernel-bench`,
//! target thumbv7em-none-eabihf, profile firmware).
#![no_std]
#![no_main]

use brdf_meter::kernel;
use brdf_meter::nalgebra::{ArrayStorage, SMatrix, SVector};
use brdf_meter::shape;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hio};

const N: usize = shape::BINS;
const M: usize = shape::LEDS;
const POINTS: usize = 3;
const KMAX: usize = 16;

/// A line buffer written to the semihosting console with SYS_WRITE0 (what
/// QEMU's `-semihosting-config chardev=` captures; writes to a `:tt` handle
/// go to QEMU's own stdout instead).
struct Line {
    buf: [u8; 160],
    len: usize,
}

impl Line {
    const fn new() -> Self {
        Self { buf: [0; 160], len: 0 }
    }
    fn push(&mut self, s: &[u8]) {
        for &b in s {
            if self.len + 2 >= self.buf.len() {
                self.flush_keep();
            }
            self.buf[self.len] = b;
            self.len += 1;
        }
    }
    fn hex(&mut self, x: u32) {
        let mut d = [0u8; 9];
        for (k, c) in d[..8].iter_mut().enumerate() {
            let nib = (x >> (28 - 4 * k)) & 0xf;
            *c = if nib < 10 { b'0' + nib as u8 } else { b'a' + nib as u8 - 10 };
        }
        d[8] = b' ';
        self.push(&d);
    }
    fn flush_keep(&mut self) {
        self.buf[self.len] = 0;
        // SAFETY: SYS_WRITE0 takes a NUL-terminated string: `buf` holds one
        // (push keeps a byte free for the NUL).
        unsafe { cortex_m_semihosting::syscall1!(WRITE0, self.buf.as_ptr()) };
        self.len = 0;
    }
    fn end(&mut self) {
        self.push(b"\n");
        self.flush_keep();
    }
}

/// A segment boundary for the trace counter. Never inlined: its address is
/// what the script looks for.
#[inline(never)]
#[unsafe(no_mangle)]
pub fn kernel_bench_mark() {
    // SAFETY: a plain no-op.
    unsafe { core::arch::asm!("nop", options(nomem, nostack)) };
}

#[inline(never)]
#[unsafe(no_mangle)]
pub fn kernel_bench_f32(wt: &SMatrix<f32, M, N>, v: &SVector<f32, M>, out: &mut SVector<f32, N>) {
    kernel::mat_vec_f32_into(wt.as_view(), v, out);
}

#[inline(never)]
#[unsafe(no_mangle)]
pub fn kernel_bench_quantise_v(v: &[f32; M], vq: &mut [u32; kernel::q15_v_words(M)]) -> i32 {
    kernel::quantise_v_q15(v, vq)
}

#[inline(never)]
#[unsafe(no_mangle)]
pub fn kernel_bench_q15(
    w: &[u32; kernel::q15_w_words(N, M)],
    vq: &[u32; kernel::q15_v_words(M)],
    acc: &mut [i32; kernel::q15_acc_len(N)],
) {
    kernel::mat_vec_q15(w, vq, M, acc);
}

#[inline(never)]
#[unsafe(no_mangle)]
pub fn kernel_bench_dequantise(acc: &[i32; kernel::q15_acc_len(N)], inv: &[f32; N], k: i32, out: &mut [f32; N]) {
    kernel::dequantise_q15(&acc[..N], inv, k, out);
}

/// The affine estimator's constant term: `out += b` (n adds).
#[inline(never)]
#[unsafe(no_mangle)]
pub fn kernel_bench_offset(out: &mut [f32; N], b: &SVector<f32, N>) {
    for (o, x) in out.iter_mut().zip(b.as_slice()) {
        *o += *x;
    }
}

#[inline(never)]
#[unsafe(no_mangle)]
pub fn kernel_bench_select(c: &[f32], v: &[f32; M]) -> usize {
    kernel::select_cluster(c, v)
}

struct Lcg(u32);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (self.0 >> 8) as f32 / (1u32 << 24) as f32
    }
}

/// W transposed (M x N): the blob's row-major n x m in memory.
static mut W: SMatrix<f32, M, N> = SMatrix::from_array_storage(ArrayStorage([[0.0; M]; N]));
static mut WQ: [u32; kernel::q15_w_words(N, M)] = [0; kernel::q15_w_words(N, M)];
static mut INV: [f32; N] = [0.0; N];
static mut CENTROIDS: [f32; KMAX * M] = [0.0; KMAX * M];

#[entry]
fn main() -> ! {
    // SAFETY: single-threaded firmware, no interrupts use these statics.
    let (w, wq, inv, cents) = unsafe {
        (
            &mut *core::ptr::addr_of_mut!(W),
            &mut *core::ptr::addr_of_mut!(WQ),
            &mut *core::ptr::addr_of_mut!(INV),
            &mut *core::ptr::addr_of_mut!(CENTROIDS),
        )
    };
    let mut rng = Lcg(12345);
    // Column-major: W's rows in turn, as the blob stores them.
    for x in w.iter_mut() {
        *x = (rng.next() - 0.5) * 60.0;
    }
    for c in cents.iter_mut() {
        *c = rng.next() / M as f32 * 2.0;
    }
    let mut line = Line::new();
    // Segment order, then the inputs.
    line.push(b"SEG quantise_w");
    line.end();
    for p in 0..POINTS {
        for name in [&b"gen"[..], b"f32", b"quantise_v", b"q15", b"dequantise", b"offset"] {
            line.push(b"SEG ");
            line.push(name);
            line.push(b" ");
            line.hex(p as u32);
            line.end();
        }
        for k in 1..=KMAX {
            line.push(b"SEG select ");
            line.hex(p as u32);
            line.hex(k as u32);
            line.end();
        }
    }
    line.push(b"W ");
    for x in w.iter() {
        line.hex(x.to_bits());
    }
    line.end();
    line.push(b"C ");
    for x in cents.iter() {
        line.hex(x.to_bits());
    }
    line.end();

    // Load-time quantisation (as the device does when it activates a blob).
    kernel_bench_mark();
    kernel::quantise_w_q15(w.as_slice(), N, M, wq, inv);
    kernel_bench_mark();

    let mut out = SVector::<f32, N>::zeros();
    let mut acc = [0i32; kernel::q15_acc_len(N)];
    let mut rho_q = [0.0f32; N];
    for p in 0..POINTS {
        // Readings spanning magnitudes (the Q15 block exponent varies).
        let scale = [1.0f32, 37.5, 0.003][p];
        let v: [f32; M] = core::array::from_fn(|_| (rng.next() + 0.05) * scale);
        // The offset bench adds the f32 result to this (a stand-in for b).
        let mut shifted: [f32; N] = core::array::from_fn(|j| v[j % M]);
        // Outside the marks: the f32 segment counts the kernel call only.
        let v_vec = SVector::from(v);
        kernel_bench_mark();
        kernel_bench_f32(w, &v_vec, &mut out);
        kernel_bench_mark();
        let mut vq = [0u32; kernel::q15_v_words(M)];
        let k = kernel_bench_quantise_v(&v, &mut vq);
        kernel_bench_mark();
        kernel_bench_q15(wq, &vq, &mut acc);
        kernel_bench_mark();
        kernel_bench_dequantise(&acc, inv, k, &mut rho_q);
        kernel_bench_mark();
        kernel_bench_offset(&mut shifted, &out);
        kernel_bench_mark();
        let mut sel = [0usize; KMAX];
        for (kk, s) in sel.iter_mut().enumerate() {
            *s = kernel_bench_select(&cents[..(kk + 1) * M], &v);
            kernel_bench_mark();
        }
        line.push(b"V ");
        for x in v {
            line.hex(x.to_bits());
        }
        line.end();
        line.push(b"OUT ");
        for x in out.iter() {
            line.hex(x.to_bits());
        }
        line.end();
        line.push(b"ACC ");
        line.hex(k as u32);
        for x in acc {
            line.hex(x as u32);
        }
        line.end();
        line.push(b"OFS ");
        for x in shifted {
            line.hex(x.to_bits());
        }
        line.end();
        line.push(b"RHOQ ");
        for x in rho_q {
            line.hex(x.to_bits());
        }
        line.end();
        line.push(b"SEL ");
        for s in sel {
            line.hex(s as u32);
        }
        line.end();
    }
    line.push(b"DONE");
    line.end();
    debug::exit(debug::EXIT_SUCCESS);
    halt()
}

/// After a semihosting exit QEMU has stopped; on anything else, wait here.
fn halt() -> ! {
    loop {
        // SAFETY: wait for an interrupt; nothing else.
        unsafe { core::arch::asm!("wfi", options(nomem, nostack)) };
    }
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo<'_>) -> ! {
    if let Ok(mut err) = hio::hstderr() {
        let _ = err.write_all(b"kernel-bench panic\n");
    }
    debug::exit(debug::EXIT_FAILURE);
    halt()
}
