//! The QEMU platform layer: what the application needs from QEMU 10's
//! `b-l475e-iot01a` machine, written against the registers QEMU emulates.
//!
//! QEMU emulates this chip's RCC, GPIO, USART and the Cortex-M SysTick and
//! NVIC; it stubs TIM, DMA, ADC, USB and the FLASH controller (flash is
//! read-only), and accepts only 32-bit accesses to the USART. embassy-stm32's
//! init, USART driver and TIM time driver therefore do not work there (see
//! docs/design.md), so this layer replaces them:
//!
//! - [`usart`]: USART1 as the transport (interrupt-driven receive into a
//!   pipe with back-pressure, polled transmit; 32-bit register accesses).
//! - [`time_driver`]: an embassy-time driver on SysTick.
//! - [`leds`]: the m LEDs as GPIOE outputs.
//! - [`sensor`]: a simulated line sensor serving frames of a scene the host
//!   loads over the link; it sees which LED is lit by reading GPIOE.
//! - [`flash`]: the calibration slots in RAM (QEMU's flash is read-only), so
//!   provisioning works but does not survive a restart of QEMU (the recipe
//!   slots likewise).
//! - [`reject`]: the inspection's reject output on PA4 (the board's pin).
pub mod flash;
pub mod leds;
mod regs;
pub mod reject;
pub mod sensor;
pub mod time_driver;
pub mod usart;

/// Enables the clocks of the peripherals this layer uses.
pub fn init() {
    use regs::*;
    // SAFETY: single-threaded boot, before any task runs.
    unsafe {
        modify(RCC_AHB2ENR, |v| v | RCC_AHB2ENR_GPIOEEN);
        modify(RCC_APB2ENR, |v| v | RCC_APB2ENR_USART1EN);
    }
}

// (Panic messages and exit codes reach the QEMU process through the
// cortex-m-semihosting crate: see src/bin/qemu-fw.rs's panic handler.)
