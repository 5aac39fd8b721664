//! The protocol client: request/reply with sequence numbers and typed errors,
//! chunked provisioning, measurement streams, simulated scenes. The same
//! client over a faulty link (retries, resynchronisation, a tolerant
//! measurement) is in `retrying`.
use super::Transport;
use super::retrying::LinkStats;
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
    /// The device speaks another protocol version. Its frames passed their
    /// CRC, so this is no damage on the way: nothing it sends can be read,
    /// and asking again cannot help.
    #[error(
        "the device speaks protocol {device} and these host tools speak protocol {host}: they cannot talk to each \
         other. Use the host tools of the device's firmware release, or bring the firmware to this release (on the \
         board with standard `dfu-util -D` and this release's signed image, which does not go through this protocol; \
         a QEMU instrument: start it again with these tools' `qemu`)",
        host = protocol::PROTOCOL_VERSION
    )]
    ProtocolMismatch {
        /// The version in the device's frames.
        device: u16,
    },
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
    pub(super) t: T,
    pub(super) frames: FrameReader,
    pub(super) ready: VecDeque<Result<Frame, LinkError>>,
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
                            Err(FrameError::UnsupportedVersion { got }) => {
                                Err(LinkError::ProtocolMismatch { device: got })
                            }
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
}
