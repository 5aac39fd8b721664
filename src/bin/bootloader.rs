//! The bootloader (embassy-boot) for the B-L475E-IOT01A (feature
//! `bootloader-board`, `cargo bootloader`) and for QEMU's b-l475e-iot01a
//! (feature `bootloader-qemu`, `cargo qemu-bootloader`). It sits at the
//! chip's reset vector (memory.x's BOOTLOADER, 24 KiB), runs the library's
//! `firmware::boot::prepare` (swap a marked update in, or revert a trial
//! that did not confirm) and starts the active image.
//!
//! A bootloader that cannot prepare (a flash error mid-swap) resets instead
//! of starting a half-swapped image: the swap records its progress per page,
//! so the next attempt resumes where this one stopped.
#![no_std]
#![no_main]

use brdf_meter::platform::bootloader::start_image;
use brdf_meter::shape::board::ACTIVE;
use cortex_m_rt::entry;

#[entry]
fn main() -> ! {
    #[cfg(feature = "bootloader-board")]
    let prepared = brdf_meter::platform::bootloader::board::prepare();
    #[cfg(feature = "bootloader-qemu")]
    let prepared = {
        use brdf_meter::platform::bootloader::qemu::Rom;
        use brdf_meter::shape::board as map;
        let mut buf = [0u8; brdf_meter::firmware::boot::SWAP_BUFFER];
        brdf_meter::firmware::boot::prepare(
            Rom::new(map::ACTIVE, map::ACTIVE_LEN),
            Rom::new(map::DFU, map::DFU_LEN),
            Rom::new(map::BOOT_STATE, map::BOOT_STATE_LEN),
            &mut buf,
        )
    };
    if prepared.is_err() {
        cortex_m::peripheral::SCB::sys_reset();
    }
    // SAFETY: memory.x links every application at ACTIVE, vector table first.
    unsafe { start_image(ACTIVE) }
}

/// A panic in the bootloader resets the chip (there is no one to tell; the
/// next attempt may succeed, and embassy-boot's swap resumes where it was).
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    cortex_m::peripheral::SCB::sys_reset()
}
