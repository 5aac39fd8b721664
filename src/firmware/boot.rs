//! What the bootloader does before it starts the active image, on any NOR
//! flash: embassy-boot's `BootLoader::prepare_boot` over the ACTIVE, DFU and
//! STATE partitions. The bootloader binaries (board and QEMU) call this, and
//! the host simulation calls the very same function on its NOR fake, power
//! cuts included.
//!
//! - state Boot (or Revert, or DfuDetach): nothing to do;
//! - state Swap, not yet swapped: the update in DFU is swapped with the
//!   active image, page by page, each page's progress recorded in STATE
//!   before the next (a power cut resumes where it stopped);
//! - state Swap, already swapped (the new image ran on trial and did not
//!   confirm before this reset): the swap is undone, the previous image is
//!   active again, and the state says Revert.
use embassy_boot::{BootError, BootLoader, BootLoaderConfig, State};
use embedded_storage::nor_flash::NorFlash;

/// The swap's copy buffer: one flash page (a divisor of the page, as
/// embassy-boot asks; a whole page keeps the flash operations fewest).
pub const SWAP_BUFFER: usize = crate::shape::FLASH_PAGE;

/// Runs the bootloader's part over the three partitions; returns the state
/// it found (after a swap: `Swap`; after a revert: `Swap` too, the state
/// partition then reads Revert).
pub fn prepare<A: NorFlash, D: NorFlash, S: NorFlash>(
    active: A,
    dfu: D,
    state: S,
    buf: &mut [u8; SWAP_BUFFER],
) -> Result<State, BootError> {
    BootLoader::new(BootLoaderConfig { active, dfu, state }).prepare_boot(buf)
}
