//! What the QEMU bench firmwares (line bench, inspection bench) share: a
//! host file read over semihosting and its little-endian fields, lines printed on the semihosting
//! console, failing with a message, halting. Included by each bench with
//! `#[path]` (a folder without `main.rs` is no binary of its own).
use cortex_m_semihosting::{debug, hio};

/// The little-endian u32 at byte `at` of a bench's data file.
pub fn u32_at(d: &[u8], at: usize) -> usize {
    u32::from_le_bytes([d[at], d[at + 1], d[at + 2], d[at + 3]]) as usize
}

/// A segment boundary for the trace counter (`host-tools`' `count_segments`
/// looks for this symbol). Never inlined: its address is what it looks for.
#[inline(never)]
#[unsafe(no_mangle)]
pub fn bench_mark() {
    // SAFETY: a plain no-op.
    unsafe { core::arch::asm!("nop", options(nomem, nostack)) };
}

/// A bench's input file, 4-byte aligned (a calibration read in place).
#[repr(C, align(4))]
pub struct Aligned<const N: usize>(pub [u8; N]);

/// Reads a host file (path NUL-terminated, relative to QEMU's working
/// directory) over semihosting; returns the bytes read.
pub fn read_file(path: &[u8], buf: &mut [u8]) -> usize {
    // SAFETY: semihosting calls with valid pointers and lengths.
    unsafe {
        let fd = cortex_m_semihosting::syscall!(
            OPEN,
            path.as_ptr(),
            cortex_m_semihosting::nr::open::R_BINARY,
            path.len() - 1
        );
        if fd == usize::MAX {
            fail(b"bench: cannot open its data file (see the bench's docs for the command that writes it)");
        }
        let left = cortex_m_semihosting::syscall!(READ, fd, buf.as_mut_ptr(), buf.len());
        cortex_m_semihosting::syscall!(CLOSE, fd);
        buf.len() - left
    }
}

/// A line written to the semihosting console with SYS_WRITE0.
pub struct Line {
    buf: [u8; 96],
    len: usize,
}

impl Line {
    pub const fn new() -> Self {
        Self { buf: [0; 96], len: 0 }
    }
    pub fn push(&mut self, s: &[u8]) {
        for &c in s {
            if self.len + 2 < self.buf.len() {
                self.buf[self.len] = c;
                self.len += 1;
            }
        }
    }
    pub fn num(&mut self, mut x: u32) {
        let mut d = [0u8; 10];
        let mut k = d.len();
        loop {
            k -= 1;
            d[k] = b'0' + (x % 10) as u8;
            x /= 10;
            if x == 0 {
                break;
            }
        }
        self.push(&d[k..]);
    }
    pub fn end(&mut self) {
        self.push(b"\n");
        self.buf[self.len] = 0;
        // SAFETY: SYS_WRITE0 takes a NUL-terminated string: `buf` holds one.
        unsafe { cortex_m_semihosting::syscall1!(WRITE0, self.buf.as_ptr()) };
        self.len = 0;
    }
}

/// Closes the last segment (each boundary opens one), tells the host the
/// run is complete and ends QEMU with success.
pub fn done() -> ! {
    bench_mark();
    let mut l = Line::new();
    l.push(b"DONE");
    l.end();
    debug::exit(debug::EXIT_SUCCESS);
    halt()
}

/// Prints `msg` on the host's stderr and ends QEMU with a failure.
pub fn fail(msg: &[u8]) -> ! {
    if let Ok(mut err) = hio::hstderr() {
        let _ = err.write_all(msg);
        let _ = err.write_all(b"\n");
    }
    debug::exit(debug::EXIT_FAILURE);
    halt()
}

/// After a semihosting exit QEMU has stopped; on anything else, wait here.
pub fn halt() -> ! {
    loop {
        // SAFETY: wait for an interrupt; nothing else.
        unsafe { core::arch::asm!("wfi", options(nomem, nostack)) };
    }
}
