//! The m LEDs as GPIOE pins 0..m (push-pull outputs). QEMU has no PWM timer,
//! so the drive is on/off: any non-zero intensity lights the LED.
use super::regs::*;
use crate::hw::Leds;

/// LEDs on GPIOE pins `0..M`.
pub struct GpioLeds<const M: usize>(());

impl<const M: usize> GpioLeds<M> {
    /// Configures the pins as outputs, all off (touches GPIOE: once, at boot).
    pub fn configure() -> Self {
        const { assert!(M <= 16) };
        // SAFETY: boot-time configuration of GPIOE, owned by this driver.
        unsafe {
            modify(GPIOE + GPIO_MODER, |mut v| {
                for k in 0..M {
                    v = (v & !(0b11 << (2 * k))) | (0b01 << (2 * k));
                }
                v
            });
            write(GPIOE + GPIO_BSRR, ((1u32 << M) - 1) << 16);
        }
        Self(())
    }
}

/// Which LED is lit, read back from the pins (what the simulated sensor sees).
pub fn lit<const M: usize>() -> Option<u8> {
    // SAFETY: reading the output data register has no side effect.
    let odr = unsafe { read(GPIOE + GPIO_ODR) } & ((1u32 << M) - 1);
    (odr != 0).then(|| odr.trailing_zeros() as u8)
}

impl<const M: usize> Leds for GpioLeds<M> {
    fn count(&self) -> usize {
        M
    }
    async fn set(&mut self, led: Option<u8>, intensity: u16) {
        let all = (1u32 << M) - 1;
        let on = match led {
            Some(k) if (k as usize) < M && intensity > 0 => 1u32 << k,
            _ => 0,
        };
        // One BSRR write: reset the others and set the one, atomically.
        // SAFETY: GPIOE pins 0..M belong to this driver.
        unsafe { write(GPIOE + GPIO_BSRR, ((all & !on) << 16) | on) };
    }
}
