//! The acquisition pipeline: for each line, a dark frame and one frame per LED
//! in the calibrated order, then dark subtraction, white calibration (per pixel
//! and LED) and per-point quality flags.
//!
//! [`correct_point`] is the one definition of a corrected reading: the device
//! runs it, and the host runs it to reproduce the device's numbers bit for bit.
use crate::protocol::flags;
use nalgebra::SVector;

/// Dark-corrected signal (counts) below which a reading is flagged
/// under-exposed: a few LSB of a 12-bit converter, where quantisation and dark
/// noise dominate.
pub const MIN_SIGNAL_COUNTS: f32 = 8.0;

/// Raw frames of one line: the dark frame and, for each reading i, the frame
/// taken with LED `led_order[i]` lit.
#[derive(Clone)]
pub struct RawLine<const M: usize, const P: usize> {
    /// Dark frame.
    pub dark: [u16; P],
    /// Frame of reading i (reading order, not LED index).
    pub lit: [[u16; P]; M],
}

impl<const M: usize, const P: usize> RawLine<M, P> {
    /// All zeros.
    pub const fn new() -> Self {
        Self { dark: [0; P], lit: [[0; P]; M] }
    }
}

impl<const M: usize, const P: usize> Default for RawLine<M, P> {
    fn default() -> Self {
        Self::new()
    }
}

/// Corrects one point: `v[i] = (lit[i] - dark) / white[i]`, in f32, and flags
/// saturation (a raw value at full scale), under-exposure (signal below
/// [`MIN_SIGNAL_COUNTS`]) and non-finite results. Fixed-size form of
/// [`correct_point_into`] (same operations, same bits).
#[inline]
pub fn correct_point<const M: usize>(dark: u16, lit: &[u16; M], white: &[f32; M], full_scale: u16) -> ([f32; M], u8) {
    let mut v = [0.0f32; M];
    let f = correct_point_into(dark, lit, white, full_scale, &mut v);
    (v, f)
}

/// Corrects one point of `lit.len()` readings into `v`; returns its flags.
/// The one definition of a corrected reading (the host uses it to reproduce
/// the device's numbers).
///
/// # Panics
/// If `lit`, `white` and `v` differ in length.
#[inline]
pub fn correct_point_into(dark: u16, lit: &[u16], white: &[f32], full_scale: u16, v: &mut [f32]) -> u8 {
    assert!(lit.len() == white.len() && lit.len() == v.len(), "one white value and one output per reading");
    let mut f = 0u8;
    if dark >= full_scale {
        f |= flags::SATURATED;
    }
    for i in 0..v.len() {
        if lit[i] >= full_scale {
            f |= flags::SATURATED;
        }
        let s = lit[i] as f32 - dark as f32;
        if s < MIN_SIGNAL_COUNTS {
            f |= flags::UNDER_EXPOSED;
        }
        v[i] = s / white[i];
        if !v[i].is_finite() {
            f |= flags::NON_FINITE;
        }
    }
    f
}

/// Corrects a whole line into `v` and `fl` (one entry per pixel).
pub fn correct_line<const M: usize, const P: usize>(
    raw: &RawLine<M, P>,
    white: &[[f32; M]; P],
    full_scale: u16,
    v: &mut [SVector<f32, M>; P],
    fl: &mut [u8; P],
) {
    for p in 0..P {
        let lit: [u16; M] = core::array::from_fn(|i| raw.lit[i][p]);
        fl[p] = correct_point_into(raw.dark[p], &lit, &white[p], full_scale, v[p].as_mut_slice());
    }
}

/// Timing and drive of an acquisition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AcqConfig {
    /// Sensor integration time per frame.
    pub exposure_us: u32,
    /// Wait after switching LEDs before integrating.
    pub settle_us: u32,
    /// LED drive, 0..=u16::MAX.
    pub intensity: u16,
}

impl Default for AcqConfig {
    fn default() -> Self {
        Self { exposure_us: 500, settle_us: 50, intensity: u16::MAX }
    }
}

/// Reads one line's frames: dark, then one frame per reading with LED
/// `order[i]` lit. The LEDs are off when this returns, error or not.
#[cfg(feature = "app")]
pub async fn acquire_line<L: crate::hw::Leds, S: crate::hw::LineSensor, const M: usize, const P: usize>(
    leds: &mut L,
    sensor: &mut S,
    order: &[u8; M],
    cfg: &AcqConfig,
    raw: &mut RawLine<M, P>,
) -> Result<(), crate::hw::SensorError> {
    use embassy_time::Timer;
    let settle = || Timer::after_micros(cfg.settle_us as u64);
    leds.set(None, 0).await;
    settle().await;
    let mut r = sensor.read_frame(cfg.exposure_us, &mut raw.dark).await;
    for (&led, lit) in order.iter().zip(raw.lit.iter_mut()) {
        if r.is_err() {
            break;
        }
        leds.set(Some(led), cfg.intensity).await;
        settle().await;
        r = sensor.read_frame(cfg.exposure_us, lit).await;
    }
    leds.set(None, 0).await;
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corrects_and_flags() {
        let white = [1000.0f32, 500.0, 250.0];
        let (v, f) = correct_point(100, &[1100, 600, 350], &white, 4095);
        assert_eq!(v, [1.0, 1.0, 1.0]);
        assert_eq!(f, 0);
        let (_, f) = correct_point(100, &[4095, 600, 350], &white, 4095);
        assert_eq!(f, flags::SATURATED);
        let (v, f) = correct_point(100, &[1100, 104, 350], &white, 4095);
        assert_eq!(f, flags::UNDER_EXPOSED);
        assert_eq!(v[1], 4.0 / 500.0);
        let (_, f) = correct_point(4095, &[4095, 4095, 4095], &white, 4095);
        assert_eq!(f, flags::SATURATED | flags::UNDER_EXPOSED);
        let (_, f) = correct_point(0, &[10, 10, 10], &[f32::MIN_POSITIVE, 1.0, 1.0], 4095);
        assert_eq!(f & flags::NON_FINITE, flags::NON_FINITE);
    }

    #[test]
    fn line_correction_matches_point_correction() {
        let mut raw = RawLine::<2, 3>::new();
        raw.dark = [10, 20, 30];
        raw.lit = [[110, 220, 330], [60, 70, 80]];
        let white = [[100.0, 50.0], [200.0, 25.0], [300.0, 10.0]];
        let mut v = [SVector::<f32, 2>::zeros(); 3];
        let mut fl = [0; 3];
        correct_line(&raw, &white, 4095, &mut v, &mut fl);
        for p in 0..3 {
            let (vp, f) = correct_point(raw.dark[p], &[raw.lit[0][p], raw.lit[1][p]], &white[p], 4095);
            assert_eq!(v[p], SVector::from(vp));
            assert_eq!(fl[p], f);
        }
    }
}
