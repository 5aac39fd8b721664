//! The chip's flash, shared: one embassy-stm32 blocking driver behind a
//! mutex ([`Chip`]), and a [`Window`] of it for each user: the calibration
//! store (CAL_SLOT_A and CAL_SLOT_B, back to back) and embassy-boot's
//! updater (DFU and BOOT_STATE). A window refuses every access past its own
//! pages, so an update cannot reach the calibration or recipe slots, nor the
//! store the images.
//!
//! The addresses come from the linker symbols memory.x exports, so they are
//! written down once, and are checked against `crate::shape::board` at boot;
//! memory.x limits the image to ACTIVE, so it never overlaps anything else.
//!
//! Erases and writes are split into 2 KiB pages, feeding the watchdog after
//! each page: a whole-slot erase takes about 3.5 s (160 pages x 22-25 ms),
//! longer than the watchdog period, while each page is proof of progress. A
//! flash operation that hangs still resets the board.

use core::cell::RefCell;
use embassy_stm32::Peri;
use embassy_stm32::flash::{Blocking, Error, FLASH_BASE, Flash, WRITE_SIZE};
use embassy_stm32::peripherals::FLASH;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use static_cell::StaticCell;

use crate::hw::MappedFlash;
use crate::platform::flash_window::{SharedFlash, Window};
use crate::shape::board as map;

use super::watchdog;

/// Erase page size of the STM32L475VG.
pub const PAGE: u32 = crate::shape::FLASH_PAGE as u32;
// The chip driver's program unit is the one the fakes and provisioning use.
const _: () = assert!(WRITE_SIZE == crate::shape::FLASH_WRITE);

/// The chip's flash, shared by its windows.
pub type Chip = SharedFlash<CriticalSectionRawMutex, ChipFlash>;
/// A window of the chip's flash: the calibration store's, the updater's.
pub type Part = Window<'static, CriticalSectionRawMutex, ChipFlash>;
/// The calibration region (slot A then slot B) as the store sees it.
pub type CalFlash = Part;

unsafe extern "C" {
    static __cal_slot_a_start: u8;
    static __cal_slot_b_start: u8;
    static __cal_slot_len: u8;
    static __bootloader_state_start: u8;
    static __bootloader_state_end: u8;
    static __bootloader_dfu_start: u8;
    static __bootloader_dfu_end: u8;
    static __recipe_slot_a_start: u8;
    static __recipe_slot_b_start: u8;
    static __recipe_slot_len: u8;
}

/// A linker symbol's address (its value; the symbol is never read).
macro_rules! sym {
    ($s:ident) => {
        &raw const $s as usize
    };
}

/// The whole flash of the chip (offset 0 = `FLASH_BASE`): embassy-stm32's
/// blocking driver, page by page, with the data cache flushed after every
/// change and the watchdog fed after every page.
pub struct ChipFlash {
    flash: Flash<'static, Blocking>,
}

/// Resets the flash data cache (ART) so in-place reads see what was just
/// erased or programmed: the flash driver does not, and a cached line of the
/// old content would otherwise be read back (RM0351 3.3.x; ST's HAL flushes
/// after erase for the same reason).
fn flush_data_cache() {
    let acr = embassy_stm32::pac::FLASH.acr();
    if acr.read().dcen() {
        acr.modify(|w| w.set_dcen(false));
        acr.modify(|w| w.set_dcrst(true));
        acr.modify(|w| w.set_dcrst(false));
        acr.modify(|w| w.set_dcen(true));
    }
}

/// Takes the flash controller and shares it. Call once.
pub fn share(flash: Peri<'static, FLASH>) -> &'static Chip {
    static CHIP: StaticCell<Chip> = StaticCell::new();
    CHIP.init(Mutex::new(RefCell::new(ChipFlash { flash: Flash::new_blocking(flash) })))
}

/// The window `addr..addr + len` (absolute addresses) of the chip.
fn window(chip: &'static Chip, addr: usize, len: usize) -> Part {
    assert!(addr >= FLASH_BASE, "flash window below the flash");
    Window::new(chip, (addr - FLASH_BASE) as u32, len as u32)
}

/// The calibration region: slot A then slot B, back to back. Panics if
/// memory.x's slots are not where `crate::shape::board` says (a build
/// mistake, caught at boot).
pub fn calibration(chip: &'static Chip) -> CalFlash {
    let (a, b, len) = (sym!(__cal_slot_a_start), sym!(__cal_slot_b_start), sym!(__cal_slot_len));
    assert!(
        (a, b, len) == (map::SLOT_A as usize, map::SLOT_B as usize, map::SLOT_LEN as usize),
        "memory.x disagrees with shape::board"
    );
    assert_eq!(b, a + len, "memory.x: CAL_SLOT_B must follow CAL_SLOT_A");
    defmt::info!("calibration slots: A at {=usize:#x}, B at {=usize:#x}, {=usize} bytes each", a, b, len);
    window(chip, a, 2 * len)
}

/// The inspection recipe region: slot A then slot B, back to back, checked
/// against `crate::shape::board` as the calibration's.
pub fn recipes(chip: &'static Chip) -> Part {
    let (a, b, len) = (sym!(__recipe_slot_a_start), sym!(__recipe_slot_b_start), sym!(__recipe_slot_len));
    assert!(
        (a, b, len) == (map::RECIPE_SLOT_A as usize, map::RECIPE_SLOT_B as usize, map::RECIPE_SLOT_LEN as usize),
        "memory.x's recipe slots disagree with shape::board"
    );
    assert_eq!(b, a + len, "memory.x: RECIPE_SLOT_B must follow RECIPE_SLOT_A");
    defmt::info!("recipe slots: A at {=usize:#x}, B at {=usize:#x}, {=usize} bytes each", a, b, len);
    window(chip, a, 2 * len)
}

/// Any page-aligned region of the chip's flash as a store's window (two
/// slots of `len / 2`): the board tests' spare region
/// (`crate::shape::board::TEST_REGION`). Writes outside it are refused.
pub fn region(chip: &'static Chip, addr: usize, len: usize) -> CalFlash {
    assert!(len.is_multiple_of(2 * PAGE as usize), "a store region is two slots of whole pages");
    window(chip, addr, len)
}

/// embassy-boot's update (DFU) and state partitions, where the bootloader
/// reads them (memory.x's `__bootloader_*` symbols, offsets from the start
/// of flash). Panics if they disagree with `crate::shape::board`.
pub fn update_partitions(chip: &'static Chip) -> (Part, Part) {
    let dfu = (sym!(__bootloader_dfu_start), sym!(__bootloader_dfu_end));
    let state = (sym!(__bootloader_state_start), sym!(__bootloader_state_end));
    let base = map::BOOTLOADER as usize;
    assert!(
        dfu == ((map::DFU as usize) - base, (map::DFU + map::DFU_LEN) as usize - base)
            && state == ((map::BOOT_STATE as usize) - base, (map::BOOT_STATE + map::BOOT_STATE_LEN) as usize - base),
        "memory.x's boot partitions disagree with shape::board"
    );
    defmt::info!("update partition at {=u32:#x}, boot state at {=u32:#x}", map::DFU, map::BOOT_STATE);
    (window(chip, base + dfu.0, dfu.1 - dfu.0), window(chip, base + state.0, state.1 - state.0))
}

// SAFETY: the chip's flash is always mapped and readable for the program's
// life, and its bytes change only through this type's `write`/`erase` (the
// one driver; memory.x keeps every static out of flash).
unsafe impl MappedFlash for ChipFlash {
    fn mapped(&self, offset: u32, len: usize) -> &'static [u8] {
        assert!(offset as usize + len <= crate::shape::FLASH_SIZE as usize, "mapped range past the flash");
        // SAFETY: in range (checked above); see the impl's safety note.
        unsafe { core::slice::from_raw_parts((FLASH_BASE + offset as usize) as *const u8, len) }
    }
}

impl ErrorType for ChipFlash {
    type Error = Error;
}

impl ReadNorFlash for ChipFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Error> {
        self.flash.blocking_read(offset, bytes)
    }

    fn capacity(&self) -> usize {
        crate::shape::FLASH_SIZE as usize
    }
}

impl NorFlash for ChipFlash {
    const WRITE_SIZE: usize = WRITE_SIZE;
    const ERASE_SIZE: usize = PAGE as usize;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Error> {
        if from > to || to > crate::shape::FLASH_SIZE {
            return Err(Error::Size);
        }
        if !from.is_multiple_of(PAGE) || !to.is_multiple_of(PAGE) {
            return Err(Error::Unaligned);
        }
        for page in (from..to).step_by(PAGE as usize) {
            let r = self.flash.blocking_erase(page, page + PAGE);
            flush_data_cache();
            r?;
            watchdog::progress();
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Error> {
        if !(offset as usize).is_multiple_of(WRITE_SIZE) || !bytes.len().is_multiple_of(WRITE_SIZE) {
            return Err(Error::Unaligned);
        }
        for (k, chunk) in bytes.chunks(PAGE as usize).enumerate() {
            let r = self.flash.blocking_write(offset + (k as u32) * PAGE, chunk);
            flush_data_cache();
            r?;
            watchdog::progress();
        }
        Ok(())
    }
}
