//! On-target tests and benchmark for the B-L475E-IOT01A (defmt-test, run by
//! probe-rs): what QEMU and the host simulation cannot show, checked on the
//! real chip.
//!
//! - **Reset survival**: the calibration the previous run committed to the
//!   spare store is found intact after the reset that starts this run
//!   (`scripts/board-test.sh` runs the harness twice for this).
//! - **Calibration store on the real flash**: provision the golden signed
//!   calibration (`tests/golden/board-check/calibration.blob`) with the
//!   library's store, commit, reopen as a reboot would, compare the bytes;
//!   corrupt the newest slot's blob (erase one of its pages) and its header
//!   and check the store falls back to the older slot, then to none. All in
//!   `shape::board::TEST_REGION` (two 16 KiB slots at the top of the image
//!   region), never the calibration slots.
//! - **Kernel bit-exactness**: every golden point (`expected.bin`, computed
//!   on the host from the same blob by `tests/board_golden.rs`) estimated by
//!   the device's per-point path, matrices in RAM and read in place from
//!   flash, equal to the host's value bit for bit.
//! - **Cycles** (DWT CYCCNT): per point and per line of P = 128 points, both
//!   matrix homes, printed.
//! - **Sensor timing** (DWT CYCCNT): a frame's wall time against its
//!   exposure, and the readout's time per pixel against the ADC's fastest
//!   conversions and the driver's timeout. Needs no sensor attached (the
//!   ADC then reads a floating pin; only timing is checked).
//!
//! This is the root package's one test target (`[[test]] board-tests`,
//! `harness = false`, feature `board-tests`): defmt-test compiles its tests
//! only under `cfg(test)`, so it is built by `cargo test --no-run` for the
//! chip. Build: `cargo board-tests-fw`. Run: `bash scripts/board-test.sh`
//! (builds, then runs only when `probe-rs list` finds a probe) or
//! `cargo board-tests-run` (the probe-rs runner of `.cargo/config.toml`).
#![no_std]
#![no_main]

use brdf_meter::blob::BlobView;
use brdf_meter::estimate::{Calibration, MatrixHome, ZoneMatrix};
use brdf_meter::hw::{LineSensor, MappedFlash};
use brdf_meter::nalgebra::SVector;
use brdf_meter::platform::board::{self, flash::CalFlash, sensor::Tsl1401};
use brdf_meter::shape::{self, board::PIXELS};
use brdf_meter::signed::{TRUSTED_KEYS, TRUSTS_DEVELOPMENT_KEY};
use brdf_meter::store::{SLOT_HEADER_LEN, Store};
use cortex_m::peripheral::DWT;
use defmt::Debug2Format;
use defmt_rtt as _;
use panic_probe as _;
use static_cell::StaticCell;

const N: usize = shape::BINS;
const M: usize = shape::LEDS;

/// 4-byte aligned bytes, as a flash slot holds a blob.
#[repr(C, align(4))]
struct Aligned<T: ?Sized>(T);

/// The signed test calibration (n = 81, m = 7, P = 128, 2 zones).
static CALIBRATION: &Aligned<[u8]> = &Aligned(*include_bytes!("../golden/board-check/calibration.blob"));
/// Golden points: pixel (u32), m readings, n values (f32), little-endian.
static EXPECTED: &Aligned<[u8]> = &Aligned(*include_bytes!("../golden/board-check/expected.bin"));
const RECORD: usize = 4 * (1 + M + N);

/// One golden point.
fn golden(k: usize) -> (usize, SVector<f32, M>, [f32; N]) {
    let r = &EXPECTED.0[k * RECORD..(k + 1) * RECORD];
    let f = |i: usize| f32::from_le_bytes([r[4 * i], r[4 * i + 1], r[4 * i + 2], r[4 * i + 3]]);
    let pixel = u32::from_le_bytes([r[0], r[1], r[2], r[3]]) as usize;
    (pixel, SVector::from_fn(|i, _| f(1 + i)), core::array::from_fn(|j| f(1 + M + j)))
}

fn golden_points() -> usize {
    EXPECTED.0.len() / RECORD
}

/// Where the image ends in flash (cortex-m-rt's symbols): the test region
/// must lie above it.
fn image_end() -> usize {
    unsafe extern "C" {
        static __sidata: u8;
        static __sdata: u8;
        static __edata: u8;
        static __veneer_limit: u8;
    }
    // Only the symbols' addresses are taken.
    let data = (&raw const __edata as usize) - (&raw const __sdata as usize);
    (&raw const __sidata as usize + data).max(&raw const __veneer_limit as usize)
}

/// Provisions `image` (a signed calibration) into the inactive slot exactly
/// as the application does: begin, chunks of the protocol's size, commit.
fn provision(store: &mut Store<CalFlash>, image: &[u8]) -> brdf_meter::store::SlotInfo {
    let crc = brdf_meter::blob::CRC32.checksum(image);
    store.begin(image.len() as u32, crc).unwrap_or_else(|e| defmt::panic!("begin: {}", Debug2Format(&e)));
    let mut at = 0u32;
    for chunk in image.chunks(brdf_meter::protocol::MAX_CHUNK) {
        at = store.write_chunk(at, chunk).unwrap_or_else(|e| defmt::panic!("write at {}: {}", at, Debug2Format(&e)));
    }
    store.commit(|_| Ok(())).unwrap_or_else(|e| defmt::panic!("commit: {}", Debug2Format(&e)))
}

/// Reopens the store on its flash, as boot does.
fn reopen(store: Store<CalFlash>) -> Store<CalFlash> {
    Store::open(store.into_flash(), shape::board::TEST_SLOT_LEN, TRUSTED_KEYS, |_| true)
}

/// Cycles `f` takes (DWT CYCCNT, 32 bits: at 80 MHz up to 53 s).
fn cycles(f: impl FnOnce()) -> u32 {
    let t0 = DWT::cycle_count();
    f();
    DWT::cycle_count().wrapping_sub(t0)
}

pub struct State {
    store: Option<Store<CalFlash>>,
    sensor: Tsl1401,
    /// Matrices copied to RAM (room for the test calibration's 2 zones).
    in_ram: Calibration<N, M, PIXELS>,
    /// No RAM budget: matrices read in place from the flash slot.
    in_flash: Calibration<N, M, PIXELS>,
}

impl State {
    fn store(&mut self) -> &mut Store<CalFlash> {
        self.store.as_mut().expect("store open")
    }

    fn reopen(&mut self) {
        let s = self.store.take().expect("store open");
        self.store = Some(reopen(s));
    }

    /// Loads the store's active calibration into both homes.
    fn load(&mut self) {
        let (info, view) = self.store().active_blob().expect("an active calibration");
        self.in_ram.load(&view, info).unwrap_or_else(|e| defmt::panic!("load (RAM): {}", Debug2Format(&e)));
        self.in_flash.load(&view, info).unwrap_or_else(|e| defmt::panic!("load (in place): {}", Debug2Format(&e)));
        assert_eq!(self.in_ram.home(), Some(MatrixHome::Ram));
        assert_eq!(self.in_flash.home(), Some(MatrixHome::InPlace));
    }
}

// The test calibration is signed with the development key.
const _: () = assert!(
    TRUSTS_DEVELOPMENT_KEY,
    "the board tests need the development key trusted: build them without BRDF_TRUSTED_KEYS"
);

/// The test calibration's signed image and its blob.
fn test_calibration() -> (&'static [u8], BlobView<'static>) {
    let image: &'static [u8] = &CALIBRATION.0;
    let blob = brdf_meter::signed::verify(image, TRUSTED_KEYS).expect("the test calibration verifies");
    (image, BlobView::parse(blob).expect("the test calibration parses"))
}

#[defmt_test::tests]
mod tests {
    use super::*;

    #[init]
    fn init() -> State {
        let end = image_end();
        defmt::info!("image ends at {=usize:#x}; test region at {=u32:#x}", end, shape::board::TEST_REGION);
        assert!(end <= shape::board::TEST_REGION as usize, "the test image reaches into its own store region");

        let mut cp = cortex_m::Peripherals::take().expect("core peripherals");
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
        let p = embassy_stm32::init(board::config());
        let sysclk = embassy_stm32::rcc::clocks(&p.RCC).sys.to_hertz().map(|h| h.0);
        assert_eq!(sysclk, Some(board::SYSCLK_HZ), "SYSCLK");

        let chip = board::flash::share(p.FLASH);
        let flash =
            board::flash::region(chip, shape::board::TEST_REGION as usize, 2 * shape::board::TEST_SLOT_LEN as usize);
        let store = Store::open(flash, shape::board::TEST_SLOT_LEN, TRUSTED_KEYS, |_| true);
        let sensor = Tsl1401::new(p.ADC1, p.PC5, p.DMA1_CH1, p.PD14, p.PA3);
        static RAM: StaticCell<[ZoneMatrix<N, M>; 2]> = StaticCell::new();
        static NONE: StaticCell<[ZoneMatrix<N, M>; 0]> = StaticCell::new();
        State {
            store: Some(store),
            sensor,
            in_ram: Calibration::new(RAM.init([ZoneMatrix::zeros(); 2])),
            in_flash: Calibration::new(NONE.init([])),
        }
    }

    /// First, before anything writes: what the previous run committed.
    #[test]
    fn a_calibration_committed_before_the_reset_is_intact(state: &mut State) {
        let (image, _) = test_calibration();
        match state.store().active_blob() {
            Some((info, _)) => {
                let stored = state.store().flash().mapped(
                    u32::from(info.slot) * shape::board::TEST_SLOT_LEN + SLOT_HEADER_LEN as u32,
                    info.blob_len as usize,
                );
                assert!(stored == image, "the calibration found after the reset is not the one committed");
                defmt::println!(
                    "reset survival: the calibration committed by the previous run survived the reset (slot {}, sequence {})",
                    info.slot,
                    info.sequence
                );
            }
            None => defmt::println!(
                "reset survival: nothing committed before this reset (first run on this board); run again to check"
            ),
        }
    }

    #[test]
    fn provisioning_commits_and_a_reopened_store_finds_it(state: &mut State) {
        let (image, _) = test_calibration();
        let before = state.store().active().map(|a| a.sequence);
        let info = provision(state.store(), image);
        assert_eq!(Some(info.sequence), Some(before.map_or(1, |s| s.wrapping_add(1))));
        state.reopen();
        let active = state.store().active().expect("the committed calibration after reopening");
        assert_eq!((active.slot, active.sequence), (info.slot, info.sequence));
        let (_, view) = state.store().active_blob().expect("active blob");
        let (_, golden) = test_calibration();
        assert!(view.as_bytes() == golden.as_bytes(), "the blob read back differs from the one written");
    }

    #[test]
    fn a_corrupt_slot_is_rejected_and_the_older_one_is_used(state: &mut State) {
        let (image, _) = test_calibration();
        let older = provision(state.store(), image);
        let newer = provision(state.store(), image);
        assert_ne!(older.slot, newer.slot);
        let page = board::flash::PAGE;
        let base = |slot: u8| u32::from(slot) * shape::board::TEST_SLOT_LEN;
        // Blob bytes of the newer slot turned to 0xFF: its blob CRC fails.
        let s = state.store.take().expect("store");
        let mut flash = s.into_flash();
        embedded_storage::nor_flash::NorFlash::erase(&mut flash, base(newer.slot) + page, base(newer.slot) + 2 * page)
            .unwrap_or_else(|e| defmt::panic!("erase: {}", Debug2Format(&e)));
        let s = Store::open(flash, shape::board::TEST_SLOT_LEN, TRUSTED_KEYS, |_| true);
        let a = s.active().expect("the older slot");
        assert_eq!((a.slot, a.sequence), (older.slot, older.sequence), "fell back to the older slot");
        // Then the older slot's header: nothing valid is left.
        let mut flash = s.into_flash();
        embedded_storage::nor_flash::NorFlash::erase(&mut flash, base(older.slot), base(older.slot) + page)
            .unwrap_or_else(|e| defmt::panic!("erase: {}", Debug2Format(&e)));
        let mut s = Store::open(flash, shape::board::TEST_SLOT_LEN, TRUSTED_KEYS, |_| true);
        assert!(s.active().is_none(), "a slot without a valid header or blob was accepted");
        // Leave a valid calibration for the next run's reset check.
        let info = provision(&mut s, image);
        defmt::println!("store: committed slot {}, sequence {} for the next run", info.slot, info.sequence);
        state.store = Some(reopen(s));
    }

    #[test]
    fn the_kernel_matches_the_host_bit_for_bit(state: &mut State) {
        state.load();
        let mut out = SVector::<f32, N>::zeros();
        for cal in [&state.in_ram, &state.in_flash] {
            for k in 0..golden_points() {
                let (pixel, v, want) = golden(k);
                cal.estimate_pixel(pixel, &v, &mut out);
                for j in 0..N {
                    if out[j].to_bits() != want[j].to_bits() {
                        defmt::panic!(
                            "{} point {} (pixel {}) bin {}: device {=u32:#x}, host {=u32:#x}",
                            Debug2Format(&cal.home()),
                            k,
                            pixel,
                            j,
                            out[j].to_bits(),
                            want[j].to_bits()
                        );
                    }
                }
            }
        }
        defmt::println!(
            "kernel: {} golden points bit-identical to the host, matrices in RAM and in flash",
            golden_points()
        );
    }

    #[test]
    fn cycles_per_point_and_per_line(state: &mut State) {
        state.load();
        let mut out = SVector::<f32, N>::zeros();
        let (_, v, _) = golden(0);
        for (name, cal) in [("RAM", &state.in_ram), ("flash", &state.in_flash)] {
            // Warm the flash accelerator's caches as a running line does.
            cal.estimate_pixel(0, &v, &mut out);
            let mut best = u32::MAX;
            let mut worst = 0;
            for p in 0..PIXELS {
                let c = cycles(|| {
                    cal.estimate_pixel(p, &v, &mut out);
                });
                best = best.min(c);
                worst = worst.max(c);
            }
            let line = cycles(|| {
                for p in 0..PIXELS {
                    cal.estimate_pixel(p, &v, &mut out);
                }
            });
            defmt::println!(
                "cycles ({} matrices): per point {} best, {} worst; per line of {} points {} ({} per point, {} us at 80 MHz)",
                name,
                best,
                worst,
                PIXELS,
                line,
                line / PIXELS as u32,
                line / (board::SYSCLK_HZ / 1_000_000)
            );
            // 567 multiply-accumulates: at least one cycle each; QEMU counts
            // ~700 instructions per point, so 10x that on average means
            // something is badly wrong (the worst single point may include
            // an interrupt, so it is only printed).
            let per_point = line / PIXELS as u32;
            assert!(best >= (N * M) as u32 && per_point < 10 * 700, "{} cycles per point", per_point);
        }
    }

    #[test]
    fn a_frame_takes_its_exposure_plus_the_readout(state: &mut State) {
        let mhz = board::SYSCLK_HZ / 1_000_000;
        let mut frame = [0u16; PIXELS];
        let mut frame_cycles = |exposure_us: u32, state: &mut State| {
            cycles(|| {
                embassy_futures::block_on(state.sensor.read_frame(exposure_us, &mut frame))
                    .unwrap_or_else(|e| defmt::panic!("read_frame: {}", Debug2Format(&e)));
            })
        };
        let short = frame_cycles(1_000, state);
        let long = frame_cycles(5_000, state);
        let readout = short.saturating_sub(1_000 * mhz);
        defmt::println!(
            "sensor: frame at 1 ms exposure {} cycles, at 5 ms {} cycles; readout (flush + read) {} cycles = {} us, {} cycles per pixel",
            short,
            long,
            readout,
            readout / mhz,
            readout / PIXELS as u32
        );
        assert!(short >= 1_000 * mhz, "a 1 ms frame took less than 1 ms");
        // The exposure is timed from the flush's 18th clock: 4 ms more
        // exposure is 4 ms more frame, to embassy-time's tick (1 us) and
        // the readout's jitter.
        let extra_us = long.saturating_sub(short) / mhz;
        assert!((3_950..=4_050).contains(&extra_us), "4 ms more exposure took {} us more", extra_us);
        // Per pixel: at least OVERSAMPLE conversions of 37 ADC clocks (the
        // fastest ADC clock is SYSCLK), at most the driver's 2 ms timeout.
        let per_pixel = readout / PIXELS as u32;
        let min = board::sensor::OVERSAMPLE as u32 * 37;
        assert!(per_pixel >= min && per_pixel <= 2_000 * mhz, "{} cycles per pixel", per_pixel);
    }
}
