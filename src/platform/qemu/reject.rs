//! The reject output as GPIOA pin 4 (the board's D7 = PA4), push-pull,
//! active high. QEMU drives the pin's register but shows no level to the
//! host, so the application also reports every pulse on the link
//! (`crate::app::reject_output`); the tests read that.
use super::regs::*;
use crate::hw::RejectOutput;

/// The pin.
const PIN: u32 = 4;

/// The reject output on PA4.
pub struct GpioReject(());

impl GpioReject {
    /// Clocks GPIOA and configures the pin as an output, low (once, at boot).
    pub fn configure() -> Self {
        // SAFETY: boot-time configuration; GPIOA pin 4 belongs to this driver.
        unsafe {
            modify(RCC_AHB2ENR, |v| v | RCC_AHB2ENR_GPIOAEN);
            write(GPIOA + GPIO_BSRR, 1 << (PIN + 16));
            modify(GPIOA + GPIO_MODER, |v| (v & !(0b11 << (2 * PIN))) | (0b01 << (2 * PIN)));
        }
        Self(())
    }

    /// The pin's output level, read back.
    pub fn level() -> bool {
        // SAFETY: reading the output data register has no side effect.
        unsafe { read(GPIOA + GPIO_ODR) & (1 << PIN) != 0 }
    }
}

impl RejectOutput for GpioReject {
    fn set(&mut self, on: bool) {
        // SAFETY: one BSRR write sets or resets this driver's pin only.
        unsafe { write(GPIOA + GPIO_BSRR, if on { 1 << PIN } else { 1 << (PIN + 16) }) };
    }
}
