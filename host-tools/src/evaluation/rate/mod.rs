//! The instrument's measurement rate, end to end: which stage limits the
//! line rate, for the handheld (the board, P = 128) and the QEMU build
//! (P = 32).
//!
//! - Device compute and framing per line: exact instruction counts of the
//!   line bench firmware (`src/bin/line-bench.rs`, `scripts/line-bench.sh`)
//!   in QEMU, stage by stage (correction, estimation, value encoding,
//!   postcard serialisation, CRC, COBS, the copy to the outgoing frame),
//!   turned into cycles with the Cortex-M4 timings of the kernel bench
//!   (`tradeoff::kernel_bench`) and into time at 80 MHz. Its data: a blob
//!   of the kind `train` ships (scale-free piecewise on the measured
//!   prior, root form, the out-of-prior flag and the gloss readings)
//!   trained for the build's scene, and one line of that scene's raw
//!   frames from the scene simulator.
//! - Acquisition per line: derived from the firmware's settings and the
//!   sensor's timing, for the frames the device takes of that line: the
//!   long exposure's, and the shorter exposures' of the frames that
//!   saturate ([`acquisition`]). The bench corrects the same frames.
//! - The link: bytes and USB packets per line of the frames the device
//!   sends (rebuilt on the host with the same library, [`frames`], and
//!   checked against the bench's frame count), at USB full speed ([`link`]).
//!
//! The three run concurrently (two line buffers: line k+1 is acquired while
//! line k is estimated and sent), except the correction, which the
//! acquisition task runs frame by frame while the next frame's LED settles
//! (the bench replays the line's frames in the order they are read and
//! counts each): what it adds to the acquisition is what is left after the
//! last frame plus each frame's correction beyond its settle. So the line
//! period is the largest of acquisition + that, the CPU's work (compute and
//! framing, every frame's correction, plus the acquisition's own busy time:
//! flush and readout; one core), and the link's time.
pub mod acquisition;
pub mod frames;
pub mod link;
pub mod report;

use crate::calibration::demo::train_scale_free_for_scene;
use crate::evaluation::tradeoff::kernel_bench::Segment;
use crate::forward::scene::Scene;
use crate::forward::scene::frames::{patent_scene, reading_order_le, scene_frames};
use anyhow::{Context, ensure};
use brdf_meter::acquire::AcqConfig;
use brdf_meter::blob::BlobView;
use brdf_meter::protocol::Encoding;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// One build's inputs to the bench.
pub struct BuildInput {
    /// "board" or "qemu".
    pub name: &'static str,
    /// Pixels P.
    pub pixels: usize,
    /// Zones of the trained calibration.
    pub zones: usize,
    /// The calibration blob.
    pub blob: Vec<u8>,
    /// One line of raw frames as the scene simulator serves them: per
    /// exposure level (the long one, then `shorter` of the shorter ones),
    /// frame 0 dark, 1 + k under LED k.
    pub frames: Vec<Vec<u16>>,
    /// Shorter exposures in `frames`.
    pub shorter: usize,
    /// Sensor full scale.
    pub full_scale: u16,
    /// The firmware's acquisition settings.
    pub acq: AcqConfig,
    /// The line's acquisition time.
    pub acquisition: acquisition::LineAcquisition,
    /// Where the scene came from.
    pub scene: String,
    /// What the calibration is.
    pub calibration: String,
}

/// What a bench blob is, read from it (the prior is `train`'s default,
/// the measured one, which the blob does not record).
fn describe(blob: &[u8]) -> anyhow::Result<String> {
    let view = brdf_meter::blob::BlobView::parse(blob).map_err(|e| anyhow::anyhow!("the bench's blob: {e}"))?;
    Ok(format!(
        "{} on the MERL prior, {} form, {} out-of-prior flag, {}",
        crate::calibration::estimators::kind_name(view.estimator()),
        crate::calibration::train::Form::of_blob(&view).name(),
        view.out_of_prior_form().map_or("no", |f| f.name()),
        if view.has_gloss() { "gloss readings" } else { "no gloss readings" }
    ))
}

/// Trains the two builds' calibrations (the kind `train` ships) and
/// simulates a line of each: the handheld scene (`scenes/handheld.toml`,
/// P = 128, `board_zones` zones, at most the board's RAM budget of 8) and
/// the patent-profile scene (P = 32, 1 zone, as the QEMU demo's kind fits
/// its slot). The per-point instruction counts do not depend on the number
/// of zones (the zone only picks the matrices).
pub fn prepare(root: &Path, board_zones: usize) -> anyhow::Result<Vec<BuildInput>> {
    ensure!(
        (1..=brdf_meter::shape::board::RAM_ZONES).contains(&board_zones),
        "board zones {board_zones}: 1 to {} (the board's RAM budget)",
        brdf_meter::shape::board::RAM_ZONES
    );
    let path = root.join("scenes/handheld.toml");
    let handheld = Scene::load(&path).with_context(|| format!("loading {}", path.display()))?;
    ensure!(handheld.instrument.sensor.pixels == BOARD_P, "the handheld scene is not the board's P");
    let acq = brdf_meter::platform::timing::ACQUISITION;
    let board = build::<BOARD_P>(
        ("board", "scenes/handheld.toml", &handheld),
        board_zones,
        handheld.instrument.sensor.full_scale as u16,
        acq,
        |frames| acquisition::board(&acq, BOARD_P, frames),
    )?;
    let qacq = brdf_meter::platform::timing::QEMU_ACQUISITION;
    let qemu = build::<QEMU_P>(
        ("qemu", "patent profile", &patent_scene(QEMU_P)),
        1,
        brdf_meter::shape::qemu::FULL_SCALE,
        qacq,
        |frames| acquisition::qemu(&qacq, frames),
    )?;
    Ok(vec![board, qemu])
}

/// One build's input: a calibration of `zones` zones trained for the
/// scene, one line of its frames, and that line's acquisition (`timing`
/// of the frames the device takes of it).
fn build<const P: usize>(
    (name, label, scene): (&'static str, &str, &Scene),
    zones: usize,
    full_scale: u16,
    acq: AcqConfig,
    timing: impl FnOnce(acquisition::Frames) -> acquisition::LineAcquisition,
) -> anyhow::Result<BuildInput> {
    let blob = train_scale_free_for_scene(scene, zones, 0.02, true)?.blob;
    let frames = scene_frames(scene, 1)?.remove(0);
    let shorter = shorter_in(&frames, brdf_meter::shape::FRAMES_PER_LINE, &acq)?;
    let view = BlobView::parse(&blob).map_err(|e| anyhow::anyhow!("the bench's blob: {e}"))?;
    let taken = frames_taken::<P>(&view, &frames, shorter, full_scale, &acq)?;
    Ok(BuildInput {
        name,
        pixels: P,
        zones,
        calibration: describe(&blob)?,
        acquisition: timing(taken),
        blob,
        frames,
        shorter,
        full_scale,
        acq,
        scene: label.into(),
    })
}

const BOARD_P: usize = brdf_meter::shape::board::PIXELS;
const QEMU_P: usize = brdf_meter::shape::qemu::PIXELS;

/// The shorter exposures a scene's line holds frames of (the patent
/// profile: none; the handheld: the firmware's), at most the firmware's.
fn shorter_in(frames: &[Vec<u16>], per_level: usize, acq: &AcqConfig) -> anyhow::Result<usize> {
    ensure!(
        !frames.is_empty() && frames.len().is_multiple_of(per_level),
        "the scene's line has {} frames, not a whole number of exposures of {per_level}",
        frames.len()
    );
    Ok((frames.len() / per_level - 1).min(acq.short_levels()))
}

/// The frames the device takes of the line, by the acquisition's own rule.
fn frames_taken<const P: usize>(
    view: &BlobView<'_>,
    frames: &[Vec<u16>],
    shorter: usize,
    full_scale: u16,
    acq: &AcqConfig,
) -> anyhow::Result<acquisition::Frames> {
    ensure!(view.dims().m == brdf_meter::shape::LEDS, "the bench's blob has m = {}", view.dims().m);
    let bytes = reading_order_le(view, frames, shorter);
    let raw = brdf_meter::acquire::RawLine::<{ brdf_meter::shape::LEDS }, P>::from_le_frames(&bytes, shorter);
    Ok(acquisition::Frames::taken(&raw, full_scale, acq))
}

/// Writes the line bench's input file (layout: `src/bin/line-bench.rs`):
/// `LBD2`, then per build pixels, full scale, the shorter exposures in its
/// frames, blob length, frames length (u32 LE), the blob padded to 4
/// bytes, the frames (per exposure level the dark frame and the LED frames
/// in reading order, u16 LE).
pub fn write_bench_data(path: &Path, builds: &[BuildInput]) -> anyhow::Result<()> {
    let mut out = b"LBD2".to_vec();
    for b in builds {
        let view = BlobView::parse(&b.blob).map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let frames = reading_order_le(&view, &b.frames, b.shorter);
        for x in [b.pixels, b.full_scale as usize, b.shorter, b.blob.len(), frames.len()] {
            out.extend((x as u32).to_le_bytes());
        }
        out.extend(&b.blob);
        out.resize(out.len().next_multiple_of(4), 0);
        out.extend(frames);
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    crate::output::io::write_atomic(path, &out)
}

/// Runs `scripts/line-bench.sh` in `root` and counts its segments; the
/// trace (hundreds of MB) is deleted once counted.
pub fn run_bench(root: &Path) -> anyhow::Result<Vec<Segment>> {
    crate::evaluation::tradeoff::kernel_bench::run_traced(
        root,
        "scripts/line-bench.sh",
        &root.join("target/line-bench"),
    )
}

/// Instructions and cycles of one stage over a line.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Cost {
    /// Instructions executed (exact, QEMU).
    pub instructions: f64,
    /// Cortex-M4 cycle estimate.
    pub cycles: f64,
}

impl Cost {
    /// Microseconds at the board's 80 MHz.
    pub fn us(&self) -> f64 {
        self.cycles / brdf_meter::platform::timing::SYSCLK_HZ as f64 * 1e6
    }
}

impl std::ops::AddAssign for Cost {
    fn add_assign(&mut self, o: Self) {
        self.instructions += o.instructions;
        self.cycles += o.cycles;
    }
}

/// Per (build pixels, encoding): per stage, its cost over the line and its
/// number of segments (for the framing stages: frames; for `overlap`, the
/// line's frames corrected while the next settles).
pub type StageCosts = BTreeMap<(usize, String), BTreeMap<String, (Cost, usize)>>;

/// The bench's counts: per stage, and per build each overlapped frame's
/// correction on its own (to hold against the settle).
#[derive(Clone, Debug, Default)]
pub struct BenchCosts {
    /// Per build and encoding, per stage.
    pub stages: StageCosts,
    /// Per build pixels, each frame corrected while the next settles, in
    /// the order read.
    pub overlapped: BTreeMap<usize, Vec<Cost>>,
}

/// The stages of an encoding's line, in order: `overlap` (the frames
/// corrected while the next settles), `correct` (what is left after the
/// last frame), then the estimation and framing.
pub const STAGES: [&str; 8] = ["overlap", "correct", "estimate", "push", "serialise", "seal", "stuff", "copy"];

/// Sums the bench's segments by (build pixels, encoding, stage); the
/// correction (run once per build) is filed under every encoding, and
/// protocol 2's stages under "p2" without their prefix.
pub fn stage_costs(segments: &[Segment]) -> anyhow::Result<BenchCosts> {
    let mut out = StageCosts::new();
    let mut correct: BTreeMap<usize, Cost> = BTreeMap::new();
    let mut overlapped: BTreeMap<usize, Vec<Cost>> = BTreeMap::new();
    for s in segments {
        ensure!(s.name.len() == 3, "segment name {:?}", s.name);
        let build: usize = s.name[0].parse().with_context(|| format!("segment build {:?}", s.name))?;
        let cost = Cost { instructions: s.instructions, cycles: s.cycles };
        match s.name[1].as_str() {
            "end" => {}
            "correct" => *correct.entry(build).or_default() += cost,
            "overlap" => overlapped.entry(build).or_default().push(cost),
            stage => {
                let stage = stage.strip_prefix("p2-").unwrap_or(stage);
                let e = out.entry((build, s.name[2].clone())).or_default().entry(stage.to_string()).or_default();
                e.0 += cost;
                e.1 += 1;
            }
        }
    }
    for ((build, _), stages) in out.iter_mut() {
        let c = *correct.get(build).with_context(|| format!("no correction segment for P = {build}"))?;
        stages.insert("correct".into(), (c, 1));
        let frames = overlapped.get(build).map_or(&[][..], Vec::as_slice);
        let mut sum = Cost::default();
        for f in frames {
            sum += *f;
        }
        stages.insert("overlap".into(), (sum, frames.len()));
    }
    Ok(BenchCosts { stages: out, overlapped })
}

/// What a line's correction adds to its acquisition, us: what is left
/// after the last frame (`after_last`), plus each frame's correction, run
/// while the next frame's LED settles, beyond that settle.
pub fn correction_in_series(after_last: Cost, frames: &[Cost], settle_us: f64) -> f64 {
    after_last.us() + frames.iter().map(|f| (f.us() - settle_us).max(0.0)).sum::<f64>()
}

/// The encodings the report covers: the three of protocol 3 and protocol
/// 2's one frame per point.
pub const ENCODINGS: [(&str, Option<Encoding>); 4] = [
    ("sigma16", Some(Encoding::Sigma16)),
    ("f32", Some(Encoding::F32)),
    ("corrected", Some(Encoding::Corrected)),
    ("p2", None),
];

/// One build and encoding's line budget.
#[derive(Clone, Debug, Serialize)]
pub struct EncodingBudget {
    /// Encoding name (`p2`: protocol 2, one f32 frame per point).
    pub encoding: String,
    /// Per stage, in [`STAGES`] order.
    pub stages: Vec<(String, Cost)>,
    /// Everything the CPU does for the line.
    pub compute: Cost,
    /// The line's traffic.
    pub traffic: link::LineTraffic,
    /// Link time at the theoretical and the practical packet rate, us.
    pub link_us: (f64, f64),
    /// Line period, us: the largest of the stages below.
    pub period_us: f64,
    /// The stage that sets it: "acquisition", "CPU" (its work for the line
    /// plus the acquisition's busy time: one core) or "link".
    pub limit: String,
    /// What the correction adds to the acquisition, us: what is left after
    /// the last frame, plus each overlapped frame's correction beyond the
    /// settle it runs in.
    pub correction_in_series_us: f64,
    /// The largest overlapped frame's correction, us (against the settle).
    pub largest_frame_us: f64,
    /// The overlapped frames, and how many of them overrun their settle.
    pub overlapped_frames: (usize, usize),
    /// Compute (without the correction, which the acquisition task runs)
    /// over acquisition time: the target is at most 1/4.
    pub compute_share: f64,
}

/// One build's budget.
#[derive(Clone, Debug, Serialize)]
pub struct BuildBudget {
    /// "board" or "qemu".
    pub name: String,
    /// Pixels.
    pub pixels: usize,
    /// Zones of the calibration measured.
    pub zones: usize,
    /// The scene its line came from.
    pub scene: String,
    /// What the calibration is.
    pub calibration: String,
    /// Acquisition time per line.
    pub acquisition: acquisition::LineAcquisition,
    /// Each frame's correction while the next one settles, us, in the
    /// order read.
    pub overlapped_frame_us: Vec<f64>,
    /// Per encoding.
    pub encodings: Vec<EncodingBudget>,
    /// Sigma16's error against the uncertainty, on this line.
    pub sigma16: frames::QuantisationError,
}

/// The budget of every build and encoding from the bench's counts.
pub fn budget(
    builds: &[BuildInput],
    costs: &BenchCosts,
    practical_packets_per_ms: f64,
) -> anyhow::Result<Vec<BuildBudget>> {
    builds
        .iter()
        .map(|b| {
            let view = BlobView::parse(&b.blob).map_err(|e| anyhow::anyhow!("{e:?}"))?;
            let encodings = ENCODINGS
                .iter()
                .map(|(name, enc)| {
                    let st = costs
                        .stages
                        .get(&(b.pixels, name.to_string()))
                        .with_context(|| format!("no bench counts for P = {}, {name}", b.pixels))?;
                    let line = frames::line_frames(&view, &b.frames, b.full_scale, &b.acq, *enc);
                    let bench_frames = st.get("serialise").map_or(0, |s| s.1);
                    ensure!(
                        bench_frames == line.len(),
                        "P = {}, {name}: the bench framed {bench_frames} frames, the host {}",
                        b.pixels,
                        line.len()
                    );
                    let stages: Vec<(String, Cost)> =
                        STAGES.iter().map(|s| (s.to_string(), st.get(*s).map_or(Cost::default(), |c| c.0))).collect();
                    let mut compute = Cost::default();
                    for (_, c) in &stages {
                        compute += *c;
                    }
                    let in_settles = st.get("overlap").map_or(Cost::default(), |c| c.0);
                    let correct = st.get("correct").map_or(Cost::default(), |c| c.0);
                    let frames = costs.overlapped.get(&b.pixels).map_or(&[][..], Vec::as_slice);
                    let correction_in_series_us = correction_in_series(correct, frames, b.acquisition.settle_us);
                    let largest_frame_us = frames.iter().map(Cost::us).fold(0.0, f64::max);
                    let over = frames.iter().filter(|f| f.us() > b.acquisition.settle_us).count();
                    let traffic = frames::traffic(&line);
                    let link_us =
                        (traffic.time_us(link::THEORETICAL_PACKETS_PER_MS), traffic.time_us(practical_packets_per_ms));
                    // One core: the CPU's period holds its work for the line
                    // and the acquisition's own busy time (flush, readout).
                    let acq_busy = b.acquisition.line_us - b.acquisition.cpu_free_us;
                    let candidates = [
                        ("acquisition", b.acquisition.line_us + correction_in_series_us),
                        ("CPU", compute.us() + acq_busy),
                        ("link", link_us.1),
                    ];
                    let (limit, period_us) =
                        candidates.iter().copied().fold(("", 0.0f64), |a, c| if c.1 > a.1 { c } else { a });
                    Ok(EncodingBudget {
                        encoding: name.to_string(),
                        compute_share: (compute.us() - correct.us() - in_settles.us()) / b.acquisition.line_us,
                        correction_in_series_us,
                        largest_frame_us,
                        overlapped_frames: (frames.len(), over),
                        stages,
                        compute,
                        traffic,
                        link_us,
                        period_us,
                        limit: limit.to_string(),
                    })
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
            Ok(BuildBudget {
                name: b.name.into(),
                pixels: b.pixels,
                zones: b.zones,
                scene: b.scene.clone(),
                calibration: b.calibration.clone(),
                acquisition: b.acquisition.clone(),
                overlapped_frame_us: costs
                    .overlapped
                    .get(&b.pixels)
                    .map_or(vec![], |f| f.iter().map(Cost::us).collect()),
                encodings,
                sigma16: frames::sigma16_error(&view, &b.blob, &b.frames, b.full_scale, &b.acq)?,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seg(name: &str, i: f64) -> Segment {
        Segment { name: name.split(' ').map(str::to_string).collect(), instructions: i, cycles: 2.0 * i }
    }

    #[test]
    fn segments_are_summed_by_build_encoding_and_stage() {
        let segs = [
            seg("128 overlap -", 40.0),
            seg("128 overlap -", 60.0),
            seg("128 correct -", 100.0),
            seg("128 estimate f32", 10.0),
            seg("128 push f32", 5.0),
            seg("128 serialise f32", 1.0),
            seg("128 estimate f32", 10.0),
            seg("128 serialise f32", 2.0),
            seg("128 estimate p2", 10.0),
            seg("128 p2-seal p2", 3.0),
            seg("128 end -", 1e9),
        ];
        let costs = stage_costs(&segs).unwrap();
        let c = &costs.stages;
        let f = &c[&(128, "f32".to_string())];
        assert_eq!(f["overlap"], (Cost { instructions: 100.0, cycles: 200.0 }, 2));
        assert_eq!(costs.overlapped[&128].len(), 2);
        assert_eq!(costs.overlapped[&128][1].instructions, 60.0);
        assert_eq!(f["estimate"], (Cost { instructions: 20.0, cycles: 40.0 }, 2));
        assert_eq!(f["serialise"].1, 2);
        assert_eq!(f["correct"].0.instructions, 100.0);
        assert_eq!(c[&(128, "p2".to_string())]["seal"].0.instructions, 3.0);
        assert!(stage_costs(&[seg("32 estimate f32", 1.0)]).is_err(), "no correction");
    }

    #[test]
    fn only_what_overruns_a_settle_adds_to_the_acquisition() {
        // 80 cycles a microsecond: frames of 150, 250 and 200 us against a
        // settle of 200 us, and 30 us after the last frame.
        let us = |t: f64| Cost { instructions: 0.0, cycles: 80.0 * t };
        let frames = [us(150.0), us(250.0), us(200.0)];
        assert!((correction_in_series(us(30.0), &frames, 200.0) - 80.0).abs() < 1e-9);
        assert!((correction_in_series(us(30.0), &[], 200.0) - 30.0).abs() < 1e-9);
    }
}
