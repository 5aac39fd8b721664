//! The decision's latency and cost, counted exactly in QEMU: the inspection
//! bench firmware (`src/bin/inspect-bench.rs`, run by
//! `scripts/inspect-bench.sh` with an execution trace) runs, on the board's
//! shape (P = 128), what the device does between a line's last LED frame and
//! its verdict (the correction left after that frame, decision, the
//! verdict's frame; each earlier frame's correction, which runs while the
//! next frame's LED settles, and the decision's first part, which runs
//! while the last LED frame integrates, are counted on their own) and, for the
//! comparison, the estimation path of every point; the trace is counted
//! with the kernel bench's counter (instructions exact, Cortex-M4 cycles
//! from its timing table, zero wait states assumed).
use super::lines::{DeviceModel, HostInspector};
use super::teach::{TeachSpec, Window, teach};
use crate::evaluation::tradeoff::kernel_bench::run_traced;
use crate::forward::scene::Scene;
use crate::forward::scene::defects::{DefectScene, DefectSpec, Extent};
use anyhow::ensure;
use brdf_meter::blob::BlobView;
use brdf_meter::inspect::RecipeView;
use brdf_meter::platform::timing::SYSCLK_HZ;
use serde::Serialize;
use std::path::Path;

/// One line's counts.
#[derive(Clone, Debug, Serialize)]
pub struct LineCost {
    /// Which line (defect-free, with a defect).
    pub line: String,
    /// Whether the device rejected it (the firmware's verdict, checked against the host's).
    pub rejected: bool,
    /// Bytes of its verdict frame.
    pub frame_bytes: usize,
    /// Per stage: (name, instructions, cycles).
    pub stages: Vec<(String, f64, f64)>,
    /// Frames corrected while the next one settles (all but the last).
    pub overlapped_frames: usize,
    /// The largest of those frames' corrections, cycles: what must fit in
    /// the settling time for the overlap to cost the line nothing.
    pub overlapped_max_cycles: f64,
    /// The decision's first part, worked out while the last LED frame
    /// integrates, cycles: what must fit in the exposure.
    pub early_cycles: f64,
    /// Points whose first part was worked out then (the rest are worked
    /// out whole after the last frame).
    pub early_points: usize,
    /// Correction left after the last frame + decision + frame, cycles.
    pub latency_cycles: f64,
    /// The same in us at 80 MHz.
    pub latency_us: f64,
    /// Decision cycles per point over the estimation path's per point.
    pub decision_share: f64,
    /// The same with the decision's first part (worked out before the
    /// last frame) counted in.
    pub decision_share_with_early: f64,
}

/// Prepares the data, runs the bench in QEMU and counts it.
pub fn run(root: &Path, zones: usize, progress: &dyn Fn(&str)) -> anyhow::Result<Vec<LineCost>> {
    let p = brdf_meter::shape::board::PIXELS;
    let scene = Scene::load(&root.join("scenes/handheld.toml"))?;
    ensure!(scene.instrument.sensor.pixels == p, "the handheld scene is not the board's P");
    progress("training a scale-free calibration for the handheld");
    let noise = crate::forward::scene::noise_level::relative_noise_level(&scene)?;
    let blob = crate::calibration::demo::train_scale_free_for_scene(&scene, zones, noise, false)?.blob;
    let view = BlobView::parse(&blob).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let full_scale = scene.instrument.sensor.full_scale.round() as u16;
    let model = DeviceModel::new(view, full_scale, brdf_meter::platform::timing::ACQUISITION)?;
    // The 8-zone calibration (the board's RAM budget) reads gloss with an sd
    // of ~1.3 GU per pixel on this sample: a +-4 GU window keeps the
    // defect-free line good (the figures are the decision's cost, not its
    // sensitivity: `inspect roc` has that).
    progress("teaching a recipe on 100 lines");
    let clean = DefectScene::new("defect-free", scene.clone(), &[])?;
    let lines = (0..100).map(|l| Ok(model.correct(&clean.raw_frames_at(l)?))).collect::<anyhow::Result<Vec<_>>>()?;
    let spec = TeachSpec { windows: [Window::Absolute(-4.0, 4.0), Window::Off, Window::Off], ..TeachSpec::default() };
    let recipe = teach(&model, &lines, &spec)?.bytes;
    let scratch = DefectSpec::Scratch {
        at: Extent { first_pixel: 60, pixels: 4, first_line: 0, lines: 1 << 40 },
        brdf: crate::forward::brdf::BrdfSpec::Ward { rho_d: 0.6, rho_s: Some(0.2), alpha: 0.3 },
    };
    let defect = DefectScene::new("scratch", scene.clone(), &[scratch])?;
    let frames = [clean.raw_frames_at(200)?, defect.raw_frames_at(201)?];
    // The host's verdicts, the same way (one inspection, two lines).
    let rv = RecipeView::parse(&recipe).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let mut host = HostInspector::new(p)?;
    let want: Vec<bool> = frames
        .iter()
        .enumerate()
        .map(|(k, f)| host.line(&rv, &model, k as u32, &model.correct(f)).rejected())
        .collect();
    let data = bench_data(&blob, &recipe, &frames, &view, full_scale)?;
    let dir = root.join("target/inspect-bench");
    std::fs::create_dir_all(&dir)?;
    crate::output::io::write_atomic(&dir.join("data.bin"), &data)?;
    progress("running the bench in QEMU (instruction trace)");
    let segs = run_traced(root, "scripts/inspect-bench.sh", &dir)?;
    let stdout = std::fs::read_to_string(dir.join("stdout.txt"))?;
    let verdicts: Vec<(bool, usize, usize)> = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("VERDICT "))
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            let number = |i: usize| w.get(i).and_then(|n| n.parse().ok()).unwrap_or(0);
            (w.get(1) == Some(&"reject"), number(2), number(3))
        })
        .collect();
    ensure!(verdicts.len() == frames.len(), "the bench printed {} verdicts for {} lines", verdicts.len(), frames.len());
    let names = ["defect-free", "4-pixel scratch"];
    let mut out = Vec::new();
    for (k, (rejected, bytes, early_points)) in verdicts.into_iter().enumerate() {
        ensure!(
            rejected == want[k],
            "line {k}: the firmware's verdict (reject {rejected}) is not the host's ({})",
            want[k]
        );
        let stages: Vec<(String, f64, f64)> = segs
            .iter()
            .filter(|s| {
                s.name.first().map(String::as_str) == Some(&k.to_string())
                    && s.name.get(1).map(String::as_str) != Some("end")
            })
            .map(|s| (s.name[1].clone(), s.instructions, s.cycles))
            .collect();
        let cyc = |n: &str| stages.iter().filter(|s| s.0 == n).map(|s| s.2).sum::<f64>();
        let latency = cyc("correct") + cyc("decide") + cyc("frame");
        let overlapped: Vec<f64> = stages.iter().filter(|s| s.0 == "overlap").map(|s| s.2).collect();
        out.push(LineCost {
            line: names[k].into(),
            rejected,
            frame_bytes: bytes,
            overlapped_frames: overlapped.len(),
            overlapped_max_cycles: overlapped.iter().copied().fold(0.0, f64::max),
            early_cycles: cyc("early"),
            early_points,
            latency_cycles: latency,
            latency_us: latency / SYSCLK_HZ as f64 * 1e6,
            decision_share: cyc("decide") / cyc("estimate"),
            decision_share_with_early: (cyc("early") + cyc("decide")) / cyc("estimate"),
            stages,
        });
    }
    Ok(out)
}

/// The bench's input (layout: `src/bin/inspect-bench.rs`): `IBD1`, P, full
/// scale, blob, recipe and frames lengths (u32 LE), the blob and the recipe
/// each padded to 4 bytes, then per line per exposure level (long, then the
/// shorter ones) the dark frame and the LED frames in reading order (u16 LE).
fn bench_data(
    blob: &[u8],
    recipe: &[u8],
    lines: &[Vec<Vec<u16>>],
    view: &BlobView<'_>,
    full_scale: u16,
) -> anyhow::Result<Vec<u8>> {
    let m = view.dims().m;
    let shorter = brdf_meter::acquire::MAX_SHORT_EXPOSURES;
    let mut frames = Vec::new();
    for f in lines {
        ensure!(f.len() >= (1 + shorter) * (m + 1), "the scene lists fewer shorter exposures than the device takes");
        frames.extend(crate::forward::scene::frames::reading_order_le(view, f, shorter));
    }
    let mut out = b"IBD1".to_vec();
    for x in [view.dims().pixels, full_scale as usize, blob.len(), recipe.len(), frames.len()] {
        out.extend((x as u32).to_le_bytes());
    }
    for part in [blob, recipe] {
        out.extend(part);
        out.resize(out.len().next_multiple_of(4), 0);
    }
    out.extend(frames);
    Ok(out)
}
