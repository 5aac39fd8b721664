//! The fuzz targets' bodies, one plain function per target.
//!
//! The cargo-fuzz crate (`tests/fuzz/`, nightly) calls these from its
//! `fuzz_target!`s; the stable test `tests/fuzz_replay.rs` replays the
//! checked-in corpus and every regression input through the same functions,
//! so `cargo test` covers what the campaigns found without nightly.
//!
//! Each body panics only when the code under test breaks a property: a parser
//! that panics, accepts something inconsistent, or a store that boots into
//! anything but the old or the new calibration, whole. Bad input must end in
//! an error value.
//!
//! A target is registered in three places, so adding one (the signature check
//! is the next) means: a body here, a `[[bin]]` + `fuzz_targets/NAME.rs` in
//! `tests/fuzz/`, and a line in [`TARGETS`].
use brdf_meter::blob::{BlobView, CRC32};
use brdf_meter::platform::host_sim::SimFlash;
use brdf_meter::protocol::{self, FrameReader, MAX_FRAME, PointsFrame, Pushed, Request, Response, Streamed};
use brdf_meter::store::Store;
use brdf_meter::test_blobs::{dev_trusted, signed_test_blob as test_blob};
use host_tools::device::link::{Client, LinkError, Transport, decode_with};
use std::time::Duration;

/// A target's body: one input, a panic when a property breaks.
pub type Body = fn(&[u8]);

/// Every target: its name (the corpus and regression folder) and body.
pub const TARGETS: &[(&str, Body)] = &[
    ("frame_decode", frame_decode),
    ("frame_reader", frame_reader),
    ("blob_parse", blob_parse),
    ("store_ops", store_ops),
    ("scene_toml", scene_toml),
    ("prior_file", prior_file),
];

/// Re-encodes a decoded message and decodes it again: the two encodings must
/// be the same bytes (messages compare by their bytes, so NaN values do not
/// make equal messages look different).
macro_rules! assert_round_trips {
    ($ty:ty, $seq:expr, $msg:expr) => {{
        let mut first = [0u8; MAX_FRAME];
        let n = protocol::encode($seq, $msg, &mut first).expect("a message that decoded re-encodes");
        let mut again = first;
        let (seq2, msg2) = protocol::decode::<$ty>(&mut again[..n - 1]).expect("an encoded message decodes");
        assert_eq!(seq2, $seq);
        let mut second = [0u8; MAX_FRAME];
        let m = protocol::encode($seq, &msg2, &mut second).expect("re-encodes");
        assert_eq!(first[..n], second[..m], "a message changed through encode/decode");
    }};
}

/// Arbitrary bytes as one frame (delimiter stripped), decoded as a request
/// and as a reply: an error or a message that round-trips. The same bytes
/// are also tried as a message body in a valid envelope (version, length,
/// CRC, COBS), so the message decoding behind the CRC check is reached too.
pub fn frame_decode(data: &[u8]) {
    decode_frame(data);
    if data.len() + 12 <= protocol::MAX_PAYLOAD {
        let mut raw = Vec::with_capacity(data.len() + 12);
        raw.extend_from_slice(&protocol::PROTOCOL_VERSION.to_le_bytes());
        raw.extend_from_slice(&((data.len() + 12) as u16).to_le_bytes());
        raw.extend_from_slice(&7u32.to_le_bytes());
        raw.extend_from_slice(data);
        raw.extend_from_slice(&CRC32.checksum(&raw).to_le_bytes());
        decode_frame(&cobs::encode_vec(&raw));
    }
}

fn decode_frame(data: &[u8]) {
    let mut buf = data.to_vec();
    if let Ok((seq, req)) = protocol::decode::<Request<'_>>(&mut buf) {
        assert_round_trips!(Request<'_>, seq, &req);
    }
    let mut buf = data.to_vec();
    if let Ok((seq, resp)) = protocol::decode::<Response<'_>>(&mut buf) {
        assert_round_trips!(Response<'_>, seq, &resp);
        // Replies the host keeps are detached from the frame's buffer.
        match resp.detach() {
            Ok(owned) => assert_round_trips!(Response<'_>, seq, &owned),
            Err(Streamed::Point(point)) => assert_round_trips!(Response<'_>, seq, &Response::Point(point)),
            Err(Streamed::Points(points)) => {
                assert_round_trips!(Response<'_>, seq, &Response::Points(points));
                decode_line_frame(&points);
            }
        }
    }
}

/// A line frame decoded as the host does: without a blob, and with a small
/// test calibration (whatever the frame's CRC, so the decoding behind the
/// CRC check is reached): records or an error, never a panic, and every
/// record the frame's, in order.
fn decode_line_frame(f: &PointsFrame<'_>) {
    static BLOB: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    let blob = BLOB.get_or_init(|| brdf_meter::test_blobs::test_blob(9, 3, 2, 6, 0.5));
    let view = BlobView::parse(blob).expect("a valid test blob");
    for v in [None, Some(&view)] {
        if let Ok(recs) = decode_with(f, v) {
            assert_eq!(recs.len(), f.count());
            for (k, r) in recs.iter().enumerate() {
                assert_eq!(
                    (r.line, r.seq, r.point as u32),
                    (f.line, f.seq.wrapping_add(k as u32), f.first_point as u32 + k as u32)
                );
                assert_eq!(r.values.len(), f.bins.count as usize);
            }
        }
    }
}

/// What the frame reader must make of a byte stream: the pieces between
/// `0x00`s, empty pieces skipped, pieces longer than [`MAX_FRAME`] reported
/// as oversized, an unfinished last piece held back.
#[derive(Debug, PartialEq)]
enum Cut {
    Frame(Vec<u8>),
    Oversized,
}

fn model_cuts(stream: &[u8]) -> Vec<Cut> {
    let mut pieces: Vec<&[u8]> = stream.split(|b| *b == 0).collect();
    pieces.pop(); // after the last delimiter: not a frame yet
    pieces
        .into_iter()
        .filter(|p| !p.is_empty())
        .map(|p| if p.len() > MAX_FRAME { Cut::Oversized } else { Cut::Frame(p.to_vec()) })
        .collect()
}

/// A transport that hands the client a byte stream in given chunk sizes, then
/// reports the end of the stream as an I/O error (so the client stops at once
/// rather than waiting for a timeout).
struct Chunked<'a> {
    rest: &'a [u8],
    sizes: &'a [u8],
    k: usize,
}

impl Transport for Chunked<'_> {
    fn send(&mut self, _bytes: &[u8]) -> std::io::Result<()> {
        Ok(())
    }
    fn recv(&mut self, buf: &mut [u8], _timeout: Duration) -> std::io::Result<usize> {
        if self.rest.is_empty() {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        // Chunks of 1 to 256 bytes as the input says (each read costs the
        // client a 4 KiB buffer, so a whole stream byte by byte is slow).
        let want =
            if self.sizes.is_empty() { self.rest.len() } else { 1 + self.sizes[self.k % self.sizes.len()] as usize };
        self.k += 1;
        let n = want.min(buf.len()).min(self.rest.len());
        buf[..n].copy_from_slice(&self.rest[..n]);
        self.rest = &self.rest[n..];
        Ok(n)
    }
}

/// A byte stream (after a first byte giving how many chunk-size bytes follow)
/// through the [`FrameReader`] byte by byte and through the host client in
/// those chunk sizes: both must cut exactly the frames of `model_cuts`, and
/// every frame decodes or errors cleanly, the same way in both.
pub fn frame_reader(data: &[u8]) {
    let Some((&k, rest)) = data.split_first() else { return };
    let k = (k as usize % 8).min(rest.len());
    let (sizes, stream) = rest.split_at(k);
    let want = model_cuts(stream);

    let mut reader = FrameReader::new();
    let mut got = Vec::new();
    for &b in stream {
        match reader.push(b) {
            Pushed::More => {}
            Pushed::Oversized => got.push(Cut::Oversized),
            Pushed::Frame(f) => {
                assert!(f.len() <= MAX_FRAME);
                got.push(Cut::Frame(f.to_vec()));
            }
        }
    }
    assert_eq!(got, want, "the frame reader cut the stream differently from the model");

    let mut client = Client::new(Chunked { rest: stream, sizes, k: 0 }).expect("no I/O on send");
    for cut in &want {
        let f = client.next_frame(Duration::from_secs(60));
        match (cut, f) {
            (Cut::Oversized, Err(LinkError::Frame(protocol::FrameError::Oversized))) => {}
            (Cut::Frame(bytes), f) => {
                let mut copy = bytes.clone();
                let direct = protocol::decode::<Response<'_>>(&mut copy);
                match (direct, f) {
                    (Ok((seq, _)), Ok(frame)) => assert_eq!(frame.seq, seq),
                    // A line frame that reads but does not decode into points
                    // (this client holds no calibration blob).
                    (Ok((_, Response::Points(_))), Err(LinkError::Stream(_))) => {}
                    // A whole frame of another version: the client names the
                    // device's version rather than calling the frame unreadable.
                    (
                        Err(protocol::FrameError::UnsupportedVersion { got }),
                        Err(LinkError::ProtocolMismatch { device }),
                    ) => {
                        assert_eq!(got, device)
                    }
                    (Err(e), Err(LinkError::Frame(g))) => assert_eq!(e, g),
                    (d, f) => panic!("client and decoder disagree: {d:?} vs {f:?}"),
                }
            }
            (c, f) => panic!("client yielded {f:?} where the model has {c:?}"),
        }
    }
    match client.next_frame(Duration::from_secs(60)) {
        Err(LinkError::Io(_)) => {}
        other => panic!("the client yielded more frames than the stream holds: {other:?}"),
    }
}

/// Arbitrary bytes as a calibration blob: an error, or a view whose every
/// accessor stays in bounds and agrees with the bytes.
pub fn blob_parse(data: &[u8]) {
    // Twice: at the fuzzer's (any) alignment, and 4-byte aligned as in flash,
    // where matrices are read in place.
    let aligned: Vec<u32> = data
        .chunks(4)
        .map(|c| {
            let mut w = [0u8; 4];
            w[..c.len()].copy_from_slice(c);
            u32::from_ne_bytes(w)
        })
        .collect();
    let aligned_bytes: &[u8] = &bytemuck_bytes(&aligned)[..data.len()];
    for bytes in [data, aligned_bytes] {
        let Ok(v) = BlobView::parse(bytes) else { continue };
        check_view(&v, bytes);
    }
    // Again with the CRC its sizes call for made right, so the semantic
    // checks behind the CRC are reached too.
    if data.len() >= brdf_meter::blob::HEADER_LEN {
        let word = |o: usize| u16::from_le_bytes([data[o], data[o + 1]]) as usize;
        let dims = brdf_meter::blob::Dims { n: word(8), m: word(10), zones: word(12), pixels: word(14) };
        let len = dims.blob_len();
        if (brdf_meter::blob::HEADER_LEN + 4..=data.len()).contains(&len) {
            let mut fixed = data.to_vec();
            let crc = CRC32.checksum(&fixed[..len - 4]);
            fixed[len - 4..len].copy_from_slice(&crc.to_le_bytes());
            if let Ok(v) = BlobView::parse(&fixed) {
                check_view(&v, &fixed);
            }
        }
    }
}

fn bytemuck_bytes(words: &[u32]) -> &[u8] {
    // SAFETY: u32 has no padding and every byte pattern is a valid u8.
    unsafe { core::slice::from_raw_parts(words.as_ptr().cast::<u8>(), words.len() * 4) }
}

fn check_view(v: &BlobView<'_>, bytes: &[u8]) {
    let d = v.dims();
    let blob = v.as_bytes();
    if v.version() == 1 {
        assert_eq!(blob.len(), d.blob_len(), "the view's length is the one its sizes give");
    } else {
        assert!(blob.len() >= d.blob_len(), "later formats only add sections");
    }
    assert!(blob.len() <= bytes.len());
    assert_eq!(blob, &bytes[..blob.len()], "the view is the input's prefix");
    assert_eq!(v.crc(), u32::from_le_bytes(blob[blob.len() - 4..].try_into().unwrap()));
    assert_eq!(CRC32.checksum(&blob[..blob.len() - 4]), v.crc());
    assert!(v.noise_rel().is_finite() && v.noise_rel() >= 0.0);
    let wu = v.white_uncertainty();
    assert!((0.0..=brdf_meter::blob::MAX_WHITE_UNCERTAINTY).contains(&wu), "the white's uncertainty {wu}");
    let gu = v.gloss_uncertainty();
    assert!((0.0..=brdf_meter::blob::MAX_GLOSS_UNCERTAINTY).contains(&gu), "the gloss scale's uncertainty {gu}");
    assert!(gu == 0.0 || v.has_gloss(), "only a blob with gloss readings states a gloss scale's uncertainty");
    let _ = (v.estimator(), v.far_field(), v.summary());
    let mut prev = f32::NEG_INFINITY;
    for i in 0..d.n {
        let g = v.grid_deg(i);
        assert!(g > prev && (-90.0..=90.0).contains(&g));
        prev = g;
    }
    let order = v.led_order();
    assert_eq!(order.len(), d.m);
    assert!(order.iter().all(|&l| (l as usize) < d.m));
    assert!(d.zones >= 1 && v.zone_start(0) == 0);
    for p in 0..d.pixels {
        let z = v.zone_of_pixel(p);
        assert!(z < d.zones && v.zone_start(z) as usize <= p);
        for i in 0..d.m {
            let w = v.white(p, i);
            assert!(w.is_finite() && w > 0.0);
        }
    }
    let mut mat = vec![0f32; d.n * d.m];
    for z in 0..d.zones {
        for j in 0..d.n {
            let u = v.uncertainty(z, j);
            assert!(u.is_finite() && u >= 0.0);
        }
        v.copy_matrix(z, &mut mat);
        for j in 0..d.n {
            for i in 0..d.m {
                assert_eq!(mat[j * d.m + i].to_bits(), v.w(z, j, i).to_bits());
                assert!(mat[j * d.m + i].is_finite());
            }
        }
        if let Some(in_place) = v.matrix_in_place(z) {
            assert_eq!(in_place.len(), mat.len());
            assert!(in_place.iter().zip(&mat).all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }
    // The gloss section: every block in bounds, the parse's rules hold, the
    // in-place view agrees with the copies.
    let mut block = vec![0f32; brdf_meter::gloss::block_len(d.m)];
    assert_eq!(v.has_gloss(), v.version() >= 3);
    let kg = v.gloss_clusters();
    assert!(v.has_gloss_centroids() || kg == v.clusters());
    for z in 0..d.zones {
        let mut cents = vec![0f32; kg * d.m];
        if v.copy_gloss_centroids(z, &mut cents) {
            assert!(cents.iter().all(|x| x.is_finite()));
            if let Some(g) = v.gloss_in_place() {
                let at = z * kg * d.m;
                assert!(g.centroids[at..at + cents.len()].iter().zip(&cents).all(|(a, b)| a.to_bits() == b.to_bits()));
            }
        }
        for c in 0..kg {
            let Some((assigned, index, reference)) = v.copy_gloss(z, c, &mut block) else { continue };
            assert!(assigned > 0.0 && index > 1.0);
            if reference.is_nan() {
                // A zone without a reading: its blocks all NaN.
                assert!(block.iter().all(|x| x.is_nan()));
            } else {
                assert!(reference > 0.0 && reference.is_finite());
                assert!(block.iter().all(|x| x.is_finite()));
            }
            if let Some(g) = v.gloss_in_place() {
                let bl = block.len();
                let at = (z * kg + c) * bl;
                assert!(g.blocks[at..at + bl].iter().zip(&block).all(|(a, b)| a.to_bits() == b.to_bits()));
                // The reference of the zone's first pixel (version 4) or the zone's (3).
                let r = if v.version() == 3 { z } else { v.zone_start(z) as usize };
                assert_eq!(g.reference[r].to_bits(), reference.to_bits());
            }
        }
    }
}

/// Slot length of the store target: two pages, so a power cut anywhere in a
/// provisioning is a few thousand steps at most.
const FUZZ_SLOT: u32 = 2 * SimFlash::PAGE as u32;

/// Valid blobs of different sizes the store target provisions.
fn store_blobs() -> &'static [Vec<u8>; 4] {
    static BLOBS: std::sync::OnceLock<[Vec<u8>; 4]> = std::sync::OnceLock::new();
    BLOBS.get_or_init(|| {
        let b = [
            test_blob(5, 3, 2, 4, 1.0),
            test_blob(5, 3, 2, 4, 2.0),
            test_blob(8, 4, 2, 16, 3.0),
            test_blob(12, 6, 3, 24, 4.0),
        ];
        assert!(b.iter().all(|x| x.len() <= (FUZZ_SLOT as usize) - brdf_meter::store::SLOT_HEADER_LEN));
        b
    })
}

/// Reads input bytes one at a time, zero past the end.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        let Some((&b, rest)) = self.0.split_first() else { return 0 };
        self.0 = rest;
        b
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.u8(), self.u8()])
    }
}

fn open_store(flash: SimFlash) -> Store<SimFlash> {
    Store::open(flash, FUZZ_SLOT, dev_trusted(), |_| true)
}

/// What boot must find: the model's calibration, whole.
fn assert_active(st: &Store<SimFlash>, model: &Option<Vec<u8>>, when: &str) {
    let found = st.active_blob().map(|(_, v)| v.as_bytes().to_vec());
    assert_eq!(found.as_deref(), model.as_deref(), "{when}: the store's calibration is not the model's");
}

/// How a provisioning in the store target ends.
enum Ending {
    Commit,
    Abort,
    /// Declares a wrong CRC at begin, so commit must refuse.
    WrongCrc,
}

/// Operation sequences on the calibration store over the simulated NOR flash,
/// against a model (the calibration boot must find): provision a blob (in
/// chunks of any size, committed, aborted, or with a wrong CRC), cut the
/// power at any step of it, reboot, read the active calibration. After any
/// cut, boot finds the old or the new blob whole, never a mix, never none when
/// there was one.
pub fn store_ops(data: &[u8]) {
    let blobs = store_blobs();
    let mut input = Bytes(data);
    let mut flash = SimFlash::new(2 * FUZZ_SLOT as usize);
    let mut st = open_store(flash.clone());
    let mut model: Option<Vec<u8>> = None;
    for _ in 0..24 {
        if input.0.is_empty() {
            break;
        }
        let op = input.u8();
        match op % 4 {
            // Provision, perhaps with a power cut.
            0 | 1 => {
                // What is sent is the signed calibration; what boot finds
                // (and the model holds) is its blob.
                let new = &blobs[(op as usize >> 2) % blobs.len()];
                let new_blob = &new[..new.len() - brdf_meter::signed::TRAILER_LEN];
                let chunk = 1 + (input.u16() as usize % protocol::MAX_CHUNK);
                let ending = match input.u8() % 8 {
                    0 => Ending::Abort,
                    1 => Ending::WrongCrc,
                    _ => Ending::Commit,
                };
                let cut = (op % 4 == 1).then(|| input.u16() as usize * 2);
                if let Some(k) = cut {
                    flash.cut_after(k);
                }
                let r = provision(&mut st, new, chunk, &ending);
                if cut.is_some() {
                    // Power back on, whatever happened.
                    flash = flash.reboot();
                    st = open_store(flash.clone());
                    let found = st.active_blob().map(|(_, v)| v.as_bytes().to_vec());
                    match (&ending, r.is_ok()) {
                        // A completed commit survives the power cycle.
                        (Ending::Commit, true) => assert_eq!(found.as_deref(), Some(new_blob)),
                        // Only a commit may have made it before the cut.
                        (Ending::Commit, false) => assert!(
                            found.as_deref() == model.as_deref() || found.as_deref() == Some(new_blob),
                            "after a cut, boot found neither the old nor the new calibration"
                        ),
                        _ => assert_eq!(
                            found.as_deref(),
                            model.as_deref(),
                            "a cut abandoned provisioning changed the calibration"
                        ),
                    }
                    model = found;
                } else {
                    match ending {
                        Ending::Commit => {
                            r.expect("provisioning a valid blob without a cut succeeds");
                            model = Some(new_blob.to_vec());
                        }
                        Ending::Abort => r.expect("abort succeeds"),
                        Ending::WrongCrc => assert!(r.is_err(), "a blob with a wrong CRC was committed"),
                    }
                    assert_active(&st, &model, "after provisioning");
                }
            }
            // Reboot.
            2 => {
                flash = flash.reboot();
                st = open_store(flash.clone());
                assert_active(&st, &model, "after a reboot");
            }
            // Read the active calibration in place.
            _ => {
                assert_active(&st, &model, "reading the active calibration");
                // The slot holds the signed calibration: the blob, then its
                // signature trailer; the header's CRC covers both.
                if let Some((info, v)) = st.active_blob() {
                    let signed = blobs
                        .iter()
                        .find(|b| b.starts_with(v.as_bytes()))
                        .expect("one of the provisioned calibrations");
                    assert_eq!((info.blob_len as usize, info.blob_crc), (signed.len(), CRC32.checksum(signed)));
                }
            }
        }
    }
}

fn provision(st: &mut Store<SimFlash>, blob: &[u8], chunk: usize, ending: &Ending) -> Result<(), String> {
    let crc = CRC32.checksum(blob) ^ if matches!(ending, Ending::WrongCrc) { 1 } else { 0 };
    st.begin(blob.len() as u32, crc).map_err(|e| format!("{e:?}"))?;
    let mut off = 0u32;
    for c in blob.chunks(chunk) {
        off = st.write_chunk(off, c).map_err(|e| format!("{e:?}"))?;
    }
    match ending {
        Ending::Abort => st.abort().map_err(|e| format!("{e:?}")),
        _ => st.commit(|_| Ok(())).map(|_| ()).map_err(|e| format!("{e:?}")),
    }
}

/// Arbitrary text as a scene file: a scene or an error naming where.
pub fn scene_toml(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Err(e) = host_tools::forward::scene::Scene::parse(text, "fuzz.toml") {
        assert!(!e.message.is_empty(), "an error that says nothing: {e:?}");
    }
}

/// Arbitrary bytes as a prior file: the first byte picks the prior TOML or a
/// measured-sample CSV; either parses or errors.
pub fn prior_file(data: &[u8]) {
    let Some((&kind, rest)) = data.split_first() else { return };
    if kind % 2 == 0 {
        let Ok(text) = std::str::from_utf8(rest) else { return };
        let _ =
            host_tools::output::config::parse_toml::<host_tools::forward::prior::PriorSpec>(text, "fuzz-prior.toml");
    } else {
        // The CSV reader reads files: one scratch file per process.
        thread_local! {
            static PATH: std::path::PathBuf = std::env::temp_dir()
                .join(format!("brdf-fuzz-prior-{}-{:?}.csv", std::process::id(), std::thread::current().id()));
        }
        PATH.with(|path| {
            std::fs::write(path, rest).expect("writing the scratch CSV");
            let _ = host_tools::forward::prior::read_measured_csv(path);
        });
    }
}
