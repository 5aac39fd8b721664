//! End to end in QEMU: the QEMU firmware (built by this test) on QEMU's
//! b-l475e-iot01a machine, over its TCP serial on 127.0.0.1, driven by
//! host-tools' link: provision a blob trained by host-tools, measure a scene
//! from host-tools' scene simulator, and check every streamed value bit for
//! bit against the host's f32 computation on the same corrected readings.
use brdf_meter::blob::{BlobView, CRC32};
use brdf_meter::protocol::{
    BinRange, DeviceError, Encoding, FrameError, MAX_CHUNK, MAX_FRAME, Request, Response, SizeField, StreamFormat,
    encode, point_uncertainty,
};
use brdf_meter::signed::SignatureFault;
use host_tools::calibration::demo::train_for_scene;
use host_tools::calibration::signing::{sign_blob, sign_with_dev_key};
use host_tools::device::link::{Client, LinkError, PointRecord, Reply, TcpTransport};
use host_tools::device::reference::expected_line;
use host_tools::forward::scene::frames::{patent_scene, scene_frames};
use std::time::Duration;
use system_tests::qemu::start;

const PIXELS: usize = brdf_meter::shape::qemu::PIXELS;
const ZONES: usize = 4;

fn check_bit_identical(blob: &[u8], frames: &[Vec<Vec<u16>>], points: &[PointRecord], lines: usize, full_scale: u16) {
    let view = BlobView::parse(blob).unwrap();
    assert_eq!(points.len(), lines * PIXELS, "one frame per point");
    // A calibration with the gloss section: the device computes the readings
    // (not NaN), except in a zone the calibration marks as without them.
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
    let mut compared = 0;
    for (k, p) in points.iter().enumerate() {
        let line = k / PIXELS;
        let want = &expected_line(
            &view,
            &frames[line % frames.len()],
            full_scale,
            &brdf_meter::platform::timing::QEMU_ACQUISITION,
        )[k % PIXELS];
        assert_eq!((p.line as usize, p.seq as usize, p.point as usize), (line, k, k % PIXELS));
        assert_eq!(system_tests::meta_bits(p), system_tests::expected_meta_bits(want), "zone/flags of point {k}");
        for (j, (g, w)) in p.values.iter().zip(&want.values).enumerate() {
            assert_eq!(g.to_bits(), w.to_bits(), "point {k} bin {j}: device {g:e}, host {w:e}");
            compared += 1;
        }
        assert_eq!(p.values.len(), want.values.len());
    }
    assert_eq!(compared, lines * PIXELS * view.dims().n);
}

fn device_error<T: std::fmt::Debug>(r: Result<T, LinkError>) -> DeviceError {
    match r {
        Err(LinkError::Device(e)) => e,
        other => panic!("expected a device error, got {other:?}"),
    }
}

/// A calibration for `scene` trained by host-tools and signed with the
/// development key (which the QEMU firmware trusts by default).
fn signed_for_scene(scene: &host_tools::forward::scene::Scene, zones: usize, noise: f64) -> Vec<u8> {
    sign_with_dev_key(&train_for_scene(scene, zones, noise).unwrap().blob)
}

fn connect(q: &host_tools::device::link::qemu::QemuInstrument) -> Client<TcpTransport> {
    let mut c = q.connect().unwrap();
    c.timeout = Duration::from_secs(20);
    // f32 values (bit for bit) unless a test asks for another encoding.
    c.format = brdf_meter::protocol::StreamFormat::LOSSLESS;
    c
}

#[test]
fn qemu_provisions_a_trained_blob_and_streams_bit_identical_estimates() {
    let q = start(Duration::from_secs(240));
    let mut c = connect(&q);
    let info = c.info().unwrap_or_else(|e| panic!("{e}: {}", q.log_text()));
    // Counted from here: the request that found the device booting may
    // have reached it cut, a bad frame of its own (`Client::wait_ready`).
    let at_start = c.status().unwrap();
    assert_eq!(
        (info.bins as usize, info.leds as usize, info.pixels as usize),
        (brdf_meter::shape::BINS, brdf_meter::shape::LEDS, PIXELS)
    );
    assert!(info.simulated && info.calibration.is_none());

    let scene = patent_scene(PIXELS);
    let trained = train_for_scene(&scene, ZONES, 0.02).unwrap();
    let cal = c.provision(&sign_with_dev_key(&trained.blob), |_, _| {}).unwrap();
    assert_eq!((cal.zones, cal.in_ram), (ZONES as u16, true));
    assert_eq!(cal.blob_crc, BlobView::parse(&trained.blob).unwrap().crc());

    let frames = scene_frames(&scene, 4).unwrap();
    c.load_scene(&frames).unwrap();
    let lines = 6;
    let points = c.measure(lines as u32).unwrap();
    check_bit_identical(&trained.blob, &frames, &points, lines, info.full_scale);
    // Every zone is exercised and the values are real estimates.
    let zones: std::collections::BTreeSet<u16> = points.iter().map(|p| p.zone).collect();
    assert_eq!(zones.len(), ZONES);
    assert!(points.iter().all(|p| p.values.iter().all(|v| v.is_finite())));
    assert!(points.iter().any(|p| p.values.iter().any(|v| *v > 0.1)));
    let st = c.status().unwrap();
    assert_eq!((st.lines_total, st.bad_frames, st.measuring), (lines as u32, at_start.bad_frames, false));

    // The other encodings, decoded with the blob: the corrected readings
    // give the same bits (the host runs the device's kernel), Sigma16 is
    // within 1/256 of each bin's uncertainty, a bin subset its bins.
    c.set_calibration(&trained.blob).unwrap();
    let view = BlobView::parse(&trained.blob).unwrap();
    for format in [
        StreamFormat { encoding: Encoding::Corrected, bins: None },
        StreamFormat::default(),
        StreamFormat { encoding: Encoding::Sigma16, bins: Some(BinRange { first: 3, step: 7, count: 11 }) },
    ] {
        c.format = format;
        c.load_scene(&frames).unwrap(); // a measurement starts at the scene's first line
        let got = c.measure(2).unwrap();
        assert_eq!(got.len(), 2 * PIXELS);
        let bins = format.bin_range(view.dims().n);
        for (g, e) in got.iter().zip(&points) {
            assert_eq!(
                (g.seq, g.zone, g.cluster, g.flags, g.sigma_scale.to_bits()),
                (e.seq, e.zone, e.cluster, e.flags, e.sigma_scale.to_bits())
            );
            assert_eq!(g.values.len(), bins.count as usize);
            for (v, j) in g.values.iter().zip(bins.bins()) {
                if g.encoding == Encoding::Sigma16 {
                    let u =
                        point_uncertainty(view.uncertainty_of(g.zone as usize, g.cluster as usize, j), g.sigma_scale);
                    assert!((v - e.values[j]).abs() <= u / 256.0, "point {} bin {j}", g.seq);
                } else {
                    assert_eq!(v.to_bits(), e.values[j].to_bits(), "point {} bin {j}", g.seq);
                }
            }
        }
    }
    c.format = StreamFormat::LOSSLESS;

    // A scale-free piecewise calibration on the MERL prior: the Cortex-M4F
    // gives the host's bits too (values, cluster, out-of-prior flag, scale).
    let sf = host_tools::calibration::demo::train_scale_free_for_scene(&scene, 1, 0.02, true).unwrap();
    c.provision(&brdf_meter::test_blobs::sign_for_tests(&sf.blob), |_, _| {}).unwrap();
    c.load_scene(&frames).unwrap(); // a measurement starts at the scene's first line
    let points = c.measure(2).unwrap();
    check_bit_identical(&sf.blob, &frames, &points, 2, info.full_scale);
    assert!(points.iter().all(|p| p.sigma_scale > 0.0 && p.sigma_scale != 1.0));

    // A zone that cannot read the gloss standard (marked as training marks
    // it): NaN readings there, real ones elsewhere, the host's bits.
    let marked = system_tests::without_gloss_reading(&trained.blob, 1);
    c.provision(&sign_with_dev_key(&marked), |_, _| {}).unwrap();
    c.load_scene(&frames).unwrap();
    let points = c.measure(2).unwrap();
    check_bit_identical(&marked, &frames, &points, 2, info.full_scale);
    assert!(points.iter().any(|p| p.zone == 1) && points.iter().any(|p| p.zone == 0 && p.readings[0].is_finite()));
    assert!(!q.log_text().contains("panic"), "{}", q.log_text());
    system_tests::qemu::assert_stack_within_reserve(&q, "provisioning and measuring with each kind of calibration");
}

#[test]
fn qemu_demo_provisions_what_train_writes_and_reads_its_scene_with_few_flags() {
    // What `host-tools qemu --demo` sets up by default: the kind `train`
    // writes (scale-free piecewise on the measured prior), one zone and as
    // many clusters as the QEMU build's slot takes, on the handheld's line
    // cut to the device's pixels. It must provision (a count chosen for
    // the board's slot alone came out 2 KB too large for it) and read its
    // own scene as a plausible estimate: no value below zero, every gloss
    // reading a number, few points flagged out of prior.
    use host_tools::device::qemu_demo::{DemoEstimator, DemoScene, set_up};
    let q = start(Duration::from_secs(240));
    let mut c = connect(&q);
    let info = c.info().unwrap_or_else(|e| panic!("{e}: {}", q.log_text()));
    let dir = tempfile::tempdir().unwrap();
    let (signed, cal) = set_up(&mut c, &dir.path().join("demo.blob"), DemoEstimator::default(), DemoScene::default())
        .unwrap_or_else(|e| panic!("{e:#}: {}", q.log_text()));
    assert!(signed.len() <= info.max_blob as usize, "{} bytes for a slot of {}", signed.len(), info.max_blob);
    assert_eq!(cal.zones, 1);
    let blob = &signed[..signed.len() - brdf_meter::signed::TRAILER_LEN];
    let view = BlobView::parse(blob).unwrap();
    assert!(view.clusters() >= 2, "piecewise: {} clusters", view.clusters());
    let points = c.measure(4).unwrap();
    assert_eq!(points.len(), 4 * PIXELS);
    // Bit for bit as the host's reference on the Cortex-M4F build: the
    // estimates, and the gloss readings from the gloss rows' own clusters
    // where training chose them (blob flag bit 9).
    let frames = scene_frames(&DemoScene::default().scene(PIXELS).unwrap(), 4).unwrap();
    check_bit_identical(blob, &frames, &points, 4, info.full_scale);
    assert!(points.iter().all(|p| p.values.iter().all(|v| *v >= 0.0)), "a negative value");
    assert!(points.iter().all(|p| p.readings[0].is_finite()), "a gloss reading not a number");
    let flagged = points.iter().filter(|p| p.flags & brdf_meter::protocol::flags::OUT_OF_PRIOR != 0).count();
    assert!(flagged * 10 <= points.len(), "{flagged} of {} points flagged out of prior", points.len());
}

#[test]
fn qemu_refuses_bad_blobs_and_frames_and_keeps_measuring_with_its_calibration() {
    let q = start(Duration::from_secs(240));
    let mut c = connect(&q);
    let info = c.info().unwrap();
    // Counted from here: the request that found the device booting may
    // have reached it cut, a bad frame of its own (`Client::wait_ready`).
    let at_start = c.status().unwrap();
    let scene = patent_scene(PIXELS);
    let good = signed_for_scene(&scene, 2, 0.02);
    let cal = c.provision(&good, |_, _| {}).unwrap();
    let frames = scene_frames(&scene, 2).unwrap();
    c.load_scene(&frames).unwrap();

    // A blob corrupted in transit: refused at commit (whole-blob CRC).
    let newer_blob = train_for_scene(&scene, 3, 0.05).unwrap().blob;
    let newer = sign_with_dev_key(&newer_blob);
    let crc = CRC32.checksum(&newer);
    let mut bad = newer.clone();
    bad[newer.len() / 2] ^= 0x01;
    c.request(&Request::ProvisionBegin { len: bad.len() as u32, crc }).unwrap();
    for (k, ch) in bad.chunks(MAX_CHUNK).enumerate() {
        c.request(&Request::ProvisionChunk { offset: (k * MAX_CHUNK) as u32, data: ch }).unwrap();
    }
    assert_eq!(
        device_error(c.request(&Request::ProvisionCommit)),
        DeviceError::CrcMismatch { declared: crc, computed: CRC32.checksum(&bad) }
    );
    // A valid blob trained for another instrument (16 pixels).
    let other = signed_for_scene(&patent_scene(16), 2, 0.02);
    assert_eq!(
        device_error(c.provision(&other, |_, _| {})),
        DeviceError::Mismatch { field: SizeField::Pixels, device: PIXELS as u16, blob: 16 }
    );
    // A calibration changed before sending (CRC consistent): its signature
    // no longer verifies; signed after the change, the blob's own CRC
    // catches it.
    assert_eq!(
        device_error(c.provision(&bad, |_, _| {})),
        DeviceError::SignatureRejected(SignatureFault::BadSignature)
    );
    let mut corrupt = newer_blob.clone();
    corrupt[newer_blob.len() / 2] ^= 0x01;
    assert!(matches!(
        device_error(c.provision(&sign_with_dev_key(&corrupt), |_, _| {})),
        DeviceError::BlobRejected { .. }
    ));
    // Unsigned, and signed by a key the firmware does not trust.
    assert_eq!(
        device_error(c.provision(&newer_blob, |_, _| {})),
        DeviceError::SignatureRejected(SignatureFault::Unsigned)
    );
    assert_eq!(
        device_error(c.provision(&sign_blob(&newer_blob, &[0x5A; 32]), |_, _| {})),
        DeviceError::SignatureRejected(SignatureFault::UnknownKey)
    );

    // Malformed frames: corrupted, oversized, out-of-order chunk.
    let mut f = [0u8; MAX_FRAME];
    let n = encode(900, &Request::Status, &mut f).unwrap();
    let mut corrupt = f[..n].to_vec();
    corrupt[n - 3] = if corrupt[n - 3] == 0x01 { 0x02 } else { 0x01 };
    c.send_raw(&corrupt).unwrap();
    let r = c.next_frame(Duration::from_secs(10)).unwrap();
    assert!(
        matches!(r.reply, Reply::Msg(Response::Error(DeviceError::Frame(FrameError::BadCrc | FrameError::Cobs)))),
        "{r:?}"
    );
    c.send_raw(&vec![0x11u8; 2 * MAX_FRAME + 7]).unwrap();
    c.send_raw(&[0]).unwrap();
    let r = c.next_frame(Duration::from_secs(10)).unwrap();
    assert_eq!(r.reply, Reply::Msg(Response::Error(DeviceError::Frame(FrameError::Oversized))));
    c.request(&Request::ProvisionBegin { len: newer.len() as u32, crc }).unwrap();
    assert_eq!(
        device_error(c.request(&Request::ProvisionChunk { offset: 64, data: &newer[64..128] })),
        DeviceError::OutOfOrder { expected: 0, got: 64 }
    );
    c.request(&Request::ProvisionAbort).unwrap();

    // Still the first calibration, still measuring with it, bit for bit.
    assert_eq!(c.info().unwrap().calibration, Some(cal));
    let points = c.measure(2).unwrap();
    check_bit_identical(&good, &frames, &points, 2, info.full_scale);
    let st = c.status().unwrap();
    assert_eq!(st.bad_frames - at_start.bad_frames, 2);
    assert!(st.refused - at_start.refused >= 7);
}

#[test]
fn qemu_serves_the_same_protocol_over_a_serial_port() {
    // QEMU's serial on a pseudo-terminal, opened with the serialport crate
    // exactly as a real instrument on /dev/ttyACM* is.
    let q = host_tools::device::link::qemu::QemuInstrument::start_pty(
        &system_tests::qemu::firmware(),
        Duration::from_secs(240),
        &[],
    )
    .unwrap();
    let mut c = q.connect_serial().unwrap();
    c.timeout = Duration::from_secs(20);
    c.format = StreamFormat::LOSSLESS;
    assert!(q.addr.starts_with("/dev/pts/"), "{}", q.addr);
    let scene = patent_scene(PIXELS);
    let blob = signed_for_scene(&scene, 2, 0.02);
    c.provision(&blob, |_, _| {}).unwrap();
    let frames = scene_frames(&scene, 1).unwrap();
    c.load_scene(&frames).unwrap();
    let points = c.measure(1).unwrap();
    let full_scale = c.info().unwrap().full_scale;
    check_bit_identical(&blob, &frames, &points, 1, full_scale);
}

/// `host-tools measure` as a user runs it against the QEMU instrument: the
/// summary, the plot with its uncertainty band, and the standard files,
/// which read back to the values the measurement's JSON holds.
#[test]
fn qemu_measure_writes_the_plot_and_the_standard_files() {
    let q = start(Duration::from_secs(240));
    let mut c = connect(&q);
    let scene = patent_scene(PIXELS);
    let signed = signed_for_scene(&scene, ZONES, 0.02);
    c.provision(&signed, |_, _| {}).unwrap_or_else(|e| panic!("{e}: {}", q.log_text()));
    drop(c);
    let dir = tempfile::tempdir().unwrap();
    let blob = dir.path().join("cal.blob");
    std::fs::write(&blob, &signed).unwrap();
    let args = host_tools::cli::measure::Args {
        device: host_tools::device::link::Endpoint { port: None, tcp: Some(q.addr.clone()) },
        blob,
        lines: 2,
        csv: dir.path().join("m.csv"),
        json: dir.path().join("m.json"),
        result: dir.path().join("m-result.json"),
        result_zones: vec![],
        scene: host_tools::cli::sim_scene::SimSceneArgs {
            scene: Some("patent".into()),
            scene_lines: Some(1),
            ..Default::default()
        },
        exports: host_tools::cli::exports::ExportArgs {
            plot: Some(dir.path().join("m.svg")),
            plot_points: vec![0, 15, 31],
            bird: Some(dir.path().join("m.bird.json")),
            astm: Some(dir.path().join("m.astm")),
            result_astm: Some(dir.path().join("m-result.astm")),
            result_bird: None,
            view_deg: 45.0,
            solid_angle_sr: Some(1e-3),
        },
        encoding: host_tools::cli::measure::EncodingArg::Sigma16,
        bins: None,
    };
    host_tools::cli::measure::run(args).unwrap_or_else(|e| panic!("{e:#}: {}", q.log_text()));
    let svg = std::fs::read_to_string(dir.path().join("m.svg")).unwrap();
    assert_eq!(svg.matches("<polygon").count(), 3, "one uncertainty band per plotted point");
    assert!(svg.contains("line 0 point 15"));
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("m.json")).unwrap()).unwrap();
    let csv = std::fs::read_to_string(dir.path().join("m.csv")).unwrap();
    assert!(csv.starts_with("# brdf-meter/points schema_version 3; source measure;"), "the point schema");
    assert_eq!((&j["schema"], &j["source"]), (&"brdf-meter/points".into(), &"measure".into()));
    let (profiles, view) = host_tools::output::bird::read(&dir.path().join("m.bird.json")).unwrap();
    assert_eq!((profiles.len(), view), (2 * PIXELS, 45.0));
    for (p, jp) in profiles.iter().zip(j["points"].as_array().unwrap()) {
        assert_eq!(
            (u64::from(p.line), u64::from(p.point)),
            (jp["line"].as_u64().unwrap(), jp["pixel"].as_u64().unwrap())
        );
        for ((r, u), (jr, ju)) in p
            .reflectance
            .iter()
            .zip(&p.uncertainty)
            .zip(jp["rho"].as_array().unwrap().iter().zip(jp["u_rho"].as_array().unwrap()))
        {
            assert!((r - jr.as_f64().unwrap()).abs() <= 1e-6 * r.abs().max(1e-6));
            assert!((u - ju.as_f64().unwrap()).abs() <= 1e-6 * u.abs().max(1e-6));
        }
    }
    let t = host_tools::output::astm_e1392::read(&dir.path().join("m-l1-p31.astm")).unwrap();
    assert_eq!(t.rows.len(), brdf_meter::shape::BINS);
    // The device's gloss readings travel with the profiles: in the plot's
    // legend, the BiRD file's ad hoc section and the ASTM header.
    assert!(svg.contains(" GU, haze ") && svg.contains(" HU, distinctness "), "legend without readings");
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("m.bird.json")).unwrap()).unwrap();
    let readings = doc["metadata"]["adhoc_section"]["gloss_readings"].as_array().unwrap();
    assert_eq!(readings.len(), 2 * PIXELS);
    let (a, b) = (readings[5]["gloss_gu"].as_f64().unwrap(), j["points"][5]["gloss_gu"].as_f64().unwrap());
    assert_eq!(a as f32, b as f32, "the device's f32 reading, unchanged");
    assert!(t.header.iter().any(|(k, _)| k == "GLOSS_GU"), "{:?}", t.header);
    // The result: the centre zones' gloss, its mean and the calibration's
    // part of its budget as the points' file gives them.
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("m-result.json")).unwrap()).unwrap();
    assert_eq!(r["schema"], "brdf-meter/result");
    let zones: Vec<u64> = r["zones"].as_array().unwrap().iter().map(|z| z.as_u64().unwrap()).collect();
    let centre: Vec<&serde_json::Value> = j["points"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| zones.contains(&p["zone"].as_u64().unwrap()) && p["gloss_gu"].is_number())
        .collect();
    assert!(!centre.is_empty() && centre.len() < 2 * PIXELS, "{zones:?}");
    let g = &r["readings"][0];
    assert_eq!((g["reading"].as_str(), g["points"].as_u64()), (Some("gloss_gu"), Some(centre.len() as u64)));
    let n = centre.len() as f64;
    let mean = centre.iter().map(|p| p["gloss_gu"].as_f64().unwrap()).sum::<f64>() / n;
    let rms = (centre.iter().map(|p| p["u_gloss_gu"].as_f64().unwrap().powi(2)).sum::<f64>() / n).sqrt();
    assert!((g["value"].as_f64().unwrap() - mean).abs() <= 1e-5 * mean, "{g} vs {mean}");
    assert!((g["budget"][0]["u"].as_f64().unwrap() - rms).abs() <= 1e-5 * rms, "{g} vs {rms}");
    // U = k u_c, k from the effective degrees of freedom: at least 2.
    let k = g["coverage_factor"].as_f64().unwrap();
    assert!(k >= 2.0 && g["expanded_u"].as_f64().unwrap() == k * g["u"].as_f64().unwrap(), "{g}");
    // And the mean BRDF, bin by bin, over the same points, also as a table.
    let b = &r["brdf"];
    let table = host_tools::output::astm_e1392::read(&dir.path().join("m-result.astm")).unwrap();
    assert_eq!(table.rows.len(), brdf_meter::shape::BINS);
    assert_eq!(b["points"].as_u64(), Some(centre.len() as u64));
    for k in [0, 40, 80] {
        let mean = centre.iter().map(|p| p["rho"][k].as_f64().unwrap()).sum::<f64>() / n;
        let got = b["value"][k].as_f64().unwrap();
        assert!((got - mean).abs() <= 1e-5 * mean.abs().max(1e-3), "bin {k}: {got} vs {mean}");
    }
    // Each bin's coverage interval is value +- U, never below 0 (to the
    // last digit or so: JSON's decimals are parsed back here).
    for k in 0..brdf_meter::shape::BINS {
        let (v, u) = (b["value"][k].as_f64().unwrap(), b["expanded_u"][k].as_f64().unwrap());
        let (lo, hi) = (b["interval"][k][0].as_f64().unwrap(), b["interval"][k][1].as_f64().unwrap());
        let near = |a: f64, b: f64| (a - b).abs() <= 1e-12 * (1.0 + b.abs());
        assert!(lo >= 0.0 && near(lo, (v - u).max(0.0)) && near(hi, v + u), "bin {k}: {lo} .. {hi}, {v} +- {u}");
    }
    assert!(!q.log_text().contains("panic"), "{}", q.log_text());
}

/// `host-tools standardise` against the QEMU instrument, as a user runs it:
/// the device reads a white tile (Lambertian 0.9 under the patent profile)
/// that is certified at 0.8, so the calibration's white reference is
/// rescaled by 0.9 / 0.8; provisioned, the device reads the same tile at
/// 0.8, and the standardised calibration is still for this scene's optics.
/// Then the gloss scale, on a black glass (the ideal one) certified at
/// 96 GU, which the white just standardised puts at 0.8 / 0.9 of 100 GU:
/// provisioned, the device reads it at 96.
#[test]
fn qemu_standardised_on_a_tile_and_a_black_glass_reads_them_at_their_certified_values() {
    use host_tools::cli::sim_scene::SimSceneArgs;
    use host_tools::cli::standardise::{Args, Source};
    use host_tools::forward::scene::frames::{NamedScene, named_scene_frames};
    let q = start(Duration::from_secs(240));
    let mut c = connect(&q);
    let signed = signed_for_scene(&patent_scene(PIXELS), ZONES, 0.02);
    c.provision(&signed, |_, _| {}).unwrap_or_else(|e| panic!("{e}: {}", q.log_text()));
    drop(c);
    let dir = tempfile::tempdir().unwrap();
    let (blob, out) = (dir.path().join("cal.signed"), dir.path().join("std.signed"));
    std::fs::write(&blob, &signed).unwrap();
    let tile = r#"{ model = "lambertian", rho = 0.9 }"#;
    let args = Args {
        blob: blob.clone(),
        tile_rf: Some(0.8),
        tile_u: 0.004,
        tile_k: None,
        black_glass_gu: None,
        black_glass_u: 0.0,
        black_glass_k: None,
        source: Source { port: None, tcp: Some(q.addr.clone()), readings: None },
        corrected_with: Default::default(),
        lines: 16,
        scene: SimSceneArgs { scene: Some("patent".into()), scene_surface: Some(tile.into()), ..Default::default() },
        out: out.clone(),
        key: Some(host_tools::calibration::signing::dev_key_path()),
        report: Some(dir.path().join("std.json")),
    };
    host_tools::cli::standardise::run(args).unwrap_or_else(|e| panic!("{e:#}: {}", q.log_text()));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("std.json")).unwrap()).unwrap();
    assert_eq!(report["lines"], 16, "every line a distinct draw: {report}");
    let image = host_tools::device::provision::read_blob(&out).unwrap();
    // The calibration states its white's uncertainty; the device takes it.
    let stated = BlobView::parse(&image).unwrap().white_uncertainty();
    assert_eq!(stated, report["u_rel"].as_f64().unwrap() as f32);
    assert!(stated >= 0.004 / 0.8, "at least the certificate's: {stated}");
    let mut c = connect(&q);
    c.provision(&image, |_, _| {}).unwrap_or_else(|e| panic!("{e}: {}", q.log_text()));
    // The same tile, other draws of its noise.
    let view = BlobView::parse(&image).unwrap();
    let named = NamedScene { spec: "patent", first_line: 8, surface: Some(tile) };
    let (frames, _) = named_scene_frames(named, &view, 4, c.info().unwrap().full_scale).unwrap();
    c.load_scene(&frames).unwrap();
    c.set_calibration(&image).unwrap();
    c.format = StreamFormat { encoding: Encoding::Corrected, bins: None };
    let points = c.measure(4).unwrap_or_else(|e| panic!("{e}: {}", q.log_text()));
    assert_eq!(points.len(), 4 * PIXELS);
    let m = view.dims().m;
    for i in 0..m {
        let mean = points.iter().map(|p| f64::from(p.corrected[i])).sum::<f64>() / points.len() as f64;
        assert!((mean - 0.8).abs() < 0.004, "reading {i}: the tile reads {mean}, certified 0.8");
    }
    drop(c);

    // The gloss scale, on the white just standardised.
    let glass = r#"{ model = "smooth-dielectric", n = 1.567 }"#;
    let gloss_out = dir.path().join("std-gloss.signed");
    let args = Args {
        blob: out.clone(),
        tile_rf: None,
        tile_u: 0.0,
        tile_k: None,
        black_glass_gu: Some(96.0),
        black_glass_u: 0.4,
        black_glass_k: None,
        source: Source { port: None, tcp: Some(q.addr.clone()), readings: None },
        corrected_with: Default::default(),
        lines: 16,
        scene: SimSceneArgs {
            scene: Some("patent".into()),
            scene_surface: Some(glass.into()),
            scene_line: 16,
            ..Default::default()
        },
        out: gloss_out.clone(),
        key: Some(host_tools::calibration::signing::dev_key_path()),
        report: Some(dir.path().join("gloss.json")),
    };
    host_tools::cli::standardise::run(args).unwrap_or_else(|e| panic!("{e:#}: {}", q.log_text()));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("gloss.json")).unwrap()).unwrap();
    let ratio = report["ratio_median"].as_f64().unwrap();
    // The white certified at 0.8 for a tile of 0.9 put every reading
    // 0.8 / 0.9 of its value: the ideal glass reads about 89 GU.
    assert!((ratio - 100.0 * 0.8 / 0.9 / 96.0).abs() < 0.02, "{report}");
    let image = host_tools::device::provision::read_blob(&gloss_out).unwrap();
    let view = BlobView::parse(&image).unwrap();
    assert_eq!(view.gloss_uncertainty(), report["u_rel"].as_f64().unwrap() as f32);
    assert_eq!(view.white_uncertainty(), stated, "the white's is kept");
    let mut c = connect(&q);
    c.provision(&image, |_, _| {}).unwrap_or_else(|e| panic!("{e}: {}", q.log_text()));
    let named = NamedScene { spec: "patent", first_line: 40, surface: Some(glass) };
    let (frames, _) = named_scene_frames(named, &view, 4, c.info().unwrap().full_scale).unwrap();
    c.load_scene(&frames).unwrap();
    c.set_calibration(&image).unwrap();
    let points = c.measure(4).unwrap_or_else(|e| panic!("{e}: {}", q.log_text()));
    let g = brdf_meter::gloss::SPECULAR_GU;
    let mean = points.iter().map(|p| f64::from(p.readings[g])).sum::<f64>() / points.len() as f64;
    assert!((mean - 96.0).abs() < 1.5, "the black glass reads {mean} GU, certified 96");
    drop(c);
    // `verify` on the device agrees with the same standard, on every zone.
    let report = dir.path().join("verify.json");
    let args = host_tools::cli::verify::Args {
        blob: gloss_out.clone(),
        gloss_gu: 96.0,
        gloss_u: 0.4,
        gloss_k: None,
        source: Source { port: None, tcp: Some(q.addr.clone()), readings: None },
        corrected_with: Default::default(),
        lines: 8,
        scene: SimSceneArgs {
            scene: Some("patent".into()),
            scene_surface: Some(glass.into()),
            scene_line: 48,
            ..Default::default()
        },
        zones: (0..ZONES).collect(),
        report: Some(report.clone()),
    };
    host_tools::cli::verify::run(args).unwrap_or_else(|e| panic!("{e:#}: {}", q.log_text()));
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!((r["agrees"].as_bool(), r["zones"].as_array().map(Vec::len)), (Some(true), Some(ZONES)), "{r}");
    assert!(!q.log_text().contains("panic"), "{}", q.log_text());
}
