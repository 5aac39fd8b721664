//! The instrument's build-time shape and flash geometry, written down once.
//!
//! Every firmware (board-fw, qemu-fw, kernel-bench), the host simulation
//! (tests/), the firmware budget check and factory provisioning (host-tools)
//! take these numbers from here. `memory.x` stays the linker's own file; the
//! board firmware checks the linker's slot symbols against [`board`] at boot,
//! and host-tools checks its parse of memory.x against it in its tests.

/// Angle bins of the estimated BRDF, `n` (the patent profile's 81).
pub const BINS: usize = 81;
/// LEDs fitted and readings per point, `m`.
pub const LEDS: usize = 7;
/// Frames per line: one dark frame, then one per LED.
pub const FRAMES_PER_LINE: usize = LEDS + 1;
/// Gloss readings streamed with every point (specular gloss, haze,
/// distinctness; their order and definitions: `crate::gloss`).
pub const READINGS: usize = 3;

/// NOR erase unit of the STM32L475VG's flash (and of every flash fake).
pub const FLASH_PAGE: usize = 2048;
/// NOR program unit (a double word) of the STM32L475VG's flash.
pub const FLASH_WRITE: usize = 8;
/// Address of the chip's flash in the memory map.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// Size of the chip's flash.
pub const FLASH_SIZE: u32 = 1024 * 1024;

/// The B-L475E-IOT01A board firmware (memory.x holds the same map).
pub mod board {
    /// Pixels of the line sensor, `P`.
    pub const PIXELS: usize = 128;
    /// Largest calibration the product runs: one zone per pixel.
    pub const MAX_ZONES: usize = PIXELS;
    /// Zones whose matrices are copied to RAM (8 x 81 x 7 f32 = 18 KiB); a
    /// calibration with more zones runs in place from its flash slot.
    pub const RAM_ZONES: usize = 8;
    /// Flash for the firmware image, from [`super::FLASH_BASE`].
    pub const IMAGE_LEN: u32 = 256 * 1024;
    /// Calibration slot A (right after the image).
    pub const SLOT_A: u32 = super::FLASH_BASE + IMAGE_LEN;
    /// Length of one calibration slot: a Z = 128 blob fits.
    pub const SLOT_LEN: u32 = 384 * 1024;
    /// Calibration slot B (right after slot A).
    pub const SLOT_B: u32 = SLOT_A + SLOT_LEN;
    /// One slot of the board tests' own calibration store (bin
    /// `board-tests`): room for their 2-zone test calibration.
    pub const TEST_SLOT_LEN: u32 = 8 * super::FLASH_PAGE as u32;
    /// Where the board tests' two store slots start: the top of the image
    /// region, below slot A. Only the test image (which checks at start that
    /// it ends below this) uses it, and flashing board-fw again overwrites it;
    /// the calibration slots are never touched by the tests.
    pub const TEST_REGION: u32 = SLOT_A - 2 * TEST_SLOT_LEN;
    /// SRAM1 (statics, stack, the RAM zone buffer).
    pub const RAM_ORIGIN: u32 = 0x2000_0000;
    /// Size of SRAM1.
    pub const RAM_LEN: u32 = 96 * 1024;

    const _: () = assert!(SLOT_B + SLOT_LEN <= super::FLASH_BASE + super::FLASH_SIZE);
    const _: () = assert!(TEST_REGION > super::FLASH_BASE && (TEST_REGION as usize).is_multiple_of(super::FLASH_PAGE));
    const _: () = assert!(
        (SLOT_LEN as usize).is_multiple_of(super::FLASH_PAGE) && (SLOT_A as usize).is_multiple_of(super::FLASH_PAGE)
    );
}

/// The QEMU firmware and the host simulation of it (same sizes, so the tests
/// of one hold for the other).
pub mod qemu {
    /// Pixels of the simulated line sensor.
    pub const PIXELS: usize = 32;
    /// Zones whose matrices are copied to RAM (9 KiB); larger calibrations
    /// run in place from the (RAM-backed) slot.
    pub const RAM_ZONES: usize = 4;
    /// Calibration slot length: 8 pages, room for a blob of 6 zones.
    pub const SLOT_LEN: u32 = 8 * super::FLASH_PAGE as u32;
    /// Scene lines the simulated sensor holds.
    pub const FRAME_LINES: usize = 4;
    /// The simulated converter's full scale: the board's 12-bit ADC, so the
    /// handheld's scenes saturate (and take their shorter exposures) as on
    /// the board.
    pub const FULL_SCALE: u16 = 4095;
}
