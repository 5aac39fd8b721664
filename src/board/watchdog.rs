//! The independent watchdog (IWDG, clocked by the LSI, so it runs even if the
//! main clocks fail).
//!
//! It is fed only as a consequence of healthy work:
//! - [`healthy`] by the firmware's supervisor loop, and only while
//!   [`Health`] says the application is healthy: the executor runs (the loop
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

/// A measurement whose lines stop completing for this long is stuck. The
/// longest healthy line is 8 frames at the longest exposure (8 x 100 ms) plus
/// readouts and sending 128 point frames: well below 2 s.
pub const STALL_LIMIT_MS: u64 = 3_000;

/// Decides, from the application's status, whether it is healthy.
#[derive(Clone, Copy, Debug, Default)]
pub struct Health {
    last_lines: u32,
    last_progress_ms: u64,
}

impl Health {
    /// Observes the status at `now_ms`; returns whether the application is
    /// healthy: idle, or measuring with a line completed within
    /// [`STALL_LIMIT_MS`].
    pub fn observe(&mut self, now_ms: u64, measuring: bool, lines_total: u32) -> bool {
        if !measuring || lines_total != self.last_lines {
            self.last_lines = lines_total;
            self.last_progress_ms = now_ms;
        }
        now_ms.saturating_sub(self.last_progress_ms) < STALL_LIMIT_MS
    }
}

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
