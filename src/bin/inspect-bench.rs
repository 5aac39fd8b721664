//! Inspection bench firmware for QEMU (b-l475e-iot01a): what the device runs
//! for an inspected line between the last LED frame and the verdict, stage
//! by stage, on real data, so that `scripts/inspect-bench.sh` can count each
//! stage's instructions exactly from QEMU's execution trace (as the line
//! bench does) and `host-tools inspect bench` can report the decision
//! latency and the decision's cost against the estimation path.
//!
//! Input: `target/inspect-bench/data.bin` (written by `host-tools inspect
//! bench`), read over semihosting: the board's shape (P = 128), a trained
//! calibration, a recipe taught for it, and two lines of raw frames (a
//! defect-free one, one with a defect). Per line, between calls of
//! [`bench_mark`]:
//! - `overlap`, once per frame but the last, in the order the acquisition
//!   reads them (`RawLine::frames_read`): that frame's correction
//!   (`acquire::LineCorrection::frame`), which the acquisition task runs
//!   while the next frame's LED settles, so it is not in the latency; each
//!   is counted, so the largest can be held against the settling time;
//! - `early`: the first part of each point's decision
//!   (`UnscaledLine::work_out`, for the pixels whose other readings are
//!   corrected), which the acquisition task works out while the last LED's
//!   long frame integrates, so it is not in the latency either;
//! - `correct`: what is left after the last frame: its correction and
//!   `LineCorrection::finish`;
//! - `decide`: `Inspector::line_with` those first parts (the rest of each
//!   point's statistics and the whole statistics of the points without
//!   one, windows, runs, drift; the calibration's out-of-prior question at
//!   the points out);
//! - `frame`: the verdict's frame (postcard, CRC, COBS: `protocol::encode`);
//! - `estimate`: `Calibration::estimate_point` for every point: the
//!   estimation path a measurement runs instead, for the comparison.
#![no_std]
#![no_main]

use brdf_meter::acquire::by_frame::Target;
use brdf_meter::acquire::{FrameRead, LineCorrection, MAX_SHORT_EXPOSURES, RawLine};
use brdf_meter::blob::BlobView;
use brdf_meter::estimate::{Calibration, ZoneMatrix};
use brdf_meter::in_place::zeroed;
use brdf_meter::inspect::decide::UnscaledLine;
use brdf_meter::inspect::{Inspector, RecipeView};
use brdf_meter::nalgebra::SVector;
use brdf_meter::protocol::{self, MAX_FRAME, Response, flags};
use brdf_meter::shape;
use brdf_meter::store::SlotInfo;
use cortex_m_rt::entry;

#[path = "bench_io/mod.rs"]
mod bench_io;
use bench_io::{Aligned, Line, bench_mark, done, fail, read_file, u32_at};

const N: usize = shape::BINS;
const M: usize = shape::LEDS;
const P: usize = shape::board::PIXELS;
const DATA_LEN: usize = 56 * 1024;

static mut DATA: Aligned<DATA_LEN> = Aligned([0; DATA_LEN]);
static mut RAM: [ZoneMatrix<N, M>; shape::board::RAM_ZONES] =
    [ZoneMatrix::from_array_storage(brdf_meter::nalgebra::ArrayStorage([[0.0; M]; N])); shape::board::RAM_ZONES];
static mut INSPECTOR: Inspector<P> = Inspector::new();
/// In SRAM2: SRAM1 holds the data, the matrices and the stack.
#[unsafe(link_section = ".sram2")]
static mut EARLY: core::mem::MaybeUninit<UnscaledLine<P>> = core::mem::MaybeUninit::uninit();
/// The calibration, the line replayed and its corrected readings, in SRAM2
/// too: as locals of `main` they took 14 KB of its 16 KB stack.
#[unsafe(link_section = ".sram2")]
static mut CAL: core::mem::MaybeUninit<Calibration<N, M, P>> = core::mem::MaybeUninit::uninit();
#[unsafe(link_section = ".sram2")]
static mut RAW: core::mem::MaybeUninit<RawLine<M, P>> = core::mem::MaybeUninit::uninit();
#[unsafe(link_section = ".sram2")]
static mut V: core::mem::MaybeUninit<[SVector<f32, M>; P]> = core::mem::MaybeUninit::uninit();
static mut OUT: [u8; MAX_FRAME] = [0; MAX_FRAME];

/// Names the segments (first pass) or marks them (second pass).
fn at(marking: bool, line: usize, stage: &[u8]) {
    if marking {
        bench_mark();
    } else {
        let mut l = Line::new();
        l.push(b"SEG ");
        l.num(line as u32);
        l.push(b" ");
        l.push(stage);
        l.end();
    }
}

/// Bytes of one line in the data: every exposure level's dark and LED frames.
const LINE_BYTES: usize = 2 * P * (M + 1) * (1 + MAX_SHORT_EXPOSURES);

#[entry]
fn main() -> ! {
    // SAFETY: single-threaded firmware, no interrupts use these statics;
    // zeros are a line (integers, `bool`s), readings and first parts
    // (`f32`s, `bool`s: `UnscaledLine::new()`).
    let (data, ram, inspector, early, out, cal, raw, v) = unsafe {
        (
            &mut (*core::ptr::addr_of_mut!(DATA)).0,
            &mut *core::ptr::addr_of_mut!(RAM),
            &mut *core::ptr::addr_of_mut!(INSPECTOR),
            zeroed(&mut *core::ptr::addr_of_mut!(EARLY)),
            &mut *core::ptr::addr_of_mut!(OUT),
            &mut *core::ptr::addr_of_mut!(CAL),
            zeroed(&mut *core::ptr::addr_of_mut!(RAW)),
            zeroed(&mut *core::ptr::addr_of_mut!(V)),
        )
    };
    let n = read_file(b"target/inspect-bench/data.bin\0", data);
    let data: &'static [u8] = &data[..n];
    if n < 24 || &data[..4] != b"IBD1" || u32_at(data, 4) != P {
        fail(b"inspect-bench: no data for P = 128 (run `host-tools inspect bench`)");
    }
    let full_scale = u32_at(data, 8) as u16;
    let (blob_len, recipe_len, frames_len) = (u32_at(data, 12), u32_at(data, 16), u32_at(data, 20));
    let blob = &data[24..24 + blob_len];
    let recipe_at = 24 + blob_len.div_ceil(4) * 4;
    let recipe = &data[recipe_at..recipe_at + recipe_len];
    let frames_at = recipe_at + recipe_len.div_ceil(4) * 4;
    let frames = &data[frames_at..frames_at + frames_len];
    let view = BlobView::parse(blob).unwrap_or_else(|_| fail(b"inspect-bench: bad blob"));
    let cal = cal.write(Calibration::<N, M, P>::new(ram));
    if cal.load(&view, SlotInfo { slot: 0, sequence: 1, blob_len: blob.len() as u32, blob_crc: 0 }).is_err() {
        fail(b"inspect-bench: the blob does not fit this build");
    }
    let recipe = RecipeView::parse(recipe).unwrap_or_else(|_| fail(b"inspect-bench: bad recipe"));
    let acq = brdf_meter::platform::timing::ACQUISITION;
    let (active, pixels) = cal.loaded().expect("loaded");
    let (white, linearity) = (&pixels.white, active.linearity.as_ref());
    let lines = frames.len() / LINE_BYTES;
    for marking in [false, true] {
        for l in 0..lines {
            raw.read_le_frames(&frames[l * LINE_BYTES..], MAX_SHORT_EXPOSURES);
            v.iter_mut().for_each(|x| *x = SVector::zeros());
            let mut fl = [0u8; P];
            let mut by_frame = LineCorrection::<M, P>::new();
            let read: heapless::Vec<FrameRead, { 1 + M * (1 + MAX_SHORT_EXPOSURES) }> =
                raw.frames_read(full_scale, acq.short_levels()).collect();
            if read.is_empty() {
                fail(b"inspect-bench: a line without frames");
            }
            early.clear();
            for (k, f) in read.iter().enumerate() {
                if *f == FrameRead::Long(M - 1) {
                    // While that frame integrates, before its correction.
                    at(marking, l, b"early");
                    let _ = early.work_out(&recipe, v, |p| by_frame.final_through(p, M - 1));
                }
                let mut t = Target { raw, white, linearity, full_scale, cfg: &acq, v, fl: &mut fl };
                if k + 1 == read.len() {
                    at(marking, l, b"correct");
                    by_frame.frame(*f, &mut t);
                    by_frame.finish(&mut t);
                } else {
                    at(marking, l, b"overlap");
                    by_frame.frame(*f, &mut t);
                }
            }
            at(marking, l, b"decide");
            let verdict = inspector.line_with(&recipe, l as u32, &v[..], &fl, Some(early), |p| {
                let mut rho = SVector::<f32, N>::zeros();
                cal.estimate_point(p, &v[p], fl[p], &mut rho).flags & flags::OUT_OF_PRIOR != 0
            });
            at(marking, l, b"frame");
            let n = protocol::encode(1, &Response::Verdict(verdict), out).unwrap_or(0);
            core::hint::black_box(&out[..n]);
            at(marking, l, b"estimate");
            let mut rho = SVector::<f32, N>::zeros();
            for p in 0..P {
                core::hint::black_box(cal.estimate_point(p, &v[p], fl[p], &mut rho));
            }
            at(marking, l, b"end");
            if !marking {
                let mut s = Line::new();
                s.push(b"VERDICT ");
                s.num(l as u32);
                s.push(if verdict.rejected() { b" reject " } else { b" good " });
                s.num(n as u32);
                s.push(b" ");
                s.num(early.ready() as u32);
                s.end();
            }
        }
    }
    done()
}
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo<'_>) -> ! {
    fail(b"inspect-bench panic")
}
