//! The calibration region of the chip's flash: the two slots memory.x
//! reserves (CAL_SLOT_A, CAL_SLOT_B), as one `NorFlash` window whose offset 0
//! is the start of slot A (the layout `crate::store::Store` expects),
//! and as memory (`MappedFlash`) so blobs and matrices are read in place.
//!
//! The addresses come from the linker symbols memory.x exports, so they are
//! written down once; memory.x limits FLASH (the image) to the space below
//! slot A, so the image can never overlap the calibration.
//!
//! Erases and writes are split into 2 KiB pages, feeding the watchdog after
//! each page: a whole-slot erase takes about 4.5 s (192 pages x 22-25 ms),
//! longer than the watchdog period, while each page is proof of progress. A
//! flash operation that hangs still resets the board.

use embassy_stm32::Peri;
use embassy_stm32::flash::{Blocking, Error, FLASH_BASE, Flash, WRITE_SIZE};
use embassy_stm32::peripherals::FLASH;
use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};

use crate::hw::MappedFlash;

use super::watchdog;

/// Erase page size of the STM32L475VG.
pub const PAGE: u32 = crate::shape::FLASH_PAGE as u32;
// The chip driver's program unit is the one the fakes and provisioning use.
const _: () = assert!(WRITE_SIZE == crate::shape::FLASH_WRITE);

unsafe extern "C" {
    static __cal_slot_a_start: u8;
    static __cal_slot_b_start: u8;
    static __cal_slot_len: u8;
}

/// Address of calibration slot A (memory.x).
pub fn slot_a_addr() -> usize {
    // Only the symbol's address is taken; it is never read.
    &raw const __cal_slot_a_start as usize
}
/// Address of calibration slot B (memory.x).
pub fn slot_b_addr() -> usize {
    &raw const __cal_slot_b_start as usize
}
/// Length of one slot in bytes (memory.x; the symbol's value is the length).
pub fn slot_len() -> usize {
    &raw const __cal_slot_len as usize
}

/// The calibration region: slot A then slot B, back to back.
pub struct CalFlash {
    flash: Flash<'static, Blocking>,
    /// Offset of slot A from the start of flash.
    base: u32,
    len: u32,
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

impl CalFlash {
    /// Takes the flash controller. Panics if memory.x's slots are not where
    /// `crate::shape::board` says (two page-aligned, back-to-back regions):
    /// a build mistake, caught at boot.
    pub fn new(flash: Peri<'static, FLASH>) -> Self {
        use crate::shape::board::{SLOT_A, SLOT_B, SLOT_LEN};
        let (a, b, len) = (slot_a_addr(), slot_b_addr(), slot_len());
        assert!(
            (a, b, len) == (SLOT_A as usize, SLOT_B as usize, SLOT_LEN as usize),
            "memory.x disagrees with shape::board"
        );
        assert!(a >= FLASH_BASE && a.is_multiple_of(PAGE as usize) && len.is_multiple_of(PAGE as usize));
        assert_eq!(b, a + len, "memory.x: CAL_SLOT_B must follow CAL_SLOT_A");
        defmt::info!("calibration slots: A at {=usize:#x}, B at {=usize:#x}, {=usize} bytes each", a, b, len);
        Self::region(flash, a, 2 * len)
    }

    /// Any page-aligned region of the chip's flash as the store's window
    /// (two slots of `len / 2`): the board tests' spare region
    /// (`crate::shape::board::TEST_REGION`). Writes outside it are refused.
    pub fn region(flash: Peri<'static, FLASH>, addr: usize, len: usize) -> Self {
        let end = crate::shape::FLASH_BASE as usize + crate::shape::FLASH_SIZE as usize;
        assert!(addr >= FLASH_BASE && addr.is_multiple_of(PAGE as usize) && len.is_multiple_of(2 * PAGE as usize));
        assert!(addr + len <= end, "flash region past the end of flash");
        Self { flash: Flash::new_blocking(flash), base: (addr - FLASH_BASE) as u32, len: len as u32 }
    }

    /// Length of one slot (slot A at offset 0, slot B at this offset).
    pub fn slot_len(&self) -> u32 {
        self.len / 2
    }

    fn check(&self, offset: u32, len: usize) -> Result<(), Error> {
        match offset.checked_add(len as u32) {
            Some(end) if end <= self.len => Ok(()),
            _ => Err(Error::Size),
        }
    }
}

// SAFETY: the region is inside the chip's flash, always mapped and readable
// for the program's life; memory.x keeps the image and every static out of
// it, so its bytes change only through this type's `write`/`erase`.
unsafe impl MappedFlash for CalFlash {
    fn mapped(&self, offset: u32, len: usize) -> &'static [u8] {
        self.check(offset, len).expect("mapped range outside the calibration region");
        let addr = FLASH_BASE + (self.base + offset) as usize;
        // SAFETY: in range (checked above); see the impl's safety note.
        unsafe { core::slice::from_raw_parts(addr as *const u8, len) }
    }
}

impl ErrorType for CalFlash {
    type Error = Error;
}

impl ReadNorFlash for CalFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Error> {
        self.check(offset, bytes.len())?;
        self.flash.blocking_read(self.base + offset, bytes)
    }

    fn capacity(&self) -> usize {
        self.len as usize
    }
}

impl NorFlash for CalFlash {
    const WRITE_SIZE: usize = WRITE_SIZE;
    const ERASE_SIZE: usize = PAGE as usize;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Error> {
        if from > to {
            return Err(Error::Size);
        }
        self.check(from, (to - from) as usize)?;
        if !from.is_multiple_of(PAGE) || !to.is_multiple_of(PAGE) {
            return Err(Error::Unaligned);
        }
        let mut page = from;
        while page < to {
            let r = self.flash.blocking_erase(self.base + page, self.base + page + PAGE);
            flush_data_cache();
            r?;
            watchdog::progress();
            page += PAGE;
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Error> {
        self.check(offset, bytes.len())?;
        if !(offset as usize).is_multiple_of(WRITE_SIZE) || !bytes.len().is_multiple_of(WRITE_SIZE) {
            return Err(Error::Unaligned);
        }
        for (k, chunk) in bytes.chunks(PAGE as usize).enumerate() {
            let r = self.flash.blocking_write(self.base + offset + (k as u32) * PAGE, chunk);
            flush_data_cache();
            r?;
            watchdog::progress();
        }
        Ok(())
    }
}
