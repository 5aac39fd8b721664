//! The bootloader's platform (feature `bootloader-board` or
//! `bootloader-qemu`, bare-metal target only): the flash it swaps on, and the
//! jump into the active image. What it does between the two is the library's
//! [`crate::firmware::boot::prepare`], which the host simulation runs too.
#[cfg(feature = "bootloader-board")]
pub mod board;
#[cfg(feature = "bootloader-qemu")]
pub mod qemu;

/// Starts the image whose vector table is at `addr`: points VTOR at it,
/// loads its initial stack pointer and jumps to its reset handler (what
/// embassy-boot-stm32's `BootLoader::load` does, without its HAL).
///
/// # Safety
/// `addr` holds a vector table of an image linked to run there.
pub unsafe fn start_image(addr: u32) -> ! {
    // SAFETY: the caller vouches for the vector table; nothing of the
    // bootloader runs after the jump.
    unsafe {
        let scb = &*cortex_m::peripheral::SCB::PTR;
        scb.vtor.write(addr);
        cortex_m::asm::bootload(addr as *const u32)
    }
}
