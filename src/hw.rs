//! The hardware the application needs, behind traits, so the same application
//! code runs on the board (embassy-stm32), in QEMU (a small board layer of its
//! own) and in the host simulation (in-memory fakes).
//!
//! Transports use `embedded_io_async::{Read, Write}`; calibration storage uses
//! `embedded_storage::nor_flash::NorFlash`. Only what has no standard trait is
//! defined here.
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

/// A line sensor: P pixels, each one point on the surface.
pub trait LineSensor {
    /// Pixels per line.
    fn pixels(&self) -> usize;
    /// Largest raw value; readings at or above it are saturated.
    fn full_scale(&self) -> u16;
    /// Integrates light for `exposure_us` microseconds and reads one frame.
    async fn read_frame(&mut self, exposure_us: u32, out: &mut [u16]) -> Result<(), SensorError>;
}
