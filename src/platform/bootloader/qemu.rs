//! The QEMU bootloader's flash: QEMU 10's b-l475e-iot01a maps the chip's
//! flash as ROM (its flash controller is a stub), so this NOR flash reads the
//! memory-mapped bytes and refuses every erase and write. Enough for the
//! bootloader's normal path (boot state Boot: nothing to write, start the
//! active image); a swap cannot run here (see docs/guide/firmware-updates.md
//! for what QEMU shows and what it cannot).
use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash};

/// Why the ROM refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RomError {
    /// Outside the region.
    OutOfBounds,
    /// QEMU's flash cannot be erased or written.
    ReadOnly,
}

impl NorFlashError for RomError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            Self::ReadOnly => NorFlashErrorKind::Other,
        }
    }
}

/// `len` bytes of memory-mapped flash from `base`.
pub struct Rom {
    base: u32,
    len: u32,
}

impl Rom {
    /// The region `base..base + len` (absolute addresses).
    pub const fn new(base: u32, len: u32) -> Self {
        Self { base, len }
    }
}

impl ErrorType for Rom {
    type Error = RomError;
}

impl ReadNorFlash for Rom {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), RomError> {
        if offset as usize + bytes.len() > self.len as usize {
            return Err(RomError::OutOfBounds);
        }
        // SAFETY: inside the chip's flash, which is always mapped and readable.
        let src = unsafe { core::slice::from_raw_parts((self.base + offset) as *const u8, bytes.len()) };
        bytes.copy_from_slice(src);
        Ok(())
    }
    fn capacity(&self) -> usize {
        self.len as usize
    }
}

impl NorFlash for Rom {
    const WRITE_SIZE: usize = crate::shape::FLASH_WRITE;
    const ERASE_SIZE: usize = crate::shape::FLASH_PAGE;
    fn erase(&mut self, _: u32, _: u32) -> Result<(), RomError> {
        Err(RomError::ReadOnly)
    }
    fn write(&mut self, _: u32, _: &[u8]) -> Result<(), RomError> {
        Err(RomError::ReadOnly)
    }
}
