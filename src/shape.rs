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

/// The B-L475E-IOT01A board's flash map and sizes (memory.x holds the same
/// map; the drawing is in memory.x and docs/guide/firmware-updates.md).
///
/// Flash, in order: bootloader, boot state, active image, update (DFU)
/// image, two inspection-recipe slots, two calibration slots. The QEMU
/// machine has the same chip and the same map.
pub mod board {
    use super::{FLASH_BASE, FLASH_PAGE, FLASH_SIZE};

    const PAGE: u32 = FLASH_PAGE as u32;
    const KIB: u32 = 1024;

    /// Pixels of the line sensor, `P`.
    pub const PIXELS: usize = 128;
    /// Largest calibration the product runs, in zones (at n = [`super::BINS`],
    /// m = [`super::LEDS`], P = [`PIXELS`]): the largest zone count whose
    /// signed calibration of bare matrices (`blob::Dims::blob_len`) fits one
    /// [`SLOT_LEN`] slot. The firmware budget check proves it fits and that
    /// one zone more would not; change it together with the shape. A trained
    /// calibration also carries its gloss rows and per-pixel references, so
    /// fewer of its zones fit (117 of the Wiener kind); host-tools' `train`
    /// says when a blob is more than a slot takes.
    pub const MAX_ZONES: usize = 124;
    /// Zones whose matrices are copied to RAM (8 x 81 x 7 f32 = 18 KiB); a
    /// calibration with more zones runs in place from its flash slot.
    pub const RAM_ZONES: usize = 8;

    /// The bootloader (embassy-boot), at the chip's reset vector.
    pub const BOOTLOADER: u32 = FLASH_BASE;
    /// Flash for the bootloader image.
    pub const BOOTLOADER_LEN: u32 = 24 * KIB;
    /// embassy-boot's state partition (magic word and swap progress).
    pub const BOOT_STATE: u32 = BOOTLOADER + BOOTLOADER_LEN;
    /// Length of the boot state: two pages, room for the progress words of a
    /// swap and a revert of the whole active image (embassy-boot asserts
    /// `2 + 4 x pages` words fit).
    pub const BOOT_STATE_LEN: u32 = 2 * PAGE;
    /// The active firmware image (every application links here).
    pub const ACTIVE: u32 = BOOT_STATE + BOOT_STATE_LEN;
    /// Flash for the active image.
    pub const ACTIVE_LEN: u32 = 160 * KIB;
    /// The update image (DFU partition): a new image is written here, and
    /// the swap trades it page by page with the active one.
    pub const DFU: u32 = ACTIVE + ACTIVE_LEN;
    /// Length of the update partition: the active image's plus the one page
    /// embassy-boot's swap needs, plus one spare page that keeps the slots
    /// below on round addresses.
    pub const DFU_LEN: u32 = ACTIVE_LEN + 2 * PAGE;
    /// Inspection recipe slot A.
    pub const RECIPE_SLOT_A: u32 = DFU + DFU_LEN;
    /// Length of one inspection recipe slot.
    pub const RECIPE_SLOT_LEN: u32 = 16 * KIB;
    /// Inspection recipe slot B (right after slot A).
    pub const RECIPE_SLOT_B: u32 = RECIPE_SLOT_A + RECIPE_SLOT_LEN;
    /// Calibration slot A.
    pub const SLOT_A: u32 = RECIPE_SLOT_B + RECIPE_SLOT_LEN;
    /// Length of one calibration slot (at least 320 KiB: the product's
    /// largest calibration is sized to it, see [`MAX_ZONES`]).
    pub const SLOT_LEN: u32 = 320 * KIB;
    /// Calibration slot B (right after slot A).
    pub const SLOT_B: u32 = SLOT_A + SLOT_LEN;

    /// One slot of the board tests' own calibration store (bin
    /// `board-tests`): room for their 2-zone test calibration.
    pub const TEST_SLOT_LEN: u32 = 8 * PAGE;
    /// Where the board tests' two store slots start: the top of the active
    /// image region. Only the test image (which checks at start that it ends
    /// below this) uses it, and flashing board-fw again overwrites it; the
    /// calibration slots are never touched by the tests.
    pub const TEST_REGION: u32 = ACTIVE + ACTIVE_LEN - 2 * TEST_SLOT_LEN;
    /// SRAM1 (the stack, then the statics, the RAM zone buffer among them).
    pub const RAM_ORIGIN: u32 = 0x2000_0000;
    /// Size of SRAM1.
    pub const RAM_LEN: u32 = 96 * 1024;
    /// The stack: the start of SRAM1, below the statics, so that a stack
    /// that outgrows it faults off the start of SRAM1 instead of
    /// overwriting them (memory.x's STACK; the statics have the rest).
    pub const STACK_LEN: u32 = 16 * 1024;

    const _: () = assert!(SLOT_B + SLOT_LEN == FLASH_BASE + FLASH_SIZE, "the map fills the chip's flash");
    const _: () = assert!(SLOT_LEN >= 320 * KIB, "calibration slots stay at least 320 KiB");
    const _: () =
        assert!(DFU_LEN >= ACTIVE_LEN + PAGE, "embassy-boot's swap needs one page more than the active image");
    const _: () = assert!(
        (2 + 4 * (ACTIVE_LEN / PAGE)) * super::FLASH_WRITE as u32 <= BOOT_STATE_LEN,
        "the boot state holds the progress of a swap and a revert"
    );
    const _: () = assert!(
        BOOTLOADER_LEN.is_multiple_of(PAGE)
            && ACTIVE_LEN.is_multiple_of(PAGE)
            && RECIPE_SLOT_LEN.is_multiple_of(PAGE)
            && SLOT_LEN.is_multiple_of(PAGE)
            && TEST_REGION.is_multiple_of(PAGE),
        "every region is whole erase pages"
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
    /// Inspection recipe slot length: 2 pages, room for a recipe of P = 32
    /// pixels in up to 8 groups (RAM-backed, in SRAM2 beside the update
    /// partition: SRAM1 has no room left for them and the stack).
    pub const RECIPE_SLOT_LEN: u32 = 2 * super::FLASH_PAGE as u32;
    /// Scene lines the simulated sensor holds.
    pub const FRAME_LINES: usize = 4;
    /// The simulated converter's full scale: the board's 12-bit ADC, so the
    /// handheld's scenes saturate (and take their shorter exposures) as on
    /// the board.
    pub const FULL_SCALE: u16 = 4095;
    /// The QEMU build's update partition: RAM (QEMU's flash is read-only),
    /// 24 KiB of the 32 KiB SRAM2 bank (memory.x's `.sram2`; the recipe
    /// slots take the rest), which is all the RAM the QEMU firmware's
    /// statics leave. Updates up to this size run there through transfer,
    /// verification and marking; the swap cannot.
    pub const DFU_LEN: u32 = 24 * 1024;
}
