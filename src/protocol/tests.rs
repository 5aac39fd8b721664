//! Round trips and wire bytes of every message, framing and its errors.
use super::framing::cobs_encode;
use super::*;
use crate::blob::BlobError;
use crate::hw::SensorError;
use serde::Serialize;

fn frame_of<T: Serialize>(seq: u32, msg: &T) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME];
    let n = encode(seq, msg, &mut out).unwrap();
    assert_eq!(out[n - 1], 0);
    assert!(out[..n - 1].iter().all(|b| *b != 0), "COBS leaves no zero inside a frame");
    out[..n].to_vec()
}

fn round_trip_req(req: Request<'_>) {
    let mut f = frame_of(42, &req);
    f.pop();
    let (seq, back): (u32, Request<'_>) = decode(&mut f).unwrap();
    assert_eq!(seq, 42);
    assert_eq!(back, req);
}

fn round_trip_resp(resp: Response<'_>) {
    let mut f = frame_of(7, &resp);
    f.pop();
    let (seq, back): (u32, Response<'_>) = decode(&mut f).unwrap();
    assert_eq!(seq, 7);
    assert_eq!(back, resp);
}

fn cal() -> CalInfo {
    CalInfo { slot: 1, sequence: 9, blob_crc: 0xDEAD_BEEF, blob_len: 11_000, zones: 4, in_ram: true }
}

#[test]
fn every_request_round_trips() {
    let chunk = [0u8, 1, 2, 255, 0, 0];
    let px = [1u16, 0, 65535, 300];
    for req in [
        Request::Info,
        Request::Status,
        Request::ProvisionBegin { len: 123_456, crc: 0x1234_5678 },
        Request::ProvisionChunk { offset: 512, data: &chunk },
        Request::ProvisionChunk { offset: 0, data: &[0xAB; MAX_CHUNK] },
        Request::ProvisionCommit,
        Request::ProvisionAbort,
        Request::Measure { lines: 0, format: StreamFormat::default() },
        Request::Measure { lines: u32::MAX, format: StreamFormat::LOSSLESS },
        Request::Measure {
            lines: 1,
            format: StreamFormat {
                encoding: Encoding::Corrected,
                bins: Some(BinRange { first: 3, step: 2, count: 10 }),
            },
        },
        Request::Stop,
        Request::SimFrame { line: 3, frame: 7, first_pixel: 96, pixels: LeBytes::from_u16(&px) },
        Request::SimLines { lines: 2 },
    ] {
        round_trip_req(req);
    }
}

#[test]
fn every_response_round_trips() {
    let vals = [0.5f32, -0.0, f32::MAX, f32::MIN_POSITIVE, 1.0e-40, f32::NAN];
    let status = DeviceStatus {
        measuring: true,
        lines_total: 5,
        provisioning: Some(77),
        bad_frames: 2,
        refused: 1,
        calibration: Some(cal()),
    };
    let errors = [
        DeviceError::Frame(FrameError::Truncated { declared: 30, got: 12 }),
        DeviceError::Frame(FrameError::UnsupportedVersion { got: 9 }),
        DeviceError::NoCalibration,
        DeviceError::Busy,
        DeviceError::NotProvisioning,
        DeviceError::OutOfOrder { expected: 512, got: 1024 },
        DeviceError::ChunkTooLarge { max: 512 },
        DeviceError::BlobTooLarge { len: 1 << 20, max: 12_000 },
        DeviceError::Incomplete { received: 5, len: 10 },
        DeviceError::CrcMismatch { declared: 1, computed: 2 },
        DeviceError::BlobRejected { fault: BlobFault::NonFinite, section: Some(BlobSection::Matrices), detail: 3 },
        DeviceError::Mismatch { field: SizeField::Pixels, device: 32, blob: 16 },
        DeviceError::Storage,
        DeviceError::Sensor(SensorError::NoData),
        DeviceError::Simulation,
        DeviceError::SignatureRejected(crate::signed::SignatureFault::UnknownKey),
    ];
    let mut all = vec![
        Response::Info(DeviceInfo {
            protocol: PROTOCOL_VERSION,
            firmware: [0, 1, 0],
            bins: 81,
            leds: 7,
            pixels: 32,
            full_scale: 4095,
            max_blob: 12_000,
            ram_matrix_words: 9072,
            simulated: true,
            calibration: None,
        }),
        Response::Status(status),
        Response::Status(DeviceStatus::default()),
        Response::ProvisionReady { slot: 1, max_chunk: MAX_CHUNK as u16 },
        Response::ChunkAck { next_offset: 1024 },
        Response::Committed(cal()),
        Response::Aborted,
        Response::MeasureStarted { lines: 3 },
        Response::MeasureDone { lines_done: 3 },
        Response::StopRequested,
        Response::SimLoaded,
    ];
    all.extend(errors.map(Response::Error));
    for r in all {
        round_trip_resp(r);
    }
    // Point frames carry their values bit for bit, NaN and -0.0 included.
    let p = Response::Point(PointFrame {
        line: 4,
        seq: 99,
        point: 31,
        zone: 3,
        cluster: 2,
        flags: flags::SATURATED | flags::NON_FINITE | flags::OUT_OF_PRIOR,
        sigma_scale: 0.375,
        readings: [97.5, f32::NAN, -0.0],
        reading_sigma: [0.25, f32::NAN, 1.5],
        values: LeBytes::from_f32(&vals),
    });
    let mut f = frame_of(1, &p);
    f.pop();
    let (_, back): (u32, Response<'_>) = decode(&mut f).unwrap();
    let Response::Point(pf) = back else { panic!("not a point") };
    let bits: Vec<u32> = pf.values.f32s().map(f32::to_bits).collect();
    assert_eq!(bits, vals.map(f32::to_bits));
    assert_eq!((pf.line, pf.seq, pf.point, pf.zone, pf.cluster, pf.sigma_scale), (4, 99, 31, 3, 2, 0.375));
    assert_eq!(pf.flags, flags::SATURATED | flags::NON_FINITE | flags::OUT_OF_PRIOR);
    assert_eq!(pf.readings.map(f32::to_bits), [97.5, f32::NAN, -0.0].map(f32::to_bits));
    assert_eq!(pf.reading_sigma.map(f32::to_bits), [0.25, f32::NAN, 1.5].map(f32::to_bits));
}

#[test]
fn largest_point_frame_fits() {
    let vals = [1.0f32; MAX_WIRE_BINS];
    let p = Response::Point(PointFrame {
        line: u32::MAX,
        seq: u32::MAX,
        point: u16::MAX,
        zone: u16::MAX,
        cluster: u8::MAX,
        flags: 0xFF,
        sigma_scale: f32::MAX,
        readings: [f32::MAX; crate::shape::READINGS],
        reading_sigma: [f32::MAX; crate::shape::READINGS],
        values: LeBytes::from_f32(&vals),
    });
    let mut out = [0u8; MAX_FRAME];
    encode(u32::MAX, &p, &mut out).unwrap();
    let big = Request::ProvisionChunk { offset: u32::MAX, data: &[0xFF; MAX_CHUNK] };
    encode(u32::MAX, &big, &mut out).unwrap();
    let sim = Request::SimFrame { line: 255, frame: 255, first_pixel: 65535, pixels: LeBytes(&[0xFF; MAX_SIM_BYTES]) };
    encode(u32::MAX, &sim, &mut out).unwrap();
}

#[test]
fn every_truncation_is_a_typed_error() {
    let chunk = [7u8; 40];
    let f = frame_of(3, &Request::ProvisionChunk { offset: 8, data: &chunk });
    for cut in 1..f.len() - 1 {
        let mut t = f[..cut].to_vec();
        let r: Result<(u32, Request<'_>), _> = decode(&mut t);
        assert!(
            matches!(r, Err(FrameError::Truncated { .. } | FrameError::Cobs | FrameError::BadCrc)),
            "cut at {cut}: {r:?}"
        );
    }
    // A cut that keeps the COBS structure valid is reported as truncated.
    let mut raw = [0u8; MAX_PAYLOAD];
    let mut enc = [0u8; MAX_FRAME];
    let n = encode(3, &Request::Measure { lines: 2, format: StreamFormat::LOSSLESS }, &mut enc).unwrap();
    let m = cobs::decode(&enc[..n - 1], &mut raw).unwrap();
    let mut re = [0u8; MAX_FRAME];
    let k = cobs::encode(&raw[..m - 2], &mut re);
    let r: Result<(u32, Request<'_>), _> = decode(&mut re[..k]);
    assert_eq!(r, Err(FrameError::Truncated { declared: m as u16, got: (m - 2) as u16 }));
}

#[test]
fn every_single_byte_corruption_is_a_typed_error() {
    let f = frame_of(3, &Request::ProvisionBegin { len: 1000, crc: 5 });
    for pos in 0..f.len() - 1 {
        for x in [0x01u8, 0x80, 0xFF] {
            let mut t = f[..f.len() - 1].to_vec();
            t[pos] ^= x;
            if t[pos] == 0 {
                continue; // a zero byte is a delimiter: it splits the frame, tested elsewhere
            }
            let r: Result<(u32, Request<'_>), _> = decode(&mut t);
            assert!(r.is_err(), "corruption at {pos} accepted: {r:?}");
        }
    }
}

#[test]
fn wrong_version_is_reported_before_the_body() {
    let mut raw = [0u8; 32];
    let other = PROTOCOL_VERSION + 1;
    raw[0..2].copy_from_slice(&other.to_le_bytes());
    raw[2..4].copy_from_slice(&13u16.to_le_bytes());
    raw[8] = 0xEE; // not a variant of this version
    let crc = crate::blob::CRC32.checksum(&raw[..9]);
    raw[9..13].copy_from_slice(&crc.to_le_bytes());
    let mut enc = [0u8; 64];
    let k = cobs::encode(&raw[..13], &mut enc);
    let r: Result<(u32, Request<'_>), _> = decode(&mut enc[..k]);
    assert_eq!(r, Err(FrameError::UnsupportedVersion { got: other }));
}

#[test]
fn unknown_variant_and_trailing_bytes_are_malformed() {
    for body in [&[0xEEu8][..], &[0u8, 0][..]] {
        let mut raw = [0u8; 32];
        let len = 8 + body.len() + 4;
        raw[0..2].copy_from_slice(&PROTOCOL_VERSION.to_le_bytes());
        raw[2..4].copy_from_slice(&(len as u16).to_le_bytes());
        raw[8..8 + body.len()].copy_from_slice(body);
        let crc = crate::blob::CRC32.checksum(&raw[..len - 4]);
        raw[len - 4..len].copy_from_slice(&crc.to_le_bytes());
        let mut enc = [0u8; 64];
        let k = cobs::encode(&raw[..len], &mut enc);
        let r: Result<(u32, Request<'_>), _> = decode(&mut enc[..k]);
        assert_eq!(r, Err(FrameError::Malformed), "body {body:?}");
    }
}

#[test]
fn reader_splits_frames_and_survives_oversized_garbage() {
    let a = frame_of(1, &Request::Info);
    let b = frame_of(2, &Request::Status);
    let mut stream = vec![0u8, 0];
    stream.extend_from_slice(&a);
    stream.extend(core::iter::repeat_n(0x55, MAX_FRAME * 3));
    stream.push(0);
    stream.extend_from_slice(&b);
    let mut rd = FrameReader::new();
    let mut got = Vec::new();
    for byte in stream {
        match rd.push(byte) {
            Pushed::More => {}
            Pushed::Oversized => got.push(Err(FrameError::Oversized)),
            Pushed::Frame(f) => {
                let r: Result<(u32, Request<'_>), _> = decode(f);
                got.push(r.map(|(s, _)| s));
            }
        }
    }
    assert_eq!(got, vec![Ok(1), Err(FrameError::Oversized), Ok(2)]);
}

#[test]
fn too_large_a_message_is_refused_by_the_sender() {
    let big = [0u8; MAX_PAYLOAD];
    let mut out = [0u8; MAX_FRAME];
    assert_eq!(encode(0, &Request::ProvisionChunk { offset: 0, data: &big }, &mut out), Err(FrameError::TooLarge));
}

#[test]
fn blob_errors_map_to_typed_faults() {
    let e: DeviceError = BlobError::NonFinite { section: BlobSection::White, index: 12 }.into();
    assert_eq!(
        e,
        DeviceError::BlobRejected { fault: BlobFault::NonFinite, section: Some(BlobSection::White), detail: 12 }
    );
}

fn meta(k: u16) -> PointMetaWire {
    PointMetaWire {
        zone: k,
        cluster: 1,
        flags: flags::OUT_OF_PRIOR,
        sigma_scale: -1.5,
        readings: [97.5, f32::NAN, 1.0],
        reading_sigma: [0.5, f32::NAN, 0.25],
    }
}

#[test]
fn line_frames_of_every_encoding_round_trip_and_fill_the_payload() {
    let n = crate::shape::BINS;
    let m = crate::shape::LEDS;
    let values: Vec<f32> = (0..n).map(|j| (j as f32 * 0.37).sin() * 40.0).collect();
    let sigma: Vec<f32> = (0..n).map(|j| 0.5 + 0.01 * j as f32).collect();
    let readings: Vec<f32> = (0..m).map(|i| 0.1 * i as f32).collect();
    for (encoding, bins, per_frame) in [
        (Encoding::F32, BinRange::all(n), 2),
        (Encoding::Sigma16, BinRange::all(n), 5),
        (Encoding::Sigma16, BinRange { first: 10, step: 10, count: 7 }, 21),
        (Encoding::Corrected, BinRange::all(n), 16),
    ] {
        let mut b = PointsBlock::new();
        b.start(7, 1000, 5, 0xABCD_0123, encoding, bins, m);
        let mut k = 0u16;
        let pin = |k: u16| PointIn { meta: meta(k), values: &values, readings: &readings, sigma: &sigma };
        while b.push(&pin(k)).is_ok() {
            k += 1;
        }
        assert_eq!(b.push(&pin(k)), Err(PushError::Full));
        assert_eq!((b.len(), encoding), (per_frame, encoding), "points per frame");
        // A full frame encodes within MAX_PAYLOAD.
        let mut f = frame_of(3, &Response::Points(b.frame()));
        f.pop();
        let (_, back): (u32, Response<'_>) = decode(&mut f).unwrap();
        let Response::Points(pf) = back else { panic!("not a line frame") };
        assert_eq!(pf, b.frame());
        let recs: Vec<_> = pf.records(n, m).unwrap().collect();
        assert_eq!(recs.len(), per_frame);
        for (k, (mw, data)) in recs.iter().enumerate() {
            let want = meta(k as u16);
            assert_eq!((mw.zone, mw.cluster, mw.flags, mw.sigma_scale), (want.zone, 1, flags::OUT_OF_PRIOR, -1.5));
            assert_eq!(mw.readings.map(f32::to_bits), want.readings.map(f32::to_bits));
            match encoding {
                Encoding::F32 => {
                    let got: Vec<f32> = LeBytes(data).f32s().collect();
                    assert_eq!(got, values);
                }
                Encoding::Sigma16 => {
                    for (q, j) in data.chunks_exact(2).zip(bins.bins()) {
                        let u = point_uncertainty(sigma[j], -1.5);
                        let step = sigma16_step(u).unwrap();
                        let back = i16::from_le_bytes([q[0], q[1]]) as f32 * step;
                        assert!((back - values[j]).abs() <= u / 256.0, "bin {j}: {back} vs {}", values[j]);
                    }
                }
                Encoding::Corrected => assert_eq!(LeBytes(data).f32s().collect::<Vec<_>>(), readings),
            }
        }
    }
}

#[test]
fn sigma16_steps_are_powers_of_two_between_a_256th_and_a_128th_of_the_uncertainty() {
    for u in [1e-30f32, 3.0e-3, 0.125, 0.2, 1.0, 7.9, 1e20] {
        let s = sigma16_step(u).unwrap();
        assert_eq!(s.to_bits() & 0x007f_ffff, 0, "a power of two");
        assert!(s <= u / 128.0 && s > u / 256.0, "u {u}: step {s}");
    }
    for bad in [0.0f32, -1.0, f32::NAN, f32::INFINITY, 1e-40, 1e-36] {
        assert_eq!(sigma16_step(bad), None, "{bad}");
    }
    assert_eq!(sigma16_quantise(2.5, 1.0), Some(3));
    assert_eq!(sigma16_quantise(-2.5, 1.0), Some(-3));
    assert_eq!(sigma16_quantise(32767.4, 1.0), Some(32767));
    assert_eq!(sigma16_quantise(32768.0, 1.0), None);
    assert_eq!(sigma16_quantise(f32::NAN, 1.0), None);
}

#[test]
fn a_point_sigma16_cannot_carry_is_refused_and_the_block_left_unchanged() {
    let values = [1.0f32, 1.0e6, 0.5];
    let sigma = [0.1f32, 0.1, 0.1];
    let mut b = PointsBlock::new();
    b.start(0, 0, 0, 1, Encoding::Sigma16, BinRange::all(3), 2);
    let ok = PointIn { meta: meta(0), values: &[1.0, 2.0, 3.0], readings: &[1.0, 2.0], sigma: &sigma };
    b.push(&ok).unwrap();
    let before = b.frame().data.0.to_vec();
    let huge = PointIn { meta: meta(1), values: &values, readings: &[1.0, 2.0], sigma: &sigma };
    assert_eq!(b.push(&huge), Err(PushError::NotRepresentable));
    let no_sigma = PointIn { meta: meta(1), values: &[0.0; 3], readings: &[1.0, 2.0], sigma: &[] };
    assert_eq!(b.push(&no_sigma), Err(PushError::NotRepresentable));
    assert_eq!((b.len(), b.frame().data.0), (1, &before[..]));
}

#[test]
fn bin_ranges_are_checked_against_the_bins() {
    assert!(BinRange::all(81).fits(81));
    assert!(BinRange { first: 80, step: 5, count: 1 }.fits(81));
    assert!(BinRange { first: 0, step: 10, count: 9 }.fits(81));
    assert!(!BinRange { first: 0, step: 10, count: 10 }.fits(81));
    assert!(!BinRange { first: 0, step: 0, count: 2 }.fits(81));
    assert!(!BinRange { first: 0, step: 1, count: 0 }.fits(81));
    assert!(!BinRange { first: 81, step: 1, count: 1 }.fits(81));
    assert_eq!(BinRange { first: 2, step: 3, count: 3 }.bins().collect::<Vec<_>>(), [2, 5, 8]);
}

#[test]
fn the_run_wise_cobs_encoder_gives_the_cobs_crates_bytes() {
    let mut x = 0x1234_5678u32;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        x
    };
    let mut inputs: Vec<Vec<u8>> = vec![vec![], vec![0], vec![0, 0], vec![1], vec![1; 253], vec![1; 254], vec![1; 255]];
    inputs.push([vec![1; 254], vec![0]].concat());
    inputs.push([vec![0], vec![7; 508], vec![0]].concat());
    for _ in 0..2000 {
        let len = (next() % 700) as usize;
        // Zeros now dense, now rare, so runs of every length up to 254 and beyond occur.
        let density = 1 + next() % 400;
        inputs.push((0..len).map(|_| if next() % density == 0 { 0 } else { 1 + (next() % 255) as u8 }).collect());
    }
    for src in inputs {
        let mut want = vec![0u8; src.len() + src.len() / 254 + 2];
        let n = cobs::encode(&src, &mut want);
        let mut got = vec![0u8; src.len() + src.len() / 254 + 2];
        let m = cobs_encode(&src, &mut got).unwrap();
        assert_eq!(got[..m], want[..n], "input of {} bytes", src.len());
        if m > 0 {
            assert_eq!(cobs_encode(&src, &mut got[..m - 1]), None, "too small a buffer is refused");
        }
    }
}

#[test]
fn the_devices_sigma16_path_rounds_as_the_definition_does() {
    let mut x = 0x9E37_79B9u32;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        f32::from_bits(x)
    };
    let mut checked = 0;
    for _ in 0..200_000 {
        let (v, u) = (next(), next().abs());
        let want = sigma16_step(u).and_then(|s| sigma16_quantise(v, s));
        let values = [v];
        let sigma = [u];
        let mut b = PointsBlock::new();
        b.start(0, 0, 0, 0, Encoding::Sigma16, BinRange::all(1), 1);
        let mut m = meta(0);
        m.sigma_scale = 1.0;
        let got = b.push(&PointIn { meta: m, values: &values, readings: &[0.0], sigma: &sigma });
        match want {
            Some(q) => {
                assert_eq!(got, Ok(()));
                assert_eq!(b.frame().data.0, q.to_le_bytes());
                checked += 1;
            }
            None => assert_eq!(got, Err(PushError::NotRepresentable), "v {v:e}, u {u:e}"),
        }
    }
    assert!(checked > 1000, "{checked}");
}
