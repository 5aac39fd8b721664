//! Where a certified standard's readings come from, for `standardise` and
//! `verify`: the device with the standard under it (several lines, a
//! simulated device loaded with a scene line of its own for each), or
//! logged readings of it.
use crate::cli::corrected_with::CorrectedWith;
use crate::cli::sim_scene::SimSceneArgs;
use crate::device::link::{Endpoint, PointRecord};
use crate::device::reference::{PointEstimate, PointEstimator};
use anyhow::{Context, ensure};
use brdf_meter::blob::BlobView;
use brdf_meter::protocol::{Encoding, StreamFormat};
use std::path::{Path, PathBuf};

/// The device with the standard under it, or logged readings of it.
#[derive(Clone, Debug, clap::Args)]
#[group(required = true, multiple = false)]
pub struct Source {
    /// Serial port of the instrument, the standard under it (e.g. /dev/ttyACM0).
    #[arg(long, value_name = "PATH")]
    pub port: Option<String>,
    /// TCP serial of the QEMU instrument (e.g. 127.0.0.1:4555, printed by `host-tools qemu`).
    #[arg(long, value_name = "HOST:PORT")]
    pub tcp: Option<String>,
    /// Logged corrected readings of the standard, one row per point with a
    /// `pixel` column (and a `line` column for the black glass, whose
    /// scatter is judged line by line; `simulate`'s and `measure`'s
    /// `points.csv` have both), corrected with this calibration's white
    /// reference (or the one `--corrected-with` names).
    #[arg(long, value_name = "R.csv")]
    pub readings: Option<PathBuf>,
}

/// What reading a standard on the device needs.
pub struct OnDevice<'a> {
    /// The device.
    pub source: &'a Source,
    /// A scene to load a simulated device with.
    pub scene: &'a SimSceneArgs,
    /// Lines to read.
    pub lines: u32,
    /// The calibration's file, as messages name it.
    pub blob_path: &'a Path,
}

/// The standard's points, `a.lines` lines from the device (`what`: the
/// standard, as messages name it). A simulated device holds a few scene
/// lines and cycles through them: with `--scene` it is loaded with the next
/// lines of the scene batch by batch, so every line read is a distinct
/// draw; without, only as many lines are read as it holds (more would
/// repeat draws and understate the scatter).
pub fn read_standard_on_device(a: &OnDevice<'_>, blob: &[u8], what: &str) -> anyhow::Result<Vec<PointRecord>> {
    ensure!(a.lines >= 2, "--lines {}: at least 2 lines of the {what} are needed", a.lines);
    ensure!(
        a.scene.scene_lines.is_none(),
        "--scene-lines: a scene line of its own is loaded for every line read (--lines)"
    );
    let view = BlobView::parse(blob).expect("parsed by the caller");
    let endpoint = Endpoint { port: a.source.port.clone(), tcp: a.source.tcp.clone() };
    let mut c = crate::device::link::Client::new(endpoint.open()?)?;
    let info = c.info().context("asking the device for its information")?;
    crate::device::provision::check_device_runs(info.calibration, view.crc(), a.blob_path)?;
    let held = brdf_meter::shape::qemu::FRAME_LINES as u32;
    let (lines, batch) = match (info.simulated, &a.scene.scene) {
        (false, _) => (a.lines, a.lines),
        (true, Some(_)) => (a.lines, held),
        (true, None) => {
            if a.lines > held {
                println!("a simulated sensor holds {held} distinct lines: reading {held}, not {}", a.lines);
            }
            (a.lines.min(held), held)
        }
    };
    c.timeout = std::time::Duration::from_secs(10);
    c.set_calibration(blob)?;
    c.format = StreamFormat { encoding: Encoding::Corrected, bins: None };
    let progress = crate::output::progress::bar(u64::from(lines) * u64::from(info.pixels), "points");
    let mut points = Vec::with_capacity(lines as usize * usize::from(info.pixels));
    let scene = a.scene.prepare(&info, &view)?;
    if let Some(note) = scene.as_ref().and_then(|s| s.note.as_ref()) {
        eprintln!("note: {note}");
    }
    let mut done = 0;
    while done < lines {
        let n = batch.min(lines - done);
        if let Some(scene) = &scene {
            let first = a.scene.scene_line + u64::from(done);
            crate::cli::sim_scene::load_lines(&mut c, scene, &info, &view, first, n as usize)?;
        }
        points.extend(c.measure_observed(n, &mut |_| progress.inc(1)).with_context(|| format!("reading the {what}"))?);
        done += n;
    }
    progress.finish_and_clear();
    Ok(points)
}

/// A logged point of a standard: its line (when the file has a `line`
/// column), its pixel and its m corrected readings.
pub type LoggedReading = (Option<u64>, usize, Vec<f32>);

/// Logged corrected readings, each with its line (when the file has a
/// `line` column) and pixel, as the calibration `view` would have
/// corrected them (`corrected_with`: the calibration whose white they were
/// corrected with, when not `view`'s). `scene` must name none: logged
/// readings need no simulated device.
pub fn logged_readings(
    path: &Path,
    view: &BlobView<'_>,
    scene: &SimSceneArgs,
    corrected_with: &CorrectedWith,
) -> anyhow::Result<Vec<LoggedReading>> {
    ensure!(scene.scene.is_none(), "--scene loads a simulated device; logged readings (--readings) need none");
    let mut rows = crate::cli::estimate::read_readings(path, view.dims().m)?;
    corrected_with.apply(view, path, &mut rows)?;
    let pixels = view.dims().pixels;
    rows.into_iter()
        .enumerate()
        .map(|(k, r)| {
            let pixel = r.pixel.with_context(|| {
                format!(
                    "{}: row {}: no `pixel` column; a reading of a standard takes every pixel's own readings \
                     (simulate's and measure's points.csv have it)",
                    path.display(),
                    k + 1
                )
            })?;
            ensure!(
                pixel < pixels,
                "{}: row {}: pixel {pixel}: the calibration has pixels 0..={}",
                path.display(),
                k + 1,
                pixels - 1
            );
            Ok((r.line, pixel, r.v))
        })
        .collect()
}

/// Logged corrected readings ([`logged_readings`]) estimated as the device
/// estimates them with the calibration `view`: each with its line (when
/// the file names it) and pixel.
pub fn logged_estimates(
    path: &Path,
    view: &BlobView<'_>,
    scene: &SimSceneArgs,
    corrected_with: &CorrectedWith,
) -> anyhow::Result<Vec<(Option<u64>, usize, PointEstimate)>> {
    let rows = logged_readings(path, view, scene, corrected_with)?;
    let zones = (0..view.dims().zones).map(|z| PointEstimator::new(*view, z)).collect::<anyhow::Result<Vec<_>>>()?;
    Ok(rows
        .iter()
        .map(|(line, pixel, v)| (*line, *pixel, zones[view.zone_of_pixel(*pixel)].apply_pixel(*pixel, v)))
        .collect())
}

/// Writes the readings file `from` to `to` without its first column (the
/// `line` column `simulate` and the tests write first): logged readings
/// that do not name their lines.
#[cfg(test)]
pub(crate) fn write_without_line_column(from: &Path, to: &Path) {
    let text = std::fs::read_to_string(from).unwrap();
    let rows: String = text.lines().map(|l| l.split_once(',').expect("a first column").1.to_string() + "\n").collect();
    std::fs::write(to, rows).unwrap();
}
