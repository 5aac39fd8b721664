//! The NOR flash rules every flash fake follows, written once: pages of
//! [`FLASH_PAGE`] bytes erased to 0xFF, writes of [`FLASH_WRITE`] bytes only to
//! erased words (real NOR would corrupt them), range and alignment checks, as
//! the STM32L4's flash. The storage underneath is a parameter ([`NorStorage`]):
//! the QEMU firmware keeps its calibration slots in a static RAM buffer, the
//! host simulation in a heap buffer that can lose power at any step.
//!
//! Each page erase and each byte written is one *step*, announced to the
//! storage before it happens; a storage that refuses a step stops the
//! operation there, as a power cut would: the byte in progress is not written,
//! a page erase in progress leaves the page half erased.
use crate::hw::MappedFlash;
use crate::shape::{FLASH_PAGE, FLASH_WRITE};
use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash};

/// Why a fake flash refused an operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NorFault {
    /// Not aligned to the write or erase size.
    NotAligned,
    /// Outside the flash.
    OutOfBounds,
    /// A write to a word that is not erased.
    NotErased,
    /// The power was cut (the storage refused a step).
    PowerCut,
}

impl NorFlashError for NorFault {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::NotAligned => NorFlashErrorKind::NotAligned,
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            Self::NotErased | Self::PowerCut => NorFlashErrorKind::Other,
        }
    }
}

/// One operation that reached the flash (for tests of the write pattern).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashOp {
    /// Page erase at this offset.
    Erase(u32),
    /// Write of this many bytes at this offset.
    Write(u32, u32),
}

/// The bytes under a [`NorFake`].
///
/// # Safety
/// `base()` points to `capacity()` bytes that stay valid while any slice
/// handed out by [`NorFake`]'s `mapped` is in use, and that change only
/// through the `NorFake` holding this storage (or its clones).
pub unsafe trait NorStorage {
    /// First byte.
    fn base(&self) -> *mut u8;
    /// Number of bytes (a multiple of [`FLASH_PAGE`]).
    fn capacity(&self) -> usize;
    /// One step (a page erase or a byte written) is about to happen; an
    /// error stops the operation before it.
    fn step(&self) -> Result<(), NorFault> {
        Ok(())
    }
    /// An operation passed its checks and is about to reach the flash.
    fn record(&self, _op: FlashOp) {}
}

/// A NOR flash with the STM32L4's rules over storage `S`.
#[derive(Clone)]
pub struct NorFake<S> {
    storage: S,
}

impl<S: NorStorage> NorFake<S> {
    /// A flash over `storage`, whose bytes are taken as they are.
    pub fn over(storage: S) -> Self {
        assert!(storage.capacity().is_multiple_of(FLASH_PAGE), "a NOR fake holds whole pages");
        Self { storage }
    }

    /// The storage.
    pub fn storage(&self) -> &S {
        &self.storage
    }

    fn check(&self, offset: u32, len: usize, align: usize) -> Result<(), NorFault> {
        if !(offset as usize).is_multiple_of(align) || !len.is_multiple_of(align) {
            return Err(NorFault::NotAligned);
        }
        match (offset as usize).checked_add(len) {
            Some(end) if end <= self.storage.capacity() => Ok(()),
            _ => Err(NorFault::OutOfBounds),
        }
    }
}

impl<S> ErrorType for NorFake<S> {
    type Error = NorFault;
}

impl<S: NorStorage> ReadNorFlash for NorFake<S> {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), NorFault> {
        self.check(offset, bytes.len(), 1)?;
        bytes.copy_from_slice(self.mapped(offset, bytes.len()));
        Ok(())
    }
    fn capacity(&self) -> usize {
        self.storage.capacity()
    }
}

impl<S: NorStorage> NorFlash for NorFake<S> {
    const WRITE_SIZE: usize = FLASH_WRITE;
    const ERASE_SIZE: usize = FLASH_PAGE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), NorFault> {
        if to < from {
            return Err(NorFault::OutOfBounds);
        }
        self.check(from, (to - from) as usize, FLASH_PAGE)?;
        for page in (from..to).step_by(FLASH_PAGE) {
            // SAFETY: in bounds (checked above); no mapped slice in use covers
            // a range being erased (the MappedFlash contract).
            let p = unsafe { self.storage.base().add(page as usize) };
            if let Err(e) = self.storage.step() {
                // Power lost mid-erase: half the page is erased, half is not.
                unsafe { core::ptr::write_bytes(p, 0xFF, FLASH_PAGE / 2) };
                return Err(e);
            }
            self.storage.record(FlashOp::Erase(page));
            unsafe { core::ptr::write_bytes(p, 0xFF, FLASH_PAGE) };
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), NorFault> {
        self.check(offset, bytes.len(), FLASH_WRITE)?;
        if self.mapped(offset, bytes.len()).iter().any(|b| *b != 0xFF) {
            return Err(NorFault::NotErased);
        }
        self.storage.record(FlashOp::Write(offset, bytes.len() as u32));
        for (i, b) in bytes.iter().enumerate() {
            self.storage.step()?;
            // SAFETY: in bounds (checked above); see `erase`.
            unsafe { *self.storage.base().add(offset as usize + i) = *b };
        }
        Ok(())
    }
}

// SAFETY: the bytes change only through `erase`/`write` above, range by
// range, and stay valid as `NorStorage`'s contract says.
unsafe impl<S: NorStorage> MappedFlash for NorFake<S> {
    fn mapped(&self, offset: u32, len: usize) -> &'static [u8] {
        assert!(offset as usize + len <= self.storage.capacity(), "mapped range outside the flash");
        // SAFETY: in bounds; lifetime per NorStorage's contract.
        unsafe { core::slice::from_raw_parts(self.storage.base().add(offset as usize), len) }
    }
}
