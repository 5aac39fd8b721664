//! The acquisition time of one line, derived from the firmware's own
//! settings and the sensor readout's timing (`brdf_meter::platform::timing`):
//! the frames the line takes ([`Frames`]: a dark frame and m lit frames at
//! the long exposure, and, where a frame saturates, a dark frame and that
//! frame again at each shorter exposure the firmware configures), each an
//! LED settle, the part of the flush readout before integration starts, the
//! exposure and the readout.
//!
//! Derived: settle and exposure (timers), the flush's 296 cycles before the
//! 18th clock, the readout's 180 cycles per pixel (16 cycles AO settling,
//! [`OVERSAMPLE`] conversions of 24.5 + 12.5 ADC cycles at SYSCLK, two half
//! CLK periods of 8 cycles). Assumed (no board on this project's machines,
//! and QEMU has no ADC or DMA): the software cost of each pixel's ADC/DMA
//! read (driver set-up, the transfer-complete interrupt, the task's wake),
//! [`ASSUMED_PIXEL_OVERHEAD_US`] per pixel; the table also gives the line
//! time without it.
use brdf_meter::acquire::{AcqConfig, FrameRead, MAX_SHORT_EXPOSURES, RawLine};
use brdf_meter::platform::timing::{
    ADC_CONVERSION_HALF_CYCLES, ADC_SAMPLE_HALF_CYCLES, HALF_CLK_CYCLES, INTEGRATION_START_CLOCK, OVERSAMPLE,
    SETTLE_CYCLES, SYSCLK_HZ,
};
use serde::Serialize;

/// Assumed software cost of one pixel's ADC/DMA read (embassy-stm32's
/// `Adc::read` set-up, the DMA interrupt and the task's wake), microseconds.
pub const ASSUMED_PIXEL_OVERHEAD_US: f64 = 5.0;

/// The frames of one line, by exposure: how many at each, the long
/// exposure's first.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Frames {
    /// (exposure us, frames at it), longest first; no entry with 0 frames.
    pub by_exposure: Vec<(f64, usize)>,
}

impl Frames {
    /// A line that saturates nowhere: `frames` frames (the dark one and one
    /// per reading) at the long exposure.
    pub fn long_only(acq: &AcqConfig, frames: usize) -> Self {
        Self { by_exposure: vec![(acq.exposure_us as f64, frames)] }
    }

    /// A line whose every frame saturates at every exposure but the
    /// shortest: all `frames` again at each of `shorter_us`.
    pub fn every_exposure(long_us: f64, shorter_us: &[f64], frames: usize) -> Self {
        Self { by_exposure: std::iter::once(long_us).chain(shorter_us.iter().copied()).map(|e| (e, frames)).collect() }
    }

    /// The frames the acquisition (`brdf_meter::acquire::acquire_line`)
    /// takes of the recorded line `raw`: its frames in reading order
    /// (`RawLine::frames_read`, the device's rule: a shorter exposure of a
    /// reading whose longer frame saturated somewhere), and a dark frame at
    /// each shorter exposure that takes any.
    pub fn taken<const M: usize, const P: usize>(raw: &RawLine<M, P>, full_scale: u16, acq: &AcqConfig) -> Self {
        let levels = acq.short_levels();
        let mut count = [0usize; 1 + MAX_SHORT_EXPOSURES];
        for f in raw.frames_read(full_scale, levels) {
            match f {
                FrameRead::Dark | FrameRead::Long(_) => count[0] += 1,
                FrameRead::Short { level, .. } => count[1 + level] += 1,
            }
        }
        let mut by_exposure = vec![(acq.exposure_us as f64, count[0])];
        for l in 0..levels {
            if count[1 + l] > 0 {
                by_exposure.push((acq.short_exposures_us[l] as f64, 1 + count[1 + l]));
            }
        }
        Self { by_exposure }
    }

    /// Frames in all.
    pub fn count(&self) -> usize {
        self.by_exposure.iter().map(|(_, n)| n).sum()
    }

    /// Exposure summed over the frames, us.
    pub fn exposure_us(&self) -> f64 {
        self.by_exposure.iter().map(|(e, n)| e * *n as f64).sum()
    }

    /// "8 at 2000 us + 8 at 125 us": how the reports print it.
    pub fn describe(&self) -> String {
        self.by_exposure.iter().map(|(e, n)| format!("{n} at {e:.0} us")).collect::<Vec<_>>().join(" + ")
    }
}

/// One line's acquisition time, by part.
#[derive(Clone, Debug, Serialize)]
pub struct LineAcquisition {
    /// The frames the line takes, by exposure.
    pub frames: Frames,
    /// LED settle per frame, us.
    pub settle_us: f64,
    /// Flush readout before integration starts, per frame, us (derived).
    pub flush_us: f64,
    /// The long exposure, us.
    pub exposure_us: f64,
    /// Readout per frame from the clock and ADC timing, us (derived).
    pub readout_us: f64,
    /// Assumed ADC/DMA software cost per frame, us.
    pub assumed_overhead_us: f64,
    /// Whole line, us (with the assumed overhead).
    pub line_us: f64,
    /// Whole line without the assumed overhead, us.
    pub line_derived_us: f64,
    /// The same line had nothing saturated (its long exposure's frames
    /// alone), us, with the assumed overhead.
    pub long_only_us: f64,
    /// Of the line, the time the CPU is free for estimation and framing
    /// (settles and exposures: the acquisition task waits on timers), us.
    pub cpu_free_us: f64,
}

/// The board: a TSL1401 read through ADC1 and DMA, taking `frames`.
pub fn board(acq: &AcqConfig, pixels: usize, frames: Frames) -> LineAcquisition {
    let us = |cycles: f64| cycles / SYSCLK_HZ as f64 * 1e6;
    // start_pulse (two half periods), CLK low + a half period, then clocks
    // 2..=18 of two half periods each before integration starts.
    let flush_cycles = 3 * HALF_CLK_CYCLES as usize + (INTEGRATION_START_CLOCK - 1) * 2 * HALF_CLK_CYCLES as usize;
    let adc_cycles = OVERSAMPLE as f64 * (ADC_SAMPLE_HALF_CYCLES + ADC_CONVERSION_HALF_CYCLES) as f64 / 2.0;
    let pixel_cycles = SETTLE_CYCLES as f64 + adc_cycles + 2.0 * HALF_CLK_CYCLES as f64;
    let readout_cycles = 2.0 * HALF_CLK_CYCLES as f64 + pixels as f64 * pixel_cycles;
    let n = frames.count() as f64;
    // Every frame but its exposure costs the same.
    let per_frame = |overhead: f64| acq.settle_us as f64 + us(flush_cycles as f64) + us(readout_cycles) + overhead;
    let fixed = |overhead: f64| n * per_frame(overhead);
    let overhead = pixels as f64 * ASSUMED_PIXEL_OVERHEAD_US;
    let long = frames.by_exposure.first().map_or(0.0, |(e, k)| *k as f64 * (per_frame(overhead) + e));
    LineAcquisition {
        settle_us: acq.settle_us as f64,
        flush_us: us(flush_cycles as f64),
        exposure_us: acq.exposure_us as f64,
        readout_us: us(readout_cycles),
        assumed_overhead_us: overhead,
        line_us: fixed(overhead) + frames.exposure_us(),
        line_derived_us: fixed(0.0) + frames.exposure_us(),
        long_only_us: long,
        cpu_free_us: n * acq.settle_us as f64 + frames.exposure_us(),
        frames,
    }
}

/// The QEMU build: its simulated sensor hands a frame over at once, so a
/// line is its settles and exposures.
pub fn qemu(acq: &AcqConfig, frames: Frames) -> LineAcquisition {
    let line = frames.count() as f64 * acq.settle_us as f64 + frames.exposure_us();
    let long = frames.by_exposure.first().map_or(0.0, |(e, k)| *k as f64 * (acq.settle_us as f64 + e));
    LineAcquisition {
        settle_us: acq.settle_us as f64,
        flush_us: 0.0,
        exposure_us: acq.exposure_us as f64,
        readout_us: 0.0,
        assumed_overhead_us: 0.0,
        line_us: line,
        line_derived_us: line,
        long_only_us: long,
        cpu_free_us: line,
        frames,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_board_line_follows_from_its_settings() {
        let acq = brdf_meter::platform::timing::ACQUISITION;
        let a = board(&acq, 128, Frames::long_only(&acq, 8));
        // 296 cycles of flush, 16 + 128 x 180 cycles of readout at 80 MHz.
        assert!((a.flush_us - 3.7).abs() < 1e-9);
        assert!((a.readout_us - 288.2).abs() < 1e-9);
        assert!((a.line_derived_us - 8.0 * (200.0 + 3.7 + 2000.0 + 288.2)).abs() < 1e-6);
        assert!((a.line_us - a.line_derived_us - 8.0 * 128.0 * ASSUMED_PIXEL_OVERHEAD_US).abs() < 1e-6);
        assert_eq!(a.cpu_free_us, 8.0 * 2200.0);
        let qacq = brdf_meter::platform::timing::QEMU_ACQUISITION;
        let q = qemu(&qacq, Frames::long_only(&qacq, 8));
        assert_eq!(q.line_us, 8.0 * (100.0 + 400.0));
        // Frames at a shorter exposure cost all but the exposure again.
        let s = board(&acq, 128, Frames { by_exposure: vec![(2000.0, 8), (125.0, 3)] });
        assert!((s.line_derived_us - a.line_derived_us - 3.0 * (200.0 + 3.7 + 125.0 + 288.2)).abs() < 1e-6);
        assert_eq!(s.cpu_free_us, 8.0 * 2200.0 + 3.0 * 325.0);
        assert_eq!(s.long_only_us, a.line_us);
    }

    #[test]
    fn the_frames_taken_are_the_devices() {
        // Two readings, four pixels, a 12-bit sensor: reading 0 saturates at
        // the long exposure and at the first shorter one, reading 1 nowhere.
        const M: usize = 2;
        const P: usize = 4;
        let acq = brdf_meter::platform::timing::ACQUISITION;
        let mut raw = RawLine::<M, P>::new();
        raw.lit[0] = [100, 4095, 100, 100];
        raw.lit[1] = [100; P];
        for l in 0..MAX_SHORT_EXPOSURES {
            raw.short_taken[l] = [true; M];
        }
        raw.short[0][0] = [10, 4095, 10, 10];
        let f = Frames::taken(&raw, 4095, &acq);
        assert_eq!(f.by_exposure, vec![(2000.0, 3), (125.0, 2), (25.0, 2)]);
        assert_eq!(f.count(), 7);
        assert_eq!(f.describe(), "3 at 2000 us + 2 at 125 us + 2 at 25 us");
        // Nothing saturated (nor, then, at the shorter exposures): the long
        // exposure's frames alone.
        raw.lit[0][1] = 4000;
        raw.short[0][0][1] = 250;
        assert_eq!(Frames::taken(&raw, 4095, &acq), Frames::long_only(&acq, 3));
        // Where the sensor has no shorter frames, none are taken.
        raw.lit[0][1] = 4095;
        raw.short_taken = [[false; M]; MAX_SHORT_EXPOSURES];
        assert_eq!(Frames::taken(&raw, 4095, &acq), Frames::long_only(&acq, 3));
    }
}
