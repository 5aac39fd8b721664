//! The independent watchdog (IWDG, clocked by the LSI, so it runs even if the
//! main clocks fail).
//!
//! It is fed only as a consequence of healthy work:
//! - [`healthy`] by the firmware's supervisor loop, and only while
//!   [`crate::platform::watchdog_health::Health`] says the application is healthy: the executor runs (the loop
//!   itself gets polled) and, during a measurement, lines keep completing;
//! - [`progress`] by flash operations, once per 2 KiB page or write.
//!
//! Nothing feeds it unconditionally, so a hung executor (a busy loop, a
//! peripheral wait that never ends) or a measurement that stops producing
//! lines resets the board, which then boots from the last good calibration
//! slot (the store never writes the active one).

use core::cell::RefCell;

use critical_section::Mutex;
use embassy_stm32::Peri;
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::wdg::IndependentWatchdog;

/// Watchdog period. Longest healthy gap: one measurement cycle of m = 7 LEDs
/// plus the dark frame at the longest exposure (8 x 100 ms) plus readouts,
/// well below 1 s; 4 s leaves margin for USB stalls.
pub const TIMEOUT_US: u32 = 4_000_000;

static WDG: Mutex<RefCell<Option<IndependentWatchdog<'static, IWDG>>>> = Mutex::new(RefCell::new(None));

/// Starts the watchdog. It cannot be stopped again (hardware rule).
pub fn start(iwdg: Peri<'static, IWDG>) {
    let mut w = IndependentWatchdog::new(iwdg, TIMEOUT_US);
    w.unleash();
    critical_section::with(|cs| WDG.borrow_ref_mut(cs).replace(w));
    defmt::info!("watchdog started, {} ms", TIMEOUT_US / 1000);
}

fn pet() {
    critical_section::with(|cs| {
        if let Some(w) = WDG.borrow_ref_mut(cs).as_mut() {
            w.pet();
        }
    });
}

/// The supervisor found the application healthy.
pub fn healthy() {
    pet();
}

/// A long flash operation completed one more page.
pub fn progress() {
    pet();
}
