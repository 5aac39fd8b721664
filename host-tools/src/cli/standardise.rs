//! `host-tools standardise`: standardise a calibration on a certified
//! white tile (`calibration::standardise`) or its gloss scale on a
//! certified black glass (`calibration::standardise_gloss`): read the
//! standard, on the device (several lines) or from logged readings, and
//! write the calibration with its white reference (or gloss references)
//! rescaled so the standard reads its certified value again. Everything is
//! checked before anything is written; the device is not touched
//! (provision the result with `host-tools provision`, which keeps the last
//! good calibration if it fails).
use crate::calibration::standardise::{Standardisation, Tile, TileReading, standardise};
use crate::calibration::standardise_gloss::{BlackGlass, GlossReading, GlossStandardisation, standardise_gloss};
use crate::cli::certificate::CertificateUncertainty;
pub use crate::cli::standard_source::Source;
use crate::cli::standard_source::{OnDevice, logged_estimates, logged_readings, read_standard_on_device};
use anyhow::{Context, ensure};
use brdf_meter::blob::BlobView;
use std::path::PathBuf;

/// Standardise a calibration on a certified white tile (the white reference
/// rescaled by the tile's readings, for LEDs that drifted since
/// calibration), or its gloss scale on a certified black glass (right after
/// the white).
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("standard").required(true).args(["tile_rf", "black_glass_gu"])))]
pub struct Args {
    /// The calibration to standardise: the signed file the device runs, or
    /// the unsigned blob it was signed from.
    #[arg(long, value_name = "CAL")]
    pub blob: PathBuf,
    /// The white tile's certified reflectance factor at the instrument's
    /// geometry (a perfect diffuser is 1).
    #[arg(long, value_name = "RF")]
    pub tile_rf: Option<f64>,
    /// Its uncertainty from the certificate: the standard uncertainty
    /// (k = 1), or with --tile-k the expanded uncertainty U it prints.
    #[arg(long, value_name = "U", default_value_t = 0.0)]
    pub tile_u: f64,
    /// The coverage factor the certificate states --tile-u at (e.g. 2):
    /// the standard uncertainty is then U / k.
    #[arg(long, value_name = "K")]
    pub tile_k: Option<f64>,
    /// Or the black-glass gloss standard's certified gloss at the
    /// instrument's geometry, GU: the gloss scale is standardised on it.
    /// Standardise on the white tile first.
    #[arg(long, value_name = "GU")]
    pub black_glass_gu: Option<f64>,
    /// Its uncertainty from the certificate, GU: the standard uncertainty
    /// (k = 1), or with --black-glass-k the expanded uncertainty U it prints.
    #[arg(long, value_name = "U", default_value_t = 0.0)]
    pub black_glass_u: f64,
    /// The coverage factor the certificate states --black-glass-u at (e.g.
    /// 2): the standard uncertainty is then U / k.
    #[arg(long, value_name = "K")]
    pub black_glass_k: Option<f64>,
    /// Where the standard's readings come from.
    #[command(flatten)]
    pub source: Source,
    /// The calibration logged readings were corrected with, when not this one.
    #[command(flatten)]
    pub corrected_with: crate::cli::corrected_with::CorrectedWith,
    /// Lines of the standard to read on the device.
    #[arg(long, default_value_t = 32)]
    pub lines: u32,
    /// A scene for a simulated device: the standard under the
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
    /// uncertainty; or the gloss scale's) as JSON here.
    #[arg(long, value_name = "PATH")]
    pub report: Option<PathBuf>,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    a.corrected_with.check_logged(a.source.readings.is_some())?;
    let file = crate::device::provision::read_blob_to_decode(&a.blob)?;
    let view = BlobView::parse(&file).expect("read_blob_to_decode checked it");
    let blob = view.as_bytes().to_vec();
    let secret = a.key.as_deref().map(crate::calibration::signing::read_secret).transpose()?;
    let found = match (a.tile_rf, a.black_glass_gu) {
        (Some(rf), None) => {
            ensure!(
                a.black_glass_u == 0.0 && a.black_glass_k.is_none(),
                "--black-glass-u and --black-glass-k go with --black-glass-gu, not --tile-rf"
            );
            let u = CertificateUncertainty { u: a.tile_u, k: a.tile_k, flags: ("--tile-u", "--tile-k") };
            let tile = u.checked(|u| Tile::new(rf, u))?;
            Found::White(white(&a, &view, &blob, tile)?)
        }
        (None, Some(gu)) => {
            ensure!(
                a.tile_u == 0.0 && a.tile_k.is_none(),
                "--tile-u and --tile-k go with --tile-rf, not --black-glass-gu"
            );
            let u = CertificateUncertainty {
                u: a.black_glass_u,
                k: a.black_glass_k,
                flags: ("--black-glass-u", "--black-glass-k"),
            };
            let glass = u.checked(|u| BlackGlass::new(gu, u))?;
            Found::Gloss(gloss(&a, &view, &blob, glass)?)
        }
        _ => unreachable!("clap requires exactly one of --tile-rf and --black-glass-gu"),
    };
    let (new, crc_before, table) = match &found {
        Found::White((s, _)) => (s.blob(&blob)?, s.crc_before, s.table()),
        Found::Gloss((s, _)) => (s.blob(&blob)?, s.crc_before, s.table()),
    };
    let crc = BlobView::parse(&new).expect("the rewrite parsed it").crc();
    let (bytes, signed) = match &secret {
        Some(seed) => (crate::calibration::signing::sign_blob(&new, seed), true),
        None => (new, false),
    };
    crate::output::io::write_atomic(&a.out, &bytes).with_context(|| format!("writing {}", a.out.display()))?;
    if let Some(r) = &a.report {
        match &found {
            Found::White((s, source)) => {
                crate::output::io::write_json(r, &Report { source, crc_after: crc, standardisation: s })?
            }
            Found::Gloss((s, source)) => {
                crate::output::io::write_json(r, &Report { source, crc_after: crc, standardisation: s })?
            }
        }
    }
    print!("{table}");
    println!(
        "wrote {} ({} bytes, calibration {crc_before:#010x} -> {crc:#010x}, {}){}",
        a.out.display(),
        bytes.len(),
        if signed { "signed" } else { "unsigned: `host-tools sign` it before provisioning" },
        a.report.as_ref().map_or(String::new(), |r| format!(" and {}", r.display()))
    );
    if matches!(found, Found::White(_)) && view.gloss_uncertainty() > 0.0 {
        println!(
            "its gloss scale was standardised on the black glass, and is kept: standardise on the black glass again \
             now, so the gloss scale rests on this white"
        );
    }
    println!(
        "provision it with `host-tools provision`; an inspection recipe taught with {crc_before:#010x} must be taught \
         again"
    );
    Ok(())
}

impl Args {
    /// What reading the standard on the device needs.
    fn on_device(&self) -> OnDevice<'_> {
        OnDevice { source: &self.source, scene: &self.scene, lines: self.lines, blob_path: &self.blob }
    }
}

/// What was standardised, and where its readings came from.
enum Found {
    White((Standardisation, String)),
    Gloss((GlossStandardisation, String)),
}

/// The white tile's standardisation, from logged readings or the device.
fn white(a: &Args, view: &BlobView<'_>, blob: &[u8], tile: Tile) -> anyhow::Result<(Standardisation, String)> {
    match &a.source.readings {
        Some(path) => {
            let rows = logged_readings(path, view, &a.scene, &a.corrected_with)?;
            let points = rows.iter().map(|(_, pixel, v)| TileReading { pixel: *pixel, v, flags: 0 });
            let s = standardise(view, points, tile).with_context(|| format!("{}", path.display()))?;
            Ok((s, path.display().to_string()))
        }
        None => {
            let points = read_standard_on_device(&a.on_device(), blob, "tile")?;
            let s = standardise(
                view,
                points.iter().map(|p| TileReading { pixel: usize::from(p.point), v: &p.corrected, flags: p.flags }),
                tile,
            )
            .context("the device's readings of the tile")?;
            Ok((s, "the device".to_string()))
        }
    }
}

/// The black glass's standardisation: the gloss the device read, or (from
/// logged readings) what the device would read, with this calibration.
fn gloss(
    a: &Args,
    view: &BlobView<'_>,
    blob: &[u8],
    standard: BlackGlass,
) -> anyhow::Result<(GlossStandardisation, String)> {
    ensure!(
        view.has_gloss(),
        "{}: this calibration reads no gloss (its blob has no gloss section): there is no gloss scale to standardise",
        a.blob.display()
    );
    match &a.source.readings {
        Some(path) => {
            let points = logged_estimates(path, view, &a.scene, &a.corrected_with)?
                .into_iter()
                .enumerate()
                .map(|(k, (line, pixel, e))| {
                    let line = line.with_context(|| {
                        format!(
                            "{}: row {}: no `line` column; the black glass's scatter is judged line by line \
                                 (simulate's and measure's points.csv have it)",
                            path.display(),
                            k + 1
                        )
                    })?;
                    Ok(GlossReading { line, pixel, gu: e.readings[brdf_meter::gloss::SPECULAR_GU], flags: e.flag_bits })
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
            let s = standardise_gloss(view, points, standard).with_context(|| format!("{}", path.display()))?;
            Ok((s, path.display().to_string()))
        }
        None => {
            let points = read_standard_on_device(&a.on_device(), blob, "black glass")?;
            let s = standardise_gloss(
                view,
                points.iter().map(|p| GlossReading {
                    line: u64::from(p.line),
                    pixel: usize::from(p.point),
                    gu: p.readings[brdf_meter::gloss::SPECULAR_GU],
                    flags: p.flags,
                }),
                standard,
            )
            .context("the device's readings of the black glass")?;
            Ok((s, "the device".to_string()))
        }
    }
}

/// The JSON report.
#[derive(serde::Serialize)]
struct Report<'a, S> {
    source: &'a str,
    crc_after: u32,
    #[serde(flatten)]
    standardisation: &'a S,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn args(blob: &Path, readings: &Path, out: &Path) -> Args {
        Args {
            blob: blob.into(),
            tile_rf: Some(0.9),
            tile_u: 0.002,
            tile_k: None,
            black_glass_gu: None,
            black_glass_u: 0.0,
            black_glass_k: None,
            source: Source { port: None, tcp: None, readings: Some(readings.into()) },
            corrected_with: Default::default(),
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
        // The white needs no `line` column (its scatter is each pixel's):
        // the same readings without it give the same white.
        let unlined = dir.path().join("tile-no-lines.csv");
        crate::cli::standard_source::write_without_line_column(&readings, &unlined);
        let same = dir.path().join("cal-std-unlined.signed");
        run(args(&cal, &unlined, &same)).unwrap();
        let white = |path: &Path| {
            let image = crate::device::provision::read_blob(path).unwrap();
            let v = BlobView::parse(&image).unwrap();
            let (p, m) = (v.dims().pixels, v.dims().m);
            (0..p * m).map(|k| v.white(k / m, k % m)).collect::<Vec<f32>>()
        };
        assert_eq!(white(&new), white(&same));
        // The certificate's expanded uncertainty at its k, as printed: the
        // same calibration, byte for byte, as its standard uncertainty.
        let printed = dir.path().join("cal-std-printed.signed");
        let mut at_k = args(&cal, &readings, &printed);
        (at_k.tile_u, at_k.tile_k) = (0.004, Some(2.0));
        run(at_k).unwrap();
        assert_eq!(std::fs::read(&printed).unwrap(), std::fs::read(&new).unwrap());
        // A coverage factor no certificate states is refused, named, and
        // nothing is written.
        let never = dir.path().join("cal-bad-k.signed");
        let mut bad_k = args(&cal, &readings, &never);
        bad_k.tile_k = Some(0.5);
        assert!(format!("{:#}", run(bad_k).unwrap_err()).starts_with("--tile-k 0.5: "));
        assert!(!never.exists());
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
        bad.tile_rf = Some(0.3);
        let e = format!("{:#}", run(bad).unwrap_err());
        assert!(e.contains("times its certified 0.3"), "{e}");
        assert!(!refused.exists() && !refused.with_extension("json").exists());
    }

    /// LEDs drifting each at its own rate (the scene's `led-drift` with
    /// `rates_per_frame`, one LED dimming, one steady, the rest
    /// brightening): the standardisation finds each LED's own drift, the
    /// mean of `1 + rate t` over the frames it read, to within the tile's
    /// noise over 32 lines.
    #[test]
    fn the_standardisation_finds_each_leds_own_drift_in_a_simulated_scene() {
        use crate::forward::scene::{DriftRate, EffectSpec};
        let dir = tempfile::tempdir().unwrap();
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mut scene = crate::forward::scene::Scene::load(&root.join("scenes/matte-white.toml")).unwrap();
        let m = scene.instrument.leds.len();
        let rates: Vec<f64> = (0..m).map(|k| 2e-6 * (k as f64 - 1.0)).collect();
        scene.effects.push(EffectSpec::LedDrift { rate: DriftRate::PerLed(rates.clone()) });
        crate::output::config::Validate::validate(&scene).unwrap();
        let (first, lines) = (2000u64, 32u64);
        let (out, _) = crate::forward::scene::readings::simulate_lines(&scene, first, lines).unwrap();
        let blob = brdf_meter::test_blobs::test_blob(9, m, 1, out.pixels, 0.5);
        let cal = dir.path().join("cal.blob");
        std::fs::write(&cal, &blob).unwrap();
        let readings = dir.path().join("tile.csv");
        std::fs::write(&readings, crate::forward::scene::readings::points_csv(&out).unwrap()).unwrap();
        let new = dir.path().join("cal-std.signed");
        run(args(&cal, &readings, &new)).unwrap();
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(new.with_extension("json")).unwrap()).unwrap();
        let found = report["readings"].as_array().unwrap();
        assert_eq!(found.len(), m);
        // Frames since calibration of LED k's frame, the mean over the lines.
        let mean_time = |k: usize| (first as f64 + (lines as f64 - 1.0) / 2.0) * (m as f64 + 1.0) + 1.0 + k as f64;
        // (The readings' columns are the scene's LEDs in its order: the
        // report's `reading`; its `led` is the test blob's LED order.)
        for r in found {
            let k = r["reading"].as_u64().unwrap() as usize;
            let want = 1.0 + rates[k] * mean_time(k);
            let got = r["ratio_median"].as_f64().unwrap();
            assert!((got - want).abs() < 0.012, "LED {k}: found {got}, drifted {want}");
        }
        // The LEDs did drift apart (about 0.03 a step): one common factor
        // could not have passed the check above.
        let span = rates[m - 1] * mean_time(m - 1) - rates[0] * mean_time(0);
        assert!(span > 0.15, "{span}");
    }

    /// The gloss scale from logged readings: the host computes each point's
    /// gloss as the device would, and the standardised calibration reads
    /// the standard's certified value from the same readings, zone by zone.
    #[test]
    fn a_black_glass_reads_its_certified_value_after_standardisation() {
        use crate::device::reference::PointEstimator;
        let dir = tempfile::tempdir().unwrap();
        let (p, m) = (8, 5);
        let blob = brdf_meter::test_blobs::test_blob_with_gloss(9, m, 2, p, 0.5, None);
        let cal = dir.path().join("cal.blob");
        std::fs::write(&cal, &blob).unwrap();
        // 6 lines of readings, the same shape on every pixel, scaled a
        // little line by line.
        let row = |l: usize, px: usize| -> Vec<f32> {
            (0..m).map(|i| (0.15 + 0.03 * i as f32 + 0.003 * px as f32) * (1.0 + 0.001 * (l % 2) as f32)).collect()
        };
        let mut csv = String::from("line,pixel,L1,L2,L3,L4,L5\n");
        for l in 0..6 {
            for px in 0..p {
                let v: Vec<String> = row(l, px).iter().map(|x| x.to_string()).collect();
                csv += &format!("{l},{px},{}\n", v.join(","));
            }
        }
        let readings = dir.path().join("glass.csv");
        std::fs::write(&readings, csv).unwrap();
        let view = BlobView::parse(&blob).unwrap();
        let zone_mean = |v: &BlobView<'_>, z: usize| {
            let e = PointEstimator::new(*v, z).unwrap();
            let pixels = (v.zone_start(z) as usize)..(v.zone_start(z) as usize + p / 2);
            let gs: Vec<f64> = (0..6)
                .flat_map(|l| pixels.clone().map(move |px| (l, px)))
                .map(|(l, px)| f64::from(e.apply_pixel(px, &row(l, px)).readings[0]))
                .collect();
            gs.iter().sum::<f64>() / gs.len() as f64
        };
        // Certified between what the calibration reads in its two zones
        // (7 % apart): each is within the range of it.
        let certified = (zone_mean(&view, 0) + zone_mean(&view, 1)) / 2.0;
        let out = dir.path().join("cal-gloss.blob");
        let args = Args {
            tile_rf: None,
            tile_u: 0.0,
            tile_k: None,
            black_glass_gu: Some(certified),
            black_glass_u: 0.0,
            black_glass_k: None,
            key: None,
            report: None,
            ..args(&cal, &readings, &out)
        };
        run(args).unwrap();
        let new = std::fs::read(&out).unwrap();
        let nv = BlobView::parse(&new).unwrap();
        for z in 0..2 {
            // Each zone by its own factor (zone 1 read it otherwise).
            assert!((zone_mean(&nv, z) / certified - 1.0).abs() < 1e-5, "zone {z} reads the certified value");
        }
        assert!(nv.gloss_uncertainty() > 0.0, "the scatter of the lines' means");
        // A calibration whose scale is off by more than the range: the white first.
        let refused = dir.path().join("refused.blob");
        let args = Args { black_glass_gu: Some(certified / 1.2), ..args_gloss(&cal, &readings, &refused) };
        let e = format!("{:#}", run(args).unwrap_err());
        assert!(e.contains("Standardise on the white tile first"), "{e}");
        assert!(!refused.exists());
        // Without a `line` column the lines' scatter cannot be judged:
        // refused, naming the file and row.
        let unlined = dir.path().join("glass-no-lines.csv");
        crate::cli::standard_source::write_without_line_column(&readings, &unlined);
        let e = format!("{:#}", run(args_gloss(&cal, &unlined, &refused)).unwrap_err());
        assert!(e.contains("glass-no-lines.csv: row 1: no `line` column"), "{e}");
        assert!(!refused.exists());
    }

    fn args_gloss(blob: &Path, readings: &Path, out: &Path) -> Args {
        Args {
            tile_rf: None,
            tile_u: 0.0,
            tile_k: None,
            black_glass_gu: Some(100.0),
            key: None,
            report: None,
            ..args(blob, readings, out)
        }
    }
}
