//! When the application counts as healthy, for the watchdog: pure logic, no
//! hardware, so it is built for the library's host tests and the host
//! simulation's as well as for the board firmware (its supervisor,
//! src/bin/board-fw.rs, feeds the watchdog by it, with
//! `app::Shared::measuring_lines` for "measuring").

/// A measurement whose lines stop completing for this long is stuck. The
/// longest healthy line is 8 frames, each taken again at up to 2 shorter
/// exposures when it saturates (24 frames), each at most the sensor's
/// longest exposure (100 ms) plus its settle and readout (about 1 ms), and
/// sending 128 points: under 2.5 s. The board's own settings acquire such
/// a line in about 45 ms (`host-tools rate` counts a line's frames).
pub const STALL_LIMIT_MS: u64 = 3_000;

/// Decides, from the application's status, whether it is healthy.
#[derive(Clone, Copy, Debug, Default)]
pub struct Health {
    last_lines: u32,
    last_progress_ms: u64,
    was_measuring: bool,
}

impl Health {
    /// Observes the status at `now_ms`; returns whether the application is
    /// healthy: idle, or measuring with a line completed within
    /// [`STALL_LIMIT_MS`] (or since the measurement started).
    pub fn observe(&mut self, now_ms: u64, measuring: bool, lines_total: u32) -> bool {
        let started = measuring && !self.was_measuring;
        self.was_measuring = measuring;
        if !measuring || started || lines_total != self.last_lines {
            self.last_lines = lines_total;
            self.last_progress_ms = now_ms;
        }
        now_ms.saturating_sub(self.last_progress_ms) < STALL_LIMIT_MS
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn idle_is_healthy_however_long() {
        let mut h = Health::default();
        for t in (0..100_000).step_by(250) {
            assert!(h.observe(t, false, 5));
        }
    }

    #[test]
    fn a_measurement_is_healthy_while_lines_complete() {
        let mut h = Health::default();
        let mut lines = 0;
        for t in (0..20_000).step_by(250) {
            if t % 1000 == 0 {
                lines += 1;
            }
            assert!(h.observe(t, true, lines), "at {t} ms");
        }
    }

    #[test]
    fn a_stalled_measurement_is_not_and_recovers_when_lines_resume() {
        let mut h = Health::default();
        assert!(h.observe(0, false, 7));
        // Measuring starts at 1 s; no line ever completes.
        assert!(h.observe(1_000, true, 7));
        assert!(h.observe(1_000 + STALL_LIMIT_MS - 1, true, 7));
        assert!(!h.observe(1_000 + STALL_LIMIT_MS, true, 7));
        assert!(!h.observe(10_000, true, 7));
        // A line completes: healthy again.
        assert!(h.observe(10_250, true, 8));
        // The measurement ends: healthy.
        assert!(h.observe(20_000, false, 8));
    }
}
