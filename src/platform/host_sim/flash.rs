//! The host simulation's flash: the shared NOR rules ([`NorFake`]) over a heap
//! buffer that can lose power at any step. After `cut_after(k)` steps (bytes
//! written or pages erased) the flash stops - the byte in progress is not
//! written, a page erase in progress leaves the page half erased - and every
//! later operation fails, as on a dead device. `reboot()` gives a fresh handle
//! on a copy of the memory, as after power returns; `restore()` powers the
//! same memory back on with given contents.
use crate::platform::nor_fake::{FlashOp, NorFake, NorFault, NorStorage};
use crate::shape::FLASH_PAGE;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// The simulated flash (cheap to clone; clones share the memory).
pub type SimFlash = NorFake<PowerCutMemory>;

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
        // last handle is going: see the NorStorage impl on slices' lifetime.
        unsafe { drop(Box::from_raw(core::ptr::slice_from_raw_parts_mut(self.mem, self.len))) }
    }
}

// The memory is only touched through the store's contract (see MappedFlash):
// writes never overlap a mapped slice in use. Tests share a flash between a
// store and a checker on one thread at a time.
unsafe impl Send for Inner {}
unsafe impl Sync for Inner {}

/// Heap memory under [`SimFlash`], with a power switch and an operation log.
#[derive(Clone)]
pub struct PowerCutMemory {
    inner: Arc<Inner>,
}

// SAFETY: the memory is changed only through the NorFake over it. Unlike real
// flash it is freed with the last handle, so the 'static slices of `mapped`
// must not outlive every handle: the store and a calibration hold a handle
// (the store owns one) for as long as they use them, which is what the tests
// do. Simulation only.
unsafe impl NorStorage for PowerCutMemory {
    fn base(&self) -> *mut u8 {
        self.inner.mem
    }
    fn capacity(&self) -> usize {
        self.inner.len
    }
    fn step(&self) -> Result<(), NorFault> {
        if self.inner.dead.load(Ordering::SeqCst) {
            return Err(NorFault::PowerCut);
        }
        let s = self.inner.steps.fetch_add(1, Ordering::SeqCst);
        if s >= self.inner.cut_at.load(Ordering::SeqCst) {
            self.inner.dead.store(true, Ordering::SeqCst);
            return Err(NorFault::PowerCut);
        }
        Ok(())
    }
    fn record(&self, op: FlashOp) {
        self.inner.log.lock().unwrap().push(op);
    }
}

impl SimFlash {
    /// Page (erase) size, as on the STM32L4.
    pub const PAGE: usize = FLASH_PAGE;

    /// An erased flash of `len` bytes (a multiple of the page size).
    pub fn new(len: usize) -> Self {
        Self::with_contents(vec![0xFFu8; len])
    }

    /// A flash holding `contents` (whole pages), e.g. an image composed on
    /// the host for the chip.
    pub fn with_contents(contents: Vec<u8>) -> Self {
        let len = contents.len();
        // Freed when the last handle goes (see `Inner`'s Drop).
        let mem = Box::leak(contents.into_boxed_slice()).as_mut_ptr();
        NorFake::over(PowerCutMemory {
            inner: Arc::new(Inner {
                mem,
                len,
                steps: AtomicUsize::new(0),
                cut_at: AtomicUsize::new(usize::MAX),
                dead: AtomicBool::new(false),
                log: Mutex::new(Vec::new()),
            }),
        })
    }

    fn inner(&self) -> &Inner {
        &self.storage().inner
    }

    /// Cuts the power after `steps` more steps (bytes written or pages erased).
    pub fn cut_after(&self, steps: usize) {
        let now = self.inner().steps.load(Ordering::SeqCst);
        self.inner().cut_at.store(now + steps, Ordering::SeqCst);
    }

    /// Steps done so far.
    pub fn steps(&self) -> usize {
        self.inner().steps.load(Ordering::SeqCst)
    }

    /// Whether the power was cut.
    pub fn is_dead(&self) -> bool {
        self.inner().dead.load(Ordering::SeqCst)
    }

    /// Operations that reached the flash.
    pub fn log(&self) -> Vec<FlashOp> {
        self.inner().log.lock().unwrap().clone()
    }

    /// Power back on: a handle on a copy of the memory as it is now, with no
    /// cut pending (a copy, so the caller can retry the same cut elsewhere).
    pub fn reboot(&self) -> Self {
        Self::with_contents(self.contents())
    }

    /// Power back on with `contents` (the whole memory) written in place,
    /// as a debugger restoring an image: unlike [`Self::reboot`], every
    /// handle sees them, so a store holding one carries on over them. No cut
    /// is pending, and the step count and the log start again.
    pub fn restore(&self, contents: &[u8]) {
        let inner = self.inner();
        assert_eq!(contents.len(), inner.len, "a restore writes the whole memory");
        // SAFETY: in bounds; like a write, done while no mapped slice of this
        // memory is in use (see the NorStorage impl).
        unsafe { core::ptr::copy_nonoverlapping(contents.as_ptr(), inner.mem, inner.len) };
        inner.steps.store(0, Ordering::SeqCst);
        inner.cut_at.store(usize::MAX, Ordering::SeqCst);
        inner.dead.store(false, Ordering::SeqCst);
        inner.log.lock().unwrap().clear();
    }

    /// The whole memory, copied.
    pub fn contents(&self) -> Vec<u8> {
        use crate::hw::MappedFlash;
        self.mapped(0, self.inner().len).to_vec()
    }
}
