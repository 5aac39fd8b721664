//! The client's inspection calls: provision a recipe, run an inspection
//! (verdicts, reject pulses, a rejected line's points when asked), read the
//! inspection's status.
use super::Transport;
use super::client::{Client, LinkError, PointRecord, Reply, SlotKind};
use brdf_meter::inspect::Verdict;
use brdf_meter::inspect::recipe::DelayUnit;
use brdf_meter::protocol::{DeviceError, InspectStatus, RecipeInfo, Request, Response};
use std::time::Duration;

/// A reject pulse the device reported.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct PulseEvent {
    /// The (last) rejected line it was driven for.
    pub line: u32,
    /// Start, us on the device's clock.
    pub start_us: u64,
    /// Length, us.
    pub len_us: u32,
}

/// How long after a run's last verdict its `MeasureDone` may come with a
/// recipe's reject pulse of `pulse_us` and its `delay`: the device sends it
/// once the last pulse is over, which starts at most the delay in time after
/// that verdict (a delay in lines still held at the end pulses at once) and
/// lasts the pulse; plus a second for the link. A client whose timeout is
/// shorter gives up on a run that is going well (`inspect run` raises its
/// timeout to this).
pub fn end_of_run_wait(pulse_us: u32, (delay, unit): (u32, DelayUnit)) -> Duration {
    let delay_us = match unit {
        DelayUnit::Micros => u64::from(delay),
        DelayUnit::Lines => 0,
    };
    Duration::from_micros(delay_us + u64::from(pulse_us)) + Duration::from_secs(1)
}

/// What an inspection sent.
#[derive(Clone, Debug, Default)]
pub struct InspectRun {
    /// One verdict per line, in order.
    pub verdicts: Vec<Verdict>,
    /// The reject pulses, in order.
    pub pulses: Vec<PulseEvent>,
    /// The points of rejected lines (when asked).
    pub points: Vec<PointRecord>,
    /// Bytes on the link of the verdict and pulse frames (COBS frames with
    /// their delimiter, re-encoded by the device's own encoder: the same bytes).
    pub link_bytes: usize,
}

impl<T: Transport> Client<T> {
    /// Provisions a signed recipe; on any error the device keeps its previous one.
    pub fn provision_recipe(
        &mut self,
        recipe: &[u8],
        progress: impl FnMut(usize, usize),
    ) -> Result<RecipeInfo, LinkError> {
        match self.send_signed(recipe, SlotKind::Recipe, progress) {
            Ok(Response::RecipeCommitted(r)) => Ok(r),
            Ok(r) => Err(LinkError::Unexpected(format!("{r:?} to RecipeCommit"))),
            Err(LinkError::Device(DeviceError::SignatureRejected(f))) => Err(LinkError::RecipeSignature(f)),
            Err(e) => Err(e),
        }
    }

    /// The active recipe and the inspection's counters.
    pub fn inspect_status(&mut self) -> Result<InspectStatus, LinkError> {
        match self.request(&Request::InspectStatus)? {
            Response::Inspection(s) => Ok(s),
            r => Err(LinkError::Unexpected(format!("{r:?} to InspectStatus"))),
        }
    }

    /// Inspects `lines` lines (>= 1); `on_verdict` sees each verdict as it
    /// arrives. The run ends with the device's `MeasureDone`, which follows
    /// the last reject pulse it reports (merged pulses report once for
    /// several rejected lines, so only the device knows when they are over).
    pub fn inspect(
        &mut self,
        lines: u32,
        defect_points: bool,
        on_verdict: &mut dyn FnMut(&Verdict),
    ) -> Result<InspectRun, LinkError> {
        assert!(lines >= 1, "an inspection of at least one line");
        let seq = self.send(&Request::Inspect { lines, defect_points, format: self.format })?;
        let mut run = InspectRun::default();
        let mut started = false;
        let mut error = None;
        loop {
            let f = match self.next_frame(self.timeout) {
                // The last verdict is in: what is left is a reject pulse the
                // device is still driving ([`end_of_run_wait`]).
                Err(LinkError::Timeout(..)) if run.verdicts.len() == lines as usize => {
                    return Err(LinkError::Timeout(self.timeout, "the end of the inspection's last reject pulse"));
                }
                Err(LinkError::Timeout(..)) => return Err(LinkError::Timeout(self.timeout, "inspection verdicts")),
                r => r?,
            };
            if f.seq != seq && f.seq != 0 {
                continue;
            }
            if let Reply::Msg(r @ (Response::Verdict(_) | Response::RejectPulse { .. })) = &f.reply {
                run.link_bytes += frame_len(seq, r);
            }
            match f.reply {
                Reply::Msg(Response::MeasureStarted { .. }) => started = true,
                Reply::Msg(Response::Verdict(v)) => {
                    on_verdict(&v);
                    run.verdicts.push(v);
                }
                Reply::Msg(Response::RejectPulse { line, start_us, len_us }) => {
                    run.pulses.push(PulseEvent { line, start_us, len_us })
                }
                Reply::Point(p) => run.points.push(p),
                Reply::Points(ps) => run.points.extend(ps),
                Reply::Msg(Response::Error(e)) if !started => return Err(LinkError::Device(e)),
                Reply::Msg(Response::Error(e)) => error = Some(e),
                Reply::Msg(Response::MeasureDone { lines_done }) => {
                    if let Some(e) = error {
                        return Err(LinkError::Device(e));
                    }
                    if lines_done != lines {
                        return Err(LinkError::Unexpected(format!("{lines_done} of {lines} lines inspected")));
                    }
                    return Ok(run);
                }
                Reply::Msg(r) => return Err(LinkError::Unexpected(format!("{r:?} during an inspection"))),
            }
        }
    }
}

/// Bytes of the frame that carries `r` with sequence number `seq`.
pub fn frame_len(seq: u32, r: &Response<'_>) -> usize {
    let mut buf = [0u8; brdf_meter::protocol::MAX_FRAME];
    brdf_meter::protocol::encode(seq, r, &mut buf).expect("every reply fits a frame")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_end_of_a_run_waits_for_a_delay_in_time_and_the_pulse() {
        assert_eq!(end_of_run_wait(25_000, (8_000_000, DelayUnit::Micros)), Duration::from_micros(9_025_000));
        // A delay in lines still held at the end pulses at once.
        assert_eq!(end_of_run_wait(25_000, (3, DelayUnit::Lines)), Duration::from_micros(1_025_000));
    }
}
