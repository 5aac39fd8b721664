//! The acquisition time of one line, derived from the firmware's own
//! settings and the sensor readout's timing (`brdf_meter::platform::timing`):
//! a dark frame and m lit frames, each an LED settle, the part of the flush
//! readout before integration starts, the exposure and the readout.
//!
//! Derived: settle and exposure (timers), the flush's 296 cycles before the
//! 18th clock, the readout's 180 cycles per pixel (16 cycles AO settling,
//! [`OVERSAMPLE`] conversions of 24.5 + 12.5 ADC cycles at SYSCLK, two half
//! CLK periods of 8 cycles). Assumed (no board on this project's machines,
//! and QEMU has no ADC or DMA): the software cost of each pixel's ADC/DMA
//! read (driver set-up, the transfer-complete interrupt, the task's wake),
//! [`ASSUMED_PIXEL_OVERHEAD_US`] per pixel; the table also gives the line
//! time without it.
use brdf_meter::acquire::AcqConfig;
use brdf_meter::platform::timing::{
    ADC_CONVERSION_HALF_CYCLES, ADC_SAMPLE_HALF_CYCLES, HALF_CLK_CYCLES, INTEGRATION_START_CLOCK, OVERSAMPLE,
    SETTLE_CYCLES, SYSCLK_HZ,
};
use serde::Serialize;

/// Assumed software cost of one pixel's ADC/DMA read (embassy-stm32's
/// `Adc::read` set-up, the DMA interrupt and the task's wake), microseconds.
pub const ASSUMED_PIXEL_OVERHEAD_US: f64 = 5.0;

/// One line's acquisition time, by part.
#[derive(Clone, Debug, Serialize)]
pub struct LineAcquisition {
    /// Frames per line (dark + m).
    pub frames: usize,
    /// LED settle per frame, us.
    pub settle_us: f64,
    /// Flush readout before integration starts, per frame, us (derived).
    pub flush_us: f64,
    /// Exposure per frame, us.
    pub exposure_us: f64,
    /// Readout per frame from the clock and ADC timing, us (derived).
    pub readout_us: f64,
    /// Assumed ADC/DMA software cost per frame, us.
    pub assumed_overhead_us: f64,
    /// Whole line, us (with the assumed overhead).
    pub line_us: f64,
    /// Whole line without the assumed overhead, us.
    pub line_derived_us: f64,
    /// Of the line, the time the CPU is free for estimation and framing
    /// (settles and exposures: the acquisition task waits on timers), us.
    pub cpu_free_us: f64,
}

/// The board: a TSL1401 read through ADC1 and DMA.
pub fn board(acq: &AcqConfig, pixels: usize, frames: usize) -> LineAcquisition {
    let us = |cycles: f64| cycles / SYSCLK_HZ as f64 * 1e6;
    // start_pulse (two half periods), CLK low + a half period, then clocks
    // 2..=18 of two half periods each before integration starts.
    let flush_cycles = 3 * HALF_CLK_CYCLES as usize + (INTEGRATION_START_CLOCK - 1) * 2 * HALF_CLK_CYCLES as usize;
    let adc_cycles = OVERSAMPLE as f64 * (ADC_SAMPLE_HALF_CYCLES + ADC_CONVERSION_HALF_CYCLES) as f64 / 2.0;
    let pixel_cycles = SETTLE_CYCLES as f64 + adc_cycles + 2.0 * HALF_CLK_CYCLES as f64;
    let readout_cycles = 2.0 * HALF_CLK_CYCLES as f64 + pixels as f64 * pixel_cycles;
    let per_frame = |overhead: f64| {
        acq.settle_us as f64 + us(flush_cycles as f64) + acq.exposure_us as f64 + us(readout_cycles) + overhead
    };
    let overhead = pixels as f64 * ASSUMED_PIXEL_OVERHEAD_US;
    LineAcquisition {
        frames,
        settle_us: acq.settle_us as f64,
        flush_us: us(flush_cycles as f64),
        exposure_us: acq.exposure_us as f64,
        readout_us: us(readout_cycles),
        assumed_overhead_us: overhead,
        line_us: frames as f64 * per_frame(overhead),
        line_derived_us: frames as f64 * per_frame(0.0),
        cpu_free_us: frames as f64 * (acq.settle_us + acq.exposure_us) as f64,
    }
}

/// The QEMU build: its simulated sensor hands a frame over at once, so a
/// line is its settles and exposures.
pub fn qemu(acq: &AcqConfig, frames: usize) -> LineAcquisition {
    let per_frame = (acq.settle_us + acq.exposure_us) as f64;
    LineAcquisition {
        frames,
        settle_us: acq.settle_us as f64,
        flush_us: 0.0,
        exposure_us: acq.exposure_us as f64,
        readout_us: 0.0,
        assumed_overhead_us: 0.0,
        line_us: frames as f64 * per_frame,
        line_derived_us: frames as f64 * per_frame,
        cpu_free_us: frames as f64 * per_frame,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_board_line_follows_from_its_settings() {
        let a = board(&brdf_meter::platform::timing::ACQUISITION, 128, 8);
        // 296 cycles of flush, 16 + 128 x 180 cycles of readout at 80 MHz.
        assert!((a.flush_us - 3.7).abs() < 1e-9);
        assert!((a.readout_us - 288.2).abs() < 1e-9);
        assert!((a.line_derived_us - 8.0 * (200.0 + 3.7 + 2000.0 + 288.2)).abs() < 1e-6);
        assert!((a.line_us - a.line_derived_us - 8.0 * 128.0 * ASSUMED_PIXEL_OVERHEAD_US).abs() < 1e-6);
        assert_eq!(a.cpu_free_us, 8.0 * 2200.0);
        let q = qemu(&brdf_meter::platform::timing::QEMU_ACQUISITION, 8);
        assert_eq!(q.line_us, 8.0 * (100.0 + 400.0));
    }
}
