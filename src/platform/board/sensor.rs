//! A 128-pixel TSL1401-class line sensor: SI and CLK driven from GPIO, the
//! analog output read by ADC1 through DMA.
//!
//! # How a frame is read
//! The TSL1401 transfers every pixel's charge to its sample-and-hold at the
//! SI pulse and shifts the held values out on AO, one per CLK rising edge;
//! the 129th clock ends the output. Integration of the next line starts at
//! the 18th clock after SI. So one frame of `exposure_us` is:
//! 1. a flush readout (SI + 129 clocks, values discarded), noting the time of
//!    its 18th clock: integration starts there;
//! 2. waiting until `exposure_us` after that instant (asynchronously: USB and
//!    the other tasks keep running);
//! 3. the real readout: SI + 128 clocks, each followed by [`OVERSAMPLE`] ADC
//!    conversions moved by DMA and averaged, then the 129th clock.
//!
//! Because the held values are frozen at SI, the readout's own timing (which
//! the executor may stretch) does not change the pixel values.
//! The shortest exposure is the flush's remaining 111 clocks (tens of us).

use crate::hw::{LineSensor, SensorError};
use embassy_stm32::Peri;
use embassy_stm32::adc::{Adc, AdcChannel, AnyAdcChannel, SampleTime};
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::peripherals::{ADC1, DMA1_CH1, PA3, PC5, PD14};
use embassy_time::{Duration, Instant, Timer, with_timeout};

use super::Irqs;

/// Pixels per line (the build shape's P; the TSL1401 has 128).
pub const PIXELS: usize = crate::shape::board::PIXELS;
/// 12-bit ADC: readings at or above this are saturated.
pub const FULL_SCALE: u16 = 4095;
/// ADC conversions averaged per pixel.
pub const OVERSAMPLE: usize = crate::platform::timing::OVERSAMPLE;
/// Longest integration the TSL1401 datasheet allows (100 ms); longer requests
/// are clamped.
pub const MAX_EXPOSURE_US: u32 = 100_000;
/// Clock after SI at which the next integration starts (datasheet).
use crate::platform::timing::INTEGRATION_START_CLOCK;
/// AO settling and half CLK periods, in cycles at 80 MHz (the numbers and
/// their reasons: `crate::platform::timing`).
use crate::platform::timing::{HALF_CLK_CYCLES, SETTLE_CYCLES};
/// Longest time one pixel's DMA read may take before the sensor is declared
/// dead (4 conversions take about 2 us).
const PIXEL_TIMEOUT: Duration = Duration::from_millis(2);

/// The line sensor on ADC1 with DMA.
pub struct Tsl1401 {
    adc: Adc<'static, ADC1>,
    ao: AnyAdcChannel<'static, ADC1>,
    dma: Peri<'static, DMA1_CH1>,
    si: Output<'static>,
    clk: Output<'static>,
}

impl Tsl1401 {
    /// SI on PD14, CLK on PA3, AO on PC5 (ADC1_IN14), DMA1 channel 1.
    pub fn new(
        adc: Peri<'static, ADC1>,
        ao: Peri<'static, PC5>,
        dma: Peri<'static, DMA1_CH1>,
        si: Peri<'static, PD14>,
        clk: Peri<'static, PA3>,
    ) -> Self {
        Self {
            adc: Adc::new(adc),
            ao: ao.degrade_adc(),
            dma,
            si: Output::new(si, Level::Low, Speed::VeryHigh),
            clk: Output::new(clk, Level::Low, Speed::VeryHigh),
        }
    }

    /// One CLK pulse with SI high across its rising edge (the start of a
    /// readout).
    fn start_pulse(&mut self) {
        self.si.set_high();
        cortex_m::asm::delay(HALF_CLK_CYCLES); // SI setup before CLK (20 ns min)
        self.clk.set_high();
        cortex_m::asm::delay(HALF_CLK_CYCLES); // SI hold after CLK (0 ns min)
        self.si.set_low();
    }

    fn clock(&mut self) {
        self.clk.set_high();
        cortex_m::asm::delay(HALF_CLK_CYCLES);
        self.clk.set_low();
        cortex_m::asm::delay(HALF_CLK_CYCLES);
    }

    /// Flush readout: discards the held line and returns the instant at which
    /// the next integration started.
    fn flush(&mut self) -> Instant {
        self.start_pulse();
        self.clk.set_low();
        cortex_m::asm::delay(HALF_CLK_CYCLES);
        let mut started = Instant::now();
        for k in 2..=PIXELS + 1 {
            self.clock();
            if k == INTEGRATION_START_CLOCK {
                started = Instant::now();
            }
        }
        started
    }

    /// Samples AO once the current pixel is on it: OVERSAMPLE conversions by
    /// DMA, averaged.
    async fn sample(&mut self) -> Result<u16, SensorError> {
        cortex_m::asm::delay(SETTLE_CYCLES);
        let mut buf = [0u16; OVERSAMPLE];
        let read =
            self.adc.read(self.dma.reborrow(), Irqs, [(&mut self.ao, SampleTime::CYCLES24_5)].into_iter(), &mut buf);
        with_timeout(PIXEL_TIMEOUT, read).await.map_err(|_| SensorError::Timeout)?;
        let sum: u32 = buf.iter().map(|&x| u32::from(x)).sum();
        Ok((sum / OVERSAMPLE as u32) as u16)
    }
}

impl LineSensor for Tsl1401 {
    fn pixels(&self) -> usize {
        PIXELS
    }

    fn full_scale(&self) -> u16 {
        FULL_SCALE
    }

    async fn read_frame(&mut self, exposure_us: u32, out: &mut [u16]) -> Result<(), SensorError> {
        if out.len() != PIXELS {
            return Err(SensorError::BadLength);
        }
        let exposure_us = if exposure_us > MAX_EXPOSURE_US {
            defmt::warn!("exposure {} us clamped to {} us", exposure_us, MAX_EXPOSURE_US);
            MAX_EXPOSURE_US
        } else {
            exposure_us
        };
        let started = self.flush();
        Timer::at(started + Duration::from_micros(u64::from(exposure_us))).await;

        // Pixel 1 is on AO after the SI clock's rising edge.
        self.start_pulse();
        let mut result = Ok(());
        for o in out.iter_mut() {
            // CLK is high here: the current pixel is on AO. After an error the
            // remaining clocks still run, so the sensor ends its output cleanly.
            if result.is_ok() {
                match self.sample().await {
                    Ok(v) => *o = v,
                    Err(e) => result = Err(e),
                }
            }
            self.clk.set_low();
            cortex_m::asm::delay(HALF_CLK_CYCLES);
            self.clk.set_high();
            cortex_m::asm::delay(HALF_CLK_CYCLES);
        }
        // The last rising edge above was the 129th clock: it ends the output.
        self.clk.set_low();
        result
    }
}
