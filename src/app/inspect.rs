//! Inspection in the application: the recipe store behind a port (as the
//! firmware updater is), the recipe requests, one line's decision in the
//! estimation task, and the reject output's task.
//!
//! An inspected line costs its correction (in the acquisition task), then
//! here [`crate::inspect::Inspector::line`] on the corrected readings and
//! one verdict frame: no BRDF is estimated, except for the out-of-prior
//! question at the points already out and, when the host asked, the points
//! of a rejected line.
use super::{Core, OutFrame, Shared};
use crate::hw::{MappedFlash, RejectOutput};
use crate::inspect::reject::Pulse;
use crate::inspect::{RecipeStore, RecipeView, Verdict, check_recipe};
use crate::protocol::{DeviceError, InspectStatus, RecipeInfo, Response, flags};
use crate::store::SlotInfo;
use embassy_futures::select::{Either, select};
use embassy_time::{Instant, Timer};
use nalgebra::SVector;

/// The recipe store as the application holds it (any flash).
pub trait RecipeSlots {
    /// Starts writing a recipe; returns the slot.
    fn begin(&mut self, len: u32, crc: u32) -> Result<u8, DeviceError>;
    /// Writes recipe bytes; returns the next offset.
    fn write_chunk(&mut self, offset: u32, data: &[u8]) -> Result<u32, DeviceError>;
    /// Verifies (and asks `accept`), then activates the written recipe.
    fn commit(
        &mut self,
        accept: &mut dyn FnMut(&RecipeView<'static>) -> Result<(), DeviceError>,
    ) -> Result<SlotInfo, DeviceError>;
    /// Abandons the provisioning.
    fn abort(&mut self) -> Result<(), DeviceError>;
    /// The active recipe.
    fn active(&self) -> Option<(SlotInfo, RecipeView<'static>)>;
    /// Why the newest whole recipe is not readable, if so.
    fn unreadable(&self) -> Option<DeviceError>;
}

impl<RF: MappedFlash> RecipeSlots for RecipeStore<RF> {
    fn begin(&mut self, len: u32, crc: u32) -> Result<u8, DeviceError> {
        RecipeStore::begin(self, len, crc).map_err(DeviceError::from)
    }
    fn write_chunk(&mut self, offset: u32, data: &[u8]) -> Result<u32, DeviceError> {
        RecipeStore::write_chunk(self, offset, data).map_err(DeviceError::from)
    }
    fn commit(
        &mut self,
        accept: &mut dyn FnMut(&RecipeView<'static>) -> Result<(), DeviceError>,
    ) -> Result<SlotInfo, DeviceError> {
        RecipeStore::commit(self, accept).map_err(DeviceError::from)
    }
    fn abort(&mut self) -> Result<(), DeviceError> {
        RecipeStore::abort(self).map_err(DeviceError::from)
    }
    fn active(&self) -> Option<(SlotInfo, RecipeView<'static>)> {
        self.active_blob()
    }
    fn unreadable(&self) -> Option<DeviceError> {
        RecipeStore::unreadable(self)
    }
}

/// The platform's recipe store, as the application holds it.
pub type RecipePort = &'static mut (dyn RecipeSlots + Send);

/// What an inspection job asks beyond its lines.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InspectJob {
    /// Whether a rejected line's points follow its verdict.
    pub defect_points: bool,
}

fn recipe_info(slot: SlotInfo, view: &RecipeView<'_>) -> RecipeInfo {
    RecipeInfo {
        slot: slot.slot,
        sequence: slot.sequence,
        crc: view.crc(),
        version: view.settings().version,
        calibration_crc: view.settings().calibration_crc,
    }
}

impl<F, const N: usize, const M: usize, const P: usize> Core<F, N, M, P> {
    fn calibration_crc(&self) -> Option<u32> {
        self.cal.active().map(|a| a.info.blob_crc)
    }

    /// The active recipe when it fits the active calibration.
    pub(super) fn usable_recipe(&self) -> Result<RecipeView<'static>, DeviceError> {
        let slots = self.recipes.as_deref().ok_or(DeviceError::NoRecipe)?;
        let (_, view) = slots.active().ok_or_else(|| slots.unreadable().unwrap_or(DeviceError::NoRecipe))?;
        check_recipe::<M, P>(&view, self.calibration_crc())?;
        Ok(view)
    }

    /// The recipe requests (refused while measuring by the caller).
    pub(super) fn recipe_request(
        &mut self,
        req: &crate::protocol::Request<'_>,
    ) -> Result<Response<'static>, DeviceError> {
        use crate::protocol::Request;
        let cal_crc = self.calibration_crc();
        let slots = self.recipes.as_deref_mut().ok_or(DeviceError::NoRecipe)?;
        match *req {
            Request::RecipeBegin { len, crc } => slots
                .begin(len, crc)
                .map(|slot| Response::ProvisionReady { slot, max_chunk: crate::protocol::MAX_CHUNK as u16 }),
            Request::RecipeChunk { offset, data } => {
                slots.write_chunk(offset, data).map(|next_offset| Response::ChunkAck { next_offset })
            }
            Request::RecipeCommit => {
                let info = slots.commit(&mut |v| check_recipe::<M, P>(v, cal_crc))?;
                let (_, view) = slots.active().ok_or(DeviceError::Storage)?;
                self.inspector = crate::inspect::Inspector::new();
                Ok(Response::RecipeCommitted(recipe_info(info, &view)))
            }
            Request::RecipeAbort => slots.abort().map(|_| Response::Aborted),
            _ => Err(DeviceError::NoRecipe),
        }
    }

    /// Reply to `InspectStatus`.
    pub(super) fn inspect_status(&self) -> InspectStatus {
        let slots = self.recipes.as_deref();
        let active = slots.and_then(|s| s.active());
        InspectStatus {
            recipe: active.map(|(slot, view)| recipe_info(slot, &view)),
            refused: match self.usable_recipe() {
                Err(DeviceError::NoRecipe) if active.is_none() => slots.and_then(|s| s.unreadable()),
                Err(e) => Some(e),
                Ok(_) => None,
            },
            inspecting: self.status.measuring && self.inspecting,
            counters: self.inspector.counters(),
        }
    }
}

impl<F: MappedFlash, const N: usize, const M: usize, const P: usize> Shared<F, N, M, P> {
    /// Opens the recipe store on `flash` (two slots of `slot_len` bytes):
    /// the newest signed recipe for this device's shape and its active
    /// calibration is taken. The platform keeps it in a static and hands it
    /// over with [`Self::set_recipes`].
    pub fn open_recipes<RF: MappedFlash>(&self, flash: RF, slot_len: u32) -> RecipeStore<RF> {
        let cal = self.core.lock(|c| c.borrow().calibration_crc());
        RecipeStore::open(flash, slot_len, crate::signed::TRUSTED_KEYS, |v| check_recipe::<M, P>(v, cal).is_ok())
    }

    /// Hands the application the platform's recipe store: it then takes
    /// recipes over the link and inspects. (By reference, once the
    /// application is in its static: the QEMU build's stack has no room for
    /// another copy of it.)
    pub fn set_recipes(&self, port: RecipePort) {
        self.core.lock(|c| c.borrow_mut().recipes = Some(port));
    }

    /// Decides one corrected line (the estimation task's inspection step):
    /// the verdict, and the reject pulse it schedules, if any. `None` when
    /// the recipe no longer fits (the job then ends with that error).
    pub(super) fn decide_line(
        &self,
        line: u32,
        v: &[SVector<f32, M>; P],
        reading_flags: &[u8; P],
        early: &crate::inspect::decide::UnscaledLine<P>,
    ) -> Result<(Verdict, Option<Pulse>), DeviceError> {
        let now = Instant::now().as_micros();
        self.core.lock(|c| {
            let c = &mut *c.borrow_mut();
            let recipe = c.recipe_view.ok_or(DeviceError::NoRecipe)?;
            let cal = &c.cal;
            // The calibration's out-of-prior flag, asked only of the points
            // the recipe already found out (an estimate costs ~20 times the decision).
            let out_of_prior = |p: usize| {
                let mut rho = SVector::<f32, N>::zeros();
                cal.active().is_some()
                    && cal.estimate_point(p, &v[p], reading_flags[p], &mut rho).flags & flags::OUT_OF_PRIOR != 0
            };
            let verdict = c.inspector.line_with(&recipe, line, v, reading_flags, Some(early), out_of_prior);
            let pulse = c.reject_plan.after_verdict(recipe.settings(), line, verdict.rejected(), now);
            Ok((verdict, pulse))
        })
    }

    /// Hands `pulse` (of the job `seq`) to the reject output, counted as
    /// under way until its event is on the link.
    pub(super) async fn schedule_pulse(&self, seq: u32, pulse: Pulse) {
        self.core.lock(|c| c.borrow_mut().pulses_under_way += 1);
        self.reject.send((seq, pulse)).await;
    }

    /// The end of an inspection: the rejected lines whose delay in lines
    /// outlasts the run pulse now (no line is left to count it down), then
    /// this waits until every pulse of the run has been driven and reported
    /// (at most the recipe's delay and pulse after the last verdict). The
    /// run's `MeasureDone` follows: the host cannot tell the end of the
    /// pulses itself, since pulses that overlap merge into one event. (A new
    /// inspection starts with an empty schedule.)
    pub(super) async fn finish_pulses(&self, seq: u32) {
        // No line completes from here on: the watchdog's stall rule must not
        // take a long delay in time for a stall (`Shared::measuring_lines`).
        self.core.lock(|c| c.borrow_mut().awaiting_pulses = true);
        let now = Instant::now().as_micros();
        while let Some(pulse) = self.core.lock(|c| {
            let c = &mut *c.borrow_mut();
            c.reject_plan.flush(c.recipe_view?.settings(), now)
        }) {
            self.schedule_pulse(seq, pulse).await;
        }
        // Woken by each pulse the reject output reports; a signal left over
        // from an earlier run costs one more look at the count, no more.
        while self.core.lock(|c| c.borrow().pulses_under_way) > 0 {
            self.pulse_reported.wait().await;
        }
        self.core.lock(|c| c.borrow_mut().awaiting_pulses = false);
    }
}

/// The reject output's task: drives each scheduled pulse on `out` (pulses
/// that overlap merge into one), reports it on the link
/// ([`Response::RejectPulse`]: what QEMU and the host simulation can show)
/// and counts it.
pub async fn reject_output<F, O, const N: usize, const M: usize, const P: usize>(
    shared: &Shared<F, N, M, P>,
    mut out: O,
) -> !
where
    F: MappedFlash,
    O: RejectOutput,
{
    out.set(false);
    // A pulse taken from the schedule while another was driven, due only
    // after that one ended: the next to drive.
    let mut carried = None;
    loop {
        let (seq, first) = match carried.take() {
            Some(p) => p,
            None => shared.reject.receive().await,
        };
        Timer::at(Instant::from_micros(first.start_us)).await;
        let start = Instant::now();
        out.set(true);
        let mut end = start + embassy_time::Duration::from_micros(first.len_us as u64);
        let mut pulse = Pulse { line: first.line, start_us: start.as_micros(), len_us: first.len_us };
        let mut taken = 1;
        // A pulse due before this one ends lengthens it; one due later (a
        // delay in time schedules pulses ahead) is a pulse of its own.
        loop {
            match select(Timer::at(end), shared.reject.receive()).await {
                Either::First(()) => break,
                Either::Second(later) if Instant::from_micros(later.1.start_us) > end => {
                    carried = Some(later);
                    Timer::at(end).await;
                    break;
                }
                Either::Second((_, next)) => {
                    let next_end = Instant::from_micros(next.start_us.max(start.as_micros()))
                        + embassy_time::Duration::from_micros(next.len_us as u64);
                    end = end.max(next_end);
                    pulse.line = next.line;
                    taken += 1;
                }
            }
        }
        out.set(false);
        pulse.len_us = (end - start).as_micros() as u32;
        shared.core.lock(|c| c.borrow_mut().inspector.count_pulse());
        let f: OutFrame = super::tasks::frame(
            seq,
            &Response::RejectPulse { line: pulse.line, start_us: pulse.start_us, len_us: pulse.len_us },
        );
        shared.out.send(f).await;
        // Reported: an inspection waiting for its pulses may end now.
        shared.core.lock(|c| {
            let c = &mut *c.borrow_mut();
            c.pulses_under_way = c.pulses_under_way.saturating_sub(taken);
        });
        shared.pulse_reported.signal(());
    }
}
