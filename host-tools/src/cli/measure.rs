//! `host-tools measure`: measure lines and write every point as CSV and JSON.
use crate::device::link::{Endpoint, PointRecord};
use crate::forward::scene::frames::{SceneFrames, analytic_scene, patent_scene, scene_frames};
use anyhow::{Context, bail};
use brdf_meter::blob::BlobView;
use brdf_meter::protocol::flags;
use serde::Serialize;
use std::path::PathBuf;

/// Measure N lines; write one row (CSV) / object (JSON) per point with its
/// BRDF vector and the calibration's predicted per-bin uncertainty.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The device.
    #[command(flatten)]
    pub device: Endpoint,
    /// The calibration blob the device runs (for the angle grid and the
    /// per-bin uncertainty; checked against the device's by CRC).
    #[arg(long, value_name = "PATH")]
    pub blob: PathBuf,
    /// Lines to measure.
    #[arg(long, default_value_t = 1)]
    pub lines: u32,
    /// CSV output.
    #[arg(long, value_name = "PATH", default_value = "out/measure.csv")]
    pub csv: PathBuf,
    /// JSON output.
    #[arg(long, value_name = "PATH", default_value = "out/measure.json")]
    pub json: PathBuf,
    /// Simulated devices only: load a scene first: `patent` (host-tools' scene
    /// simulator, patent profile), `analytic` (a simple synthetic pattern) or
    /// a scene TOML file.
    #[arg(long, value_name = "patent|analytic|PATH")]
    pub scene: Option<String>,
    /// Scene lines to load (the device cycles through them), 1..=4.
    #[arg(long, default_value_t = 1)]
    pub scene_lines: usize,
}

#[derive(Serialize)]
struct PointJson<'a> {
    line: u32,
    point: u16,
    zone: u16,
    flags: Vec<&'static str>,
    values: &'a [f32],
    uncertainty: Vec<f32>,
}

#[derive(Serialize)]
struct MeasureJson<'a> {
    blob_crc: u32,
    lines: u32,
    angles_deg: Vec<f32>,
    points: Vec<PointJson<'a>>,
}

fn flag_names(f: u8) -> Vec<&'static str> {
    let mut v = Vec::new();
    if f & flags::SATURATED != 0 {
        v.push("saturated");
    }
    if f & flags::UNDER_EXPOSED != 0 {
        v.push("under-exposed");
    }
    if f & flags::NON_FINITE != 0 {
        v.push("non-finite");
    }
    v
}

/// Loads scene `spec` into a simulated device.
pub fn load_scene<T: crate::device::link::Transport>(
    c: &mut crate::device::link::Client<T>,
    view: &BlobView<'_>,
    spec: &str,
    lines: usize,
    full_scale: u16,
) -> anyhow::Result<SceneFrames> {
    if !(1..=4).contains(&lines) {
        bail!("--scene-lines {lines}: the simulated sensor holds 1 to 4 lines");
    }
    let pixels = view.dims().pixels;
    let frames = match spec {
        "analytic" => analytic_scene(view, lines, full_scale),
        "patent" => scene_frames(&patent_scene(pixels), lines)?,
        path => {
            let mut s = crate::forward::scene::Scene::load(std::path::Path::new(path)).with_context(|| format!("loading scene {path}"))?;
            if s.instrument.sensor.pixels != pixels {
                eprintln!("note: scene {path} has {} pixels; simulating {pixels} for this device", s.instrument.sensor.pixels);
                s.instrument.sensor.pixels = pixels;
            }
            scene_frames(&s, lines)?
        }
    };
    c.load_scene(&frames).context("loading the scene into the simulated sensor")?;
    Ok(frames)
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    if a.lines == 0 {
        bail!("--lines must be at least 1");
    }
    let bytes = std::fs::read(&a.blob).with_context(|| format!("reading {}", a.blob.display()))?;
    let view = BlobView::parse(&bytes).map_err(|e| anyhow::anyhow!("{} is not a valid blob: {e}", a.blob.display()))?;
    let mut c = crate::device::link::Client::new(a.device.open()?)?;
    let info = c.info().context("asking the device for its information")?;
    match info.calibration {
        None => bail!("the device has no calibration: provision {} first (`host-tools provision`)", a.blob.display()),
        Some(cal) if cal.blob_crc != view.crc() => bail!(
            "the device runs calibration {:#010x} but {} is {:#010x}: give the blob it runs, or provision this one",
            cal.blob_crc,
            a.blob.display(),
            view.crc()
        ),
        Some(_) => {}
    }
    if let Some(spec) = &a.scene {
        if !info.simulated {
            bail!("--scene is for simulated devices (QEMU); this device has a real sensor");
        }
        load_scene(&mut c, &view, spec, a.scene_lines, info.full_scale)?;
    }
    c.timeout = std::time::Duration::from_secs(10);
    let points: Vec<PointRecord> = c.measure(a.lines).context("measuring")?;
    let d = view.dims();
    let angles: Vec<f32> = (0..d.n).map(|j| view.grid_deg(j)).collect();
    let unc = |z: u16| -> Vec<f32> { (0..d.n).map(|j| view.uncertainty(z as usize, j)).collect() };
    // CSV: one row per point, rho then uncertainty for each angle.
    let mut csv = String::from("line,point,zone,flags");
    for g in &angles {
        csv.push_str(&format!(",rho_{g}"));
    }
    for g in &angles {
        csv.push_str(&format!(",u_{g}"));
    }
    csv.push('\n');
    for p in &points {
        csv.push_str(&format!("{},{},{},{}", p.line, p.point, p.zone, flag_names(p.flags).join("|")));
        for v in &p.values {
            csv.push_str(&format!(",{v:e}"));
        }
        for u in unc(p.zone) {
            csv.push_str(&format!(",{u:e}"));
        }
        csv.push('\n');
    }
    let json = MeasureJson {
        blob_crc: view.crc(),
        lines: a.lines,
        angles_deg: angles,
        points: points
            .iter()
            .map(|p| PointJson {
                line: p.line,
                point: p.point,
                zone: p.zone,
                flags: flag_names(p.flags),
                values: &p.values,
                uncertainty: unc(p.zone),
            })
            .collect(),
    };
    crate::output::io::write_atomic(&a.csv, csv.as_bytes())?;
    crate::output::io::write_json(&a.json, &json)?;
    let flagged = points.iter().filter(|p| p.flags != 0).count();
    println!(
        "measured {} lines, {} points ({} flagged): {} and {}",
        a.lines,
        points.len(),
        flagged,
        a.csv.display(),
        a.json.display()
    );
    Ok(())
}
