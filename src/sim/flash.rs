//! An in-memory NOR flash that behaves like the STM32L4's (2 KiB pages erased
//! to 0xFF, 8-byte writes that must land on erased words) and can lose power
//! at any operation: every byte written and every page erase is one step, and
//! after `cut_after(k)` steps the flash stops — the byte in progress is not
//! written, a page erase in progress leaves the page half erased — and every
//! later operation fails, as on a dead device. `reboot()` gives a fresh handle
//! on the same memory, as after power returns.
use crate::hw::MappedFlash;
use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// What went wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SimFlashError {
    /// Not aligned to the write or erase size.
    NotAligned,
    /// Outside the flash.
    OutOfBounds,
    /// A write to a word that is not erased (real NOR would corrupt it).
    NotErased,
    /// The power was cut.
    PowerCut,
}

impl NorFlashError for SimFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::NotAligned => NorFlashErrorKind::NotAligned,
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            _ => NorFlashErrorKind::Other,
        }
    }
}

/// One step that reached the flash (for tests that look at the write pattern).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashOp {
    /// Page erase at this offset.
    Erase(u32),
    /// Write of this many bytes at this offset.
    Write(u32, u32),
}

struct Inner {
    mem: *mut u8,
    len: usize,
    steps: AtomicUsize,
    cut_at: AtomicUsize,
    dead: AtomicBool,
    log: Mutex<Vec<FlashOp>>,
}

impl Drop for Inner {
    fn drop(&mut self) {
        // SAFETY: `mem` came from a leaked boxed slice of `len` bytes, and the
        // last handle is going: see `SimFlash::mapped` on slices' lifetime.
        unsafe { drop(Box::from_raw(core::ptr::slice_from_raw_parts_mut(self.mem, self.len))) }
    }
}

// The memory is only touched through the store's contract (see MappedFlash):
// writes never overlap a mapped slice in use. Tests share a flash between a
// store and a checker on one thread at a time.
unsafe impl Send for Inner {}
unsafe impl Sync for Inner {}

/// The simulated flash (cheap to clone; clones share the memory).
#[derive(Clone)]
pub struct SimFlash {
    inner: Arc<Inner>,
}

impl SimFlash {
    /// Page (erase) size, as on the STM32L4.
    pub const PAGE: usize = 2048;

    /// An erased flash of `len` bytes (a multiple of the page size).
    pub fn new(len: usize) -> Self {
        assert!(len.is_multiple_of(Self::PAGE));
        // Freed when the last handle goes (see `mapped`).
        let mem = Box::leak(vec![0xFFu8; len].into_boxed_slice()).as_mut_ptr();
        Self {
            inner: Arc::new(Inner {
                mem,
                len,
                steps: AtomicUsize::new(0),
                cut_at: AtomicUsize::new(usize::MAX),
                dead: AtomicBool::new(false),
                log: Mutex::new(Vec::new()),
            }),
        }
    }

    /// Cuts the power after `steps` more steps (bytes written or pages erased).
    pub fn cut_after(&self, steps: usize) {
        let now = self.inner.steps.load(Ordering::SeqCst);
        self.inner.cut_at.store(now + steps, Ordering::SeqCst);
    }

    /// Steps done so far.
    pub fn steps(&self) -> usize {
        self.inner.steps.load(Ordering::SeqCst)
    }

    /// Whether the power was cut.
    pub fn is_dead(&self) -> bool {
        self.inner.dead.load(Ordering::SeqCst)
    }

    /// Operations that reached the flash.
    pub fn log(&self) -> Vec<FlashOp> {
        self.inner.log.lock().unwrap().clone()
    }

    /// Power back on: a handle on a copy of the memory as it is now, with no
    /// cut pending (a copy, so the caller can retry the same cut elsewhere).
    pub fn reboot(&self) -> Self {
        let fresh = Self::new(self.inner.len);
        fresh.snapshot_from(self);
        fresh
    }

    fn snapshot_from(&self, other: &Self) {
        // SAFETY: both regions are `len` bytes and distinct allocations.
        unsafe { core::ptr::copy_nonoverlapping(other.inner.mem, self.inner.mem, self.inner.len) }
    }

    /// The whole memory, copied.
    pub fn contents(&self) -> Vec<u8> {
        self.mapped(0, self.inner.len).to_vec()
    }

    fn step(&self) -> Result<(), SimFlashError> {
        if self.is_dead() {
            return Err(SimFlashError::PowerCut);
        }
        let s = self.inner.steps.fetch_add(1, Ordering::SeqCst);
        if s >= self.inner.cut_at.load(Ordering::SeqCst) {
            self.inner.dead.store(true, Ordering::SeqCst);
            return Err(SimFlashError::PowerCut);
        }
        Ok(())
    }

    fn check(&self, offset: u32, len: usize, align: usize) -> Result<(), SimFlashError> {
        if !(offset as usize).is_multiple_of(align) || !len.is_multiple_of(align) {
            return Err(SimFlashError::NotAligned);
        }
        if offset as usize + len > self.inner.len {
            return Err(SimFlashError::OutOfBounds);
        }
        Ok(())
    }
}

impl ErrorType for SimFlash {
    type Error = SimFlashError;
}

impl ReadNorFlash for SimFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.check(offset, bytes.len(), 1)?;
        bytes.copy_from_slice(self.mapped(offset, bytes.len()));
        Ok(())
    }
    fn capacity(&self) -> usize {
        self.inner.len
    }
}

impl NorFlash for SimFlash {
    const WRITE_SIZE: usize = 8;
    const ERASE_SIZE: usize = Self::PAGE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if to < from {
            return Err(SimFlashError::OutOfBounds);
        }
        self.check(from, (to - from) as usize, Self::PAGE)?;
        for page in (from..to).step_by(Self::PAGE) {
            let p = unsafe { self.inner.mem.add(page as usize) };
            if let Err(e) = self.step() {
                // Power lost mid-erase: half the page is erased, half is not.
                unsafe { core::ptr::write_bytes(p, 0xFF, Self::PAGE / 2) };
                return Err(e);
            }
            unsafe { core::ptr::write_bytes(p, 0xFF, Self::PAGE) };
            self.inner.log.lock().unwrap().push(FlashOp::Erase(page));
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.check(offset, bytes.len(), Self::WRITE_SIZE)?;
        if self.mapped(offset, bytes.len()).iter().any(|b| *b != 0xFF) {
            return Err(SimFlashError::NotErased);
        }
        self.inner.log.lock().unwrap().push(FlashOp::Write(offset, bytes.len() as u32));
        for (i, b) in bytes.iter().enumerate() {
            self.step()?;
            unsafe { *self.inner.mem.add(offset as usize + i) = *b };
        }
        Ok(())
    }
}

// SAFETY: the memory is changed only by `erase`/`write` above, range by
// range. Unlike real flash it is freed with the last handle, so the 'static
// slices must not outlive every handle: the store and a calibration hold a
// handle (the store owns one) for as long as they use them, which is what the
// tests do. Simulation only.
unsafe impl MappedFlash for SimFlash {
    fn mapped(&self, offset: u32, len: usize) -> &'static [u8] {
        assert!(offset as usize + len <= self.inner.len, "mapped range outside the flash");
        unsafe { core::slice::from_raw_parts(self.inner.mem.add(offset as usize), len) }
    }
}
