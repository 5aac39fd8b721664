//! The B-L475E-IOT01A board layer: the one place that knows pins, timers,
//! DMA channels and clocks. Everything above it (acquisition, estimation,
//! protocol, calibration store) is the shared library, exercised in QEMU and
//! in the host simulation; this layer only implements the library's hardware
//! traits (`crate::hw::{Leds, LineSensor}`, `embedded_io_async`
//! `Read`/`Write`, `embedded_storage` `NorFlash`) on embassy-stm32.
//!
//! # Pin map (Arduino header of the B-L475E-IOT01A, UM2153)
//!
//! | signal | pin | header | peripheral |
//! |---|---|---|---|
//! | LED 0 | PB4 | D5 | TIM3_CH1 PWM |
//! | LED 1 | PA7 | D11 | TIM3_CH2 PWM |
//! | LED 2 | PB0 | D3 | TIM3_CH3 PWM |
//! | LED 3 | PB1 | D6 | TIM3_CH4 PWM |
//! | LED 4 | PB8 | D15 | TIM4_CH3 PWM |
//! | LED 5 | PB9 | D14 | TIM4_CH4 PWM |
//! | LED 6 | PA15 | D9 | TIM2_CH1 PWM |
//! | sensor SI | PD14 | D2 | GPIO push-pull |
//! | sensor CLK | PA3 | D4 | GPIO push-pull |
//! | sensor AO | PC5 | A0 | ADC1_IN14, DMA1_CH1 |
//! | USB D- / D+ | PA11 / PA12 | CN7 (USB OTG FS) | USB_OTG_FS |
//! | USB VBUS sense | PA9 | CN7 | USB_OTG_FS |
//! | status LED | PB14 | LED2 (on board) | GPIO |
//! | reject output | PA4 | D7 | GPIO push-pull, active high (inspection) |
//!
//! Other peripherals: TIM5 is embassy-time's driver; IWDG is the watchdog;
//! FLASH holds the calibration slots and the update partitions that memory.x
//! reserves, one driver shared by both (`flash`).
//!
//! # Clocks
//! MSI at 48 MHz, trimmed by the 32.768 kHz LSE crystal (MSIPLLEN), clocks USB
//! (the STM32L475 has no HSI48; MSI+LSE is ST's crystal-less USB option).
//! The main PLL takes MSI / 6 * 20 / 2 = 80 MHz for SYSCLK, AHB and APB1/2;
//! the ADC runs from SYSCLK.

pub mod flash;
pub mod leds;
pub mod sensor;
pub mod usb;
pub mod watchdog;

use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::peripherals;
use embassy_stm32::time::Hertz;
use embassy_stm32::{Config, Peri, bind_interrupts};

/// SYSCLK the board runs at.
pub const SYSCLK_HZ: u32 = crate::platform::timing::SYSCLK_HZ;

bind_interrupts!(
    /// Interrupts the board layer's drivers need.
    pub struct Irqs {
        OTG_FS => embassy_stm32::usb::InterruptHandler<peripherals::USB_OTG_FS>;
        DMA1_CHANNEL1 => embassy_stm32::dma::InterruptHandler<peripherals::DMA1_CH1>;
    }
);

/// The embassy-stm32 configuration: clocks as described in the module docs.
pub fn config() -> Config {
    use embassy_stm32::rcc::{
        AHBPrescaler, APBPrescaler, LsConfig, MSIRange, Pll, PllMul, PllPreDiv, PllRDiv, PllSource, Sysclk, mux,
    };
    let mut config = Config::default();
    config.rcc.ls = LsConfig::default_lse();
    config.rcc.msi = Some(MSIRange::RANGE48M);
    config.rcc.hsi = false;
    config.rcc.pll = Some(Pll {
        source: PllSource::MSI,
        prediv: PllPreDiv::DIV6,
        mul: PllMul::MUL20,
        divp: None,
        divq: None,
        divr: Some(PllRDiv::DIV2),
    });
    config.rcc.sys = Sysclk::PLL1_R;
    config.rcc.ahb_pre = AHBPrescaler::DIV1;
    config.rcc.apb1_pre = APBPrescaler::DIV1;
    config.rcc.apb2_pre = APBPrescaler::DIV1;
    config.rcc.mux.clk48sel = mux::Clk48sel::MSI;
    config.rcc.mux.adcsel = mux::Adcsel::SYS;
    config
}

/// Everything the application needs from the board, ready to use.
pub struct Board {
    /// The m LEDs, PWM-driven.
    pub leds: leds::PwmLeds,
    /// The TSL1401-class line sensor.
    pub sensor: sensor::Tsl1401,
    /// The chip's flash, shared by the calibration store and the updater
    /// (`flash::calibration`, `flash::update_partitions`).
    pub flash: &'static flash::Chip,
    /// The USB port's peripherals: `usb::Usb::new` builds the device once
    /// the application (which serves its DFU interface) exists.
    pub usb: usb::UsbPins,
    /// On-board LED2, lit while the application runs healthily.
    pub status_led: Output<'static>,
    /// The inspection's reject output (PA4, Arduino D7), low.
    pub reject: RejectPin,
}

impl Board {
    /// Brings up clocks and every peripheral the firmware uses. The watchdog
    /// is handed back unstarted: the caller starts it ([`watchdog::start`])
    /// right after, so clock start-up (the LSE crystal can take a second or
    /// two) cannot reset-loop the board.
    pub fn init() -> (Self, Peri<'static, peripherals::IWDG>) {
        let p = embassy_stm32::init(config());
        let sysclk = embassy_stm32::rcc::clocks(&p.RCC).sys.to_hertz().map(|h: Hertz| h.0);
        defmt::info!("clocks: SYSCLK {} Hz", sysclk);
        if sysclk != Some(SYSCLK_HZ) {
            defmt::warn!("SYSCLK is not the {} Hz the timing constants assume", SYSCLK_HZ);
        }

        let leds = leds::PwmLeds::new(p.TIM3, p.TIM4, p.TIM2, p.PB4, p.PA7, p.PB0, p.PB1, p.PB8, p.PB9, p.PA15);
        let sensor = sensor::Tsl1401::new(p.ADC1, p.PC5, p.DMA1_CH1, p.PD14, p.PA3);
        let flash = flash::share(p.FLASH);
        let usb = usb::UsbPins { otg: p.USB_OTG_FS, dp: p.PA12, dm: p.PA11 };
        let status_led = Output::new(p.PB14, Level::Low, Speed::Low);
        let reject = RejectPin(Output::new(p.PA4, Level::Low, Speed::Low));
        (Self { leds, sensor, flash, usb, status_led, reject }, p.IWDG)
    }
}

/// The inspection's reject output: PA4 (Arduino D7), a free header pin (not
/// the LED PWM pins, the sensor's PD14/PA3/PC5, USB or the heartbeat);
/// active high, for a PLC's digital input through its interface.
pub struct RejectPin(Output<'static>);

impl crate::hw::RejectOutput for RejectPin {
    fn set(&mut self, on: bool) {
        if on {
            self.0.set_high();
        } else {
            self.0.set_low();
        }
    }
}
