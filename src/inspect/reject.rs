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
}
