//! The m LEDs, each on its own timer PWM channel, so intensity is a duty
//! cycle rather than a current source. One LED is lit at a time.
//!
//! PWM at [`PWM_HZ`]: with an exposure of 1 ms a partial PWM period changes
//! the integrated light by at most 1/50 of a period's light at mid duty;
//! full intensity (`u16::MAX`) is steady on with no ripple at all.

use crate::hw::Leds;
use embassy_stm32::Peri;
use embassy_stm32::gpio::OutputType;
use embassy_stm32::peripherals::{PA7, PA15, PB0, PB1, PB4, PB8, PB9, TIM2, TIM3, TIM4};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm, SimplePwmChannel};

/// LEDs fitted (m of the build shape; seven PWM channels are wired).
pub const LED_COUNT: usize = crate::shape::LEDS;
/// PWM carrier frequency: 80 MHz / 50 kHz = 1600 steps of duty resolution.
pub const PWM_HZ: u32 = 50_000;

/// One LED's PWM channel; the LEDs span three timers.
enum Channel {
    Tim2(SimplePwmChannel<'static, TIM2>),
    Tim3(SimplePwmChannel<'static, TIM3>),
    Tim4(SimplePwmChannel<'static, TIM4>),
}

impl Channel {
    fn set(&mut self, intensity: u16) {
        match self {
            Self::Tim2(c) => set_duty(c, intensity),
            Self::Tim3(c) => set_duty(c, intensity),
            Self::Tim4(c) => set_duty(c, intensity),
        }
    }
}

fn set_duty<T: embassy_stm32::timer::GeneralInstance4Channel>(c: &mut SimplePwmChannel<'static, T>, intensity: u16) {
    match intensity {
        0 => c.set_duty_cycle_fully_off(),
        u16::MAX => c.set_duty_cycle_fully_on(),
        i => c.set_duty_cycle_fraction(u32::from(i), u32::from(u16::MAX)),
    }
}

/// The LEDs, PWM-driven (active high: the pin drives the LED driver's input).
pub struct PwmLeds {
    ch: [Channel; LED_COUNT],
}

impl PwmLeds {
    /// Sets up TIM3 CH1-4, TIM4 CH3-4 and TIM2 CH1 as PWM outputs, all off.
    #[allow(clippy::too_many_arguments)] // one argument per pin of the pin map
    pub fn new(
        tim3: Peri<'static, TIM3>,
        tim4: Peri<'static, TIM4>,
        tim2: Peri<'static, TIM2>,
        led0: Peri<'static, PB4>,
        led1: Peri<'static, PA7>,
        led2: Peri<'static, PB0>,
        led3: Peri<'static, PB1>,
        led4: Peri<'static, PB8>,
        led5: Peri<'static, PB9>,
        led6: Peri<'static, PA15>,
    ) -> Self {
        let pp = OutputType::PushPull;
        let f = Hertz(PWM_HZ);
        let up = CountingMode::EdgeAlignedUp;
        let t3 = SimplePwm::new(
            tim3,
            Some(PwmPin::new(led0, pp)),
            Some(PwmPin::new(led1, pp)),
            Some(PwmPin::new(led2, pp)),
            Some(PwmPin::new(led3, pp)),
            f,
            up,
        )
        .split();
        let t4 =
            SimplePwm::new(tim4, None, None, Some(PwmPin::new(led4, pp)), Some(PwmPin::new(led5, pp)), f, up).split();
        let t2 = SimplePwm::new(tim2, Some(PwmPin::new(led6, pp)), None, None, None, f, up).split();
        let mut ch = [
            Channel::Tim3(t3.ch1),
            Channel::Tim3(t3.ch2),
            Channel::Tim3(t3.ch3),
            Channel::Tim3(t3.ch4),
            Channel::Tim4(t4.ch3),
            Channel::Tim4(t4.ch4),
            Channel::Tim2(t2.ch1),
        ];
        for c in ch.iter_mut() {
            c.set(0);
            match c {
                Channel::Tim2(c) => c.enable(),
                Channel::Tim3(c) => c.enable(),
                Channel::Tim4(c) => c.enable(),
            }
        }
        Self { ch }
    }
}

impl Leds for PwmLeds {
    fn count(&self) -> usize {
        LED_COUNT
    }

    async fn set(&mut self, led: Option<u8>, intensity: u16) {
        // All off first, so two LEDs are never lit together.
        for c in self.ch.iter_mut() {
            c.set(0);
        }
        if let Some(i) = led {
            match self.ch.get_mut(usize::from(i)) {
                Some(c) => c.set(intensity),
                None => defmt::warn!("LED {} does not exist (m = {}); all LEDs stay off", i, LED_COUNT),
            }
        }
    }
}
