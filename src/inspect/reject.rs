//! When the reject output fires: a rejected line's pulse starts after the
//! recipe's delay, counted in time (us after the verdict) or in lines (the
//! line trigger is the encoder's count: the pulse starts at the verdict of
//! the line `delay` lines later, when the part has moved on to the ejector).
//! Pure bookkeeping, so the host simulation and the tests see the same
//! schedule as the board; the platform's output pin and the timer are the
//! application's (`crate::app`).
use super::recipe::{DelayUnit, RecipeSettings};

/// Rejected lines whose pulse waits for a later line (delay in lines).
const QUEUE: usize = 16;

/// A reject pulse to drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pulse {
    /// The rejected line.
    pub line: u32,
    /// When it starts, us on the device's clock.
    pub start_us: u64,
    /// How long, us.
    pub len_us: u32,
}

/// The schedule of reject pulses.
#[derive(Debug, Default)]
pub struct Planner {
    waiting: heapless::Deque<(u32, u32), QUEUE>,
}

impl Planner {
    /// An empty schedule.
    pub const fn new() -> Self {
        Self { waiting: heapless::Deque::new() }
    }

    /// After the verdict of `line` (rejected or not) at `now_us`: the pulse
    /// that starts now or later, if any. With a delay in lines, the pulse of
    /// the line `delay` lines back starts now; a rejected line whose queue
    /// is full (more than 16 rejected lines within the delay) pulses at once
    /// rather than never.
    pub fn after_verdict(&mut self, s: &RecipeSettings, line: u32, rejected: bool, now_us: u64) -> Option<Pulse> {
        let pulse = |l, start_us| Pulse { line: l, start_us, len_us: s.pulse_us };
        match s.delay_unit {
            DelayUnit::Micros => rejected.then(|| pulse(line, now_us + s.delay as u64)),
            DelayUnit::Lines => {
                if rejected && let Err(item) = self.waiting.push_back((line.wrapping_add(s.delay), line)) {
                    return Some(pulse(item.1, now_us));
                }
                match self.waiting.front() {
                    Some(&(due, l)) if due.wrapping_sub(line) as i32 <= 0 => {
                        self.waiting.pop_front();
                        Some(pulse(l, now_us))
                    }
                    _ => None,
                }
            }
        }
    }

    /// At the end of an inspection, one of the rejected lines a delay in
    /// lines still holds (oldest first), to pulse at `now_us`: with no more
    /// lines there is no count left to wait for, and, as when the queue is
    /// full, a rejected part is better ejected at once than never. `None`
    /// once none is left.
    pub fn flush(&mut self, s: &RecipeSettings, now_us: u64) -> Option<Pulse> {
        self.waiting.pop_front().map(|(_, line)| Pulse { line, start_us: now_us, len_us: s.pulse_us })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delays_in_time_and_in_lines() {
        let mut s = crate::inspect::recipe::tests::settings();
        s.delay_unit = DelayUnit::Micros;
        s.delay = 5_000;
        let mut p = Planner::new();
        assert_eq!(p.after_verdict(&s, 3, false, 100), None);
        assert_eq!(p.after_verdict(&s, 4, true, 200), Some(Pulse { line: 4, start_us: 5_200, len_us: 25_000 }));
        s.delay_unit = DelayUnit::Lines;
        s.delay = 2;
        let mut p = Planner::new();
        let fired: Vec<_> = [(0, true), (1, true), (2, false), (3, false), (4, false)]
            .into_iter()
            .filter_map(|(l, r)| p.after_verdict(&s, l, r, l as u64 * 10).map(|x| (l, x.line)))
            .collect();
        assert_eq!(fired, [(2, 0), (3, 1)]);
        s.delay = 0;
        assert_eq!(Planner::new().after_verdict(&s, 7, true, 9).map(|x| x.start_us), Some(9));
    }

    #[test]
    fn the_end_of_an_inspection_flushes_the_lines_a_delay_still_holds() {
        let mut s = crate::inspect::recipe::tests::settings();
        s.delay_unit = DelayUnit::Lines;
        s.delay = 3;
        let mut p = Planner::new();
        for (l, r) in [(0, false), (1, true), (2, false), (3, true)] {
            assert_eq!(p.after_verdict(&s, l, r, 10 * l as u64), None, "line {l}");
        }
        // Line 1 waits for line 4, whose verdict fires it; lines 3 and 4
        // wait for 6 and 7, which the run does not reach.
        assert_eq!(p.after_verdict(&s, 4, true, 40).map(|x| x.line), Some(1));
        assert_eq!(p.after_verdict(&s, 5, false, 50), None);
        let flushed: Vec<_> = core::iter::from_fn(|| p.flush(&s, 60)).collect();
        assert_eq!(flushed, [3, 4].map(|line| Pulse { line, start_us: 60, len_us: s.pulse_us }));
        assert_eq!(p.flush(&s, 70), None);
        s.delay_unit = DelayUnit::Micros;
        let mut p = Planner::new();
        assert!(p.after_verdict(&s, 0, true, 0).is_some());
        assert_eq!(p.flush(&s, 10), None, "a delay in time holds nothing back");
    }
}
