//! Acquisition timing, written down once: the board firmware's settings
//! ([`ACQUISITION`]) and the TSL1401 readout's clock and ADC numbers that
//! `platform::board::sensor` runs with, and the QEMU firmware's settings
//! ([`QEMU_ACQUISITION`]), so the host's line-rate budget (`host-tools rate`)
//! derives the acquisition time from the very numbers the firmware uses. Not
//! gated: host builds read it too.
use crate::acquire::AcqConfig;

/// The board firmware's acquisition settings: integration per frame, LED
/// settling before it, full drive; a frame that saturates is taken again at
/// 1/16 and then 1/80 of the exposure (the handheld scene's `short-exposure`
/// ratios: a mirror-like sample under the specular LED reads tens to
/// hundreds of white diffusers). 25 us is just above the TSL1401's shortest
/// integration at this readout (the 111 clocks of the flush after the 18th).
pub const ACQUISITION: AcqConfig =
    AcqConfig { exposure_us: 2_000, settle_us: 200, intensity: u16::MAX, short_exposures_us: [125, 25] };
/// The QEMU firmware's acquisition settings: short, it is a simulation
/// (its simulated sensor reads a frame at once); the same exposure ratios
/// as the board's.
pub const QEMU_ACQUISITION: AcqConfig =
    AcqConfig { exposure_us: 400, settle_us: 100, intensity: u16::MAX, short_exposures_us: [25, 5] };
/// SYSCLK (and the ADC's clock: `adcsel = SYS`, no prescaler needed at 80 MHz).
pub const SYSCLK_HZ: u32 = 80_000_000;
/// ADC conversions averaged per pixel.
pub const OVERSAMPLE: usize = 4;
/// ADC sampling time per conversion, in half ADC cycles (`SampleTime::CYCLES24_5`).
pub const ADC_SAMPLE_HALF_CYCLES: u32 = 49;
/// ADC successive-approximation time of a 12-bit conversion, in half ADC
/// cycles (12.5 cycles, RM0351).
pub const ADC_CONVERSION_HALF_CYCLES: u32 = 25;
/// Clock after SI at which the next integration starts (datasheet).
pub const INTEGRATION_START_CLOCK: usize = 18;
/// AO settling after a CLK rising edge (datasheet: 120 ns) plus margin:
/// cycles at 80 MHz.
pub const SETTLE_CYCLES: u32 = 16;
/// Half a CLK period for the clocks that are not sampled: 8 cycles at 80 MHz
/// gives a 5 MHz CLK, within the TSL1401's 8 MHz.
pub const HALF_CLK_CYCLES: u32 = 8;
