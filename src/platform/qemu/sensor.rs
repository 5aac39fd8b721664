//! A simulated line sensor: frames come from a scene the host loads over the
//! link (simulation-only protocol messages) into a [`FrameStore`]; the frame
//! served is the one of the LED the GPIO pins light, as a real sensor would see.
use crate::frame_store::FrameStore;
use crate::hw::{FrameInput, FrameLoadError, LineSensor, SensorError};
use core::cell::RefCell;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex as Cs;

/// The frames, shared by the sensor and the transport's frame input.
pub struct Frames<const P: usize, const F: usize, const L: usize>(Mutex<Cs, RefCell<FrameStore<P, F, L>>>);

impl<const P: usize, const F: usize, const L: usize> Default for Frames<P, F, L> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const P: usize, const F: usize, const L: usize> Frames<P, F, L> {
    /// Empty.
    pub const fn new() -> Self {
        Self(Mutex::new(RefCell::new(FrameStore::new())))
    }
}

/// The simulated sensor: serves the loaded frames.
pub struct FrameSensor<const P: usize, const F: usize, const L: usize> {
    /// The frames it serves.
    pub frames: &'static Frames<P, F, L>,
    /// Full scale reported.
    pub full_scale: u16,
    /// Which LED is lit (read from the pins).
    pub lit: fn() -> Option<u8>,
    /// The acquisition's exposures: which level a frame's exposure is.
    pub acq: crate::acquire::AcqConfig,
}

impl<const P: usize, const F: usize, const L: usize> LineSensor for FrameSensor<P, F, L> {
    fn pixels(&self) -> usize {
        P
    }
    fn full_scale(&self) -> u16 {
        self.full_scale
    }
    async fn read_frame(&mut self, exposure_us: u32, out: &mut [u16]) -> Result<(), SensorError> {
        embassy_time::Timer::after_micros(exposure_us as u64).await;
        let lit = (self.lit)();
        let level = self.acq.level_of(exposure_us);
        self.frames.0.lock(|s| s.borrow_mut().read(lit, level, out))
    }
}

/// The transport's handle on the frames.
pub struct FramesIn<const P: usize, const F: usize, const L: usize>(pub &'static Frames<P, F, L>);

impl<const P: usize, const F: usize, const L: usize> FrameInput for FramesIn<P, F, L> {
    fn load(&mut self, line: u8, frame: u8, first: u16, px: impl Iterator<Item = u16>) -> Result<(), FrameLoadError> {
        self.0.0.lock(|s| s.borrow_mut().load(line, frame, first, px))
    }
    fn set_lines(&mut self, lines: u8) -> Result<(), FrameLoadError> {
        self.0.0.lock(|s| s.borrow_mut().set_lines(lines))
    }
    fn simulated(&self) -> bool {
        true
    }
}
