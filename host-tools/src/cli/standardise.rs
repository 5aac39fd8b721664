//! `host-tools standardise`: standardise a calibration on a certified
//! white tile (`calibration::standardise`): read the tile, on the device
//! (its corrected readings, several lines) or from logged readings, and
//! write the calibration with its white reference rescaled so the tile
//! reads its certified value again. Everything is checked before anything
//! is written; the device is not touched (provision the result with
//! `host-tools provision`, which keeps the last good calibration if it
//! fails).
use crate::calibration::standardise::{Standardisation, Tile, TileReading, standardise};
use crate::device::link::{Endpoint, PointRecord};
use anyhow::{Context, ensure};
use brdf_meter::blob::BlobView;
use brdf_meter::protocol::{Encoding, StreamFormat};
use std::path::PathBuf;

/// Standardise a calibration on a certified white tile: the white reference
/// rescaled by the tile's readings, for LEDs that drifted since calibration.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The calibration to standardise: the signed file the device runs, or
    /// the unsigned blob it was signed from.
    #[arg(long, value_name = "CAL")]
    pub blob: PathBuf,
    /// The tile's certified reflectance factor at the instrument's geometry
    /// (a perfect diffuser is 1).
    #[arg(long, value_name = "RF")]
    pub tile_rf: f64,
    /// Its standard uncertainty (k = 1) from the certificate.
    #[arg(long, value_name = "U", default_value_t = 0.0)]
    pub tile_u: f64,
    /// Where the tile's readings come from.
    #[command(flatten)]
    pub source: Source,
    /// Lines of the tile to read on the device.
    #[arg(long, default_value_t = 32)]
    pub lines: u32,
    /// A scene for a simulated device: the white tile under the
    /// calibration's instrument (e.g. scenes/matte-white.toml, or
    /// `--scene-surface` on the instrument's own scene).
    #[command(flatten)]
    pub scene: crate::cli::sim_scene::SimSceneArgs,
    /// Where to write the standardised calibration.
    #[arg(long, value_name = "OUT")]
    pub out: PathBuf,
    /// Sign it with this secret key (`host-tools keygen`); without it the
    /// blob is written unsigned (`host-tools sign` it before provisioning).
    #[arg(long, value_name = "KEY")]
    pub key: Option<PathBuf>,
    /// Also write what was found (per LED: drift, scatter; the new white's
    /// uncertainty) as JSON here.
    #[arg(long, value_name = "PATH")]
    pub report: Option<PathBuf>,
}

/// The device with the tile under it, or logged readings of the tile.
#[derive(Clone, Debug, clap::Args)]
#[group(required = true, multiple = false)]
pub struct Source {
    /// Serial port of the instrument, the tile under it (e.g. /dev/ttyACM0).
    #[arg(long, value_name = "PATH")]
    pub port: Option<String>,
    /// TCP serial of the QEMU instrument (e.g. 127.0.0.1:4555, printed by `host-tools qemu`).
    #[arg(long, value_name = "HOST:PORT")]
    pub tcp: Option<String>,
    /// Logged corrected readings of the tile, one row per point with `line`
    /// and `pixel` columns (`simulate`'s `points.csv`), corrected with this
    /// calibration's white reference.
    #[arg(long, value_name = "R.csv")]
    pub readings: Option<PathBuf>,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let tile = Tile::new(a.tile_rf, a.tile_u)?;
    let file = crate::device::provision::read_blob_to_decode(&a.blob)?;
    let view = BlobView::parse(&file).expect("read_blob_to_decode checked it");
    let blob = view.as_bytes().to_vec();
    let secret = a.key.as_deref().map(crate::calibration::signing::read_secret).transpose()?;
    let (s, source) = match &a.source.readings {
        Some(path) => {
            ensure!(
                a.scene.scene.is_none(),
                "--scene loads a simulated device; logged readings (--readings) need none"
            );
            let rows = crate::cli::estimate::read_readings(path, view.dims().m)?;
            let mut points = Vec::with_capacity(rows.len());
            for (k, r) in rows.iter().enumerate() {
                let pixel = r.pixel.with_context(|| {
                    format!(
                        "{}: row {}: no `pixel` column; a standardisation reads every pixel's own readings \
                         (simulate's points.csv has one)",
                        path.display(),
                        k + 1
                    )
                })?;
                points.push(TileReading { pixel, v: &r.v, flags: 0 });
            }
            let s = standardise(&view, points, tile).with_context(|| format!("{}", path.display()))?;
            (s, path.display().to_string())
        }
        None => {
            let points = read_tile_on_device(&a, &blob)?;
            let s = standardise(
                &view,
                points.iter().map(|p| TileReading { pixel: usize::from(p.point), v: &p.corrected, flags: p.flags }),
                tile,
            )
            .context("the device's readings of the tile")?;
            (s, "the device".to_string())
        }
    };
    let new = s.blob(&blob)?;
    let crc = BlobView::parse(&new).expect("rewrite_white parsed it").crc();
    let (bytes, signed) = match &secret {
        Some(seed) => (crate::calibration::signing::sign_blob(&new, seed), true),
        None => (new, false),
    };
    crate::output::io::write_atomic(&a.out, &bytes).with_context(|| format!("writing {}", a.out.display()))?;
    if let Some(r) = &a.report {
        crate::output::io::write_json(r, &Report { source: &source, crc_after: crc, standardisation: &s })?;
    }
    print!("{}", s.table());
    println!(
        "wrote {} ({} bytes, calibration {:#010x} -> {crc:#010x}, {}){}",
        a.out.display(),
        bytes.len(),
        s.crc_before,
        if signed { "signed" } else { "unsigned: `host-tools sign` it before provisioning" },
        a.report.as_ref().map_or(String::new(), |r| format!(" and {}", r.display()))
    );
    println!(
        "provision it with `host-tools provision`; an inspection recipe taught with {:#010x} must be taught again",
        s.crc_before
    );
    Ok(())
}

/// The JSON report.
#[derive(serde::Serialize)]
struct Report<'a> {
    source: &'a str,
    crc_after: u32,
    #[serde(flatten)]
    standardisation: &'a Standardisation,
}

/// The tile's corrected readings, `a.lines` lines from the device. A
/// simulated device holds a few scene lines and cycles through them: with
/// `--scene` it is loaded with the next lines of the scene batch by batch,
/// so every line read is a distinct draw; without, only as many lines are
/// read as it holds (more would repeat draws and understate the scatter).
fn read_tile_on_device(a: &Args, blob: &[u8]) -> anyhow::Result<Vec<PointRecord>> {
    ensure!(a.lines >= 2, "--lines {}: a standardisation needs at least 2 lines of the tile", a.lines);
    ensure!(
        a.scene.scene_lines.is_none(),
        "--scene-lines: standardise loads a scene line of its own for every line it reads (--lines)"
    );
    let view = BlobView::parse(blob).expect("parsed by the caller");
    let endpoint = Endpoint { port: a.source.port.clone(), tcp: a.source.tcp.clone() };
    let mut c = crate::device::link::Client::new(endpoint.open()?)?;
    let info = c.info().context("asking the device for its information")?;
    crate::device::provision::check_device_runs(info.calibration, view.crc(), &a.blob)?;
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
        points.extend(c.measure_observed(n, &mut |_| progress.inc(1)).context("reading the tile")?);
        done += n;
    }
    progress.finish_and_clear();
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn args(blob: &Path, readings: &Path, out: &Path) -> Args {
        Args {
            blob: blob.into(),
            tile_rf: 0.9,
            tile_u: 0.002,
            source: Source { port: None, tcp: None, readings: Some(readings.into()) },
            lines: 32,
            scene: Default::default(),
            out: out.into(),
            key: Some(crate::calibration::signing::dev_key_path()),
            report: Some(out.with_extension("json")),
        }
    }

    /// The patent profile's matt white tile (Lambertian 0.9), its LEDs 4 %
    /// brighter than when the calibration was trained: the standardised
    /// calibration reads the tile at 0.9 again, and is signed.
    #[test]
    fn a_drifted_tile_reads_its_certified_value_after_standardisation() {
        let dir = tempfile::tempdir().unwrap();
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let scene = crate::forward::scene::Scene::load(&root.join("scenes/matte-white.toml")).unwrap();
        // 16 lines of the tile, each reading 4 % high.
        let (out, _) = crate::forward::scene::readings::simulate_lines(&scene, 0, 16).unwrap();
        // What the white reference holds does not matter here: the
        // readings are taken as corrected with it.
        let blob = brdf_meter::test_blobs::test_blob(9, out.leds.len(), 1, out.pixels, 0.5);
        let cal = dir.path().join("cal.blob");
        std::fs::write(&cal, &blob).unwrap();
        let mut csv = crate::forward::scene::readings::points_csv(&out).unwrap();
        let text = String::from_utf8(csv.clone()).unwrap();
        let mut lines = text.lines();
        let mut drifted = format!("{}\n", lines.next().unwrap());
        for l in lines {
            let f: Vec<&str> = l.split(',').collect();
            let v: Vec<String> = f[2..].iter().map(|x| format!("{}", x.parse::<f64>().unwrap() * 1.04)).collect();
            drifted += &format!("{},{},{}\n", f[0], f[1], v.join(","));
        }
        csv = drifted.into_bytes();
        let readings = dir.path().join("tile.csv");
        std::fs::write(&readings, &csv).unwrap();
        let new = dir.path().join("cal-std.signed");
        run(args(&cal, &readings, &new)).unwrap();
        let image = crate::device::provision::read_blob(&new).unwrap();
        let v = BlobView::parse(&image).unwrap();
        let old = BlobView::parse(&blob).unwrap();
        let (p, m) = (old.dims().pixels, old.dims().m);
        // Every white value rose by the drift, within the noise of 16 lines.
        let mut ratios: Vec<f64> =
            (0..p * m).map(|k| f64::from(v.white(k / m, k % m)) / f64::from(old.white(k / m, k % m))).collect();
        ratios.sort_by(f64::total_cmp);
        let median = ratios[ratios.len() / 2];
        assert!((median - 1.04).abs() < 0.005, "median ratio {median}");
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(new.with_extension("json")).unwrap()).unwrap();
        assert_eq!(report["tile"]["rf"], 0.9);
        assert_eq!(report["crc_after"], v.crc());
        assert_eq!(v.white_uncertainty(), report["u_rel"].as_f64().unwrap() as f32);
        assert!(report["u_rel"].as_f64().unwrap() > 0.002 / 0.9);
        // A tile certified at another value is refused, and nothing is written.
        let refused = dir.path().join("refused.blob");
        let mut bad = args(&cal, &readings, &refused);
        bad.tile_rf = 0.3;
        let e = format!("{:#}", run(bad).unwrap_err());
        assert!(e.contains("times its certified 0.3"), "{e}");
        assert!(!refused.exists() && !refused.with_extension("json").exists());
    }
}
