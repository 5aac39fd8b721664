//! The protocol client: request/reply with sequence numbers and typed errors,
//! chunked provisioning, measurement streams, simulated scenes.
use super::Transport;
use super::stream::{DecodeError, StreamDecoder, decode_points};
use brdf_meter::protocol::{
    self, BinRange, CalInfo, DeviceError, DeviceInfo, DeviceStatus, Encoding, FrameError, FrameReader, LeBytes,
    MAX_FRAME, MAX_SIM_BYTES, Pushed, Request, Response, StreamFormat, Streamed,
};
use brdf_meter::shape::READINGS;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// What went wrong on the link.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The transport failed.
    #[error("link I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// Nothing (or not the awaited reply) arrived in time.
    #[error("no reply from the device within {0:?} while waiting for {1} (is it running, and is this the right port?)")]
    Timeout(Duration, &'static str),
    /// A frame from the device could not be read.
    #[error("unreadable frame from the device: {0:?}")]
    Frame(FrameError),
    /// The device answered with an error.
    #[error("{0}")]
    Device(DeviceError),
    /// The device answered something else than the protocol allows here.
    #[error("unexpected reply from the device: {0}")]
    Unexpected(String),
    /// A line frame that read as a frame but could not be decoded into points.
    #[error("{0}")]
    Stream(#[from] DecodeError),
    /// The device refused an inspection recipe's signature (the device's
    /// own error names the calibration store's subject).
    #[error(
        "the device refused the recipe: {0}; the previous recipe is kept (teach it again signed with a key the device \
         trusts: `host-tools inspect teach --key`, and `host-tools info` lists the keys it trusts)"
    )]
    RecipeSignature(brdf_meter::signed::SignatureFault),
}

impl LinkError {
    /// Whether the same request is worth sending again: a reply lost or
    /// garbled on the way (either direction), not a refusal.
    pub fn is_transient(&self) -> bool {
        matches!(self, Self::Timeout(..) | Self::Frame(_) | Self::Device(DeviceError::Frame(_)))
    }
}

/// A point's estimate, owned.
#[derive(Clone, Debug, PartialEq)]
pub struct PointRecord {
    /// Line number in the measurement.
    pub line: u32,
    /// Stream sequence number.
    pub seq: u32,
    /// Pixel.
    pub point: u16,
    /// Zone.
    pub zone: u16,
    /// Flags (`brdf_meter::protocol::flags`).
    pub flags: u8,
    /// Cluster within the zone (piecewise calibrations; 0 otherwise).
    pub cluster: u8,
    /// What the calibration's per-bin uncertainty is multiplied by for this point.
    pub sigma_scale: f32,
    /// The gloss readings (`brdf_meter::gloss`; NaN: none).
    pub readings: [f32; READINGS],
    /// Their standard uncertainties (k = 1).
    pub reading_sigma: [f32; READINGS],
    /// The bins `values` are (all n unless the measurement asked for fewer).
    pub bins: BinRange,
    /// How the values travelled (f32 and corrected readings: bit for bit;
    /// Sigma16: within 1/256 of the bin's uncertainty).
    pub encoding: Encoding,
    /// The values of `bins`.
    pub values: Vec<f32>,
    /// The corrected readings the device sent and the values were
    /// estimated from (the corrected encoding; empty otherwise): what its
    /// inspection decides on, and what a recipe is taught from.
    pub corrected: Vec<f32>,
}

/// A decoded frame from the device.
#[derive(Clone, Debug, PartialEq)]
pub enum Reply {
    /// Any reply but a point.
    Msg(Response<'static>),
    /// A point (a protocol 2 point frame).
    Point(PointRecord),
    /// The points of a line frame, decoded.
    Points(Vec<PointRecord>),
}

/// A frame: its sequence number and content.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Sequence number (the request it answers; 0 for unreadable requests).
    pub seq: u32,
    /// Content.
    pub reply: Reply,
}

/// What the client noticed going wrong on the link, and what it did about
/// it. The tolerant calls ([`Client::request_retrying`],
/// [`Client::provision_retrying`], [`Client::measure_tolerant`]) count here.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames that did not decode (COBS, length, CRC, version, body), skipped.
    pub bad_frames: u64,
    /// Stream points never received intact (sequence gaps, a cut stream).
    pub missing_points: u64,
    /// Stream points received again, dropped.
    pub duplicate_points: u64,
    /// Waits that ended without the awaited frame.
    pub timeouts: u64,
    /// Requests (or provisioning attempts) sent again.
    pub retries: u64,
    /// Resynchronisations: a delimiter, then the link drained until quiet.
    pub resyncs: u64,
}

/// A measurement read by [`Client::measure_tolerant`]: what arrived intact,
/// and what did not, by stream sequence number.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StreamReport {
    /// Points accepted, in stream order, each once.
    pub points: Vec<PointRecord>,
    /// Stream sequence numbers that never arrived intact.
    pub missing: Vec<u32>,
    /// Stream sequence numbers that arrived more than once (later copies dropped).
    pub duplicates: Vec<u32>,
    /// Whether `MeasureDone` arrived (a cut stream ends by a timeout instead).
    pub complete: bool,
    /// An error the device sent during the measurement.
    pub device_error: Option<DeviceError>,
    /// Sequence number of the `Measure` request whose stream this is (the
    /// last one sent, when it had to be sent again).
    pub request_seq: u32,
}

/// How [`Client::provision_retrying`] ended.
#[derive(Debug)]
pub enum ProvisionOutcome {
    /// The blob is the device's active calibration (`attempts` tries).
    Committed {
        /// The active calibration.
        cal: CalInfo,
        /// Attempts it took.
        attempts: u32,
    },
    /// Every attempt failed on the link; the device kept `active`.
    RolledBack {
        /// The calibration still active.
        active: Option<CalInfo>,
        /// Attempts made.
        attempts: u32,
        /// Why the last attempt failed.
        last_error: LinkError,
    },
}

/// Errors a retry may cure: lost or damaged frames either way, and the
/// device's complaints that follow them (an unreadable request; a chunk or
/// commit the device had already applied before its reply was lost).
fn link_fault(e: &LinkError) -> bool {
    matches!(
        e,
        LinkError::Timeout(..)
            | LinkError::Frame(_)
            | LinkError::Unexpected(_)
            | LinkError::Device(DeviceError::Frame(_) | DeviceError::OutOfOrder { .. } | DeviceError::NotProvisioning)
    )
}

/// Which two-slot store a signed image goes to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlotKind {
    /// The calibration slots.
    Calibration,
    /// The inspection recipe slots.
    Recipe,
}

/// A device client over any transport.
pub struct Client<T> {
    t: T,
    frames: FrameReader,
    ready: VecDeque<Result<Frame, LinkError>>,
    seq: u32,
    /// How long a request waits for its reply.
    pub timeout: Duration,
    /// What went wrong on the link so far.
    pub stats: LinkStats,
    /// What measurements ask the stream to carry (default: Sigma16, every bin).
    pub format: StreamFormat,
    /// The calibration blob line frames are decoded with ([`Self::set_calibration`]).
    decoder: Option<StreamDecoder>,
}

impl<T: Transport> Client<T> {
    /// A client on `t`. Sends a delimiter first, so a device that saw a partial
    /// frame before starts afresh.
    pub fn new(mut t: T) -> Result<Self, LinkError> {
        t.send(&[0])?;
        Ok(Self {
            t,
            frames: FrameReader::new(),
            ready: VecDeque::new(),
            seq: 0,
            timeout: Duration::from_secs(5),
            stats: LinkStats::default(),
            format: StreamFormat::default(),
            decoder: None,
        })
    }

    /// The calibration blob the device runs: Sigma16 and readings frames
    /// are decoded with it (and refused when they were made with another).
    pub fn set_calibration(&mut self, blob: &[u8]) -> anyhow::Result<()> {
        self.decoder = Some(StreamDecoder::new(blob)?);
        Ok(())
    }

    /// The transport (tests use it to send raw bytes).
    pub fn transport(&mut self) -> &mut T {
        &mut self.t
    }

    /// The transport back, for the next session on the same device (a new
    /// `Client` numbers its requests from 1 again, as a new process does).
    pub fn into_transport(self) -> T {
        self.t
    }

    /// Sends raw bytes (tests of malformed frames).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        Ok(self.t.send(bytes)?)
    }

    /// Encodes and sends a request; returns its sequence number.
    pub fn send(&mut self, req: &Request<'_>) -> Result<u32, LinkError> {
        self.seq = self.seq.wrapping_add(1).max(1);
        let mut buf = [0u8; MAX_FRAME];
        let n = protocol::encode(self.seq, req, &mut buf).map_err(LinkError::Frame)?;
        self.t.send(&buf[..n])?;
        Ok(self.seq)
    }

    /// The next frame from the device, waiting at most `timeout`.
    pub fn next_frame(&mut self, timeout: Duration) -> Result<Frame, LinkError> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(f) = self.ready.pop_front() {
                return f;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(LinkError::Timeout(timeout, "a frame"));
            }
            let mut buf = [0u8; 4096];
            let n = self.t.recv(&mut buf, left)?;
            for &b in &buf[..n] {
                match self.frames.push(b) {
                    Pushed::More => {}
                    Pushed::Oversized => self.ready.push_back(Err(LinkError::Frame(FrameError::Oversized))),
                    Pushed::Frame(f) => {
                        let r = match protocol::decode::<Response<'_>>(f) {
                            Err(e) => Err(LinkError::Frame(e)),
                            Ok((seq, r)) => match r.detach() {
                                Ok(m) => Ok(Frame { seq, reply: Reply::Msg(m) }),
                                Err(Streamed::Point(p)) => Ok(Frame { seq, reply: Reply::Point(p.into()) }),
                                Err(Streamed::Points(p)) => decode_points(&p, self.decoder.as_ref())
                                    .map(|pts| Frame { seq, reply: Reply::Points(pts) })
                                    .map_err(LinkError::Stream),
                            },
                        };
                        self.ready.push_back(r);
                    }
                }
            }
        }
    }

    /// Waits for the reply to request `seq` (a device error is returned as
    /// [`LinkError::Device`]). Frames of other requests are dropped.
    pub fn reply_to(&mut self, seq: u32) -> Result<Response<'static>, LinkError> {
        let deadline = Instant::now() + self.timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let f = self.next_frame(left).map_err(|e| match e {
                LinkError::Timeout(..) => LinkError::Timeout(self.timeout, "the reply to a request"),
                e => e,
            })?;
            match f {
                // The device could not read a request frame: ours.
                Frame { seq: 0, reply: Reply::Msg(Response::Error(e)) } => return Err(LinkError::Device(e)),
                Frame { seq: s, reply: Reply::Msg(Response::Error(e)) } if s == seq => {
                    return Err(LinkError::Device(e));
                }
                Frame { seq: s, reply: Reply::Msg(m) } if s == seq => return Ok(m),
                _ => {} // a stale frame of an earlier request
            }
        }
    }

    /// Sends `req` and waits for its reply.
    pub fn request(&mut self, req: &Request<'_>) -> Result<Response<'static>, LinkError> {
        let seq = self.send(req)?;
        self.reply_to(seq)
    }

    /// Waits until the device answers `Info`, asking again every 250 ms, for
    /// at most `total`: bytes sent before a device's UART is enabled are lost
    /// (QEMU's USART drops them), so the first request may vanish or arrive
    /// cut (answered by a frame error).
    pub fn wait_ready(&mut self, total: Duration) -> Result<DeviceInfo, LinkError> {
        let saved = self.timeout;
        let deadline = Instant::now() + total;
        self.timeout = Duration::from_millis(250);
        let r = loop {
            match self.info() {
                // Nothing yet, or the tail of a frame whose start was lost:
                // ask again.
                Err(LinkError::Timeout(..) | LinkError::Device(DeviceError::Frame(_))) if Instant::now() < deadline => {
                    self.t.send(&[0])?;
                }
                Err(LinkError::Timeout(..)) => break Err(LinkError::Timeout(total, "the device to answer Info")),
                other => break other,
            }
        };
        self.timeout = saved;
        r
    }

    /// Device identity and sizes.
    pub fn info(&mut self) -> Result<DeviceInfo, LinkError> {
        match self.request(&Request::Info)? {
            Response::Info(i) => Ok(i),
            r => Err(LinkError::Unexpected(format!("{r:?} to Info"))),
        }
    }

    /// Device status.
    pub fn status(&mut self) -> Result<DeviceStatus, LinkError> {
        match self.request(&Request::Status)? {
            Response::Status(s) => Ok(s),
            r => Err(LinkError::Unexpected(format!("{r:?} to Status"))),
        }
    }

    /// Provisions `blob`: begin, chunks (each acknowledged), commit. On any
    /// error the device keeps its previous calibration; this aborts the
    /// provisioning when the link still works.
    pub fn provision(&mut self, blob: &[u8], progress: impl FnMut(usize, usize)) -> Result<CalInfo, LinkError> {
        match self.send_signed(blob, SlotKind::Calibration, progress)? {
            Response::Committed(c) => Ok(c),
            r => Err(LinkError::Unexpected(format!("{r:?} to ProvisionCommit"))),
        }
    }

    /// Sends a signed image into one of the device's two-slot stores:
    /// begin, chunks (each acknowledged), commit; returns the commit's
    /// reply. Aborts when a chunk is refused and the link still works.
    pub(crate) fn send_signed(
        &mut self,
        image: &[u8],
        kind: SlotKind,
        mut progress: impl FnMut(usize, usize),
    ) -> Result<Response<'static>, LinkError> {
        let crc = brdf_meter::blob::CRC32.checksum(image);
        let len = image.len() as u32;
        let begin = match kind {
            SlotKind::Calibration => Request::ProvisionBegin { len, crc },
            SlotKind::Recipe => Request::RecipeBegin { len, crc },
        };
        let max_chunk = match self.request(&begin)? {
            Response::ProvisionReady { max_chunk, .. } => max_chunk as usize,
            r => return Err(LinkError::Unexpected(format!("{r:?} to {begin:?}"))),
        };
        let result = (|| {
            let mut offset = 0usize;
            for data in image.chunks(max_chunk.max(1)) {
                let at = offset as u32;
                let chunk = match kind {
                    SlotKind::Calibration => Request::ProvisionChunk { offset: at, data },
                    SlotKind::Recipe => Request::RecipeChunk { offset: at, data },
                };
                match self.request(&chunk)? {
                    Response::ChunkAck { next_offset } if next_offset as usize == offset + data.len() => {}
                    r => return Err(LinkError::Unexpected(format!("{r:?} to the chunk at {offset}"))),
                }
                offset += data.len();
                progress(offset, image.len());
            }
            self.request(match kind {
                SlotKind::Calibration => &Request::ProvisionCommit,
                SlotKind::Recipe => &Request::RecipeCommit,
            })
        })();
        if let Err(LinkError::Device(DeviceError::OutOfOrder { .. } | DeviceError::ChunkTooLarge { .. })) = &result {
            let _ = self.request(match kind {
                SlotKind::Calibration => &Request::ProvisionAbort,
                SlotKind::Recipe => &Request::RecipeAbort,
            });
        }
        result
    }

    /// Loads a simulated scene: `lines[l][frame][pixel]`, frame 0 dark and
    /// 1 + k under LED k.
    pub fn load_scene(&mut self, lines: &[Vec<Vec<u16>>]) -> Result<(), LinkError> {
        let per = MAX_SIM_BYTES / 2;
        for (l, frames) in lines.iter().enumerate() {
            for (f, px) in frames.iter().enumerate() {
                for (c, part) in px.chunks(per).enumerate() {
                    let bytes: Vec<u8> = part.iter().flat_map(|v| v.to_le_bytes()).collect();
                    let req = Request::SimFrame {
                        line: l as u8,
                        frame: f as u8,
                        first_pixel: (c * per) as u16,
                        pixels: LeBytes(&bytes),
                    };
                    self.expect(&req, |r| matches!(r, Response::SimLoaded))?;
                }
            }
        }
        self.expect(&Request::SimLines { lines: lines.len() as u8 }, |r| matches!(r, Response::SimLoaded))
    }

    fn expect(&mut self, req: &Request<'_>, ok: impl Fn(&Response<'_>) -> bool) -> Result<(), LinkError> {
        let r = self.request(req)?;
        if ok(&r) { Ok(()) } else { Err(LinkError::Unexpected(format!("{r:?} to {req:?}"))) }
    }

    /// Measures `lines` lines (>= 1) and returns every point, in order.
    /// Checks the stream: sequence numbers without gaps, `MeasureDone` with the
    /// line count; an error the device sends mid-stream is returned.
    pub fn measure(&mut self, lines: u32) -> Result<Vec<PointRecord>, LinkError> {
        self.measure_observed(lines, &mut |_| {})
    }

    /// [`Self::measure`], calling `on_point` as each point arrives (for a
    /// progress display).
    pub fn measure_observed(
        &mut self,
        lines: u32,
        on_point: &mut dyn FnMut(&PointRecord),
    ) -> Result<Vec<PointRecord>, LinkError> {
        assert!(lines >= 1, "use start/stop for continuous measurement");
        let seq = self.send(&Request::Measure { lines, format: self.format })?;
        let mut started = false;
        let result = self.measurement_stream(seq, lines, on_point, &mut started);
        if result.is_err() && started {
            // The device measures on: stop it and let what it already sent
            // drain, so the link (and the next session on it) starts clean
            // rather than behind a stream nobody reads.
            let _ = self.send(&Request::Stop);
            let timeout = std::mem::replace(&mut self.timeout, Duration::from_millis(500));
            let _ = self.resync();
            self.timeout = timeout;
        }
        result
    }

    /// The frames of the measurement requested with `seq`, up to its
    /// `MeasureDone` (`started` set once the device has begun).
    fn measurement_stream(
        &mut self,
        seq: u32,
        lines: u32,
        on_point: &mut dyn FnMut(&PointRecord),
        started: &mut bool,
    ) -> Result<Vec<PointRecord>, LinkError> {
        let mut points = Vec::new();
        let mut error = None;
        loop {
            let f = self.next_frame(self.timeout).map_err(|e| match e {
                LinkError::Timeout(..) => LinkError::Timeout(self.timeout, "measurement frames"),
                e => e,
            })?;
            if f.seq != seq && f.seq != 0 {
                continue;
            }
            match f.reply {
                Reply::Msg(Response::MeasureStarted { .. }) => *started = true,
                Reply::Point(p) => Self::take_in_order(&mut points, vec![p], on_point)?,
                Reply::Points(ps) => Self::take_in_order(&mut points, ps, on_point)?,
                Reply::Msg(Response::Error(e)) if !*started => return Err(LinkError::Device(e)),
                Reply::Msg(Response::Error(e)) => error = Some(e),
                Reply::Msg(Response::MeasureDone { lines_done }) => {
                    if let Some(e) = error {
                        return Err(LinkError::Device(e));
                    }
                    if lines_done != lines {
                        return Err(LinkError::Unexpected(format!("{lines_done} of {lines} lines measured")));
                    }
                    return Ok(points);
                }
                Reply::Msg(r) => return Err(LinkError::Unexpected(format!("{r:?} during a measurement"))),
            }
        }
    }

    /// Appends `got` to `points`, each the next of the stream.
    fn take_in_order(
        points: &mut Vec<PointRecord>,
        got: Vec<PointRecord>,
        on_point: &mut dyn FnMut(&PointRecord),
    ) -> Result<(), LinkError> {
        for p in got {
            if p.seq as usize != points.len() {
                return Err(LinkError::Unexpected(format!(
                    "point {} lost (got stream sequence {})",
                    points.len(),
                    p.seq
                )));
            }
            on_point(&p);
            points.push(p);
        }
        Ok(())
    }

    fn count(&mut self, e: &LinkError) {
        match e {
            LinkError::Timeout(..) => self.stats.timeouts += 1,
            LinkError::Frame(_) => self.stats.bad_frames += 1,
            _ => {}
        }
    }

    /// Takes streamed points into a tolerant measurement's report: repeats
    /// dropped, gaps reported missing.
    fn take_tolerant(
        &mut self,
        rep: &mut StreamReport,
        next: &mut u32,
        total: u32,
        got: Vec<PointRecord>,
    ) -> Result<(), LinkError> {
        for p in got {
            if p.seq < *next {
                rep.duplicates.push(p.seq);
                self.stats.duplicate_points += 1;
                continue;
            }
            if p.seq >= total {
                return Err(LinkError::Unexpected(format!("point {} of a {total}-point measurement", p.seq)));
            }
            rep.missing.extend(*next..p.seq);
            *next = p.seq + 1;
            rep.points.push(p);
        }
        Ok(())
    }

    /// Starts afresh after a fault: a delimiter ends any partial frame the
    /// device holds, then every frame in flight is dropped until the link has
    /// been quiet for [`Self::timeout`] (at most 20 timeouts, in case the
    /// device is streaming).
    pub fn resync(&mut self) -> Result<(), LinkError> {
        self.stats.resyncs += 1;
        self.t.send(&[0])?;
        self.frames = FrameReader::new();
        self.ready.clear();
        let deadline = Instant::now() + self.timeout * 20;
        while Instant::now() < deadline {
            match self.next_frame(self.timeout) {
                Ok(_) | Err(LinkError::Frame(_) | LinkError::Stream(_)) => {}
                Err(LinkError::Timeout(..)) => return Ok(()),
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    /// [`Self::request`], sent again after a resync when the reply is lost or
    /// unreadable or the device could not read the request, up to `attempts`
    /// times. Only for requests whose repetition is harmless (Info, Status,
    /// Stop, ProvisionAbort, simulated scene loads).
    pub fn request_retrying(&mut self, req: &Request<'_>, attempts: u32) -> Result<Response<'static>, LinkError> {
        let mut k = 0;
        loop {
            k += 1;
            match self.request(req) {
                Err(e) if k < attempts && e.is_transient() => {
                    self.count(&e);
                    self.stats.retries += 1;
                    self.resync()?;
                }
                r => return r,
            }
        }
    }

    /// [`Self::provision`] over a faulty link. Each request is sent again
    /// (after a resync) when it or its reply is lost or damaged: a repeated
    /// begin restarts the session, a chunk the device had already written is
    /// recognised by its `OutOfOrder` answer, a commit whose reply was lost by
    /// asking what is active. When an attempt fails all the same, the client
    /// asks the device what is active (done if it is the blob), aborts the
    /// device's session and starts again, up to `attempts` times. Either the
    /// blob ends active or the previous calibration stays so; a refusal of
    /// the blob itself is returned at once.
    pub fn provision_retrying(&mut self, blob: &[u8], attempts: u32) -> Result<ProvisionOutcome, LinkError> {
        let blob_id = brdf_meter::blob::BlobView::parse(blob).ok().map(|v| v.crc());
        let mut attempt = 0;
        loop {
            attempt += 1;
            let err = match self.provision_once_retrying(blob, blob_id, 6) {
                Ok(cal) => return Ok(ProvisionOutcome::Committed { cal, attempts: attempt }),
                Err(e) if link_fault(&e) => e,
                Err(e) => return Err(e),
            };
            self.count(&err);
            self.resync()?;
            let active = self.active_calibration()?;
            if let Some(cal) = active
                && Some(cal.blob_crc) == blob_id
            {
                return Ok(ProvisionOutcome::Committed { cal, attempts: attempt });
            }
            match self.request_retrying(&Request::ProvisionAbort, 8) {
                Ok(_) | Err(LinkError::Device(DeviceError::NotProvisioning)) => {}
                Err(e) => return Err(e),
            }
            if attempt >= attempts {
                return Ok(ProvisionOutcome::RolledBack { active, attempts: attempt, last_error: err });
            }
            self.stats.retries += 1;
        }
    }

    /// The device's active calibration, asked with retries.
    fn active_calibration(&mut self) -> Result<Option<CalInfo>, LinkError> {
        match self.request_retrying(&Request::Info, 8)? {
            Response::Info(i) => Ok(i.calibration),
            r => Err(LinkError::Unexpected(format!("{r:?} to Info"))),
        }
    }

    /// One provisioning, each request tried up to `tries` times.
    fn provision_once_retrying(&mut self, blob: &[u8], blob_id: Option<u32>, tries: u32) -> Result<CalInfo, LinkError> {
        let crc = brdf_meter::blob::CRC32.checksum(blob);
        let max_chunk = match self.request_retrying(&Request::ProvisionBegin { len: blob.len() as u32, crc }, tries)? {
            Response::ProvisionReady { max_chunk, .. } => max_chunk as usize,
            r => return Err(LinkError::Unexpected(format!("{r:?} to ProvisionBegin"))),
        };
        let mut offset = 0usize;
        for chunk in blob.chunks(max_chunk.max(1)) {
            let next = (offset + chunk.len()) as u32;
            let mut k = 0;
            loop {
                k += 1;
                match self.request(&Request::ProvisionChunk { offset: offset as u32, data: chunk }) {
                    Ok(Response::ChunkAck { next_offset }) if next_offset == next => break,
                    // An earlier copy was written; its acknowledgement was lost.
                    Err(LinkError::Device(DeviceError::OutOfOrder { expected, .. })) if expected == next && k > 1 => {
                        break;
                    }
                    Err(e) if k < tries && e.is_transient() => {
                        self.count(&e);
                        self.stats.retries += 1;
                        self.resync()?;
                    }
                    Ok(r) => return Err(LinkError::Unexpected(format!("{r:?} to the chunk at {offset}"))),
                    Err(e) => return Err(e),
                }
            }
            offset += chunk.len();
        }
        let mut k = 0;
        loop {
            k += 1;
            match self.request(&Request::ProvisionCommit) {
                Ok(Response::Committed(c)) => return Ok(c),
                Err(e) if k < tries && e.is_transient() => {
                    self.count(&e);
                    self.stats.retries += 1;
                    self.resync()?;
                    // A commit whose reply was lost has made the blob active.
                    if let Some(cal) = self.active_calibration()?
                        && Some(cal.blob_crc) == blob_id
                    {
                        return Ok(cal);
                    }
                }
                Ok(r) => return Err(LinkError::Unexpected(format!("{r:?} to ProvisionCommit"))),
                Err(e) => return Err(e),
            }
        }
    }

    /// Measures `lines` lines (>= 1) of `points_per_line` points over a
    /// faulty link: unreadable frames are skipped, repeated points dropped,
    /// and every point that never arrived intact is reported by its stream
    /// sequence number, so nothing is lost, repeated or altered unnoticed. A
    /// lost or unreadable `Measure` is sent again; a stream cut off (no
    /// `MeasureDone` within [`Self::timeout`]) is stopped and the link
    /// resynchronised, ready for the next request.
    pub fn measure_tolerant(&mut self, lines: u32, points_per_line: u32) -> Result<StreamReport, LinkError> {
        assert!(lines >= 1, "use start/stop for continuous measurement");
        let total = lines * points_per_line;
        let mut seq = self.send(&Request::Measure { lines, format: self.format })?;
        let mut sends = 1;
        let mut rep = StreamReport::default();
        let mut next = 0u32;
        let mut started = false;
        loop {
            let f = match self.next_frame(self.timeout) {
                Ok(f) => f,
                Err(LinkError::Frame(_)) => {
                    self.stats.bad_frames += 1;
                    continue;
                }
                Err(LinkError::Timeout(..)) => {
                    self.stats.timeouts += 1;
                    if started || sends >= 4 {
                        break;
                    }
                    // The request or everything after it was lost.
                    self.stats.retries += 1;
                    self.resync()?;
                    seq = self.send(&Request::Measure { lines, format: self.format })?;
                    sends += 1;
                    continue;
                }
                Err(e) => return Err(e),
            };
            if f.seq != seq && f.seq != 0 {
                continue; // a frame of an earlier request
            }
            match f.reply {
                Reply::Msg(Response::MeasureStarted { .. }) => started = true,
                Reply::Point(p) => {
                    started = true;
                    self.take_tolerant(&mut rep, &mut next, total, vec![p])?;
                }
                Reply::Points(ps) => {
                    started = true;
                    self.take_tolerant(&mut rep, &mut next, total, ps)?;
                }
                // The device could not read our Measure: send it again.
                Reply::Msg(Response::Error(DeviceError::Frame(_))) if f.seq == 0 && !started && sends < 4 => {
                    self.stats.retries += 1;
                    self.resync()?;
                    seq = self.send(&Request::Measure { lines, format: self.format })?;
                    sends += 1;
                }
                Reply::Msg(Response::Error(_)) if f.seq == 0 => {}
                // A first Measure whose replies were lost is still running.
                Reply::Msg(Response::Error(DeviceError::Busy)) if !started && sends < 4 => {
                    self.stats.retries += 1;
                    self.resync()?;
                    seq = self.send(&Request::Measure { lines, format: self.format })?;
                    sends += 1;
                }
                Reply::Msg(Response::Error(e)) if !started => return Err(LinkError::Device(e)),
                Reply::Msg(Response::Error(e)) => rep.device_error = Some(e),
                Reply::Msg(Response::MeasureDone { .. }) => {
                    rep.complete = true;
                    break;
                }
                Reply::Msg(r) => return Err(LinkError::Unexpected(format!("{r:?} during a measurement"))),
            }
        }
        rep.missing.extend(next..total);
        rep.request_seq = seq;
        self.stats.missing_points += rep.missing.len() as u64;
        if !rep.complete {
            // Stop whatever is left of the stream and start afresh.
            self.send(&Request::Stop)?;
            self.resync()?;
        }
        Ok(rep)
    }
}

#[cfg(test)]
mod tolerant_tests {
    use super::*;

    /// A device that answers each request with the next scripted byte
    /// stream, served 7 bytes at a time.
    struct Scripted {
        replies: VecDeque<Vec<u8>>,
        out: VecDeque<u8>,
    }

    impl Scripted {
        fn new(replies: Vec<Vec<u8>>) -> Self {
            Self { replies: replies.into(), out: VecDeque::new() }
        }
    }

    impl Transport for Scripted {
        fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
            if bytes.len() > 1
                && let Some(r) = self.replies.pop_front()
            {
                self.out.extend(r);
            }
            Ok(())
        }
        fn recv(&mut self, buf: &mut [u8], _timeout: Duration) -> std::io::Result<usize> {
            let n = buf.len().min(self.out.len()).min(7);
            for (d, s) in buf.iter_mut().zip(self.out.drain(..n)) {
                *d = s;
            }
            Ok(n)
        }
    }

    fn frame(seq: u32, r: &Response<'_>) -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME];
        let n = protocol::encode(seq, r, &mut buf).unwrap();
        buf[..n].to_vec()
    }

    fn point(seq: u32, values: &[u8]) -> Response<'_> {
        Response::Point(protocol::PointFrame {
            line: 0,
            seq,
            point: seq as u16,
            zone: 0,
            cluster: 0,
            flags: 0,
            sigma_scale: 1.0,
            readings: [1.0; READINGS],
            reading_sigma: [0.5; READINGS],
            values: LeBytes(values),
        })
    }

    #[test]
    fn a_tolerant_measurement_reports_lost_repeated_and_damaged_points() {
        let v = 1.5f32.to_le_bytes();
        let mut s = frame(1, &Response::MeasureStarted { lines: 1 });
        s.extend(frame(1, &point(0, &v)));
        // Point 1 lost; point 2 twice; point 3 damaged (one byte changed).
        s.extend(frame(1, &point(2, &v)));
        s.extend(frame(1, &point(2, &v)));
        let mut damaged = frame(1, &point(3, &v));
        damaged[3] ^= 0x40;
        s.extend(damaged);
        s.extend(frame(1, &point(4, &v)));
        s.extend(frame(1, &Response::MeasureDone { lines_done: 1 }));
        let mut c = Client::new(Scripted::new(vec![s])).unwrap();
        c.timeout = Duration::from_millis(50);
        let rep = c.measure_tolerant(1, 6).unwrap();
        assert!(rep.complete);
        assert_eq!(rep.points.iter().map(|p| p.seq).collect::<Vec<_>>(), [0, 2, 4]);
        assert!(rep.points.iter().all(|p| p.values == [1.5]));
        assert_eq!(rep.missing, [1, 3, 5]);
        assert_eq!(rep.duplicates, [2]);
        assert_eq!((c.stats.bad_frames, c.stats.missing_points, c.stats.duplicate_points), (1, 3, 1));
    }

    #[test]
    fn a_retried_request_skips_the_damaged_reply_and_takes_the_next() {
        // The first Info reply arrives damaged; the retry's reply (seq 2) is whole.
        let info = DeviceInfo {
            protocol: protocol::PROTOCOL_VERSION,
            firmware: [0, 1, 0],
            bins: 1,
            leds: 1,
            pixels: 1,
            full_scale: 1,
            max_blob: 1,
            ram_matrix_words: 1,
            simulated: true,
            calibration: None,
        };
        let mut first = frame(1, &Response::Info(info));
        first[2] ^= 0x01;
        let mut c = Client::new(Scripted::new(vec![first, frame(2, &Response::Info(info))])).unwrap();
        c.timeout = Duration::from_millis(50);
        let r = c.request_retrying(&Request::Info, 3).unwrap();
        assert_eq!(r, Response::Info(info));
        assert_eq!((c.stats.bad_frames, c.stats.retries), (1, 1));
    }
}
