//! A faulty link between host-tools' client and the simulated device, and the
//! soak that drives provisioning and measurements through it.
//!
//! [`FaultyLink`] wraps a [`SimDevice`] as a `Transport` and, from a seeded
//! ChaCha stream, damages the device's frames on their way to the host
//! (drops, duplicates or corrupts a byte; drops, duplicates or delays a whole
//! frame), damages the host's requests, and goes down for a while (both
//! directions) when a disconnect is scheduled, cutting the frame in flight.
//! It records the fate of every point frame the device sent: which fault hit
//! it and whether a copy reached the host intact, which is the ground truth
//! the soak holds the client's own accounting against.
//!
//! [`soak`] runs the client's tolerant calls over it and checks: every point
//! the host accepts is bit-identical to the host's reference computation and
//! in sequence, every point it did not get intact it reports missing, none is
//! accepted twice; provisioning under faults either completes (the device's
//! active calibration is the new blob) or leaves the previous one active and
//! measuring; and the client carries on after every fault without a restart
//! of either side.
use crate::sim::{FULL_SCALE, M, N, P, SLOT_LEN, SimDevice};
use brdf_meter::blob::BlobView;
use brdf_meter::estimate::Calibration;
use brdf_meter::platform::host_sim::SimFlash;
use brdf_meter::protocol::{self, DeviceError, Response};
use brdf_meter::store::Store;
use host_tools::device::link::{Client, LinkError, LinkStats, ProvisionOutcome, Transport};
use host_tools::device::reference::expected_line;
use host_tools::forward::scene::frames::{SceneFrames, analytic_scene};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::{BTreeSet, VecDeque};
use std::time::{Duration, Instant};

/// Per-frame fault probabilities.
#[derive(Clone, Copy, Debug)]
pub struct FaultRates {
    /// A device frame loses one byte.
    pub drop_byte: f64,
    /// A device frame gets one byte twice.
    pub dup_byte: f64,
    /// A device frame gets one byte changed.
    pub corrupt_byte: f64,
    /// A device frame is lost whole.
    pub drop_frame: f64,
    /// A device frame arrives twice.
    pub dup_frame: f64,
    /// The link stalls (delivers nothing) for a few reads before a frame.
    pub delay: f64,
    /// A host request loses, repeats or changes a byte, or is lost whole.
    pub request: f64,
}

impl FaultRates {
    /// About one device frame in twelve and one request in twenty damaged.
    pub const SOAK: Self = Self {
        drop_byte: 0.015,
        dup_byte: 0.015,
        corrupt_byte: 0.02,
        drop_frame: 0.01,
        dup_frame: 0.01,
        delay: 0.01,
        request: 0.05,
    };
}

/// What can happen to a device frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Fault {
    /// One byte lost.
    DropByte,
    /// One byte twice.
    DupByte,
    /// One byte changed.
    CorruptByte,
    /// The frame lost.
    DropFrame,
    /// The frame twice.
    DupFrame,
    /// The frame late (the link stalled).
    Delay,
    /// Lost to a disconnect (the first such frame is cut partway).
    Disconnect,
}

/// Every kind, for reports.
pub const FAULTS: [Fault; 7] = [
    Fault::DropByte,
    Fault::DupByte,
    Fault::CorruptByte,
    Fault::DropFrame,
    Fault::DupFrame,
    Fault::Delay,
    Fault::Disconnect,
];

/// A point frame the device sent, and what became of it.
#[derive(Clone, Copy, Debug)]
pub struct PointFate {
    /// The `Measure` request it answers.
    pub request: u32,
    /// Its stream sequence number.
    pub seq: u32,
    /// The fault that hit it.
    pub fault: Option<Fault>,
    /// Copies that reached the host intact (at a frame boundary, unaltered).
    pub intact: u32,
}

/// Counters of what the link did.
#[derive(Clone, Copy, Debug, Default)]
pub struct LinkCounts {
    /// Frames the device sent.
    pub device_frames: u64,
    /// Of them, point frames.
    pub point_frames: u64,
    /// Faults on device frames, by [`FAULTS`] index.
    pub injected: [u64; 7],
    /// Disconnects.
    pub disconnects: u64,
    /// Host requests damaged or lost (disconnects included).
    pub request_faults: u64,
}

/// The faulty link (see the module docs).
pub struct FaultyLink {
    /// The simulated device.
    pub dev: SimDevice,
    rng: ChaCha8Rng,
    /// Fault probabilities; [`None`] passes everything unharmed.
    pub rates: Option<FaultRates>,
    partial: Vec<u8>,
    out: VecDeque<u8>,
    stall: u32,
    disconnect_in: Option<(u32, u32, u32)>,
    down: u32,
    down_requests: u32,
    at_boundary: bool,
    /// What the link did.
    pub counts: LinkCounts,
    /// Point frames since the last [`FaultyLink::take_fates`].
    pub fates: Vec<PointFate>,
}

impl FaultyLink {
    /// A link to `dev` drawing its faults from `seed`; faults off until
    /// [`Self::rates`] is set.
    pub fn new(mut dev: SimDevice, seed: u64) -> Self {
        // A read with nothing to deliver waits 100 ms of simulated time, not 20 s.
        dev.recv_steps = 1000;
        Self {
            dev,
            rng: ChaCha8Rng::seed_from_u64(seed),
            rates: None,
            partial: Vec::new(),
            out: VecDeque::new(),
            stall: 0,
            disconnect_in: None,
            down: 0,
            down_requests: 0,
            at_boundary: true,
            counts: LinkCounts::default(),
            fates: Vec::new(),
        }
    }

    /// Schedules a disconnect: after `after` more device frames, the link
    /// goes down (cutting that frame partway) for `reads` host reads and
    /// until `requests` host requests have been lost.
    pub fn disconnect_after(&mut self, after: u32, reads: u32, requests: u32) {
        self.disconnect_in = Some((after, reads.max(1), requests));
    }

    fn is_down(&self) -> bool {
        self.down > 0 || self.down_requests > 0
    }

    /// The point-frame fates recorded since the last call.
    pub fn take_fates(&mut self) -> Vec<PointFate> {
        std::mem::take(&mut self.fates)
    }

    /// Random draw in `0..n`.
    fn below(&mut self, n: usize) -> usize {
        self.rng.random_range(0..n.max(1))
    }

    /// One complete device frame (delimiter included) on its way to the host.
    fn pass(&mut self, frame: Vec<u8>) {
        self.counts.device_frames += 1;
        let mut copy = frame[..frame.len() - 1].to_vec();
        // A line frame carries several points: each shares the frame's fate.
        let point = match protocol::decode::<Response<'_>>(&mut copy) {
            Ok((request, Response::Point(p))) => Some((request, p.seq, 1)),
            Ok((request, Response::Points(p))) => Some((request, p.seq, p.count() as u32)),
            _ => None,
        };
        if point.is_some() {
            self.counts.point_frames += 1;
        }
        let mut fault = None;
        let mut bytes = frame.clone();
        let mut copies = 1;
        if let Some((after, reads, requests)) = self.disconnect_in {
            if after == 0 {
                self.disconnect_in = None;
                self.down = reads;
                self.down_requests = requests;
                self.counts.disconnects += 1;
                // The frame in flight is cut partway.
                let keep = self.below(frame.len() - 1);
                bytes.truncate(keep);
                fault = Some(Fault::Disconnect);
            } else {
                self.disconnect_in = Some((after - 1, reads, requests));
            }
        }
        if fault.is_none() && self.is_down() {
            bytes.clear();
            fault = Some(Fault::Disconnect);
        }
        if let (None, Some(r)) = (fault, self.rates) {
            let x: f64 = self.rng.random();
            let mut edge = 0.0;
            let mut pick = |p: f64| {
                edge += p;
                x < edge
            };
            let i = self.below(frame.len());
            if pick(r.drop_byte) {
                bytes.remove(i);
                fault = Some(Fault::DropByte);
            } else if pick(r.dup_byte) {
                bytes.insert(i, bytes[i]);
                fault = Some(Fault::DupByte);
            } else if pick(r.corrupt_byte) {
                bytes[i] ^= 1 + self.below(255) as u8;
                fault = Some(Fault::CorruptByte);
            } else if pick(r.drop_frame) {
                bytes.clear();
                fault = Some(Fault::DropFrame);
            } else if pick(r.dup_frame) {
                copies = 2;
                fault = Some(Fault::DupFrame);
            } else if pick(r.delay) {
                self.stall = 1 + self.below(3) as u32;
                fault = Some(Fault::Delay);
            }
        }
        if let Some(f) = fault {
            let k = FAULTS.iter().position(|x| *x == f).unwrap();
            self.counts.injected[k] += 1;
        }
        let mut intact = 0;
        // A repeated delimiter is an empty frame, which readers skip.
        let same = bytes == frame
            || (bytes.len() == frame.len() + 1 && bytes.ends_with(&[0, 0]) && bytes[..frame.len()] == frame[..]);
        for _ in 0..copies {
            if self.at_boundary && same {
                intact += 1;
            }
            if let Some(&last) = bytes.last() {
                self.at_boundary = last == 0;
            }
            self.out.extend(bytes.iter().copied());
        }
        if let Some((request, seq, count)) = point {
            for k in 0..count {
                self.fates.push(PointFate { request, seq: seq + k, fault, intact });
            }
        }
    }
}

impl Transport for FaultyLink {
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        if self.is_down() {
            if bytes.len() > 1 {
                self.counts.request_faults += 1;
                self.down_requests = self.down_requests.saturating_sub(1);
            }
            return Ok(());
        }
        let mut b = bytes.to_vec();
        // A lone delimiter (a resync) passes: damaging it only delays the
        // damage to the next request.
        if let Some(r) = self.rates
            && b.len() > 1
            && self.rng.random::<f64>() < r.request
        {
            self.counts.request_faults += 1;
            let i = self.below(b.len());
            match self.below(4) {
                0 => drop(b.remove(i)),
                1 => b.insert(i, b[i]),
                2 => b[i] ^= 1 + self.below(255) as u8,
                _ => b.clear(),
            }
        }
        self.dev.send(&b)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        if self.out.is_empty() || self.stall > 0 {
            let mut tmp = [0u8; 4096];
            let n = self.dev.recv(&mut tmp, timeout)?;
            for &b in &tmp[..n] {
                self.partial.push(b);
                if b == 0 {
                    let frame = std::mem::take(&mut self.partial);
                    self.pass(frame);
                }
            }
            self.down = self.down.saturating_sub(1);
            if self.stall > 0 {
                self.stall -= 1;
                return Ok(0);
            }
        }
        let n = buf.len().min(self.out.len());
        for (d, s) in buf.iter_mut().zip(self.out.drain(..n)) {
            *d = s;
        }
        Ok(n)
    }
}

/// What a soak asks for.
#[derive(Clone, Copy, Debug)]
pub struct SoakConfig {
    /// Device frames to send at least.
    pub frames: u64,
    /// Seed of the fault stream.
    pub seed: u64,
    /// Fault probabilities.
    pub rates: FaultRates,
}

/// What a soak saw. `undetected` must be 0.
#[derive(Clone, Debug, Default)]
pub struct SoakReport {
    /// What the link did.
    pub link: LinkCounts,
    /// Points the measurements asked for (lines x pixels).
    pub points_expected: u64,
    /// Point frames the host accepted.
    pub points_accepted: u64,
    /// Points the host reported missing.
    pub points_missing: u64,
    /// Point copies the host dropped as repeats.
    pub points_duplicate: u64,
    /// Faults on point frames the host's accounting caught, by [`FAULTS`]
    /// index (a delay is caught when the late point is still accepted whole).
    pub detected: [u64; 7],
    /// Faults on point frames, by [`FAULTS`] index.
    pub on_points: [u64; 7],
    /// Points lost, repeated or altered without the host knowing, plus
    /// accepted points that differ from the reference computation.
    pub undetected: u64,
    /// Points that reached the host intact but were drained after a cut
    /// stream (reported missing, so not silent).
    pub intact_discarded: u64,
    /// Measurements run.
    pub measurements: u64,
    /// Of them, cut short (no `MeasureDone` received).
    pub cut_streams: u64,
    /// Provisioning calls.
    pub provisionings: u64,
    /// Attempts over all provisioning calls.
    pub provision_attempts: u64,
    /// Calls that ended with the new blob active.
    pub provision_completed: u64,
    /// Calls that ended with the previous calibration still active.
    pub provision_rolled_back: u64,
    /// Calls that returned an error (the link stayed down past every retry).
    pub provision_gave_up: u64,
    /// Measurements or provisionings that met a fault and still succeeded.
    pub recoveries: u64,
    /// The client's own counters.
    pub client: LinkStats,
    /// Wall time.
    pub wall: Duration,
}

impl std::fmt::Display for SoakReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let l = &self.link;
        writeln!(f, "device frames sent      {}", l.device_frames)?;
        writeln!(f, "  point frames          {}", l.point_frames)?;
        writeln!(f, "points asked for        {}", self.points_expected)?;
        writeln!(f, "points accepted         {}", self.points_accepted)?;
        writeln!(f, "points reported missing {}", self.points_missing)?;
        writeln!(f, "repeats dropped         {}", self.points_duplicate)?;
        writeln!(f, "intact but drained      {}", self.intact_discarded)?;
        writeln!(f, "fault kind        injected  on points  detected")?;
        for (k, fault) in FAULTS.iter().enumerate() {
            writeln!(
                f,
                "  {:<14} {:>9} {:>10} {:>9}",
                format!("{fault:?}"),
                l.injected[k],
                self.on_points[k],
                self.detected[k]
            )?;
        }
        writeln!(f, "request faults          {}", l.request_faults)?;
        writeln!(f, "disconnects             {}", l.disconnects)?;
        writeln!(f, "UNDETECTED              {}", self.undetected)?;
        writeln!(f, "measurements            {} ({} cut short)", self.measurements, self.cut_streams)?;
        writeln!(
            f,
            "provisioning            {} calls, {} attempts, {} completed, {} rolled back, {} failed with the link down",
            self.provisionings,
            self.provision_attempts,
            self.provision_completed,
            self.provision_rolled_back,
            self.provision_gave_up
        )?;
        writeln!(f, "recoveries              {}", self.recoveries)?;
        let c = &self.client;
        writeln!(
            f,
            "client: bad frames {}, timeouts {}, retries {}, resyncs {}",
            c.bad_frames, c.timeouts, c.retries, c.resyncs
        )?;
        write!(f, "wall time               {:.1} s", self.wall.as_secs_f64())
    }
}

/// Zones of the soak's blobs.
const ZONES: usize = 4;

/// The calibration the device would boot with now (read from its flash, not
/// over the link).
fn device_active(flash: &SimFlash) -> Option<Vec<u8>> {
    let st = Store::open(flash.reboot(), SLOT_LEN, brdf_meter::test_blobs::dev_trusted(), |v| {
        Calibration::<N, M, P>::check(v).is_ok()
    });
    st.active_blob().map(|(_, v)| v.as_bytes().to_vec())
}

/// Runs the soak (see the module docs); panics on a broken property, with
/// the seed in the message so the run can be repeated.
pub fn soak(cfg: SoakConfig) -> SoakReport {
    let start = Instant::now();
    let seed = cfg.seed;
    // The blobs (what the device's store reports active) and the signed
    // calibrations that carry them over the link.
    let blobs = [1.0, 2.0, 3.0].map(|seed| brdf_meter::test_blobs::test_blob(N, M, ZONES, P, seed));
    let signed = blobs.clone().map(|b| brdf_meter::test_blobs::sign_for_tests(&b));
    let link = FaultyLink::new(SimDevice::boot(SimFlash::new(2 * SLOT_LEN as usize), ZONES), seed);
    let mut c = Client::new(link).expect("in-memory link");
    c.timeout = Duration::from_millis(40);
    // f32 values, so every accepted point is checked bit for bit.
    c.format = brdf_meter::protocol::StreamFormat::LOSSLESS;
    // Set-up without faults: the first calibration and the scene.
    c.provision(&signed[0], |_, _| {}).expect("first provisioning");
    // One scene line: the sensor cycles through the loaded lines across
    // measurements, and cut streams make that count unknowable here.
    let scene: SceneFrames = analytic_scene(&BlobView::parse(&blobs[0]).unwrap(), 1, FULL_SCALE);
    c.load_scene(&scene).expect("scene");
    let mut active = 0usize;
    let mut expected: Vec<Vec<host_tools::device::reference::ExpectedPoint>> = Vec::new();
    let mut expected_for = usize::MAX;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_50a4);
    c.transport().rates = Some(cfg.rates);
    let mut r = SoakReport::default();
    let mut round = 0u64;
    while c.transport().counts.device_frames < cfg.frames {
        round += 1;
        let faults_before = c.stats;
        if round.is_multiple_of(8) {
            // Provision the next blob, now and then with a disconnect partway.
            let next = (active + 1) % blobs.len();
            let chunks = signed[next].len().div_ceil(protocol::MAX_CHUNK) as u32;
            // Mostly short outages the retries ride out; one provisioning in
            // four meets one that loses 6 to 16 requests: more than a single
            // attempt's retries of one request (6), and from 14 on more than
            // the client's questions afterwards (8) too.
            let long = rng.random_bool(0.25);
            if long || rng.random_bool(0.5) {
                let after = rng.random_range(0..chunks + 2);
                if long {
                    c.transport().disconnect_after(after, 1, rng.random_range(6..=16));
                } else {
                    c.transport().disconnect_after(after, rng.random_range(1..40), 0);
                }
            }
            r.provisionings += 1;
            let out = c.provision_retrying(&signed[next], if long { 1 } else { 3 });
            let truth = device_active(&c.transport().dev.flash);
            match out {
                Ok(ProvisionOutcome::Committed { cal, attempts }) => {
                    assert_eq!(
                        truth.as_deref(),
                        Some(blobs[next].as_slice()),
                        "seed {seed}: committed, but not active"
                    );
                    assert_eq!(cal.blob_crc, BlobView::parse(&blobs[next]).unwrap().crc());
                    r.provision_attempts += attempts as u64;
                    r.provision_completed += 1;
                    active = next;
                }
                Ok(ProvisionOutcome::RolledBack { active: cal, attempts, .. }) => {
                    assert_eq!(
                        truth.as_deref(),
                        Some(blobs[active].as_slice()),
                        "seed {seed}: rolled back, but the old blob is not active"
                    );
                    assert_eq!(cal.map(|c| c.blob_crc), Some(BlobView::parse(&blobs[active]).unwrap().crc()));
                    r.provision_attempts += attempts as u64;
                    r.provision_rolled_back += 1;
                }
                Err(e) => {
                    // The link stayed down past every retry: the host knows
                    // it failed; the device holds the old blob or the new,
                    // whole; the host ends the session once the link is back.
                    r.provision_attempts += 1;
                    r.provision_gave_up += 1;
                    let old = truth.as_deref() == Some(blobs[active].as_slice());
                    let new = truth.as_deref() == Some(blobs[next].as_slice());
                    assert!(old || new, "seed {seed}: after a failed provisioning ({e}), neither blob is active");
                    c.transport().disconnect_in = None;
                    match c.request_retrying(&protocol::Request::ProvisionAbort, 50) {
                        Ok(_) | Err(LinkError::Device(DeviceError::NotProvisioning)) => {}
                        Err(e) => panic!("seed {seed}: the client did not recover after a failed provisioning: {e}"),
                    }
                    if new {
                        active = next;
                    }
                }
            }
            c.transport().disconnect_in = None;
            if c.stats != faults_before {
                r.recoveries += 1;
            }
            continue;
        }
        // A measurement, now and then with a disconnect partway.
        let lines = rng.random_range(1..=4u32);
        if rng.random_bool(0.1) {
            let after = rng.random_range(0..lines * P as u32 + 2);
            let reads = rng.random_range(1..6);
            c.transport().disconnect_after(after, reads, 0);
        }
        c.transport().take_fates();
        let rep =
            c.measure_tolerant(lines, P as u32).unwrap_or_else(|e| panic!("seed {seed}: measurement failed: {e}"));
        c.transport().disconnect_in = None;
        let fates = c.transport().take_fates();
        r.measurements += 1;
        r.cut_streams += u64::from(!rep.complete);
        assert_eq!(rep.device_error, None, "seed {seed}");
        if expected_for != active {
            let view = BlobView::parse(&blobs[active]).unwrap();
            expected = scene.iter().map(|frames| expected_line(&view, frames, FULL_SCALE, &crate::sim::ACQ)).collect();
            expected_for = active;
        }
        // Accepted points: bit-identical to the reference, in sequence, once.
        let total = lines * P as u32;
        let mut accepted = BTreeSet::new();
        let mut prev = None;
        for p in &rep.points {
            let want = &expected[p.line as usize % expected.len()][p.point as usize];
            let same = p.seq == p.line * P as u32 + p.point as u32
                && crate::meta_bits(p) == crate::expected_meta_bits(want)
                && p.values.len() == want.values.len()
                && p.values.iter().zip(&want.values).all(|(a, b)| a.to_bits() == b.to_bits());
            let in_order = prev.is_none_or(|q| p.seq > q);
            prev = Some(p.seq);
            if !same || !in_order || !accepted.insert(p.seq) {
                r.undetected += 1;
            }
        }
        // Every other point is reported missing, and no point is both.
        let missing: BTreeSet<u32> = rep.missing.iter().copied().collect();
        for s in 0..total {
            if accepted.contains(&s) == missing.contains(&s) {
                r.undetected += 1;
            }
        }
        // The link's ground truth: a point the host accepted reached it
        // intact; each fault on a point shows in the host's accounting: lost
        // copies as missing, a second intact copy as a repeat.
        let dups: BTreeSet<u32> = rep.duplicates.iter().copied().collect();
        // Points of an earlier Measure (sent again when its replies were
        // lost) are not this stream's; the client drops them by sequence.
        for f in fates.iter().filter(|f| f.request == rep.request_seq) {
            if f.intact == 0 && accepted.contains(&f.seq) {
                r.undetected += 1;
            }
            if f.intact > 0 && !accepted.contains(&f.seq) {
                // Drained after a cut stream: reported missing, so known.
                r.intact_discarded += 1;
            }
            if let Some(kind) = f.fault {
                let k = FAULTS.iter().position(|x| *x == kind).unwrap();
                r.on_points[k] += 1;
                let caught = match f.intact {
                    0 => missing.contains(&f.seq),
                    1 => accepted.contains(&f.seq) || missing.contains(&f.seq),
                    _ => dups.contains(&f.seq) || missing.contains(&f.seq),
                };
                if caught {
                    r.detected[k] += 1;
                } else {
                    r.undetected += 1;
                    eprintln!(
                        "seed {seed}: undetected {f:?} (stream of {total} points, complete {}, accepted {}, missing {:?}, repeats {:?})",
                        rep.complete,
                        accepted.contains(&f.seq),
                        rep.missing,
                        rep.duplicates
                    );
                }
            }
        }
        r.points_expected += total as u64;
        r.points_accepted += rep.points.len() as u64;
        r.points_missing += rep.missing.len() as u64;
        r.points_duplicate += rep.duplicates.len() as u64;
        if c.stats != faults_before && rep.complete {
            r.recoveries += 1;
        }
    }
    // Still answering, without a restart of either side.
    c.transport().rates = None;
    let info = c.request_retrying(&protocol::Request::Info, 8).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
    match info {
        Response::Info(i) => {
            assert_eq!(i.calibration.map(|c| c.blob_crc), Some(BlobView::parse(&blobs[active]).unwrap().crc()))
        }
        other => panic!("seed {seed}: {other:?} to Info"),
    }
    r.link = c.transport().counts;
    r.client = c.stats;
    r.wall = start.elapsed();
    r
}
