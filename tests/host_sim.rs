//! Host simulation of the instrument's application: the same tasks the
//! firmware runs, on an embassy executor with mock time, an in-memory NOR
//! flash and an in-memory link, driven by host-tools' own client.
use brdf_meter::blob::{BlobView, CRC32};
use brdf_meter::hw::SensorError;
use brdf_meter::platform::host_sim::SimFlash;
use brdf_meter::protocol::{
    BinRange, DeviceError, Encoding, FrameError, LeBytes, MAX_CHUNK, MAX_FRAME, MAX_PAYLOAD, PROTOCOL_VERSION, Request,
    Response, SizeField, StreamFormat, encode, flags, point_uncertainty, seal, serialise, stuff,
};
use brdf_meter::signed::SignatureFault;
use brdf_meter::test_blobs::{sign_for_tests, signed_test_blob, test_blob};
use host_tools::device::link::{Client, DecodeError, LinkError, PointRecord, Reply};
use host_tools::device::reference::expected_line;
use host_tools::forward::scene::frames::{SceneFrames, analytic_scene};
use system_tests::sim::{ACQ, FULL_SCALE, M, N, P, SLOT_LEN, SimDevice};

const ZONES: usize = 4;

fn flash() -> SimFlash {
    SimFlash::new(2 * SLOT_LEN as usize)
}

/// A client asking for f32 values (bit for bit); the other encodings have
/// tests of their own.
fn client(flash: SimFlash, ram_zones: usize) -> Client<SimDevice> {
    let mut c = Client::new(SimDevice::boot(flash, ram_zones)).unwrap();
    c.format = StreamFormat::LOSSLESS;
    c
}

/// A client on a fresh device running the test calibration of `seed`
/// ([`blob`]), with an analytic scene of `lines` lines loaded.
fn provisioned_with_scene(seed: f32, lines: usize) -> (Client<SimDevice>, Vec<u8>, SceneFrames) {
    let mut c = client(flash(), ZONES);
    let b = blob(seed);
    c.provision(&b, |_, _| {}).unwrap();
    let scene = analytic_scene(&BlobView::parse(&b).unwrap(), lines, FULL_SCALE);
    c.load_scene(&scene).unwrap();
    (c, b, scene)
}

/// A signed test calibration (development key).
fn blob(seed: f32) -> Vec<u8> {
    signed_test_blob(N, M, ZONES, P, seed)
}

/// Checks that `points` (of `lines` lines) are bit-identical to the host's
/// computation on the scene line each device line saw.
fn check_points(blob: &[u8], scene: &SceneFrames, points: &[PointRecord], lines: usize) {
    let view = BlobView::parse(blob).unwrap();
    // Readings computed on the device where the zone has them, NaN where
    // the calibration has none.
    for p in points {
        if system_tests::zone_has_gloss_reading(&view, p.zone as usize) {
            assert!(
                p.flags & brdf_meter::protocol::flags::NON_FINITE != 0 || p.readings[0].is_finite(),
                "gloss readings computed on the device"
            );
        } else {
            assert!(p.readings.iter().chain(&p.reading_sigma).all(|x| x.is_nan()), "no reading: NaN");
        }
    }
    assert_eq!(points.len(), lines * P);
    for (k, p) in points.iter().enumerate() {
        let line = k / P;
        let want = &expected_line(&view, &scene[line % scene.len()], FULL_SCALE, &ACQ)[k % P];
        assert_eq!((p.line as usize, p.seq as usize, p.point as usize), (line, k, k % P));
        assert_eq!(system_tests::meta_bits(p), system_tests::expected_meta_bits(want), "point {k}");
        let got: Vec<u32> = p.values.iter().map(|x| x.to_bits()).collect();
        let exp: Vec<u32> = want.values.iter().map(|x| x.to_bits()).collect();
        assert_eq!(got, exp, "values of point {k} differ");
    }
}

fn device_error<T: std::fmt::Debug>(r: Result<T, LinkError>) -> DeviceError {
    match r {
        Err(LinkError::Device(e)) => e,
        other => panic!("expected a device error, got {other:?}"),
    }
}

#[test]
fn provisions_then_measures_bit_identically_and_survives_reboot() {
    let fl = flash();
    let mut c = client(fl.clone(), ZONES);
    let info = c.info().unwrap();
    assert_eq!((info.bins, info.leds, info.pixels, info.full_scale), (N as u16, M as u16, P as u16, FULL_SCALE));
    assert_eq!(info.calibration, None);
    assert!(info.simulated);
    assert_eq!(device_error(c.measure(1)), DeviceError::NoCalibration);

    let b = blob(1.0);
    let mut acks = 0;
    let cal = c.provision(&b, |_, _| acks += 1).unwrap();
    assert_eq!(acks, b.len().div_ceil(MAX_CHUNK), "every chunk acknowledged");
    assert_eq!((cal.slot, cal.sequence, cal.zones, cal.in_ram), (0, 1, ZONES as u16, true));
    assert_eq!(cal.blob_crc, BlobView::parse(&b).unwrap().crc());

    let view = BlobView::parse(&b).unwrap();
    let scene = analytic_scene(&view, 2, FULL_SCALE);
    c.load_scene(&scene).unwrap();
    let pts = c.measure(3).unwrap();
    check_points(&b, &scene, &pts, 3);
    // The scene exercises several zones and non-trivial values.
    assert!(pts.iter().map(|p| p.zone).max() == Some(ZONES as u16 - 1));
    assert!(pts.iter().all(|p| p.flags == 0));
    let st = c.status().unwrap();
    assert_eq!((st.lines_total, st.measuring), (3, false));

    // LEDs: per line, all off (dark), then the calibrated order, then off.
    let sw = c.transport().scene.switches();
    let order: Vec<Option<u8>> = view.led_order().iter().map(|&l| Some(l)).collect();
    let mut one_line = vec![None];
    one_line.extend(order);
    one_line.push(None);
    assert_eq!(sw, one_line.repeat(3));

    // Power off and on: the calibration is found again.
    drop(c);
    let mut c = client(fl.reboot(), ZONES);
    assert_eq!(c.info().unwrap().calibration, Some(cal));
}

#[test]
fn matrices_larger_than_the_ram_budget_are_read_in_place() {
    let mut c = client(flash(), 1);
    let b = blob(2.0);
    let cal = c.provision(&b, |_, _| {}).unwrap();
    assert!(!cal.in_ram);
    let scene = analytic_scene(&BlobView::parse(&b).unwrap(), 1, FULL_SCALE);
    c.load_scene(&scene).unwrap();
    let pts = c.measure(2).unwrap();
    check_points(&b, &scene, &pts, 2);
}

#[test]
fn bad_blobs_are_refused_and_the_previous_calibration_keeps_measuring() {
    let mut c = client(flash(), ZONES);
    let good = blob(3.0);
    let cal = c.provision(&good, |_, _| {}).unwrap();
    let scene = analytic_scene(&BlobView::parse(&good).unwrap(), 1, FULL_SCALE);
    c.load_scene(&scene).unwrap();

    // 1. Corrupted in transit: the declared CRC is the original's.
    let newer = blob(4.0);
    let crc = CRC32.checksum(&newer);
    let mut bad = newer.clone();
    bad[1000] ^= 0x40;
    let Response::ProvisionReady { .. } = c.request(&Request::ProvisionBegin { len: bad.len() as u32, crc }).unwrap()
    else {
        panic!()
    };
    for (k, ch) in bad.chunks(MAX_CHUNK).enumerate() {
        c.request(&Request::ProvisionChunk { offset: (k * MAX_CHUNK) as u32, data: ch }).unwrap();
    }
    let e = device_error(c.request(&Request::ProvisionCommit));
    assert_eq!(e, DeviceError::CrcMismatch { declared: crc, computed: CRC32.checksum(&bad) });

    // 2. Corrupted before sending (CRC consistent with the bytes): the
    //    signature catches it; signed after the corruption, the blob's own
    //    CRC does.
    let e = device_error(c.provision(&bad, |_, _| {}));
    assert_eq!(e, DeviceError::SignatureRejected(SignatureFault::BadSignature));
    let mut corrupt = test_blob(N, M, ZONES, P, 4.0);
    corrupt[1000] ^= 0x40;
    let e = device_error(c.provision(&sign_for_tests(&corrupt), |_, _| {}));
    assert!(matches!(e, DeviceError::BlobRejected { .. }), "{e:?}");

    // 3. A valid blob for another instrument (16 pixels).
    let other = signed_test_blob(N, M, 2, 16, 5.0);
    let e = device_error(c.provision(&other, |_, _| {}));
    assert_eq!(e, DeviceError::Mismatch { field: SizeField::Pixels, device: P as u16, blob: 16 });

    // 4. Not a blob at all (nor signed), and too large.
    let e = device_error(c.provision(&[0x42; 300], |_, _| {}));
    assert_eq!(e, DeviceError::SignatureRejected(SignatureFault::Unsigned));
    let e = device_error(c.request(&Request::ProvisionBegin { len: SLOT_LEN, crc: 0 }));
    assert_eq!(e, DeviceError::BlobTooLarge { len: SLOT_LEN, max: SLOT_LEN - 32 });

    // Still the old calibration, still measuring with it, bit for bit.
    assert_eq!(c.info().unwrap().calibration, Some(cal));
    let pts = c.measure(1).unwrap();
    check_points(&good, &scene, &pts, 1);
    assert!(c.status().unwrap().refused >= 5);
}

#[test]
fn malformed_frames_get_typed_errors_and_the_device_keeps_serving() {
    let mut c = client(flash(), ZONES);
    let mut frame = [0u8; MAX_FRAME];

    // Corrupted: a byte flipped inside an Info frame.
    let n = encode(77, &Request::Info, &mut frame).unwrap();
    let mut f = frame[..n].to_vec();
    f[3] ^= 0x10;
    if f[3] == 0 {
        f[3] = 0x33;
    }
    c.send_raw(&f).unwrap();
    let r = c.next_frame(std::time::Duration::from_secs(1)).unwrap();
    assert!(
        matches!(
            r.reply,
            Reply::Msg(Response::Error(DeviceError::Frame(
                FrameError::BadCrc | FrameError::Cobs | FrameError::Truncated { .. }
            )))
        ),
        "{r:?}"
    );
    // Corrupted in the CRC itself (last payload byte).
    let n = encode(79, &Request::Info, &mut frame).unwrap();
    let mut f = frame[..n].to_vec();
    f[n - 2] = if f[n - 2] == 0x01 { 0x02 } else { 0x01 };
    c.send_raw(&f).unwrap();
    let r = c.next_frame(std::time::Duration::from_secs(1)).unwrap();
    assert!(
        matches!(r.reply, Reply::Msg(Response::Error(DeviceError::Frame(FrameError::BadCrc | FrameError::Cobs)))),
        "{r:?}"
    );

    // Truncated: the last payload bytes lost (COBS still valid).
    let n = encode(78, &Request::Measure { lines: 5, format: StreamFormat::LOSSLESS }, &mut frame).unwrap();
    let mut raw = [0u8; MAX_FRAME];
    let m = cobs::decode(&frame[..n - 1], &mut raw).unwrap();
    let mut t = vec![0u8; MAX_FRAME];
    let k = cobs::encode(&raw[..m - 3], &mut t);
    t.truncate(k);
    t.push(0);
    c.send_raw(&t).unwrap();
    let r = c.next_frame(std::time::Duration::from_secs(1)).unwrap();
    assert_eq!(
        r.reply,
        Reply::Msg(Response::Error(DeviceError::Frame(FrameError::Truncated {
            declared: m as u16,
            got: m as u16 - 3
        })))
    );

    // Oversized: a flood of non-zero bytes.
    c.send_raw(&vec![0x55u8; 3 * MAX_FRAME]).unwrap();
    c.send_raw(&[0]).unwrap();
    let r = c.next_frame(std::time::Duration::from_secs(1)).unwrap();
    assert_eq!(r.reply, Reply::Msg(Response::Error(DeviceError::Frame(FrameError::Oversized))));

    // Another protocol version (a whole frame, its CRC right): the reply
    // names the version the device got, in the device's own version, so
    // the host can say which two disagree.
    let other = PROTOCOL_VERSION + 1;
    let mut raw = [0u8; MAX_PAYLOAD];
    let len = serialise(80, &Request::Info, &mut raw).unwrap();
    raw[0..2].copy_from_slice(&other.to_le_bytes());
    seal(&mut raw[..len]);
    let n = stuff(&raw[..len], &mut frame).unwrap();
    c.send_raw(&frame[..n]).unwrap();
    let r = c.next_frame(std::time::Duration::from_secs(1)).unwrap();
    assert_eq!(r.reply, Reply::Msg(Response::Error(DeviceError::Frame(FrameError::UnsupportedVersion { got: other }))));

    // Out of order: chunks, commit and chunk without begin.
    let b = blob(6.0);
    assert_eq!(
        device_error(c.request(&Request::ProvisionChunk { offset: 0, data: &b[..64] })),
        DeviceError::NotProvisioning
    );
    assert_eq!(device_error(c.request(&Request::ProvisionCommit)), DeviceError::NotProvisioning);
    c.request(&Request::ProvisionBegin { len: b.len() as u32, crc: CRC32.checksum(&b) }).unwrap();
    c.request(&Request::ProvisionChunk { offset: 0, data: &b[..100] }).unwrap();
    assert_eq!(
        device_error(c.request(&Request::ProvisionChunk { offset: 200, data: &b[200..300] })),
        DeviceError::OutOfOrder { expected: 100, got: 200 }
    );
    assert_eq!(
        device_error(c.request(&Request::ProvisionCommit)),
        DeviceError::Incomplete { received: 100, len: b.len() as u32 }
    );
    // Simulation requests out of range.
    let px = [1u16; 4];
    assert_eq!(
        device_error(c.request(&Request::SimFrame {
            line: 99,
            frame: 0,
            first_pixel: 0,
            pixels: LeBytes::from_u16(&px)
        })),
        DeviceError::Simulation
    );
    assert_eq!(device_error(c.request(&Request::SimLines { lines: 0 })), DeviceError::Simulation);

    // And the device still serves, and provisions from scratch.
    let st = c.status().unwrap();
    assert_eq!(st.bad_frames, 5);
    let cal = c.provision(&b, |_, _| {}).unwrap();
    assert_eq!(c.info().unwrap().calibration, Some(cal));
}

#[test]
fn continuous_measurement_refuses_provisioning_and_stops_on_request() {
    let (mut c, b, scene) = provisioned_with_scene(7.0, 3);
    let seq = c.send(&Request::Measure { lines: 0, format: StreamFormat::LOSSLESS }).unwrap();
    // Let a few lines stream.
    let mut points = Vec::new();
    while points.len() < 3 * P {
        match c.next_frame(std::time::Duration::from_secs(1)).unwrap() {
            f if f.seq != seq => panic!("unexpected frame {f:?}"),
            f => {
                if let Reply::Points(ps) = f.reply {
                    points.extend(ps)
                }
            }
        }
    }
    let begin = Request::ProvisionBegin { len: b.len() as u32, crc: CRC32.checksum(&b) };
    let s2 = c.send(&begin).unwrap();
    let s3 = c.send(&Request::Measure { lines: 1, format: StreamFormat::LOSSLESS }).unwrap();
    let s4 = c.send(&Request::Stop).unwrap();
    let mut replies = Vec::new();
    let done_lines = loop {
        let f = c.next_frame(std::time::Duration::from_secs(1)).unwrap();
        match f.reply {
            Reply::Points(ps) => points.extend(ps),
            Reply::Point(p) => panic!("a protocol 2 point frame: {p:?}"),
            Reply::Msg(Response::MeasureDone { lines_done }) => break lines_done,
            Reply::Msg(m) => replies.push((f.seq, m)),
        }
    };
    assert_eq!(
        replies,
        vec![
            (s2, Response::Error(DeviceError::Busy)),
            (s3, Response::Error(DeviceError::Busy)),
            (s4, Response::StopRequested)
        ]
    );
    assert_eq!(points.len(), done_lines as usize * P, "whole lines only");
    check_points(&b, &scene, &points, done_lines as usize);
    assert!(!c.status().unwrap().measuring);
}

#[test]
fn sensor_without_a_scene_reports_a_typed_error() {
    let mut c = client(flash(), ZONES);
    c.provision(&blob(8.0), |_, _| {}).unwrap();
    assert_eq!(device_error(c.measure(2)), DeviceError::Sensor(SensorError::NoData));
    // Still serving: status after the error.
    assert!(!c.status().unwrap().measuring);
}

#[test]
fn saturated_and_dark_points_are_flagged() {
    let mut c = client(flash(), ZONES);
    let b = blob(9.0);
    c.provision(&b, |_, _| {}).unwrap();
    let view = BlobView::parse(&b).unwrap();
    let mut scene = analytic_scene(&view, 1, FULL_SCALE);
    scene[0][1][3] = FULL_SCALE; // LED 0 saturates pixel 3
    for f in 1..=M {
        scene[0][f][5] = scene[0][0][5] + 2; // pixel 5: barely above dark
    }
    c.load_scene(&scene).unwrap();
    let pts = c.measure(1).unwrap();
    check_points(&b, &scene, &pts, 1);
    assert_eq!(pts[3].flags, flags::SATURATED);
    assert_eq!(pts[5].flags, flags::UNDER_EXPOSED);
}

#[test]
fn a_new_session_measuring_as_the_last_one_did_gets_its_stream_from_point_0() {
    let (c, b, scene) = provisioned_with_scene(9.5, 2);
    let mut device = c.into_transport();
    // Two host processes in turn, each sending the same requests from seq
    // 1: the same `Measure`, down to its sequence number.
    for session in 0..2 {
        let mut c = Client::new(device).unwrap();
        c.format = StreamFormat::LOSSLESS;
        let pts = c.measure(2).unwrap_or_else(|e| panic!("session {session}: {e}"));
        check_points(&b, &scene, &pts, 2);
        device = c.into_transport();
    }
}

#[test]
fn a_measurement_the_host_gives_up_on_is_stopped_so_the_next_session_measures() {
    let (mut c, b, scene) = provisioned_with_scene(9.75, 2);
    // The host decodes with another calibration: it gives up at the first
    // frame, with lines still to come.
    c.set_calibration(&blob(5.0)).unwrap();
    c.format = StreamFormat { encoding: Encoding::Sigma16, bins: None };
    assert!(matches!(c.measure(3), Err(LinkError::Stream(DecodeError::OtherBlob { .. }))));
    let mut c = Client::new(c.into_transport()).unwrap();
    c.format = StreamFormat::LOSSLESS;
    let pts = c.measure(2).unwrap();
    check_points(&b, &scene, &pts, 2);
}

#[test]
fn line_k_plus_1_is_acquired_while_line_k_is_estimated_and_sent() {
    let (mut c, b, scene) = provisioned_with_scene(10.0, 2);
    let before = c.transport().scene.switches_timed().len();
    let pts = c.measure(3).unwrap();
    check_points(&b, &scene, &pts, 3);
    let sw = &c.transport().scene.switches_timed()[before..];
    let per_line = M + 2; // dark (all off), one per LED, all off
    assert_eq!(sw.len(), 3 * per_line);
    let sent_at_line_start = |k: usize| sw[k * per_line].1;
    // When line 1's acquisition starts, the device has sent the reply to
    // Measure and at most a few of line 0's point frames: line 0 is still
    // being estimated and sent (with one buffer, acquisition would wait for
    // all P of them to be estimated and at least P - 4 to be written).
    let during = sent_at_line_start(1) - sent_at_line_start(0);
    assert!(during < 1 + P / 2, "line 1 started only after {during} frames of line 0 were sent");
    // And line 2 starts before line 1's points are all out.
    let during = sent_at_line_start(2) - sent_at_line_start(1);
    assert!(during < 1 + P + P / 2, "{during}");
}

/// Scale-free calibrations (plain and piecewise, trained by host-tools on the
/// MERL prior for the patent-profile scene) run on the device exactly as the
/// host's reference computes them: values, zone, cluster, flags (including
/// the out-of-prior flag) and the uncertainty's scale, bit for bit. The
/// scale is the sum of the point's readings, so the estimate and its
/// uncertainty scale with the point; synthetic readings unlike any material
/// are flagged out-of-prior on the device.
#[test]
fn scale_free_calibrations_run_bit_identically_and_flag_readings_outside_the_prior() {
    use host_tools::calibration::demo::train_scale_free_for_scene;
    use host_tools::forward::scene::frames::{patent_scene, scene_frames};
    let scene = patent_scene(P);
    // (piecewise, zones, RAM budget in matrices): the last runs in place.
    for (piecewise, zones, ram) in [(false, 2, ZONES), (true, 1, ZONES), (true, 1, 1)] {
        let t = train_scale_free_for_scene(&scene, zones, 0.02, piecewise).unwrap();
        let view = BlobView::parse(&t.blob).unwrap();
        let mut c = client(flash(), ram);
        let cal = c.provision(&brdf_meter::test_blobs::sign_for_tests(&t.blob), |_, _| {}).unwrap();
        assert_eq!(cal.blob_crc, view.crc());
        assert_eq!(cal.in_ram, zones * view.clusters() <= ram);

        let frames = scene_frames(&scene, 2).unwrap();
        c.load_scene(&frames).unwrap();
        let pts = c.measure(2).unwrap();
        check_points(&t.blob, &frames, &pts, 2);
        assert!(pts.iter().all(|p| p.sigma_scale > 0.0 && p.sigma_scale != 1.0), "the scale is the readings' sum");
        assert!(pts.iter().any(|p| p.values.iter().any(|v| *v > 0.1)));
        if piecewise {
            assert!(view.clusters() >= 2);
        }

        // Synthetic readings (a pattern no material makes): flagged.
        let odd = analytic_scene(&view, 1, FULL_SCALE);
        c.load_scene(&odd).unwrap();
        let pts = c.measure(1).unwrap();
        check_points(&t.blob, &odd, &pts, 1);
        let flagged = pts.iter().filter(|p| p.flags & brdf_meter::protocol::flags::OUT_OF_PRIOR != 0).count();
        assert!(flagged > 0, "no synthetic point flagged out-of-prior (piecewise {piecewise})");

        // The same calibration with band factors 1 and 1.5: the flagged
        // points' scale carries the factor, bit for bit as the host's
        // reference, and the rest are the same bits.
        let mut with = |f: f32| {
            let b = with_band_factor(&t.blob, f);
            c.provision(&brdf_meter::test_blobs::sign_for_tests(&b), |_, _| {}).unwrap();
            c.load_scene(&odd).unwrap();
            let pts = c.measure(1).unwrap();
            check_points(&b, &odd, &pts, 1);
            pts
        };
        let (pts, again) = (with(1.0), with(1.5));
        for (a, b) in pts.iter().zip(&again) {
            let want = if a.flags & brdf_meter::protocol::flags::OUT_OF_PRIOR != 0 {
                brdf_meter::kernel::scale_free::flagged_sigma_scale(a.sigma_scale, 1.5, view.root_form())
            } else {
                a.sigma_scale
            };
            assert_eq!((b.sigma_scale.to_bits(), b.flags), (want.to_bits(), a.flags));
        }
    }
}

/// `blob` with the out-of-prior band factor `f` in its header (flag bit 5,
/// offset 56, `brdf_meter::blob`), resealed.
fn with_band_factor(blob: &[u8], f: f32) -> Vec<u8> {
    let mut b = blob.to_vec();
    let flags = u16::from_le_bytes([b[22], b[23]]) | 32;
    b[22..24].copy_from_slice(&flags.to_le_bytes());
    b[56..60].copy_from_slice(&f.to_le_bytes());
    let at = b.len() - 4;
    let crc = brdf_meter::blob::CRC32.checksum(&b[..at]);
    b[at..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(BlobView::parse(&b).unwrap().out_of_prior_band_factor(), f);
    b
}

/// A calibration with a zone that cannot read the gloss standard (its
/// reference and rows NaN, as training marks it): the device streams NaN
/// readings for that zone's points and real ones for the others, bit for
/// bit as the host's reference computes them.
#[test]
fn a_zone_without_a_gloss_reading_streams_nan_readings_bit_identically() {
    use host_tools::calibration::demo::train_for_scene;
    use host_tools::forward::scene::frames::{patent_scene, scene_frames};
    let scene = patent_scene(P);
    let trained = train_for_scene(&scene, 2, 0.02).unwrap();
    let marked = system_tests::without_gloss_reading(&trained.blob, 1);
    let view = BlobView::parse(&marked).unwrap();
    assert!(system_tests::zone_has_gloss_reading(&view, 0) && !system_tests::zone_has_gloss_reading(&view, 1));
    let mut c = client(flash(), ZONES);
    c.provision(&sign_for_tests(&marked), |_, _| {}).unwrap();
    let frames = scene_frames(&scene, 2).unwrap();
    c.load_scene(&frames).unwrap();
    let pts = c.measure(2).unwrap();
    check_points(&marked, &frames, &pts, 2);
    assert!(pts.iter().any(|p| p.zone == 0 && p.readings[0].is_finite()));
    assert!(pts.iter().any(|p| p.zone == 1));
}

/// The handheld's scene (`scenes/handheld.toml`) cut to the simulated
/// device's pixels.
fn handheld_cut() -> host_tools::forward::scene::Scene {
    host_tools::forward::scene::Scene::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/handheld.toml"),
    )
    .unwrap()
    .for_device(P)
    .unwrap()
}

/// The handheld's line cut to the simulated device, a black glass on it:
/// its frames saturate the long exposure and the device takes the shorter
/// ones (the scene's frames carry them), bit for bit as the host's
/// reference; no point is left saturated, every point reads near 100 GU.
#[test]
fn the_handheld_cut_reads_the_black_glass_through_its_shorter_exposures() {
    use host_tools::calibration::demo::{scene_prior, train_scene};
    use host_tools::forward::scene::frames::scene_frames;
    let mut scene = handheld_cut();
    let prior = scene_prior(&scene, "patent").unwrap();
    let trained = train_scene(
        &scene,
        2,
        0.01,
        brdf_meter::blob::EstimatorKind::Wiener,
        &prior,
        host_tools::forward::pairs::Criterion::Plain,
    )
    .unwrap();
    scene.surface.brdf = host_tools::forward::brdf::BrdfSpec::SmoothDielectric { n: 1.567, base_albedo: 0.0 };
    let frames = scene_frames(&scene, 2).unwrap();
    assert_eq!(frames[0].len(), 3 * (M + 1), "long and two shorter exposures");
    assert!(frames[0][1..=M].iter().any(|f| f.contains(&FULL_SCALE)), "the black glass saturates the long exposure");
    let mut c = client(flash(), ZONES);
    c.provision(&sign_for_tests(&trained.blob), |_, _| {}).unwrap();
    c.load_scene(&frames).unwrap();
    let before = c.transport().scene.switches().len();
    let pts = c.measure(2).unwrap();
    check_points(&trained.blob, &frames, &pts, 2);
    for p in &pts {
        assert_eq!(p.flags & brdf_meter::protocol::flags::SATURATED, 0, "point {}", p.point);
        assert!((p.readings[0] - 100.0).abs() < 5.0, "point {}: {} GU", p.point, p.readings[0]);
    }
    // Every other reading's frames, the shorter ones too, come before the
    // last LED's long frame: while it integrates, each pixel's other
    // readings are final (what an inspection works out early needs).
    let order = BlobView::parse(&trained.blob).unwrap().led_order();
    let sw = c.transport().scene.switches()[before..].to_vec();
    let line = sw.len() / 2;
    assert_eq!(sw[..line], sw[line..], "both lines take the same frames");
    let last_long = sw[..line].iter().position(|l| *l == Some(order[M - 1])).unwrap();
    let others = |l: &Option<u8>| l.is_some_and(|l| order[..M - 1].contains(&l));
    assert!(sw[last_long..line].iter().all(|l| !others(l)), "{sw:?}");
    assert!(
        sw[..last_long].iter().filter(|l| others(l)).count() > M - 1,
        "no shorter frame before the last LED: {sw:?}"
    );
}

/// The handheld's line cut to the simulated device, trained as the product
/// is (scale-free piecewise on the measured prior, the scene's noise): its
/// gloss rows have clusters of their own (blob flag bit 9), and the device
/// picks each point's gloss cluster and reads its gloss bit for bit as the
/// host's reference, on a glossy lobe and on the black glass. (Trained in
/// more zones, this cut of the line keeps the maps' clusters; each zone's
/// centroids are found at their offset by both the device's and the host's
/// path in `brdf_meter::blob`'s tests.)
#[test]
fn gloss_rows_with_clusters_of_their_own_read_bit_identically() {
    use host_tools::calibration::demo::{scene_prior, train_scene_for_slot};
    use host_tools::forward::scene::frames::scene_frames;
    let mut scene = handheld_cut();
    let prior = scene_prior(&scene, "merl").unwrap();
    let noise = host_tools::forward::scene::noise_level::relative_noise_level(&scene).unwrap();
    let kind = brdf_meter::blob::EstimatorKind::ScaleFreePiecewise;
    let criterion = host_tools::forward::pairs::Criterion::PeakRelative;
    let for_slot = |slot| train_scene_for_slot(&scene, 1, noise, kind, &prior, criterion, slot).unwrap();
    let trained = for_slot(host_tools::calibration::train::board_blob_capacity());
    let view = BlobView::parse(&trained.blob).unwrap();
    assert!(view.has_gloss_centroids(), "the handheld's gloss rows choose clusters of their own");
    // A slot a byte too small for them: the rows keep the maps' clusters,
    // and the maps keep their count.
    let slot = trained.blob.len() - 1;
    let smaller = for_slot(slot);
    let small = BlobView::parse(&smaller.blob).unwrap();
    assert!(smaller.blob.len() <= slot && !small.has_gloss_centroids());
    assert_eq!((small.clusters(), small.gloss_clusters()), (view.clusters(), view.clusters()));
    let mut c = client(flash(), ZONES);
    c.provision(&sign_for_tests(&trained.blob), |_, _| {}).unwrap();
    for brdf in [
        host_tools::forward::brdf::BrdfSpec::Ward { rho_d: 0.2, rho_s: Some(0.1), alpha: 0.06 },
        host_tools::forward::brdf::BrdfSpec::SmoothDielectric { n: 1.567, base_albedo: 0.0 },
    ] {
        scene.surface.brdf = brdf;
        let frames = scene_frames(&scene, 2).unwrap();
        c.load_scene(&frames).unwrap();
        let pts = c.measure(2).unwrap();
        check_points(&trained.blob, &frames, &pts, 2);
        assert!(pts.iter().all(|p| p.readings[0].is_finite() && p.readings[0] > 0.0));
    }
}

/// What every encoding must give: the f32 stream's points, values bit for
/// bit (f32, corrected readings) or within 1/256 of each bin's uncertainty
/// (Sigma16), on the bins asked for.
fn check_against_exact(view: &BlobView<'_>, exact: &[PointRecord], got: &[PointRecord], fmt: StreamFormat) {
    assert_eq!(got.len(), exact.len());
    let bins = fmt.bin_range(N);
    for (g, e) in got.iter().zip(exact) {
        let meta = |p: &PointRecord| {
            (p.line, p.seq, p.point, p.zone, p.cluster, p.flags, p.sigma_scale.to_bits(), p.readings.map(f32::to_bits))
        };
        assert_eq!(meta(g), meta(e));
        assert_eq!(g.bins, bins);
        assert_eq!(g.values.len(), bins.count as usize);
        for (v, j) in g.values.iter().zip(bins.bins()) {
            let want = e.values[j];
            if g.encoding == Encoding::Sigma16 {
                let u = point_uncertainty(view.uncertainty_of(g.zone as usize, g.cluster as usize, j), g.sigma_scale);
                assert!((v - want).abs() <= u / 256.0, "point {} bin {j}: {v} vs {want} (u {u})", g.seq);
            } else {
                assert_eq!(v.to_bits(), want.to_bits(), "point {} bin {j}", g.seq);
            }
        }
    }
}

#[test]
fn every_encoding_and_bin_subset_decodes_to_the_f32_streams_points() {
    let mut c = client(flash(), ZONES);
    let b = blob(3.0);
    c.provision(&b, |_, _| {}).unwrap();
    let view = BlobView::parse(&b).unwrap();
    let scene = analytic_scene(&view, 2, FULL_SCALE);
    c.load_scene(&scene).unwrap();
    let exact = c.measure(2).unwrap();
    check_points(&b, &scene, &exact, 2);
    c.set_calibration(&b).unwrap();
    let subset = Some(BinRange { first: 1, step: 4, count: 20 });
    let mut sigma16 = 0;
    for fmt in [
        StreamFormat::default(),
        StreamFormat { encoding: Encoding::Corrected, bins: None },
        StreamFormat { encoding: Encoding::F32, bins: subset },
        StreamFormat { encoding: Encoding::Sigma16, bins: subset },
        StreamFormat { encoding: Encoding::Corrected, bins: subset },
    ] {
        c.format = fmt;
        c.load_scene(&scene).unwrap(); // a measurement starts at the scene's first line
        let got = c.measure(2).unwrap();
        check_against_exact(&view, &exact, &got, fmt);
        assert!(got.iter().all(|p| p.encoding == fmt.encoding || p.encoding == Encoding::F32));
        sigma16 += got.iter().filter(|p| p.encoding == Encoding::Sigma16).count();
    }
    assert!(sigma16 > 0, "Sigma16 was exercised");
    assert_eq!(StreamFormat::default().encoding, Encoding::Sigma16);
}

#[test]
fn an_empty_or_out_of_range_bin_subset_is_refused() {
    let mut c = client(flash(), ZONES);
    c.provision(&blob(2.0), |_, _| {}).unwrap();
    for bins in [BinRange { first: 0, step: 1, count: 0 }, BinRange { first: 80, step: 2, count: 2 }] {
        c.format = StreamFormat { encoding: Encoding::F32, bins: Some(bins) };
        assert_eq!(device_error(c.measure(1)), DeviceError::BadBins { bins: N as u16 });
    }
}

#[test]
fn values_decoded_with_another_calibration_or_none_are_refused() {
    let (mut c, b, _) = provisioned_with_scene(2.0, 1);
    c.format = StreamFormat { encoding: Encoding::Corrected, bins: None };
    match c.measure(1) {
        Err(LinkError::Stream(DecodeError::NeedsBlob(Encoding::Corrected))) => {}
        other => panic!("decoded without the blob: {other:?}"),
    }
    c.resync().unwrap();
    let other = blob(5.0);
    c.set_calibration(&other).unwrap();
    for encoding in [Encoding::Corrected, Encoding::Sigma16] {
        c.format = StreamFormat { encoding, bins: None };
        match c.measure(1) {
            Err(LinkError::Stream(DecodeError::OtherBlob { device, host })) => {
                assert_eq!(device, BlobView::parse(&b).unwrap().crc());
                assert_eq!(host, BlobView::parse(&other).unwrap().crc());
            }
            other => panic!("decoded with another blob: {other:?}"),
        }
        c.resync().unwrap();
    }
}
