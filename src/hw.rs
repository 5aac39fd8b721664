//! The hardware the application needs, behind traits, so the same application
//! code runs on the board (embassy-stm32), in QEMU (a small board layer of its
//! own) and in the host simulation (in-memory fakes).
//!
//! Transports use `embedded_io_async::{Read, Write}`; calibration storage uses
//! `embedded_storage::nor_flash::NorFlash`, plus [`MappedFlash`] so blobs are
//! read in place. Only what has no standard trait is defined here: the LEDs,
//! the line sensor, and [`FrameInput`] (where a simulated sensor's frames come
//! from; [`NoFrameInput`] on real hardware).
#![allow(async_fn_in_trait)] // single-threaded executors: no Send bound wanted

/// The m LEDs that light the surface, one at a time.
pub trait Leds {
    /// Number of LEDs fitted.
    fn count(&self) -> usize;
    /// Lights LED `led` (index < `count()`) at relative `intensity` in
    /// 0..=u16::MAX with every other LED off; `None` turns all LEDs off (the
    /// dark frame). Returns once the drive is applied; settling is the
    /// caller's to wait for.
    async fn set(&mut self, led: Option<u8>, intensity: u16);
}

/// Why a frame could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SensorError {
    /// The sensor or its converter did not answer in time.
    Timeout,
    /// The output buffer does not have `pixels()` elements.
    BadLength,
    /// No frame is available (e.g. a simulated sensor with no scene loaded).
    NoData,
}

/// The inspection's reject output: a digital line a PLC reads (a GPIO on
/// the board; recorded in the host simulation; a GPIO QEMU cannot show, so
/// the application also reports each pulse on the link).
pub trait RejectOutput {
    /// Drives the output: `true` = reject (active).
    fn set(&mut self, on: bool);
}

/// A line sensor: P pixels, each one point on the surface.
pub trait LineSensor {
    /// Pixels per line.
    fn pixels(&self) -> usize;
    /// Largest raw value; readings at or above it are saturated.
    fn full_scale(&self) -> u16;
    /// Integrates light for `exposure_us` microseconds and reads one frame.
    /// The integration starts before the first await that waits for it:
    /// the acquisition polls the read once, then does other work while the
    /// frame integrates ([`crate::acquire::FrameWork::integrating`]).
    async fn read_frame(&mut self, exposure_us: u32, out: &mut [u16]) -> Result<(), SensorError>;
}

/// NOR flash whose content can also be read as memory: the MCU's internal
/// flash (memory-mapped at 0x0800_0000), the QEMU build's RAM-backed flash and
/// the host simulation's mock. The calibration store reads blobs in place
/// through this, so the board can run matrices larger than its RAM straight
/// from flash.
///
/// # Safety
/// The implementer guarantees that `mapped(offset, len)` returns the bytes
/// that a `read` of that range would return, that the memory stays valid for
/// the program's life, and that it changes only through this object's
/// `write`/`erase` of that range. The calibration store, for its part, never
/// writes or erases a range while a slice of it obtained here is in use (the
/// active slot is never written).
pub unsafe trait MappedFlash: embedded_storage::nor_flash::NorFlash {
    /// The bytes at `offset..offset + len` of this flash.
    ///
    /// # Panics
    /// If the range is outside the flash.
    fn mapped(&self, offset: u32, len: usize) -> &'static [u8];
}

/// Why a request to load simulated frames was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameLoadError {
    /// This device has a real sensor.
    NotSimulated,
    /// Line, frame or pixel range outside the frame store's capacity.
    OutOfRange,
}

/// Where a simulated sensor takes its frames from; the transport feeds it from
/// the simulation-only protocol messages. Real boards use [`NoFrameInput`].
pub trait FrameInput {
    /// Stores `pixels` (u16 values) at `first_pixel..` of frame `frame`
    /// (0 = dark, 1 + LED index) of frame line `line`.
    fn load(
        &mut self,
        line: u8,
        frame: u8,
        first_pixel: u16,
        pixels: impl Iterator<Item = u16>,
    ) -> Result<(), FrameLoadError>;
    /// Sets how many scene lines the sensor cycles through.
    fn set_lines(&mut self, lines: u8) -> Result<(), FrameLoadError>;
    /// Whether this device's sensor is simulated.
    fn simulated(&self) -> bool;
}

/// The [`FrameInput`] of a device with a real sensor: refuses every request.
pub struct NoFrameInput;

impl FrameInput for NoFrameInput {
    fn load(&mut self, _: u8, _: u8, _: u16, _: impl Iterator<Item = u16>) -> Result<(), FrameLoadError> {
        Err(FrameLoadError::NotSimulated)
    }
    fn set_lines(&mut self, _: u8) -> Result<(), FrameLoadError> {
        Err(FrameLoadError::NotSimulated)
    }
    fn simulated(&self) -> bool {
        false
    }
}
