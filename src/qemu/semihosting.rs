//! ARM semihosting (QEMU runs with `-semihosting-config enable=on`): the panic
//! message goes to QEMU's stderr and the exit code to the QEMU process, so a
//! firmware panic fails the test that ran it instead of hanging it.
use core::fmt::Write;

const SYS_WRITE0: usize = 0x04;
const SYS_EXIT: usize = 0x18;
const ADP_STOPPED_RUNTIME_ERROR: usize = 0x20023;

fn call(op: usize, arg: usize) {
    // SAFETY: the semihosting ABI: op in r0, argument in r1, BKPT 0xAB.
    unsafe { core::arch::asm!("bkpt 0xAB", inout("r0") op => _, in("r1") arg, options(nostack)) };
}

/// Writes `s` (NUL appended here) to the host's stderr.
pub fn write_str(s: &str) {
    let mut buf = heapless::Vec::<u8, 256>::new();
    let _ = buf.extend_from_slice(&s.as_bytes()[..s.len().min(255)]);
    let _ = buf.push(0);
    call(SYS_WRITE0, buf.as_ptr() as usize);
}

/// Ends QEMU with a failure exit code.
pub fn exit_failure() -> ! {
    call(SYS_EXIT, ADP_STOPPED_RUNTIME_ERROR);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m::interrupt::disable();
    let mut s = heapless::String::<250>::new();
    let _ = writeln!(s, "qemu-fw panic: {info}");
    write_str(&s);
    exit_failure()
}
