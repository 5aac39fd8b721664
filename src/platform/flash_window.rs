//! One flash chip, several users: the calibration store and embassy-boot's
//! updater (its DFU and STATE partitions) each get a [`Window`] on the chip's
//! one flash driver, kept behind a blocking mutex, as embassy's examples share
//! a flash with `BlockingPartition`. A window is whole erase pages at a fixed
//! offset, and refuses every access past its end, so the updater physically
//! cannot reach the calibration or recipe slots, and the store cannot reach
//! the images.
//!
//! Unlike embassy-embedded-hal's `BlockingPartition` a window also reads in
//! place ([`MappedFlash`]), which the calibration store needs to run the
//! matrices from flash. The board shares its embassy-stm32 flash this way;
//! the host simulation shares its NOR fake the same way, so the tests that
//! check what an update leaves untouched run this very code.
use crate::hw::MappedFlash;
use core::cell::RefCell;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::RawMutex;
use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash};

/// A flash shared by several windows.
pub type SharedFlash<M, F> = Mutex<M, RefCell<F>>;

/// Why a window refused an access.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WindowError<E> {
    /// Past the window's end (or before its start).
    OutOfBounds,
    /// The flash under the window refused it.
    Flash(E),
}

impl<E: NorFlashError> NorFlashError for WindowError<E> {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            Self::Flash(e) => e.kind(),
        }
    }
}

/// `len` bytes of a shared flash from `offset`, as a flash of its own
/// (offset 0 is the window's first byte).
pub struct Window<'a, M: RawMutex, F> {
    flash: &'a SharedFlash<M, F>,
    offset: u32,
    len: u32,
}

impl<M: RawMutex, F> Clone for Window<'_, M, F> {
    fn clone(&self) -> Self {
        Self { flash: self.flash, offset: self.offset, len: self.len }
    }
}

impl<'a, M: RawMutex, F: NorFlash> Window<'a, M, F> {
    /// The window `offset..offset + len` of `flash`.
    ///
    /// # Panics
    /// If the window is not whole erase pages inside the flash: a mistake in
    /// the flash map, caught at boot.
    pub fn new(flash: &'a SharedFlash<M, F>, offset: u32, len: u32) -> Self {
        let capacity = flash.lock(|f| f.borrow().capacity());
        assert!(
            (offset as usize).is_multiple_of(F::ERASE_SIZE) && (len as usize).is_multiple_of(F::ERASE_SIZE),
            "a flash window is whole erase pages"
        );
        assert!(offset as usize + len as usize <= capacity, "a flash window past the end of the flash");
        Self { flash, offset, len }
    }

    /// Its offset in the shared flash.
    pub fn offset(&self) -> u32 {
        self.offset
    }

    /// The window's `offset..offset + len` in the shared flash, if inside it.
    fn at(&self, offset: u32, len: usize) -> Result<u32, WindowError<F::Error>> {
        match offset.checked_add(len as u32) {
            Some(end) if len <= u32::MAX as usize && end <= self.len => Ok(self.offset + offset),
            _ => Err(WindowError::OutOfBounds),
        }
    }
}

impl<M: RawMutex, F: NorFlash> ErrorType for Window<'_, M, F> {
    type Error = WindowError<F::Error>;
}

impl<M: RawMutex, F: NorFlash> ReadNorFlash for Window<'_, M, F> {
    const READ_SIZE: usize = F::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let at = self.at(offset, bytes.len())?;
        self.flash.lock(|f| f.borrow_mut().read(at, bytes)).map_err(WindowError::Flash)
    }

    fn capacity(&self) -> usize {
        self.len as usize
    }
}

impl<M: RawMutex, F: NorFlash> NorFlash for Window<'_, M, F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let at = self.at(from, to.checked_sub(from).ok_or(WindowError::OutOfBounds)? as usize)?;
        self.flash.lock(|f| f.borrow_mut().erase(at, at + (to - from))).map_err(WindowError::Flash)
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let at = self.at(offset, bytes.len())?;
        self.flash.lock(|f| f.borrow_mut().write(at, bytes)).map_err(WindowError::Flash)
    }
}

// SAFETY: the window's bytes are the shared flash's bytes at its offset, so
// the flash's own guarantee (valid for the program's life, changed only
// through its write/erase) holds for them; every write and erase of the
// window goes through that flash.
unsafe impl<M: RawMutex, F: MappedFlash> MappedFlash for Window<'_, M, F> {
    fn mapped(&self, offset: u32, len: usize) -> &'static [u8] {
        let at = self.at(offset, len).unwrap_or_else(|_| panic!("mapped range outside the flash window"));
        self.flash.lock(|f| f.borrow().mapped(at, len))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::platform::host_sim::SimFlash;
    use crate::shape::FLASH_PAGE;
    use embassy_sync::blocking_mutex::raw::NoopRawMutex;

    const PAGE: u32 = FLASH_PAGE as u32;

    #[test]
    fn a_window_reaches_its_own_pages_and_nothing_else() {
        let chip = SimFlash::new(4 * FLASH_PAGE);
        let shared: SharedFlash<NoopRawMutex, SimFlash> = Mutex::new(RefCell::new(chip.clone()));
        let mut w = Window::new(&shared, PAGE, 2 * PAGE);
        assert_eq!(w.capacity(), 2 * FLASH_PAGE);
        w.erase(0, 2 * PAGE).unwrap();
        w.write(8, &[1; 8]).unwrap();
        assert_eq!(&chip.contents()[FLASH_PAGE + 8..FLASH_PAGE + 16], &[1; 8]);
        assert_eq!(w.mapped(8, 8), &[1; 8]);
        let mut b = [0u8; 8];
        w.read(8, &mut b).unwrap();
        assert_eq!(b, [1; 8]);
        // Past the end, however it is asked, is refused before the chip sees it.
        let log = chip.log().len();
        assert_eq!(w.write(2 * PAGE, &[0; 8]), Err(WindowError::OutOfBounds));
        assert_eq!(w.write(u32::MAX - 7, &[0; 8]), Err(WindowError::OutOfBounds));
        assert_eq!(w.erase(PAGE, 3 * PAGE), Err(WindowError::OutOfBounds));
        assert_eq!(w.erase(PAGE, 0), Err(WindowError::OutOfBounds));
        assert_eq!(w.read(2 * PAGE - 4, &mut b), Err(WindowError::OutOfBounds));
        assert_eq!(chip.log().len(), log);
        // The chip's own refusals come through with their kind.
        assert_eq!(w.write(8, &[2; 8]).unwrap_err().kind(), NorFlashErrorKind::Other);
        assert!(chip.contents()[..FLASH_PAGE].iter().chain(&chip.contents()[3 * FLASH_PAGE..]).all(|&x| x == 0xFF));
    }

    #[test]
    #[should_panic(expected = "whole erase pages")]
    fn a_window_that_splits_a_page_is_a_map_mistake() {
        let shared: SharedFlash<NoopRawMutex, SimFlash> = Mutex::new(RefCell::new(SimFlash::new(4 * FLASH_PAGE)));
        let _ = Window::new(&shared, 8, PAGE);
    }
}
