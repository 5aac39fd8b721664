//! Golden bytes: the encodings host and device must agree on, checked in
//! (`tests/golden/encodings.txt`) and compared byte for byte, so a change to
//! a format cannot slip past the round-trip tests without a version bump.
//!
//! Pinned: the calibration blob (format 1, its signed form, and format 2 with
//! clusters and out-of-prior data), the inspection recipe (format 1), the
//! calibration store's slot header, and one frame of
//! every request and response (and every device error) of the wire protocol.
//! The lists below match every variant without a wildcard: a new variant
//! does not compile until it has a golden line. The fuzz corpus's seeds of
//! golden frames (`tests/fuzz/corpus/frame_decode/golden-*`) are pinned to
//! these frames, and regenerated with them.
//!
//! A difference means the bytes changed: bump the version of what changed
//! (`blob::FORMAT_VERSION`, `inspect::recipe::FORMAT_VERSION`,
//! `signed::TRAILER_VERSION`, `store::SLOT_VERSION`,
//! `protocol::PROTOCOL_VERSION`)
//! and regenerate with
//!
//!     GOLDEN_REGENERATE=1 cargo test --release -p system-tests --test system -- golden_bytes::
use brdf_meter::blob::{BlobExtras, EstimatorKind, OutOfPriorData, Section, write_blob_with};
use brdf_meter::hw::SensorError;
use brdf_meter::kernel::scale_free::OutOfPriorForm;
use brdf_meter::protocol::{
    BinRange, BlobFault, CalInfo, DeviceError, DeviceInfo, DeviceStatus, Encoding, FrameError, LeBytes, MAX_FRAME,
    PointFrame, PointIn, PointMetaWire, PointsBlock, Request, Response, SizeField, StreamFormat, encode, flags,
};
use brdf_meter::store::encode_slot_header;
use brdf_meter::test_blobs::TestBlobParts;
use std::path::PathBuf;

const REGENERATE: &str = "GOLDEN_REGENERATE";

fn golden_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("golden/encodings.txt")
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

fn request_frame(seq: u32, msg: &Request<'_>) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME];
    let n = encode(seq, msg, &mut out).expect("golden messages fit a frame");
    out[..n].to_vec()
}

fn response_frame(seq: u32, msg: &Response<'_>) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME];
    let n = encode(seq, msg, &mut out).expect("golden messages fit a frame");
    out[..n].to_vec()
}

/// The name of a request's variant (exhaustive: a new variant needs a line).
fn request_name(r: &Request<'_>) -> &'static str {
    match r {
        Request::Info => "Info",
        Request::Status => "Status",
        Request::ProvisionBegin { .. } => "ProvisionBegin",
        Request::ProvisionChunk { .. } => "ProvisionChunk",
        Request::ProvisionCommit => "ProvisionCommit",
        Request::ProvisionAbort => "ProvisionAbort",
        Request::Measure { .. } => "Measure",
        Request::Stop => "Stop",
        Request::SimFrame { .. } => "SimFrame",
        Request::SimLines { .. } => "SimLines",
        Request::FirmwareInfo => "FirmwareInfo",
        Request::UpdateBegin { .. } => "UpdateBegin",
        Request::UpdateChunk { .. } => "UpdateChunk",
        Request::UpdateCommit => "UpdateCommit",
        Request::UpdateAbort => "UpdateAbort",
        Request::Reboot => "Reboot",
        Request::RecipeBegin { .. } => "RecipeBegin",
        Request::RecipeChunk { .. } => "RecipeChunk",
        Request::RecipeCommit => "RecipeCommit",
        Request::RecipeAbort => "RecipeAbort",
        Request::Inspect { .. } => "Inspect",
        Request::InspectStatus => "InspectStatus",
    }
}

/// The name of a response's variant (exhaustive).
fn response_name(r: &Response<'_>) -> &'static str {
    match r {
        Response::Info(_) => "Info",
        Response::Status(_) => "Status",
        Response::ProvisionReady { .. } => "ProvisionReady",
        Response::ChunkAck { .. } => "ChunkAck",
        Response::Committed(_) => "Committed",
        Response::Aborted => "Aborted",
        Response::MeasureStarted { .. } => "MeasureStarted",
        Response::StopRequested => "StopRequested",
        Response::MeasureDone { .. } => "MeasureDone",
        Response::SimLoaded => "SimLoaded",
        Response::Point(_) => "Point",
        Response::Points(p) => match p.encoding {
            Encoding::F32 => "Points.F32",
            Encoding::Sigma16 => "Points.Sigma16",
            Encoding::Corrected => "Points.Corrected",
        },
        Response::Error(e) => error_name(e),
        Response::Firmware(_) => "Firmware",
        Response::UpdateReady { .. } => "UpdateReady",
        Response::UpdateCommitted { .. } => "UpdateCommitted",
        Response::Rebooting => "Rebooting",
        Response::RecipeCommitted(_) => "RecipeCommitted",
        Response::Verdict(_) => "Verdict",
        Response::RejectPulse { .. } => "RejectPulse",
        Response::Inspection(_) => "Inspection",
    }
}

/// The name of a device error's variant (exhaustive).
fn error_name(e: &DeviceError) -> &'static str {
    match e {
        DeviceError::Frame(_) => "Error.Frame",
        DeviceError::NoCalibration => "Error.NoCalibration",
        DeviceError::Busy => "Error.Busy",
        DeviceError::NotProvisioning => "Error.NotProvisioning",
        DeviceError::OutOfOrder { .. } => "Error.OutOfOrder",
        DeviceError::ChunkTooLarge { .. } => "Error.ChunkTooLarge",
        DeviceError::BlobTooLarge { .. } => "Error.BlobTooLarge",
        DeviceError::Incomplete { .. } => "Error.Incomplete",
        DeviceError::CrcMismatch { .. } => "Error.CrcMismatch",
        DeviceError::BlobRejected { .. } => "Error.BlobRejected",
        DeviceError::Mismatch { .. } => "Error.Mismatch",
        DeviceError::Storage => "Error.Storage",
        DeviceError::Sensor(_) => "Error.Sensor",
        DeviceError::Simulation => "Error.Simulation",
        DeviceError::SignatureRejected(_) => "Error.SignatureRejected",
        DeviceError::BadBins { .. } => "Error.BadBins",
        DeviceError::FirmwareRejected(_) => "Error.FirmwareRejected",
        DeviceError::Update(_) => "Error.Update",
        DeviceError::CalibrationUnsupported { .. } => "Error.CalibrationUnsupported",
        DeviceError::RecipeRejected(_) => "Error.RecipeRejected",
        DeviceError::RecipeForOtherCalibration { .. } => "Error.RecipeForOtherCalibration",
        DeviceError::NoRecipe => "Error.NoRecipe",
    }
}

fn recipe_info() -> brdf_meter::protocol::RecipeInfo {
    brdf_meter::protocol::RecipeInfo {
        slot: 0,
        sequence: 3,
        crc: 0x5EED_0001,
        version: 2,
        calibration_crc: 0xDEAD_BEEF,
    }
}

/// A defect-free verdict (the frame every good line sends) and one with two defects.
fn verdict() -> brdf_meter::inspect::Verdict {
    use brdf_meter::inspect::{DefectKind, DefectRun, decide::Runs, decide::verdict};
    let mut runs = Runs::new();
    runs.push(DefectRun { first: 12, len: 4, kind: DefectKind::GlossHigh, peak_d2: 48.5 }).unwrap();
    runs.push(DefectRun { first: 90, len: 2, kind: DefectKind::OutOfPrior, peak_d2: 1e4 }).unwrap();
    brdf_meter::inspect::Verdict {
        line: 1_000,
        flags: verdict::REJECT | verdict::POINTS_FOLLOW,
        mean_gloss: 0.25,
        ewma: -0.125,
        max_d2: 1e4,
        runs,
    }
}

/// A recipe with every field set, decided with hysteresis along the line
/// (format 2) or not (format 1, as recipes taught before it are).
fn golden_recipe(along_line_hysteresis: bool) -> Vec<u8> {
    use brdf_meter::inspect::recipe::{DelayUnit, RecipeData, RecipeSettings, group_len, pixel_len, write};
    let m = 3;
    write(&RecipeData {
        pixels: 6,
        m,
        group_starts: vec![0, 4],
        group_values: (0..2).map(|g| (0..group_len(m)).map(|i| (g * 100 + i) as f32 * 0.5).collect()).collect(),
        pixel_values: (0..6).map(|p| (0..pixel_len(m)).map(|i| (p * 10 + i) as f32 * 0.25).collect()).collect(),
        settings: RecipeSettings {
            calibration_crc: 0xDEAD_BEEF,
            version: 2,
            threshold_on: 31.5,
            threshold_off: 22.0,
            min_pixels: 3,
            min_lines: 2,
            ewma_lambda: 0.125,
            ewma_limit: 0.75,
            pulse_us: 25_000,
            delay: 3,
            delay_unit: DelayUnit::Lines,
            window_hysteresis: 0.75,
            windows: [[-1.5, 1.5], [-0.5, 2.0], [f32::NEG_INFINITY, f32::INFINITY]],
            teach_quality: 1.25,
            teach_lines: 200,
            along_line_hysteresis,
        },
    })
    .expect("a valid recipe")
}

fn cal() -> CalInfo {
    CalInfo { slot: 1, sequence: 9, blob_crc: 0xDEAD_BEEF, blob_len: 11_000, zones: 4, in_ram: true }
}

/// Every golden line, `name: hex`, in a fixed order.
fn encodings() -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = Vec::new();

    // Calibration blobs: format 1, and format 2 (piecewise scale-free with
    // out-of-prior data).
    let v1 = TestBlobParts::new(9, 3, 2, 6, 0.5);
    out.push(("blob.v1".into(), v1.encode()));
    // The signed form: the blob and its trailer (Ed25519 is deterministic,
    // so the development key's signature is fixed too).
    out.push(("blob.v1.signed".into(), brdf_meter::test_blobs::sign_for_tests(&v1.encode())));
    let mut p2 = TestBlobParts::new(9, 3, 2, 6, 1.5);
    let k = 2;
    p2.unc = (0..2 * k * 9).map(|i| 0.01 + 0.001 * i as f32).collect();
    p2.mats = (0..2 * k * 9 * 3).map(|i| ((i as f32) * 0.37).sin() * 0.25).collect();
    let centroids: Vec<f32> = (0..2 * k * 3).map(|i| 0.2 + 0.05 * i as f32).collect();
    let oop: Vec<f32> = (0..2 * (2 + 3)).map(|i| 0.5 + 0.125 * i as f32).collect();
    let mut c2 = p2.contents();
    c2.estimator = EstimatorKind::ScaleFreePiecewise;
    let ex = BlobExtras {
        clusters: k,
        centroids: &centroids,
        out_of_prior: Some(OutOfPriorData {
            threshold: 9.5,
            form: OutOfPriorForm::Linear,
            data: &oop,
            band_factor: 1.0,
        }),
        ..BlobExtras::NONE
    };
    let mut b2 = vec![0u8; p2.dims.blob_len_with(&ex)];
    let n = write_blob_with(&c2, &ex, &mut b2).expect("a valid format 2 blob");
    b2.truncate(n);
    out.push(("blob.v2".into(), b2));
    // The same with the log-ratio out-of-prior statistic (flag bit 4).
    let ex = BlobExtras {
        out_of_prior: Some(OutOfPriorData {
            threshold: 1.0,
            form: OutOfPriorForm::LogRatio,
            data: &oop,
            band_factor: 1.0,
        }),
        ..ex
    };
    let mut b2 = vec![0u8; p2.dims.blob_len_with(&ex)];
    let n = write_blob_with(&c2, &ex, &mut b2).expect("a valid format 2 blob");
    b2.truncate(n);
    out.push(("blob.v2.log-ratio".into(), b2));
    // The same with the second per-bin uncertainty table, for broad
    // estimates (flag bit 8, Z x K x n before the CRC).
    let broad: Vec<f32> = (0..2 * k * 9).map(|i| 0.005 + 0.0005 * i as f32).collect();
    let exb = BlobExtras { broad_uncertainty: &broad, ..ex };
    let mut b2 = vec![0u8; p2.dims.blob_len_with(&exb)];
    let n = write_blob_with(&c2, &exb, &mut b2).expect("a valid format 2 blob with the broad table");
    b2.truncate(n);
    out.push(("blob.v2.broad-band".into(), b2));
    // Format 3: a Wiener blob with the gloss section.
    let p3 = TestBlobParts::new(9, 3, 2, 6, 0.75);
    let reference = [84.5f32, 91.25];
    let blocks: Vec<f32> = (0..2 * brdf_meter::gloss::block_len(3)).map(|i| 0.125 * (i % 9) as f32).collect();
    let ex3 = BlobExtras {
        gloss: Some(brdf_meter::blob::GlossData {
            assigned_gu: 100.0,
            refractive_index: 1.567,
            reference: &reference,
            blocks: &blocks,
            centroids: &[],
            root_readings: brdf_meter::gloss::RootReadings::Shoulders,
        }),
        ..BlobExtras::NONE
    };
    let mut b3 = vec![0u8; p3.dims.blob_len_with(&ex3)];
    let n = write_blob_with(&p3.contents(), &ex3, &mut b3).expect("a valid format 3 blob");
    b3.truncate(n);
    out.push(("blob.v3".into(), b3));
    // The same with the peak resolution in the header (flag bit 6, offset 60).
    let ex3r = BlobExtras { peak_resolution_deg: Some(0.8125), ..ex3 };
    let mut b3r = vec![0u8; p3.dims.blob_len_with(&ex3r)];
    let n = write_blob_with(&p3.contents(), &ex3r, &mut b3r).expect("a valid format 3 blob with the peak resolution");
    b3r.truncate(n);
    out.push(("blob.v3.peak-resolution".into(), b3r));
    // The same with each pixel's own resolution after the gloss section
    // (flag bit 7; NaN: the pixel takes the header's).
    let own = [0.8125f32, 0.5, f32::NAN, 0.75, 0.625, 0.8125];
    let ex3p = BlobExtras { pixel_peak_resolution_deg: &own, ..ex3r };
    let mut b3p = vec![0u8; p3.dims.blob_len_with(&ex3p)];
    let n = write_blob_with(&p3.contents(), &ex3p, &mut b3p).expect("a valid format 3 blob with per-pixel resolutions");
    b3p.truncate(n);
    out.push(("blob.v3.pixel-peak-resolution".into(), b3p));
    // Format 4 (a gloss reference per pixel): the piecewise blob above with
    // a gloss section whose rows have 3 clusters of their own (flag bit 9,
    // K_g at offset 50, their centroids after the blocks).
    let kg = 3;
    let reference4: Vec<f32> = (0..6).map(|p| 88.0 + 0.5 * p as f32).collect();
    let blocks4: Vec<f32> = (0..2 * kg * brdf_meter::gloss::block_len(3)).map(|i| 0.0625 * (i % 13) as f32).collect();
    let centroids4: Vec<f32> = (0..2 * kg * 3).map(|i| 0.25 + 0.03125 * i as f32).collect();
    let g4 = brdf_meter::blob::GlossData {
        assigned_gu: 100.0,
        refractive_index: 1.567,
        reference: &reference4,
        blocks: &blocks4,
        centroids: &centroids4,
        root_readings: brdf_meter::gloss::RootReadings::Shoulders,
    };
    let ex4 = BlobExtras { gloss: Some(g4), ..exb };
    let mut b4 = vec![0u8; p2.dims.blob_len_with(&ex4)];
    let n = write_blob_with(&c2, &ex4, &mut b4).expect("a valid format 4 blob with the gloss rows' own clusters");
    b4.truncate(n);
    out.push(("blob.v4.gloss-clusters".into(), b4));
    // The same in the root form (flag bit 3) whose gloss rows read the
    // peak's deficit over its shoulders (flag bit 10): same layout.
    let ex4d = BlobExtras {
        root_form: true,
        gloss: Some(brdf_meter::blob::GlossData { root_readings: brdf_meter::gloss::RootReadings::Deficit, ..g4 }),
        ..ex4
    };
    let mut b4d = vec![0u8; p2.dims.blob_len_with(&ex4d)];
    let n = write_blob_with(&c2, &ex4d, &mut b4d).expect("a valid root-form format 4 blob with the deficit row");
    b4d.truncate(n);
    out.push(("blob.v4.root-deficit-readings".into(), b4d));
    // The same with the sensor's linearity correction (flag bit 11, 17
    // factors before the CRC).
    let factors: [f32; brdf_meter::acquire::linearity::LINEARITY_KNOTS] =
        core::array::from_fn(|k| 1.0625 - 0.00390625 * k as f32);
    let ex4l = BlobExtras {
        linearity: Some(brdf_meter::acquire::Linearity::new(factors).expect("a valid correction")),
        ..ex4d
    };
    let mut b4l = vec![0u8; p2.dims.blob_len_with(&ex4l)];
    let n = write_blob_with(&c2, &ex4l, &mut b4l).expect("a valid format 4 blob with the linearity correction");
    b4l.truncate(n);
    out.push(("blob.v4.sensor-linearity".into(), b4l));
    // The same with its peak resolution (flag bit 6) and the factors on a
    // resolved peak's uncertainties (flag bit 12, height and width after
    // the linearity correction).
    let ex4f = BlobExtras {
        peak_resolution_deg: Some(0.8125),
        peak_factors: Some(brdf_meter::blob::PeakFactors { height: 1.25, width: 2.5 }),
        ..ex4l
    };
    let mut b4f = vec![0u8; p2.dims.blob_len_with(&ex4f)];
    let n = write_blob_with(&c2, &ex4f, &mut b4f).expect("a valid format 4 blob with the peak's factors");
    b4f.truncate(n);
    out.push(("blob.v4.peak-factors".into(), b4f));

    // The inspection recipe: 6 pixels, 3 readings, 2 groups.
    out.push(("recipe.v1".into(), golden_recipe(false)));
    out.push(("recipe.v2".into(), golden_recipe(true)));

    // The store's slot header.
    out.push(("slot_header".into(), encode_slot_header(7, 4096, 0x1234_5678).to_vec()));

    // One frame of every request.
    let chunk = [0u8, 1, 2, 255];
    let px = [1u8, 0, 255, 255];
    let requests = [
        Request::Info,
        Request::Status,
        Request::ProvisionBegin { len: 11_000, crc: 0xCAFE_F00D },
        Request::ProvisionChunk { offset: 512, data: &chunk },
        Request::ProvisionCommit,
        Request::ProvisionAbort,
        Request::Measure { lines: 3, format: StreamFormat::default() },
        Request::Stop,
        Request::SimFrame { line: 1, frame: 2, first_pixel: 16, pixels: LeBytes(&px) },
        Request::SimLines { lines: 4 },
        Request::FirmwareInfo,
        Request::UpdateBegin { len: 72_888, crc: 0x0BAD_CAFE },
        Request::UpdateChunk { offset: 1024, data: &[0, 1, 2, 3, 4, 5, 6, 7] },
        Request::UpdateCommit,
        Request::UpdateAbort,
        Request::Reboot,
        Request::RecipeBegin { len: 2_700, crc: 0x00DD_BA11 },
        Request::RecipeChunk { offset: 512, data: &chunk },
        Request::RecipeCommit,
        Request::RecipeAbort,
        Request::Inspect { lines: 0, defect_points: true, format: StreamFormat::default() },
        Request::InspectStatus,
    ];
    for r in &requests {
        out.push((format!("request.{}", request_name(r)), request_frame(42, r)));
    }
    // The measure request with every encoding and a bin subset.
    for (name, encoding) in [("F32", Encoding::F32), ("Corrected", Encoding::Corrected)] {
        let m = Request::Measure { lines: 0, format: StreamFormat { encoding, bins: None } };
        out.push((format!("request.Measure.{name}"), request_frame(42, &m)));
    }
    let subset = StreamFormat { encoding: Encoding::Sigma16, bins: Some(BinRange { first: 2, step: 3, count: 20 }) };
    out.push(("request.Measure.bins".into(), request_frame(42, &Request::Measure { lines: 1, format: subset })));

    // One frame of every response, and of every device error.
    let vals: Vec<u8> = [0.5f32, -0.0, 1.25e-3].iter().flat_map(|x| x.to_le_bytes()).collect();
    let mut responses = vec![
        Response::Info(DeviceInfo {
            protocol: brdf_meter::protocol::PROTOCOL_VERSION,
            firmware: [0, 1, 0],
            bins: 81,
            leds: 7,
            pixels: 32,
            full_scale: 65535,
            max_blob: 16_352,
            ram_matrix_words: 2268,
            simulated: true,
            calibration: Some(cal()),
        }),
        Response::Status(DeviceStatus {
            measuring: true,
            lines_total: 5,
            provisioning: Some(77),
            bad_frames: 2,
            refused: 1,
            calibration: Some(cal()),
        }),
        Response::ProvisionReady { slot: 1, max_chunk: 512 },
        Response::ChunkAck { next_offset: 1024 },
        Response::Committed(cal()),
        Response::Aborted,
        Response::MeasureStarted { lines: 3 },
        Response::StopRequested,
        Response::MeasureDone { lines_done: 3 },
        Response::SimLoaded,
        Response::Point(PointFrame {
            line: 4,
            seq: 99,
            point: 31,
            zone: 3,
            cluster: 1,
            flags: flags::SATURATED | flags::OUT_OF_PRIOR,
            sigma_scale: 2.5,
            readings: [87.25, 3.5, f32::NAN],
            reading_sigma: [0.75, 0.125, f32::NAN],
            values: LeBytes(&vals),
        }),
        Response::Firmware(brdf_meter::protocol::FirmwareInfo {
            version: [0, 2, 0],
            target: brdf_meter::firmware::image::Target::Board,
            boot: brdf_meter::protocol::BootState::Trial,
            self_test: brdf_meter::protocol::SelfTest { store: true, sensor: false, link: true },
            updates: true,
            max_image: 163_840,
            receiving: Some(4096),
            pending: None,
            blob_formats: [1, 3],
            trusted_count: 1,
            trusted: [[1, 2, 3, 4, 5, 6, 7, 8], [0; 8], [0; 8], [0; 8]],
            trusts_development_key: true,
            refused: Some(DeviceError::FirmwareRejected(brdf_meter::firmware::image::ImageFault::WrongTarget)),
        }),
        Response::UpdateReady { next_offset: 2048, max_chunk: 512 },
        Response::UpdateCommitted { version: [0, 2, 0] },
        Response::Rebooting,
        Response::RecipeCommitted(recipe_info()),
        Response::Verdict(verdict()),
        Response::RejectPulse { line: 17, start_us: 1_234_567, len_us: 25_000 },
        Response::Inspection(brdf_meter::protocol::InspectStatus {
            recipe: Some(recipe_info()),
            refused: None,
            inspecting: true,
            counters: brdf_meter::inspect::InspectCounters {
                lines: 100,
                rejected: 3,
                defects: 4,
                drift_alarms: 1,
                pulses: 3,
            },
        }),
    ];
    for e in [
        DeviceError::Frame(FrameError::Truncated { declared: 30, got: 12 }),
        DeviceError::NoCalibration,
        DeviceError::Busy,
        DeviceError::NotProvisioning,
        DeviceError::OutOfOrder { expected: 512, got: 1024 },
        DeviceError::ChunkTooLarge { max: 512 },
        DeviceError::BlobTooLarge { len: 1 << 20, max: 16_352 },
        DeviceError::Incomplete { received: 5, len: 10 },
        DeviceError::CrcMismatch { declared: 1, computed: 2 },
        DeviceError::BlobRejected { fault: BlobFault::NonFinite, section: Some(Section::Matrices), detail: 3 },
        DeviceError::Mismatch { field: SizeField::Pixels, device: 32, blob: 16 },
        DeviceError::Storage,
        DeviceError::Sensor(SensorError::NoData),
        DeviceError::Simulation,
        DeviceError::SignatureRejected(brdf_meter::signed::SignatureFault::UnknownKey),
        DeviceError::BadBins { bins: 81 },
        DeviceError::FirmwareRejected(brdf_meter::firmware::image::ImageFault::Signature(
            brdf_meter::signed::SignatureFault::BadSignature,
        )),
        DeviceError::Update(brdf_meter::protocol::UpdateFault::TooLarge { len: 200_000, max: 163_840 }),
        DeviceError::CalibrationUnsupported { format: 4, oldest: 1, newest: 3 },
        DeviceError::RecipeRejected(brdf_meter::inspect::RecipeFault::WrongShape),
        DeviceError::RecipeForOtherCalibration { recipe: 0xDEAD_BEEF, active: 0x1234_5678 },
        DeviceError::NoRecipe,
    ] {
        responses.push(Response::Error(e));
    }
    // Line frames of every encoding: two points each, as the device's
    // builder makes them (9 bins, 3 readings, one bin subset).
    let blocks: Vec<PointsBlock> = [
        (Encoding::F32, BinRange::all(9)),
        (Encoding::Sigma16, BinRange { first: 1, step: 2, count: 4 }),
        (Encoding::Corrected, BinRange::all(9)),
    ]
    .into_iter()
    .map(|(encoding, bins)| {
        let mut b = PointsBlock::new();
        b.start(4, 99, 30, 0xDEAD_BEEF, encoding, bins, 3);
        for k in 0..2u16 {
            let values: Vec<f32> = (0..9).map(|j| 0.5 - 0.125 * (j + k) as f32).collect();
            let sigma: Vec<f32> = (0..9).map(|j| 0.01 + 0.002 * j as f32).collect();
            let meta = PointMetaWire {
                zone: 3 + k,
                cluster: 1,
                flags: if k == 0 { 0 } else { flags::OUT_OF_PRIOR },
                sigma_scale: 2.5,
                readings: [97.5, 1.25, 80.0],
                reading_sigma: [0.5, 0.125, 2.0],
            };
            b.push(&PointIn { meta, values: &values, readings: &[0.25, 1.5, -0.0], sigma: &sigma })
                .expect("two points fit");
        }
        b
    })
    .collect();
    for b in &blocks {
        responses.push(Response::Points(b.frame()));
    }
    for r in &responses {
        out.push((format!("response.{}", response_name(r)), response_frame(7, r)));
    }
    out
}

#[test]
fn encodings_match_the_golden_bytes() {
    let text: String = encodings().iter().map(|(name, b)| format!("{name}: {}\n", hex(b))).collect();
    let path = golden_path();
    if std::env::var_os(REGENERATE).is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        let tmp = path.with_extension("txt.tmp");
        std::fs::write(&tmp, &text).unwrap();
        std::fs::rename(&tmp, &path).unwrap();
        eprintln!("regenerated {}", path.display());
        return;
    }
    let golden = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e}; generate it with {REGENERATE}=1 cargo test --release -p system-tests --test system -- golden_bytes::",
            path.display()
        )
    });
    let want: Vec<(&str, &str)> = golden.lines().filter_map(|l| l.split_once(": ")).collect();
    let got: Vec<(String, String)> = encodings().into_iter().map(|(n, b)| (n, hex(&b))).collect();
    let names_want: Vec<&str> = want.iter().map(|(n, _)| *n).collect();
    let names_got: Vec<&str> = got.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names_got, names_want,
        "the set of pinned encodings changed (a new message or error variant?): bump the protocol version and regenerate with {REGENERATE}=1"
    );
    for ((name, g), (_, w)) in got.iter().zip(&want) {
        assert_eq!(
            g, w,
            "the encoding of `{name}` changed: bump the version of its format (blob::FORMAT_VERSION, store::SLOT_VERSION or \
             protocol::PROTOCOL_VERSION) and regenerate with {REGENERATE}=1 cargo test --release -p system-tests --test system -- golden_bytes::"
        );
    }
}

/// The fuzz corpus's seeds named `golden-<name>` (`tests/fuzz/corpus/frame_decode/`)
/// are the golden frames of those names without their delimiter. A seed of
/// an older protocol version only reaches the version check, never the
/// decoder of the bodies it was put there for, so the seeds follow the
/// golden bytes: regenerating these rewrites them too.
#[test]
fn fuzz_seeds_of_golden_frames_are_the_golden_frames() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus/frame_decode");
    let golden: Vec<(String, Vec<u8>)> = encodings();
    let mut seeds: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.starts_with("golden-")))
        .collect();
    seeds.sort();
    assert!(!seeds.is_empty(), "{}: no golden-* seeds", dir.display());
    for seed in &seeds {
        let stem = seed.file_name().unwrap().to_str().unwrap().trim_start_matches("golden-");
        let name = stem.replace('-', ".");
        let (_, frame) = golden
            .iter()
            .find(|(n, _)| *n == name)
            .unwrap_or_else(|| panic!("{}: no golden encoding named {name}", seed.display()));
        let want = &frame[..frame.len() - 1]; // without the 0x00 delimiter
        if std::env::var_os(REGENERATE).is_some() {
            host_tools::output::io::write_atomic(seed, want).unwrap();
            continue;
        }
        let got = std::fs::read(seed).unwrap();
        assert!(
            got == want,
            "{}: not the golden frame `{name}` of this protocol version; regenerate with {REGENERATE}=1 cargo test \
             --release -p system-tests --test system -- golden_bytes::",
            seed.display()
        );
    }
}
