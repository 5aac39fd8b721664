//! The board tests' golden data (`tests/golden/board-check/`), computed here
//! on the host and checked in, so the on-target harness (`src/bin/board-tests.rs`,
//! `scripts/board-test.sh`) compares the chip's kernel with the host's bit
//! for bit without a host at run time:
//!
//! - `calibration.blob`: a signed calibration (development key) for the board's
//!   shape, n = 81, m = 7, P = 128, two zones, random matrices; the harness
//!   provisions it into its spare store and estimates with it;
//! - `expected.bin`: [`POINTS`] records of `pixel (u32)`, m readings and the
//!   n values of `rho = W_zone v` (f32), little-endian, computed with the
//!   library's per-point kernel (`kernel::mat_vec_f32_slice`).
//!
//! This test rebuilds both and fails if the checked-in files differ (the
//! harness would then compare against stale values). Regenerate after a
//! deliberate change with
//!
//!     GOLDEN_REGENERATE=1 cargo test --release -p system-tests --test system -- board_golden::
use brdf_meter::blob::{BlobView, Dims};
use brdf_meter::shape::{BINS, LEDS, board};
use brdf_meter::store::SLOT_HEADER_LEN;
use brdf_meter::test_blobs::{TestBlobParts, sign_for_tests};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::PathBuf;

/// Points checked on the board.
const POINTS: usize = 24;
/// Zones of the test calibration.
const ZONES: usize = 2;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("golden/board-check")
}

fn calibration() -> Vec<u8> {
    let (n, m, p) = (BINS, LEDS, board::PIXELS);
    let mut rng = ChaCha8Rng::seed_from_u64(2026);
    let white: Vec<f32> = (0..p * m).map(|_| rng.random_range(500.0f32..4000.0)).collect();
    let mats: Vec<f32> = (0..ZONES * n * m).map(|_| rng.random_range(-50.0f32..50.0)).collect();
    let order: Vec<u8> = (0..m as u8).collect();
    let blob = TestBlobParts::with(Dims { n, m, zones: ZONES, pixels: p }, order, white, mats).encode();
    sign_for_tests(&blob)
}

fn expected(signed: &[u8]) -> Vec<u8> {
    let blob =
        brdf_meter::signed::verify(signed, brdf_meter::test_blobs::dev_trusted()).expect("signed by the dev key");
    let view = BlobView::parse(blob).expect("valid blob");
    let (n, m) = (BINS, LEDS);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut w = vec![0.0f32; n * m];
    let mut rho = vec![0.0f32; n];
    let mut out = Vec::new();
    for k in 0..POINTS {
        // Pixels across both zones, readings over several decades.
        let pixel = (k * 37 + 5) % board::PIXELS;
        let scale = [1.0f32, 0.01, 3.0, 250.0][k % 4];
        let v: Vec<f32> = (0..m).map(|_| rng.random_range(0.0f32..1.2) * scale).collect();
        view.copy_matrix(view.zone_of_pixel(pixel), &mut w);
        brdf_meter::kernel::mat_vec_f32_slice(&w, &v, &mut rho);
        out.extend_from_slice(&(pixel as u32).to_le_bytes());
        for x in v.iter().chain(&rho) {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    out
}

#[test]
fn board_check_golden_files_are_what_the_host_computes() {
    let cal = calibration();
    assert!(
        cal.len() + SLOT_HEADER_LEN <= board::TEST_SLOT_LEN as usize,
        "the test calibration ({} B) must fit a board-test slot ({} B)",
        cal.len(),
        board::TEST_SLOT_LEN
    );
    let exp = expected(&cal);
    assert_eq!(exp.len(), POINTS * 4 * (1 + LEDS + BINS));
    let files = [("calibration.blob", cal), ("expected.bin", exp)];
    if std::env::var_os("GOLDEN_REGENERATE").is_some() {
        std::fs::create_dir_all(dir()).expect("golden dir");
        for (name, bytes) in &files {
            std::fs::write(dir().join(name), bytes).expect("writing golden");
        }
    }
    for (name, bytes) in &files {
        let path = dir().join(name);
        let on_disk = std::fs::read(&path).unwrap_or_else(|e| {
            panic!("{}: {e}; regenerate with GOLDEN_REGENERATE=1 (see this file's docs)", path.display())
        });
        assert!(
            on_disk == *bytes,
            "{} differs from the host's computation: the board tests would check stale values; \
             regenerate with GOLDEN_REGENERATE=1 cargo test --release -p system-tests --test system -- board_golden::",
            path.display()
        );
    }
}

#[test]
fn the_golden_points_cover_both_zones_and_differ_from_each_other() {
    // A golden of identical or all-zero points would let a broken kernel pass.
    let cal = calibration();
    let exp = expected(&cal);
    let rec = 4 * (1 + LEDS + BINS);
    let blob = brdf_meter::signed::verify(&cal, brdf_meter::test_blobs::dev_trusted()).expect("signed");
    let view = BlobView::parse(blob).expect("valid");
    let mut zones = std::collections::BTreeSet::new();
    let mut firsts = std::collections::BTreeSet::new();
    for r in exp.chunks_exact(rec) {
        let pixel = u32::from_le_bytes(r[..4].try_into().expect("4 bytes")) as usize;
        zones.insert(view.zone_of_pixel(pixel));
        let rho0 = f32::from_le_bytes(r[4 * (1 + LEDS)..4 * (2 + LEDS)].try_into().expect("4 bytes"));
        assert!(rho0.is_finite() && rho0 != 0.0);
        firsts.insert(rho0.to_bits());
    }
    assert_eq!(zones.len(), ZONES);
    assert_eq!(firsts.len(), POINTS);
}

#[test]
fn the_device_path_the_board_tests_call_reproduces_the_golden_on_the_host() {
    // What tests/board/main.rs runs on the chip (Calibration::estimate_pixel,
    // matrices in RAM and read in place), here on the host's build of the
    // same library: the on-target comparison then fails only if the chip
    // computes differently.
    use brdf_meter::estimate::{Calibration, MatrixHome, ZoneMatrix};
    use brdf_meter::nalgebra::SVector;
    use brdf_meter::store::SlotInfo;
    let cal = calibration();
    let blob = brdf_meter::signed::verify(&cal, brdf_meter::test_blobs::dev_trusted()).expect("signed");
    // 4-byte aligned with 'static life, as a flash slot is.
    let words: &'static mut [u32] = Box::leak(vec![0u32; blob.len().div_ceil(4)].into_boxed_slice());
    let bytes: &'static mut [u8] = &mut words_as_bytes(words)[..blob.len()];
    bytes.copy_from_slice(blob);
    let view = BlobView::parse(bytes).expect("valid");
    let slot = SlotInfo { slot: 0, sequence: 1, blob_len: blob.len() as u32, blob_crc: 0 };
    let mut in_ram =
        Calibration::<BINS, LEDS, { board::PIXELS }>::new(Box::leak(Box::new([ZoneMatrix::zeros(); ZONES])));
    let mut in_flash = Calibration::<BINS, LEDS, { board::PIXELS }>::new(Box::leak(Box::new([])));
    in_ram.load(&view, slot).expect("load");
    in_flash.load(&view, slot).expect("load");
    assert_eq!((in_ram.home(), in_flash.home()), (Some(MatrixHome::Ram), Some(MatrixHome::InPlace)));
    let exp = expected(&cal);
    let f = |r: &[u8], i: usize| f32::from_le_bytes(r[4 * i..4 * i + 4].try_into().expect("4 bytes"));
    let mut out = SVector::<f32, BINS>::zeros();
    for r in exp.chunks_exact(4 * (1 + LEDS + BINS)) {
        let pixel = u32::from_le_bytes(r[..4].try_into().expect("4 bytes")) as usize;
        let v = SVector::<f32, LEDS>::from_fn(|i, _| f(r, 1 + i));
        for c in [&in_ram, &in_flash] {
            c.estimate_pixel(pixel, &v, &mut out);
            for j in 0..BINS {
                assert_eq!(out[j].to_bits(), f(r, 1 + LEDS + j).to_bits(), "pixel {pixel} bin {j}");
            }
        }
    }
}

/// The bytes of `words` (this package has no bytemuck).
fn words_as_bytes(words: &'static mut [u32]) -> &'static mut [u8] {
    let len = 4 * words.len();
    // SAFETY: u8 has no alignment or validity requirement; the length covers
    // exactly the words' bytes, borrowed for as long as the words.
    unsafe { std::slice::from_raw_parts_mut(words.as_mut_ptr().cast::<u8>(), len) }
}
