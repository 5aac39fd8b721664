//! The protocol client: request/reply with sequence numbers and typed errors,
//! chunked provisioning, measurement streams, simulated scenes.
use super::Transport;
use brdf_meter::protocol::{
    self, CalInfo, DeviceError, DeviceInfo, DeviceStatus, FrameError, FrameReader, LeBytes, MAX_FRAME, MAX_SIM_BYTES,
    PointFrame, Pushed, Request, Response,
};
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
    /// The n values.
    pub values: Vec<f32>,
}

impl From<PointFrame<'_>> for PointRecord {
    fn from(p: PointFrame<'_>) -> Self {
        Self {
            line: p.line,
            seq: p.seq,
            point: p.point,
            zone: p.zone,
            cluster: p.cluster,
            flags: p.flags,
            sigma_scale: p.sigma_scale,
            values: p.values.f32s().collect(),
        }
    }
}

/// A decoded frame from the device.
#[derive(Clone, Debug, PartialEq)]
pub enum Reply {
    /// Any reply but a point.
    Msg(Response<'static>),
    /// A point.
    Point(PointRecord),
}

/// A frame: its sequence number and content.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Sequence number (the request it answers; 0 for unreadable requests).
    pub seq: u32,
    /// Content.
    pub reply: Reply,
}

/// A device client over any transport.
pub struct Client<T> {
    t: T,
    frames: FrameReader,
    ready: VecDeque<Result<Frame, FrameError>>,
    seq: u32,
    /// How long a request waits for its reply.
    pub timeout: Duration,
}

impl<T: Transport> Client<T> {
    /// A client on `t`. Sends a delimiter first, so a device that saw a partial
    /// frame before starts afresh.
    pub fn new(mut t: T) -> Result<Self, LinkError> {
        t.send(&[0])?;
        Ok(Self { t, frames: FrameReader::new(), ready: VecDeque::new(), seq: 0, timeout: Duration::from_secs(5) })
    }

    /// The transport (tests use it to send raw bytes).
    pub fn transport(&mut self) -> &mut T {
        &mut self.t
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
                return f.map_err(LinkError::Frame);
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
                    Pushed::Oversized => self.ready.push_back(Err(FrameError::Oversized)),
                    Pushed::Frame(f) => {
                        let r = protocol::decode::<Response<'_>>(f).map(|(seq, r)| Frame {
                            seq,
                            reply: match r.detach() {
                                Ok(m) => Reply::Msg(m),
                                Err(p) => Reply::Point(p.into()),
                            },
                        });
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
                Frame { seq: s, reply: Reply::Msg(Response::Error(e)) } if s == seq => return Err(LinkError::Device(e)),
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
    pub fn provision(&mut self, blob: &[u8], mut progress: impl FnMut(usize, usize)) -> Result<CalInfo, LinkError> {
        let crc = brdf_meter::blob::CRC32.checksum(blob);
        let max_chunk = match self.request(&Request::ProvisionBegin { len: blob.len() as u32, crc })? {
            Response::ProvisionReady { max_chunk, .. } => max_chunk as usize,
            r => return Err(LinkError::Unexpected(format!("{r:?} to ProvisionBegin"))),
        };
        let result = (|| {
            let mut offset = 0usize;
            for chunk in blob.chunks(max_chunk.max(1)) {
                match self.request(&Request::ProvisionChunk { offset: offset as u32, data: chunk })? {
                    Response::ChunkAck { next_offset } if next_offset as usize == offset + chunk.len() => {}
                    r => return Err(LinkError::Unexpected(format!("{r:?} to the chunk at {offset}"))),
                }
                offset += chunk.len();
                progress(offset, blob.len());
            }
            match self.request(&Request::ProvisionCommit)? {
                Response::Committed(c) => Ok(c),
                r => Err(LinkError::Unexpected(format!("{r:?} to ProvisionCommit"))),
            }
        })();
        if let Err(LinkError::Device(DeviceError::OutOfOrder { .. } | DeviceError::ChunkTooLarge { .. })) = &result {
            let _ = self.request(&Request::ProvisionAbort);
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
        assert!(lines >= 1, "use start/stop for continuous measurement");
        let seq = self.send(&Request::Measure { lines })?;
        let mut points = Vec::new();
        let mut started = false;
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
                Reply::Msg(Response::MeasureStarted { .. }) => started = true,
                Reply::Point(p) => {
                    if p.seq as usize != points.len() {
                        return Err(LinkError::Unexpected(format!(
                            "point frame {} lost (got stream sequence {})",
                            points.len(),
                            p.seq
                        )));
                    }
                    points.push(p);
                }
                Reply::Msg(Response::Error(e)) if !started => return Err(LinkError::Device(e)),
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
}
