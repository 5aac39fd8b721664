//! Line bench firmware for QEMU (b-l475e-iot01a): the device's whole
//! per-line path, stage by stage, on real data, so that
//! `scripts/line-bench.sh` can count each stage's instructions exactly from
//! QEMU's execution trace (as `kernel-bench` does for the kernels) and
//! `host-tools rate` can turn them into the line-rate budget.
//!
//! Input: `target/line-bench/data.bin` (written by `host-tools rate`), read
//! over semihosting: per build (P = 128, the board; P = 32, QEMU) a trained
//! calibration blob and one line of raw frames from the scene simulator,
//! with the shorter exposures the scene has, corrected with that build's
//! firmware settings (`platform::timing`).
//! For each build it runs the library functions the firmware runs, between
//! calls of [`bench_mark`]:
//! - `overlap`, once per frame but the last, in the order the acquisition
//!   reads them (`RawLine::frames_read`: a shorter exposure of a frame that
//!   saturated, as the acquisition takes it): that frame's correction (dark,
//!   the sensor's linearity when the calibration has it, white, saturation
//!   and exposure flags: `acquire::LineCorrection::frame`), which the
//!   acquisition task runs while the next frame's LED settles;
//! - `correct`: what is left after the last frame (its correction and
//!   `LineCorrection::finish`), which the acquisition task runs in series;
//! - `estimate`: `Calibration::estimate_point` for every point (zone,
//!   cluster selection, the kernel, scale, out-of-prior, the derived gloss
//!   readings when the device computes them, the guard);
//! - per encoding (f32, Sigma16, corrected readings), per frame: `push`
//!   (`PointsBlock::push` of its points: value encoding), `serialise`
//!   (header + postcard), `seal` (CRC-32), `stuff` (COBS), `copy` (into an
//!   outgoing frame buffer, as the estimation task's channel does);
//! - protocol 2's stream for comparison: one f32 `PointFrame` per point
//!   (`p2-serialise`, `p2-seal`, `p2-stuff`).
//!
//! The segment structure depends on the data (a point Sigma16 cannot carry
//! goes alone as f32), so each build runs twice: once naming the segments
//! (printed as `SEG <build> <stage> <encoding>` lines), once marking them.
//! The loop glue between the calls (a few instructions per point) is the
//! bench's, not the task's; the tasks' async machinery (channel waits,
//! executor polls) is not counted.
#![no_std]
#![no_main]

use brdf_meter::acquire::by_frame::Target;
use brdf_meter::acquire::{AcqConfig, FrameRead, LineCorrection, MAX_SHORT_EXPOSURES, RawLine};
use brdf_meter::blob::BlobView;
use brdf_meter::estimate::{Calibration, ZoneMatrix};
use brdf_meter::in_place::zeroed;
use brdf_meter::nalgebra::SVector;
use brdf_meter::protocol::{
    self, Encoding, LeBytes, MAX_FRAME, MAX_PAYLOAD, PointFrame, PointIn, PointMetaWire, PointsBlock, PushError,
    Response, StreamFormat,
};
use brdf_meter::shape;
use brdf_meter::store::SlotInfo;
use core::mem::MaybeUninit;
use cortex_m_rt::entry;

#[path = "bench_io/mod.rs"]
mod bench_io;
use bench_io::{Aligned, Line, bench_mark, done, fail, read_file, u32_at};

const N: usize = shape::BINS;
const M: usize = shape::LEDS;
const BOARD_P: usize = shape::board::PIXELS;
const QEMU_P: usize = shape::qemu::PIXELS;
const DATA_LEN: usize = 44 * 1024;

static mut DATA: Aligned<DATA_LEN> = Aligned([0; DATA_LEN]);
static mut RAM_BOARD: [ZoneMatrix<N, M>; shape::board::RAM_ZONES] =
    [ZoneMatrix::from_array_storage(brdf_meter::nalgebra::ArrayStorage([[0.0; M]; N])); shape::board::RAM_ZONES];
static mut RAM_QEMU: [ZoneMatrix<N, M>; shape::qemu::RAM_ZONES] =
    [ZoneMatrix::from_array_storage(brdf_meter::nalgebra::ArrayStorage([[0.0; M]; N])); shape::qemu::RAM_ZONES];
/// Where a frame goes after encoding (the estimation task's channel slot).
static mut OUT_SLOT: heapless::Vec<u8, MAX_FRAME> = heapless::Vec::new();
/// Each build's calibration and line, in SRAM2: as locals of `main` they
/// took 14 KB of its 16 KB stack.
#[unsafe(link_section = ".sram2")]
static mut CAL_BOARD: MaybeUninit<Calibration<N, M, BOARD_P>> = MaybeUninit::uninit();
#[unsafe(link_section = ".sram2")]
static mut CAL_QEMU: MaybeUninit<Calibration<N, M, QEMU_P>> = MaybeUninit::uninit();
#[unsafe(link_section = ".sram2")]
static mut RAW_BOARD: MaybeUninit<RawLine<M, BOARD_P>> = MaybeUninit::uninit();
#[unsafe(link_section = ".sram2")]
static mut RAW_QEMU: MaybeUninit<RawLine<M, QEMU_P>> = MaybeUninit::uninit();

/// Names the segments (first pass) or marks them (second pass).
struct Bounds {
    marking: bool,
    build: usize,
}

impl Bounds {
    #[inline(always)]
    fn at(&self, stage: &str, enc: &str) {
        if self.marking {
            bench_mark();
        } else {
            let mut l = Line::new();
            l.push(b"SEG ");
            l.num(self.build as u32);
            l.push(b" ");
            l.push(stage.as_bytes());
            l.push(b" ");
            l.push(enc.as_bytes());
            l.end();
        }
    }
}

fn enc_name(e: Encoding) -> &'static str {
    match e {
        Encoding::F32 => "f32",
        Encoding::Sigma16 => "sigma16",
        Encoding::Corrected => "corrected",
    }
}

/// Frames the block as the estimation task does: serialise, seal, stuff,
/// copy to the outgoing slot.
fn send(b: &Bounds, block: &PointsBlock, enc: &str, seq: u32) {
    let msg = Response::Points(block.frame());
    send_msg(b, &msg, enc, seq, "");
}

fn send_msg(b: &Bounds, msg: &Response<'_>, enc: &str, seq: u32, prefix: &'static str) {
    let stage = |s: &'static str| -> &'static str {
        match (prefix, s) {
            ("p2-", "serialise") => "p2-serialise",
            ("p2-", "seal") => "p2-seal",
            ("p2-", "stuff") => "p2-stuff",
            (_, s) => s,
        }
    };
    let mut raw = [0u8; MAX_PAYLOAD];
    let mut out = heapless::Vec::<u8, MAX_FRAME>::new();
    b.at(stage("serialise"), enc);
    let len = protocol::serialise(seq, msg, &mut raw).expect("fits");
    b.at(stage("seal"), enc);
    protocol::seal(&mut raw[..len]);
    b.at(stage("stuff"), enc);
    let _ = out.resize(MAX_FRAME, 0);
    let n = protocol::stuff(&raw[..len], &mut out).expect("fits");
    out.truncate(n);
    if prefix.is_empty() {
        b.at("copy", enc);
        // SAFETY: single-threaded firmware; nothing else touches the slot.
        unsafe { *core::ptr::addr_of_mut!(OUT_SLOT) = core::hint::black_box(out) };
    }
}

/// One build's line, stage by stage.
fn run<const P: usize>(b: &Bounds, cal: &Calibration<N, M, P>, raw: &RawLine<M, P>, full_scale: u16, cfg: &AcqConfig) {
    let (active, pixels) = cal.loaded().expect("loaded");
    let (white, linearity, crc) = (&pixels.white, active.linearity.as_ref(), active.info.blob_crc);
    let mut v = [SVector::<f32, M>::zeros(); P];
    let mut fl = [0u8; P];
    let read: heapless::Vec<FrameRead, { 1 + M * (1 + MAX_SHORT_EXPOSURES) }> =
        raw.frames_read(full_scale, cfg.short_levels()).collect();
    let Some((last, before)) = read.split_last() else { fail(b"line-bench: a line without frames") };
    let mut by_frame = LineCorrection::<M, P>::new();
    let mut t = Target { raw, white, linearity, full_scale, cfg, v: &mut v, fl: &mut fl };
    for f in before {
        b.at("overlap", "-");
        by_frame.frame(*f, &mut t);
    }
    b.at("correct", "-");
    by_frame.frame(*last, &mut t);
    by_frame.finish(&mut t);
    let mut block = PointsBlock::new();
    let mut rho = SVector::<f32, N>::zeros();
    let estimate = |p: usize, rho: &mut SVector<f32, N>| {
        let m = cal.estimate_point(p, &v[p], fl[p], rho);
        PointMetaWire {
            zone: m.zone,
            cluster: m.cluster,
            flags: m.flags,
            sigma_scale: m.sigma_scale,
            readings: m.readings,
            reading_sigma: m.reading_sigma,
        }
    };
    for encoding in [Encoding::F32, Encoding::Sigma16, Encoding::Corrected] {
        let e = enc_name(encoding);
        let bins = StreamFormat { encoding, bins: None }.bin_range(N);
        block.start(0, 0, 0, crc, encoding, bins, M);
        for (p, vp) in v.iter().enumerate() {
            b.at("estimate", e);
            let meta = estimate(p, &mut rho);
            b.at("push", e);
            let pin = PointIn {
                meta,
                values: rho.as_slice(),
                readings: vp.as_slice(),
                sigma: cal.uncertainty(meta.zone as usize, meta.cluster as usize),
            };
            match block.push(&pin) {
                Ok(()) => {}
                Err(PushError::Full) => {
                    send(b, &block, e, 1);
                    block.start(0, p as u32, p as u16, crc, encoding, bins, M);
                    b.at("push", e);
                    if block.push(&pin).is_err() {
                        block.start(0, p as u32, p as u16, crc, Encoding::F32, bins, M);
                        let _ = block.push(&pin);
                        send(b, &block, e, 1);
                        block.start(0, p as u32 + 1, p as u16 + 1, crc, encoding, bins, M);
                    }
                }
                Err(PushError::NotRepresentable) => {
                    if !block.is_empty() {
                        send(b, &block, e, 1);
                    }
                    block.start(0, p as u32, p as u16, crc, Encoding::F32, bins, M);
                    b.at("push", e);
                    let _ = block.push(&pin);
                    send(b, &block, e, 1);
                    block.start(0, p as u32 + 1, p as u16 + 1, crc, encoding, bins, M);
                }
            }
        }
        if !block.is_empty() {
            send(b, &block, e, 1);
        }
    }
    // Protocol 2: one f32 frame per point.
    for p in 0..P {
        b.at("estimate", "p2");
        let meta = estimate(p, &mut rho);
        let pf = PointFrame {
            line: 0,
            seq: p as u32,
            point: p as u16,
            zone: meta.zone,
            cluster: meta.cluster,
            flags: meta.flags,
            sigma_scale: meta.sigma_scale,
            readings: meta.readings,
            reading_sigma: meta.reading_sigma,
            values: LeBytes::from_f32(rho.as_slice()),
        };
        send_msg(b, &Response::Point(pf), "p2", 1, "p2-");
    }
    b.at("end", "-");
}

/// One build's inputs in the data file.
struct BuildData {
    pixels: usize,
    full_scale: u16,
    /// The shorter exposures the frames hold.
    shorter: usize,
    blob: &'static [u8],
    /// Per exposure level, the dark frame and the frames in reading order.
    frames: &'static [u8],
}

/// The build whose inputs start at `at`, and the offset after them.
fn build_at(d: &'static [u8], at: usize) -> (BuildData, usize) {
    let blob_len = u32_at(d, at + 12);
    let frames_len = u32_at(d, at + 16);
    let blob_at = at + 20;
    let frames_at = blob_at + blob_len.div_ceil(4) * 4;
    if frames_at + frames_len > d.len() {
        fail(b"line-bench: the data is cut short");
    }
    let build = BuildData {
        pixels: u32_at(d, at),
        full_scale: u32_at(d, at + 4) as u16,
        shorter: u32_at(d, at + 8),
        blob: &d[blob_at..blob_at + blob_len],
        frames: &d[frames_at..frames_at + frames_len],
    };
    if build.shorter > MAX_SHORT_EXPOSURES || build.frames.len() < 2 * build.pixels * (M + 1) * (1 + build.shorter) {
        fail(b"line-bench: the frames do not match their exposures");
    }
    (build, frames_at + frames_len)
}

/// The calibration `blob`, loaded into `cal` where it is.
fn load<const P: usize>(
    cal: &'static mut MaybeUninit<Calibration<N, M, P>>,
    ram: &'static mut [ZoneMatrix<N, M>],
    blob: &'static [u8],
) -> &'static Calibration<N, M, P> {
    let view = BlobView::parse(blob).unwrap_or_else(|_| fail(b"line-bench: bad blob"));
    let slot = SlotInfo { slot: 0, sequence: 1, blob_len: blob.len() as u32, blob_crc: 0 };
    let cal = cal.write(Calibration::<N, M, P>::new(ram));
    if cal.load(&view, slot).is_err() {
        fail(b"line-bench: the blob does not fit this build");
    }
    cal
}

/// The line `build`'s frames record, replayed into the static `raw` where
/// it is.
fn replay<const P: usize>(raw: &'static mut MaybeUninit<RawLine<M, P>>, build: &BuildData) -> &'static RawLine<M, P> {
    // SAFETY: all-zero bytes are a `RawLine` (integers and `bool`s).
    let raw = unsafe { zeroed(raw) };
    raw.read_le_frames(build.frames, build.shorter);
    raw
}

#[entry]
fn main() -> ! {
    // SAFETY: single-threaded firmware, no interrupts use these statics.
    let (data, ram_board, ram_qemu, cal_board, cal_qemu, raw_board, raw_qemu) = unsafe {
        (
            &mut (*core::ptr::addr_of_mut!(DATA)).0,
            &mut *core::ptr::addr_of_mut!(RAM_BOARD),
            &mut *core::ptr::addr_of_mut!(RAM_QEMU),
            &mut *core::ptr::addr_of_mut!(CAL_BOARD),
            &mut *core::ptr::addr_of_mut!(CAL_QEMU),
            &mut *core::ptr::addr_of_mut!(RAW_BOARD),
            &mut *core::ptr::addr_of_mut!(RAW_QEMU),
        )
    };
    let n = read_file(b"target/line-bench/data.bin\0", data);
    let data: &'static [u8] = &data[..n];
    if n < 8 || &data[..4] != b"LBD2" {
        fail(b"line-bench: no data (run `host-tools rate`)");
    }
    let (board, next) = build_at(data, 4);
    let (qemu, _) = build_at(data, next);
    if board.pixels != BOARD_P || qemu.pixels != QEMU_P {
        fail(b"line-bench: the data is for other pixel counts");
    }
    let cal_b = load(cal_board, ram_board, board.blob);
    let cal_q = load(cal_qemu, ram_qemu, qemu.blob);
    let raw_b = replay(raw_board, &board);
    let raw_q = replay(raw_qemu, &qemu);
    let (acq_b, acq_q) = (brdf_meter::platform::timing::ACQUISITION, brdf_meter::platform::timing::QEMU_ACQUISITION);
    for marking in [false, true] {
        run(&Bounds { marking, build: BOARD_P }, cal_b, raw_b, board.full_scale, &acq_b);
        run(&Bounds { marking, build: QEMU_P }, cal_q, raw_q, qemu.full_scale, &acq_q);
    }
    done()
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo<'_>) -> ! {
    fail(b"line-bench panic")
}
