//! The calibration slots of the QEMU build, in RAM: QEMU's flash is read-only
//! (its FLASH controller is a stub), so the slots live in a static buffer
//! under the shared NOR rules ([`NorFake`]). Provisioning, slot alternation
//! and the store's power-cut rules behave as on the board; a calibration does
//! not survive a restart of QEMU.
use crate::platform::nor_fake::{NorFake, NorStorage};
use core::cell::UnsafeCell;

/// The RAM holding the slots (in .bss; [`take`] erases it).
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

impl<const LEN: usize> Default for Memory<LEN> {
    fn default() -> Self {
        Self::new()
    }
}

/// A `'static` [`Memory`] as NOR storage.
pub struct StaticMemory<const LEN: usize>(&'static Memory<LEN>);

// SAFETY: a 'static buffer, changed only through the one RamFlash over it.
unsafe impl<const LEN: usize> NorStorage for StaticMemory<LEN> {
    fn base(&self) -> *mut u8 {
        self.0.0.get() as *mut u8
    }
    fn capacity(&self) -> usize {
        LEN
    }
}

/// The QEMU build's calibration flash.
pub type RamFlash<const LEN: usize> = NorFake<StaticMemory<LEN>>;

/// Takes `mem` as the calibration flash, erased. Call once.
pub fn take<const LEN: usize>(mem: &'static Memory<LEN>) -> RamFlash<LEN> {
    // SAFETY: no slice of it exists yet.
    unsafe { core::ptr::write_bytes(mem.0.get() as *mut u8, 0xFF, LEN) };
    NorFake::over(StaticMemory(mem))
}
