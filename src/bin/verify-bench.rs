//! Signature verify bench firmware for QEMU (b-l475e-iot01a): verifies two
//! signed messages by the DEVELOPMENT key (NOT FOR PRODUCTION) with the
//! device's own `brdf_meter::signed::verify`, so `scripts/verify-bench.sh`
//! can count the instructions of each verify exactly from QEMU's execution
//! trace: a 3-byte message (the fixed cost: decompressing the key and the
//! double scalar multiplication) and a 10 KiB message, about a calibration
//! blob's size (adds SHA-512 over the message).
//!
//! Each measured call sits between two calls of [`verify_bench_mark`]. The
//! exit status is success only if both signatures verify and a changed
//! message does not (outside the marks).
#![no_std]
#![no_main]
use brdf_meter::signed::{self, SignatureFault, TRAILER_LEN, Trailer};
use cortex_m_rt::entry;
use cortex_m_semihosting::debug;

/// Length of the long message.
const LONG: usize = 10240;

/// Made with Python's `cryptography` from the development key's seed, over
/// b"abc" and over the long message below (byte i = ((131 i + 7) >> 3) & 0xff).
const SIG_SHORT: &str = "9848ecc21b368f6ec8106466df0ff6429e93e05fe2717c47f3106881a2c19959842270c60da5ef7553f2bc87389c353afce6e6d17405bfba1e9cc266f42caf03";
const SIG_LONG: &str = "ee68686f79e750c4ba9c0fa56c591f5c6ce8f73d56e5bd38334a58e4189035e5c1bbf43d2010ad96807a6027408a9f0dbd7614d4587505ba5462d9226adc5f05";

static mut IMAGE: [u8; LONG + TRAILER_LEN] = [0; LONG + TRAILER_LEN];

/// A segment boundary for the trace counter. Never inlined: its address is
/// what the script looks for.
#[inline(never)]
#[unsafe(no_mangle)]
pub fn verify_bench_mark() {
    // SAFETY: a plain no-op.
    unsafe { core::arch::asm!("nop", options(nomem, nostack)) };
}

fn unhex(s: &str) -> [u8; 64] {
    let b = s.as_bytes();
    let d = |c: u8| if c <= b'9' { c - b'0' } else { c - b'a' + 10 };
    core::array::from_fn(|i| d(b[2 * i]) << 4 | d(b[2 * i + 1]))
}

/// `msg` followed by the development key's trailer with `sig`, into `out`.
fn image<'a>(out: &'a mut [u8], msg_len: usize, sig: &str) -> &'a [u8] {
    let pk = signed::TRUSTED_KEYS[0];
    let t = signed::encode_trailer(&Trailer { key_id: signed::key_id(&pk), signature: unhex(sig) });
    out[msg_len..msg_len + TRAILER_LEN].copy_from_slice(&t);
    &out[..msg_len + TRAILER_LEN]
}

#[entry]
fn main() -> ! {
    // SAFETY: single-threaded firmware, no interrupts use this static.
    let buf = unsafe { &mut *core::ptr::addr_of_mut!(IMAGE) };
    let keys = signed::TRUSTED_KEYS;
    buf[..3].copy_from_slice(b"abc");
    let short = image(buf, 3, SIG_SHORT);
    verify_bench_mark();
    let r1 = signed::verify(short, keys);
    verify_bench_mark();
    let ok1 = r1 == Ok(&b"abc"[..]);

    for (i, b) in buf[..LONG].iter_mut().enumerate() {
        *b = ((i * 131 + 7) >> 3) as u8;
    }
    let long = image(buf, LONG, SIG_LONG);
    verify_bench_mark();
    let r2 = signed::verify(long, keys);
    verify_bench_mark();
    let ok2 = r2.map(|m| m.len()) == Ok(LONG);

    buf[100] ^= 1;
    let ok3 = signed::verify(&buf[..LONG + TRAILER_LEN], keys) == Err(SignatureFault::BadSignature);
    debug::exit(if ok1 && ok2 && ok3 { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    halt()
}

fn halt() -> ! {
    loop {
        // SAFETY: wait for an interrupt; nothing else.
        unsafe { core::arch::asm!("wfi", options(nomem, nostack)) };
    }
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo<'_>) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    halt()
}
