//! The client over a faulty link: what it counts ([`LinkStats`]),
//! resynchronisation, requests and provisioning tried again, and a
//! measurement that reports what never arrived intact instead of failing
//! ([`Client::measure_tolerant`]).
use super::Transport;
use super::client::{Client, LinkError, PointRecord, Reply};
use brdf_meter::protocol::{CalInfo, DeviceError, FrameReader, Request, Response};
use std::time::Instant;

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

impl<T: Transport> Client<T> {
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
mod tests {
    use super::*;
    use brdf_meter::protocol::{self, DeviceInfo, LeBytes, MAX_FRAME};
    use brdf_meter::shape::READINGS;
    use std::collections::VecDeque;
    use std::time::Duration;

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

    /// A frame as a device of protocol `version` would send it.
    fn frame_of_version(version: u16, seq: u32, r: &Response<'_>) -> Vec<u8> {
        let mut raw = [0u8; protocol::MAX_PAYLOAD];
        let len = protocol::serialise(seq, r, &mut raw).unwrap();
        raw[0..2].copy_from_slice(&version.to_le_bytes());
        protocol::seal(&mut raw[..len]);
        let mut buf = [0u8; MAX_FRAME];
        let n = protocol::stuff(&raw[..len], &mut buf).unwrap();
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

    fn info() -> DeviceInfo {
        DeviceInfo {
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
        }
    }

    #[test]
    fn a_retried_request_skips_the_damaged_reply_and_takes_the_next() {
        // The first Info reply arrives damaged; the retry's reply (seq 2) is whole.
        let info = info();
        let mut first = frame(1, &Response::Info(info));
        first[2] ^= 0x01;
        let mut c = Client::new(Scripted::new(vec![first, frame(2, &Response::Info(info))])).unwrap();
        c.timeout = Duration::from_millis(50);
        let r = c.request_retrying(&Request::Info, 3).unwrap();
        assert_eq!(r, Response::Info(info));
        assert_eq!((c.stats.bad_frames, c.stats.retries), (1, 1));
    }

    /// A device of another protocol version is named at its first reply,
    /// not retried into a timeout: its frames are whole (their CRC holds),
    /// so asking again gets the same answer.
    #[test]
    fn a_device_of_another_protocol_version_is_named_and_not_retried() {
        for other in [protocol::PROTOCOL_VERSION - 1, protocol::PROTOCOL_VERSION + 1] {
            // What a device answers a request it cannot read: an error of seq 0.
            let refusal = Response::Error(DeviceError::Frame(protocol::FrameError::UnsupportedVersion {
                got: protocol::PROTOCOL_VERSION,
            }));
            let replies = vec![frame_of_version(other, 0, &refusal), frame(2, &Response::Info(info()))];
            let mut c = Client::new(Scripted::new(replies)).unwrap();
            c.timeout = Duration::from_millis(50);
            let e = c.request_retrying(&Request::Info, 3).unwrap_err();
            assert!(matches!(e, LinkError::ProtocolMismatch { device } if device == other), "{e:?}");
            assert_eq!((c.stats.retries, c.stats.bad_frames), (0, 0));
            let says = e.to_string();
            assert!(
                says.contains(&format!("device speaks protocol {other}"))
                    && says.contains(&format!("host tools speak protocol {}", protocol::PROTOCOL_VERSION))
                    && says.contains("dfu-util"),
                "{says}"
            );
        }
    }
}
