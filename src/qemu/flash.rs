//! The calibration slots of the QEMU build, in RAM: QEMU's flash is read-only
//! (its FLASH controller is a stub), so this `NorFlash` keeps the two slots in
//! a static buffer with NOR rules (2 KiB pages erased to 0xFF, 8-byte writes
//! only to erased words). Provisioning, slot alternation and the store's
//! power-cut rules behave as on the board; a calibration does not survive a
//! restart of QEMU.
use brdf_meter::hw::MappedFlash;
use core::cell::UnsafeCell;
use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash};

/// Page size (as the STM32L4).
pub const PAGE: usize = 2048;

/// The RAM holding the slots (in .bss; [`RamFlash::take`] erases it).
#[repr(C, align(8))]
pub struct Memory<const LEN: usize>(UnsafeCell<[u8; LEN]>);
// SAFETY: accessed only through the single RamFlash (and the store's mapped
// slices, which never overlap a write: see MappedFlash).
unsafe impl<const LEN: usize> Sync for Memory<LEN> {}

impl<const LEN: usize> Memory<LEN> {
    /// Zeroed (placed in .bss; erased at `take`).
    pub const fn new() -> Self {
        Self(UnsafeCell::new([0; LEN]))
    }
}

/// Why a flash operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RamFlashError {
    /// Misaligned.
    NotAligned,
    /// Outside.
    OutOfBounds,
    /// Write to a word not erased (programming error on real NOR).
    NotErased,
}

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::NotAligned => NorFlashErrorKind::NotAligned,
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            Self::NotErased => NorFlashErrorKind::Other,
        }
    }
}

/// A RAM-backed NOR flash over a `'static` [`Memory`].
pub struct RamFlash<const LEN: usize> {
    mem: &'static Memory<LEN>,
}

impl<const LEN: usize> RamFlash<LEN> {
    /// Takes the memory, erased. Call once.
    pub fn take(mem: &'static Memory<LEN>) -> Self {
        const { assert!(LEN.is_multiple_of(PAGE)) };
        // SAFETY: no slice of it exists yet.
        unsafe { core::ptr::write_bytes(mem.0.get() as *mut u8, 0xFF, LEN) };
        Self { mem }
    }

    fn ptr(&self, offset: u32) -> *mut u8 {
        // SAFETY: callers bound-check offset.
        unsafe { (self.mem.0.get() as *mut u8).add(offset as usize) }
    }

    fn check(offset: u32, len: usize, align: usize) -> Result<(), RamFlashError> {
        if !(offset as usize).is_multiple_of(align) || !len.is_multiple_of(align) {
            return Err(RamFlashError::NotAligned);
        }
        if offset as usize + len > LEN {
            return Err(RamFlashError::OutOfBounds);
        }
        Ok(())
    }
}

impl<const LEN: usize> ErrorType for RamFlash<LEN> {
    type Error = RamFlashError;
}

impl<const LEN: usize> ReadNorFlash for RamFlash<LEN> {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), RamFlashError> {
        Self::check(offset, bytes.len(), 1)?;
        bytes.copy_from_slice(self.mapped(offset, bytes.len()));
        Ok(())
    }
    fn capacity(&self) -> usize {
        LEN
    }
}

impl<const LEN: usize> NorFlash for RamFlash<LEN> {
    const WRITE_SIZE: usize = 8;
    const ERASE_SIZE: usize = PAGE;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), RamFlashError> {
        if to < from {
            return Err(RamFlashError::OutOfBounds);
        }
        Self::check(from, (to - from) as usize, PAGE)?;
        // SAFETY: in bounds (checked); no mapped slice covers an erased range.
        unsafe { core::ptr::write_bytes(self.ptr(from), 0xFF, (to - from) as usize) };
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), RamFlashError> {
        Self::check(offset, bytes.len(), 8)?;
        if self.mapped(offset, bytes.len()).iter().any(|b| *b != 0xFF) {
            return Err(RamFlashError::NotErased);
        }
        // SAFETY: in bounds (checked); no mapped slice covers a written range.
        unsafe { core::ptr::copy_nonoverlapping(bytes.as_ptr(), self.ptr(offset), bytes.len()) };
        Ok(())
    }
}

// SAFETY: a 'static buffer changed only by erase/write above, range by range.
unsafe impl<const LEN: usize> MappedFlash for RamFlash<LEN> {
    fn mapped(&self, offset: u32, len: usize) -> &'static [u8] {
        assert!(offset as usize + len <= LEN, "mapped range outside the flash");
        // SAFETY: in bounds, memory lives forever.
        unsafe { core::slice::from_raw_parts(self.ptr(offset), len) }
    }
}
