//! The bodies of the three tasks. Each platform wraps them in
//! `#[embassy_executor::task]` functions with its concrete types.
use super::self_test::Check;
use super::{Job, LineBuf, LineState, OutFrame, Shared};
use crate::acquire::by_frame::Target;
use crate::acquire::{FrameRead, FrameWork, LineCorrection, RawLine, acquire_line};
use crate::hw::{FrameInput, Leds, LineSensor, MappedFlash};
use crate::inspect::decide::UnscaledLine;
use crate::protocol::{
    self, DeviceError, Encoding, FrameReader, MAX_FRAME, MAX_WIRE_BINS, PointIn, PointMetaWire, PointsBlock, PushError,
    Pushed, Request, Response, flags,
};
use core::sync::atomic::Ordering;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex as Cs;
use embassy_sync::zerocopy_channel::{Receiver, Sender};
use embedded_io_async::{Read, Write};
use nalgebra::SVector;

/// Encodes a frame for the writer.
pub(super) fn frame(seq: u32, r: &Response<'_>) -> OutFrame {
    let mut f = OutFrame::new();
    let _ = f.resize(MAX_FRAME, 0);
    // Every message fits MAX_PAYLOAD by construction (protocol tests check
    // the largest of each, and N <= MAX_WIRE_BINS is checked at build time).
    let n = protocol::encode(seq, r, &mut f).unwrap_or(0);
    f.truncate(n);
    f
}

/// The transport task: reads request frames, answers each, and writes every
/// outgoing frame (replies and the estimation's point frames) in order.
pub async fn transport<F, R, W, S, const N: usize, const M: usize, const P: usize>(
    shared: &Shared<F, N, M, P>,
    mut rx: R,
    mut tx: W,
    mut scene: S,
) -> !
where
    F: MappedFlash,
    R: Read,
    W: Write,
    S: FrameInput,
{
    let reader = async {
        let mut frames = FrameReader::new();
        let mut buf = [0u8; 64];
        loop {
            let n = match rx.read(&mut buf).await {
                Ok(n) => n,
                Err(_) => continue, // line noise, overrun: the frame CRC catches the damage
            };
            for &b in &buf[..n] {
                let out = match frames.push(b) {
                    Pushed::More => continue,
                    Pushed::Oversized => {
                        shared.count_bad_frame();
                        frame(0, &Response::Error(DeviceError::Frame(protocol::FrameError::Oversized)))
                    }
                    Pushed::Frame(f) => match protocol::decode::<Request<'_>>(f) {
                        Ok((seq, req)) => {
                            shared.passed(Check::Link);
                            frame(seq, &shared.handle(seq, &req, &mut scene))
                        }
                        Err(e) => {
                            shared.count_bad_frame();
                            frame(0, &Response::Error(DeviceError::Frame(e)))
                        }
                    },
                };
                shared.out.send(out).await;
            }
        }
    };
    let writer = async {
        loop {
            let f = shared.out.receive().await;
            // A host that went away: nothing to do but keep serving.
            let _ = tx.write_all(&f).await;
            let _ = tx.flush().await;
        }
    };
    embassy_futures::join::join(reader, writer).await;
    unreachable!()
}

/// The acquisition task: runs each job line by line into the line buffers.
pub async fn acquisition<F, L, S, const N: usize, const M: usize, const P: usize>(
    shared: &Shared<F, N, M, P>,
    mut leds: L,
    mut sensor: S,
    mut lines_out: Sender<'static, Cs, LineBuf<M, P>>,
) -> !
where
    F: MappedFlash,
    L: Leds,
    S: LineSensor,
{
    if shared.on_trial() {
        // The self-test's sensor part: one dark frame now, so a trial image
        // can confirm without waiting for a measurement.
        leds.set(None, 0).await;
        let mut frame = [0u16; P];
        if sensor.read_frame(shared.acq.exposure_us, &mut frame).await.is_ok() {
            shared.passed(Check::Sensor);
        }
    }
    // Which readings of the line being acquired are corrected (kept here,
    // not per call: M x P flags).
    let mut by_frame = LineCorrection::<M, P>::new();
    loop {
        let job = shared.start.wait().await;
        let mut line = 0u32;
        let mut error = None;
        while !shared.stop.load(Ordering::SeqCst) && (job.lines == 0 || line < job.lines) {
            let active = shared.core.lock(|c| c.borrow().cal.active().map(|a| (a.led_order, a.info)));
            let Some((order, cal)) = active else {
                error = Some(DeviceError::NoCalibration);
                break;
            };
            // Waits while both buffers are in use: estimation is the pace.
            let buf = lines_out.send().await;
            let LineBuf { raw, v, flags, early, .. } = &mut *buf;
            let mut work =
                LineWork { shared, cal, v, fl: flags, by: &mut by_frame, early, inspect: job.inspect.is_some() };
            if let Err(e) = acquire_line(&mut leds, &mut sensor, &order, &shared.acq, raw, &mut work).await {
                error = Some(DeviceError::Sensor(e));
                break;
            }
            if work.finish(raw).is_none() {
                error = Some(DeviceError::NoCalibration);
                break;
            }
            buf.state = LineState::Line { job, line };
            lines_out.send_done();
            if line == 0 {
                shared.passed(Check::Sensor);
            }
            line += 1;
        }
        let buf = lines_out.send().await;
        buf.state = LineState::End { job, lines: line, error };
        lines_out.send_done();
    }
}

/// What the acquisition task does while a line's frames settle and
/// integrate: each frame corrected while the next one's LED settles, by
/// the calibration the line started with (whatever that leaves, or all of
/// it when the calibration changed meanwhile, after the last frame:
/// [`Self::finish`]); in an inspection, the first part of each point's
/// decision while the last LED frame integrates.
struct LineWork<'a, F, const N: usize, const M: usize, const P: usize> {
    shared: &'a Shared<F, N, M, P>,
    /// The calibration the line started with.
    cal: protocol::CalInfo,
    v: &'a mut [SVector<f32, M>; P],
    fl: &'a mut [u8; P],
    /// Which readings are corrected.
    by: &'a mut LineCorrection<M, P>,
    early: &'a mut UnscaledLine<P>,
    inspect: bool,
}

impl<F: MappedFlash, const N: usize, const M: usize, const P: usize> LineWork<'_, F, N, M, P> {
    /// Corrects frame `f` (`None`: what is left after the last one).
    fn correct(&mut self, f: Option<FrameRead>, raw: &RawLine<M, P>) -> Option<()> {
        self.shared.core.lock(|c| {
            let c = c.borrow();
            let (a, pixels) = c.cal.loaded()?;
            let mut t = Target {
                raw,
                white: &pixels.white,
                linearity: a.linearity.as_ref(),
                full_scale: self.shared.full_scale,
                cfg: &self.shared.acq,
                v: self.v,
                fl: self.fl,
            };
            match f {
                Some(f) if a.info == self.cal => self.by.frame(f, &mut t),
                Some(_) => {}
                None if a.info == self.cal => self.by.finish(&mut t),
                None => {
                    // The whole line again, by the calibration now active:
                    // what was worked out early is of readings now changed.
                    self.by.frame(FrameRead::Dark, &mut t);
                    self.by.finish(&mut t);
                    self.early.clear();
                }
            }
            Some(())
        })
    }

    /// What is left after the line's last frame (`None`: no calibration).
    fn finish(&mut self, raw: &RawLine<M, P>) -> Option<()> {
        self.correct(None, raw)
    }
}

impl<F: MappedFlash, const N: usize, const M: usize, const P: usize> FrameWork<M, P> for LineWork<'_, F, N, M, P> {
    fn read(&mut self, f: FrameRead, raw: &RawLine<M, P>) {
        if f == FrameRead::Dark {
            self.early.clear();
        }
        let _ = self.correct(Some(f), raw);
    }

    fn integrating(&mut self, f: FrameRead) {
        // The last LED's long exposure (2 ms on the board, the CPU idle
        // otherwise): the pixels whose other readings are all corrected get
        // the first part of their decision, which needs neither the last
        // reading nor the line's scale. The recipe is fixed while a job
        // runs and lives in flash: no lock held while this works.
        if !self.inspect || f != FrameRead::Long(M - 1) {
            return;
        }
        let recipe = self.shared.core.lock(|c| {
            let c = c.borrow();
            // Readings corrected by a calibration since replaced are
            // corrected again after the line: nothing to work out now.
            if c.cal.active().map(|a| a.info) == Some(self.cal) { c.recipe_view } else { None }
        });
        if let Some(recipe) = recipe {
            let by = &*self.by;
            let n = self.early.work_out(&recipe, self.v, |p| by.final_through(p, M - 1)) as u32;
            self.shared.core.lock(|c| {
                let mut c = c.borrow_mut();
                c.early_points = c.early_points.wrapping_add(n);
            });
        }
    }
}

/// The estimation task: `rho = W_zone v` for every point of each line,
/// several points per frame ([`crate::protocol::PointsFrame`]) in the
/// encoding the job asks for.
pub async fn estimation<F, const N: usize, const M: usize, const P: usize>(
    shared: &Shared<F, N, M, P>,
    mut lines_in: Receiver<'static, Cs, LineBuf<M, P>>,
) -> !
where
    F: MappedFlash,
{
    const { assert!(N <= MAX_WIRE_BINS, "a frame carries at most MAX_WIRE_BINS bins") };
    let mut stream_seq = 0u32;
    let mut current: Option<Job> = None;
    let mut block = PointsBlock::new();
    loop {
        let buf = lines_in.receive().await;
        match buf.state {
            LineState::Empty => {}
            LineState::Line { job, line } => {
                if current != Some(job) {
                    current = Some(job);
                    stream_seq = 0;
                }
                // An inspection sends the line's verdict, and its points only
                // for a rejected line whose points the host asked for.
                let points = match job.inspect {
                    None => P,
                    Some(ins) => match shared.decide_line(line, &buf.v, &buf.flags, &buf.early) {
                        Ok((mut verdict, pulse)) => {
                            let follow = verdict.rejected() && ins.defect_points;
                            if follow {
                                verdict.flags |= crate::inspect::decide::verdict::POINTS_FOLLOW;
                            }
                            shared.out.send(frame(job.seq, &Response::Verdict(verdict))).await;
                            if let Some(pulse) = pulse {
                                shared.schedule_pulse(job.seq, pulse).await;
                            }
                            if follow { P } else { 0 }
                        }
                        Err(e) => {
                            shared.out.send(frame(job.seq, &Response::Error(e))).await;
                            shared.stop.store(true, Ordering::SeqCst);
                            0
                        }
                    },
                };
                let bins = job.format.bin_range(N);
                let encoding = job.format.encoding;
                let crc = shared.core.lock(|c| c.borrow().cal.active().map_or(0, |a| a.info.blob_crc));
                block.start(line, stream_seq, 0, crc, encoding, bins, M);
                for p in 0..points {
                    let mut rho = SVector::<f32, N>::zeros();
                    let meta = shared.core.lock(|c| {
                        let c = c.borrow();
                        c.cal.active().is_some().then(|| c.cal.estimate_point(p, &buf.v[p], buf.flags[p], &mut rho))
                    });
                    // Never stream NaN/inf: a non-finite point is zeroed and flagged.
                    let wire = match meta {
                        Some(m) => PointMetaWire {
                            zone: m.zone,
                            cluster: m.cluster,
                            flags: m.flags,
                            sigma_scale: m.sigma_scale,
                            readings: m.readings,
                            reading_sigma: m.reading_sigma,
                        },
                        None => PointMetaWire {
                            zone: u16::MAX,
                            cluster: 0,
                            flags: buf.flags[p] | flags::NON_FINITE,
                            sigma_scale: 1.0,
                            readings: crate::gloss::NO_READINGS,
                            reading_sigma: crate::gloss::NO_READINGS,
                        },
                    };
                    let push = |block: &mut PointsBlock| {
                        shared.core.lock(|c| {
                            let c = c.borrow();
                            let sigma = match c.cal.active() {
                                Some(_) if meta.is_some() => {
                                    c.cal.uncertainty(wire.zone as usize, wire.cluster as usize)
                                }
                                _ => &[],
                            };
                            let pin =
                                PointIn { meta: wire, values: rho.as_slice(), readings: buf.v[p].as_slice(), sigma };
                            block.push(&pin)
                        })
                    };
                    match push(&mut block) {
                        Ok(()) => {}
                        Err(PushError::Full) => {
                            shared.out.send(frame(job.seq, &Response::Points(block.frame()))).await;
                            block.start(line, stream_seq, p as u16, crc, encoding, bins, M);
                            // An empty block takes any point of the block's encoding, or
                            // refuses it as not representable (handled below).
                            if push(&mut block).is_err() {
                                send_alone(shared, job.seq, &mut block, &push, crc, bins).await;
                                block.start(line, stream_seq.wrapping_add(1), p as u16 + 1, crc, encoding, bins, M);
                            }
                        }
                        Err(PushError::NotRepresentable) => {
                            if !block.is_empty() {
                                shared.out.send(frame(job.seq, &Response::Points(block.frame()))).await;
                            }
                            block.start(line, stream_seq, p as u16, crc, encoding, bins, M);
                            send_alone(shared, job.seq, &mut block, &push, crc, bins).await;
                            block.start(line, stream_seq.wrapping_add(1), p as u16 + 1, crc, encoding, bins, M);
                        }
                    }
                    stream_seq = stream_seq.wrapping_add(1);
                }
                if !block.is_empty() {
                    shared.out.send(frame(job.seq, &Response::Points(block.frame()))).await;
                }
                shared.core.lock(|c| {
                    let mut c = c.borrow_mut();
                    c.status.lines_total = c.status.lines_total.wrapping_add(1);
                });
            }
            LineState::End { job, lines, error } => {
                // The next job's stream starts at 0 even when its request is
                // this one again: a new host session numbers its requests
                // from 1, so the same `Measure` may well carry the same seq.
                current = None;
                if let Some(e) = error {
                    shared.out.send(frame(job.seq, &Response::Error(e))).await;
                }
                // Still measuring while the pulses end, so no job starts
                // under a pulse of this one.
                if job.inspect.is_some() {
                    shared.finish_pulses(job.seq).await;
                }
                shared.core.lock(|c| c.borrow_mut().status.measuring = false);
                shared.out.send(frame(job.seq, &Response::MeasureDone { lines_done: lines })).await;
            }
        }
        buf.state = LineState::Empty;
        lines_in.receive_done();
    }
}

/// Sends the point `push` pushes alone, f32 (the lossless fallback of a
/// point its block's encoding cannot carry within its bound). `block` was
/// just started at the point.
async fn send_alone<F, const N: usize, const M: usize, const P: usize>(
    shared: &Shared<F, N, M, P>,
    job_seq: u32,
    block: &mut PointsBlock,
    push: &impl Fn(&mut PointsBlock) -> Result<(), PushError>,
    crc: u32,
    bins: crate::protocol::BinRange,
) where
    F: MappedFlash,
{
    block.start(block.line, block.seq, block.first_point, crc, Encoding::F32, bins, M);
    // An f32 point always fits an empty block.
    let _ = push(block);
    shared.out.send(frame(job_seq, &Response::Points(block.frame()))).await;
}

/// How long a reset waits after it was asked for: time for the reply (or
/// USB DFU's last status) to leave before the link goes down.
pub const REBOOT_DELAY_MS: u64 = 100;

/// The reboot task: waits for a `Reboot` request (or the end of a USB DFU
/// download), lets the reply leave, then resets the chip with `reset` (the
/// bootloader then swaps in a committed update).
pub async fn reboot<F: MappedFlash, const N: usize, const M: usize, const P: usize>(
    shared: &Shared<F, N, M, P>,
    reset: fn() -> !,
) -> ! {
    shared.reboot.wait().await;
    embassy_time::Timer::after_millis(REBOOT_DELAY_MS).await;
    reset()
}
