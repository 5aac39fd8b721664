//! A stack that overflows, under QEMU (b-l475e-iot01a), to show where an
//! overflow ends on this memory map: the stack sits at the start of SRAM1,
//! below the statics (memory.x), so a recursion without end runs off the
//! start of SRAM1 into addresses that hold no memory and faults there; the
//! core cannot take the fault on that stack either and locks up (QEMU stops
//! with "Lockup", the board's watchdog resets it). The statics are never
//! written.
//!
//! A kilobyte of canary in .uninit, the highest of the statics
//! (cortex-m-rt places .data, .bss, then .uninit), is checked word by word
//! at every level of the recursion: on a map with the stack above the
//! statics (cortex-m-rt's default) the recursion writes over it first, and
//! as each level's frame is a hundred bytes, some level finds a word
//! overwritten with a kilobyte of RAM still below, says so over semihosting
//! and exits with a failure (one word could sit where every frame leaves a
//! gap).
//! Returning at all is a failure too. The test `qemu_stack_overflow` runs it (feature `qemu`, profile
//! firmware; linked from the reset vector like the QEMU benches, no
//! bootloader in front).
#![no_std]
#![no_main]

use core::sync::atomic::{AtomicU32, Ordering};
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hio};

/// The canary's value.
const ALIVE: u32 = 0x5AFE_57AC;
/// The highest statics: set in `main` (.uninit is not initialised at reset).
#[unsafe(link_section = ".uninit.stack_overflow_probe")]
static CANARY: [AtomicU32; 256] = [const { AtomicU32::new(0) }; 256];

#[entry]
fn main() -> ! {
    for word in &CANARY {
        word.store(ALIVE, Ordering::SeqCst);
    }
    say(b"stack-overflow-probe: descending\n");
    let sum = descend(0);
    say(b"stack-overflow-probe: FAILED: the recursion returned\n");
    core::hint::black_box(sum);
    exit_failure()
}

/// One level: a frame the compiler cannot drop, the canary checked, and
/// the next level.
#[inline(never)]
fn descend(depth: u32) -> u32 {
    let mut frame = [depth; 16];
    core::hint::black_box(&mut frame);
    if CANARY.iter().any(|word| word.load(Ordering::SeqCst) != ALIVE) {
        say(b"stack-overflow-probe: FAILED: the stack overwrote the statics\n");
        exit_failure();
    }
    descend(depth.wrapping_add(1)).wrapping_add(frame[depth as usize % 16])
}

fn say(msg: &[u8]) {
    if let Ok(mut err) = hio::hstderr() {
        let _ = err.write_all(msg);
    }
}

fn exit_failure() -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo<'_>) -> ! {
    say(b"stack-overflow-probe: panic\n");
    exit_failure()
}
