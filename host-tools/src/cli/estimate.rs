//! `host-tools estimate`: apply a calibration blob to logged readings
//! offline, exactly as the device does: the same library functions in f32
//! (`brdf_meter::kernel` for the linear kinds, `brdf_meter::kernel::scale_free` for
//! the scale-free kinds and the out-of-prior statistic), the same guard
//! (`brdf_meter::estimate::guard_estimate`) and flags.
//!
//! Input: one row per point, m white-corrected readings in the blob's LED
//! order (a header row is optional); with `line` and `pixel` columns (the
//! `points.csv` that `simulate` writes) each row is estimated with its
//! pixel's zone, as the device does. Readings corrected with another
//! calibration's white than the blob's (logged before a standardisation,
//! or `simulate`'s) are first corrected as the blob's white would have
//! corrected them (`--corrected-with`, `crate::cli::corrected_with`).
//! Output: the points in the point
//! schema (`output::points`, docs/point-schema.md), CSV and optionally
//! JSON, the same fields as `measure` writes: the row's line and pixel when
//! the input names them, zone, cluster, flags, the n bin values and their
//! standard uncertainties, the gloss readings (`brdf_meter::gloss`) and the
//! specular peak with theirs.
//! Everything is checked and computed before anything is written.
use crate::device::measurement_result::measurement_result;
use crate::device::reference::PointEstimator;
use crate::output::points::{Point, Points};
use anyhow::{Context, bail, ensure};
use brdf_meter::blob::BlobView;
use brdf_meter::protocol::flags;
use std::path::{Path, PathBuf};

/// Apply a calibration blob to readings offline, exactly as the device does.
#[derive(Clone, Debug, clap::Args)]
pub struct Args {
    /// The calibration blob.
    #[arg(long, value_name = "CAL")]
    pub blob: PathBuf,
    /// Readings CSV: one row per point, m white-corrected readings in the
    /// blob's LED order, after `line` and `pixel` columns when the header
    /// names them (`simulate`'s `points.csv`).
    #[arg(long, value_name = "R.csv")]
    pub readings: PathBuf,
    /// The calibration the readings were corrected with, when not --blob.
    #[command(flatten)]
    pub corrected_with: crate::cli::corrected_with::CorrectedWith,
    /// Output CSV.
    #[arg(long, value_name = "E.csv")]
    pub out: PathBuf,
    /// Also write JSON here.
    #[arg(long, value_name = "E.json")]
    pub json: Option<PathBuf>,
    /// Zone whose matrices to use for rows without a `pixel` column (the
    /// readings' pixels are in it).
    #[arg(long, default_value_t = 0)]
    pub zone: usize,
    /// Also write the result as JSON here: each gloss reading's mean over
    /// the points of `--result-zones` with its uncertainty budget, U at
    /// k = 2 and its coverage interval, and each zone's along the line
    /// (printed either way).
    #[arg(long, value_name = "PATH")]
    pub result: Option<PathBuf>,
    /// The zones the result is over (comma separated). Default: the zones
    /// at the centre of the line when the rows name their pixels (where
    /// the pixels view at the instrument's nominal geometry), else
    /// `--zone`.
    #[arg(long, value_name = "Z,...", value_delimiter = ',')]
    pub result_zones: Vec<usize>,
    /// Plot and standard files (points are the readings' pixels on their
    /// lines, as `measure`'s; rows on line 0 without `line` and `pixel` columns).
    #[command(flatten)]
    pub exports: crate::cli::exports::ExportArgs,
}

/// One point of a readings file: its line and pixel when the file names
/// them, and its m readings.
#[derive(Clone, Debug, PartialEq)]
pub struct ReadingsRow {
    /// Line (a `line` column).
    pub line: Option<u64>,
    /// Pixel (a `pixel` column): the row is estimated with that pixel's calibration.
    pub pixel: Option<usize>,
    /// The m white-corrected readings, in the blob's LED order.
    pub v: Vec<f32>,
}

/// Reads a readings CSV: every row `m` readings, after a `line` and a
/// `pixel` column when a header row names them (the `points.csv` that
/// `simulate` writes); a non-numeric first row is a header. Errors name
/// file:line and the field.
pub fn read_readings(path: &Path, m: usize) -> anyhow::Result<Vec<ReadingsRow>> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_path(path)
        .with_context(|| format!("{}: cannot open the readings", path.display()))?;
    let mut rows = Vec::new();
    let (mut line_col, mut pixel_col) = (None, None);
    for (row, rec) in rdr.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: malformed CSV", path.display()))?;
        let line = rec.position().map_or(0, |p| p.line());
        if row == 0 && rec.iter().all(|f| f.parse::<f64>().is_err()) {
            line_col = rec.iter().position(|f| f.eq_ignore_ascii_case("line"));
            pixel_col = rec.iter().position(|f| f.eq_ignore_ascii_case("pixel"));
            continue; // the header
        }
        let index_cols = usize::from(line_col.is_some()) + usize::from(pixel_col.is_some());
        if rec.len() != m + index_cols {
            bail!(
                "{}:{line}: {} column(s), but the blob is for m = {m} readings per point (one column per LED, in the \
                 blob's LED order{})",
                path.display(),
                rec.len(),
                if index_cols > 0 { ", after the line and pixel columns" } else { "" }
            );
        }
        let int = |c: Option<usize>, what: &str| -> anyhow::Result<Option<u64>> {
            c.map(|c| {
                rec[c].parse::<u64>().map_err(|_| {
                    anyhow::anyhow!("{}:{line}: column `{what}`: {:?} is not a whole number", path.display(), &rec[c])
                })
            })
            .transpose()
        };
        let mut v = Vec::with_capacity(m);
        for (i, f) in rec.iter().enumerate() {
            if Some(i) == line_col || Some(i) == pixel_col {
                continue;
            }
            let x: f32 = f
                .parse()
                .map_err(|_| anyhow::anyhow!("{}:{line}: column {}: {f:?} is not a number", path.display(), i + 1))?;
            v.push(x);
        }
        rows.push(ReadingsRow { line: int(line_col, "line")?, pixel: int(pixel_col, "pixel")?.map(|p| p as usize), v });
    }
    ensure!(!rows.is_empty(), "{}: no readings (one row of {m} numbers per point)", path.display());
    Ok(rows)
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    a.exports.check()?;
    let bytes = std::fs::read(&a.blob).with_context(|| format!("{}: cannot read the blob", a.blob.display()))?;
    let view = BlobView::parse(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", a.blob.display()))?;
    let d = view.dims();
    let app = PointEstimator::new(view, a.zone).with_context(|| format!("--zone {}", a.zone))?;
    let mut rows = read_readings(&a.readings, app.m())?;
    a.corrected_with.apply(&view, &a.readings, &mut rows)?;
    let result_zones = match (a.result_zones.is_empty(), rows.iter().any(|r| r.pixel.is_some())) {
        (true, false) => vec![app.zone()],
        _ => crate::device::measurement_result::chosen_zones(&view, &a.result_zones, "--result-zones")?,
    };
    // A row with a pixel is estimated with that pixel's zone, as the device does.
    let zones: Vec<PointEstimator<'_>> =
        (0..d.zones).map(|z| PointEstimator::new(view, z)).collect::<anyhow::Result<_>>()?;
    let mut points = Vec::with_capacity(rows.len());
    let mut schema_points = Vec::with_capacity(rows.len());
    for r in &rows {
        let (zone, e) = match r.pixel {
            Some(p) => {
                ensure!(
                    p < d.pixels,
                    "{}: pixel {p} is not one of the calibration's {} pixels",
                    a.readings.display(),
                    d.pixels
                );
                let z = view.zone_of_pixel(p);
                (z, zones[z].apply_pixel(p, &r.v))
            }
            None => (app.zone(), app.apply(&r.v)),
        };
        schema_points.push(Point {
            line: r.line,
            pixel: r.pixel.map(|p| p as u64),
            zone: u16::try_from(zone).expect("a blob's zone count fits its u16 field"),
            cluster: e.cluster,
            flags: e.flag_bits,
            rho: e.rho.clone(),
            u_rho: e.sigma.clone(),
            readings: e.readings,
            u_readings: e.reading_sigma,
        });
        points.push(e);
    }
    let (peak_resolution_deg, pixel_peak_resolution_deg) = crate::output::points::peak_resolutions(&view);
    let stated = Points {
        source: "estimate",
        calibration_crc: view.crc(),
        view_deg: a.exports.view_deg,
        peak_resolution_deg,
        pixel_peak_resolution_deg,
        peak_factors: view.peak_factors(),
        bins_deg: (0..d.n).map(|j| view.grid_deg(j)).collect(),
        points: schema_points,
    };
    // The result takes the calibration's uncertainties apart from its
    // standards'; the files state them together.
    let result = measurement_result(&view, &result_zones, &stated);
    let files = stated.with_standards_of(&view);
    let profiles = files.profiles();
    if a.exports.plot.is_some() {
        a.exports.chosen(&profiles)?; // a point the readings lack is refused before anything is written
    }
    files.write(&a.out, a.json.as_deref())?;
    if let Some(path) = &a.result {
        result.write(path)?;
    }
    let unresolved = files.unresolved_peaks();
    // Line by line when the rows name their lines, as `measure` prints it.
    let summary = crate::device::measurement_summary::summarise(points.iter().zip(&rows).map(|(p, r)| {
        crate::device::measurement_summary::SummaryPoint {
            line: r.line.and_then(|l| u32::try_from(l).ok()),
            flags: p.flag_bits,
            readings: p.readings,
        }
    }));
    print!("{}", crate::device::measurement_summary::table(&summary));
    print!("{}", result.table());
    let flagged = points.iter().filter(|p| p.flag_bits & flags::OUT_OF_PRIOR != 0).count();
    // Rows with a pixel took its zone; the others took --zone.
    let zones_used = match (rows.iter().any(|r| r.pixel.is_some()), rows.iter().all(|r| r.pixel.is_some())) {
        (_, true) => "each pixel's zone".to_string(),
        (true, false) => format!("each pixel's zone, zone {} without one", app.zone()),
        (false, _) => format!("zone {}", app.zone()),
    };
    println!(
        "{} point(s), {} estimator, {zones_used}: {flagged} out-of-prior{}; wrote {}{}",
        points.len(),
        crate::calibration::estimators::kind_name(view.estimator()),
        crate::output::points::unresolved_note(unresolved),
        a.out.display(),
        [&a.json, &a.result].into_iter().flatten().map(|p| format!(", {}", p.display())).collect::<String>()
    );
    let export = a.exports.info(
        "host-tools estimate",
        format!("offline estimate from {}", a.readings.display()),
        format!("{}, {zones_used}", crate::cli::exports::calibration_label(&view)),
    );
    let title = format!("BRDF profiles, {} ({})", a.readings.display(), export.calibration);
    a.exports.write_and_say(&profiles, &result, &export, &title)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::train::{Estimator, run as train_run};

    fn blob(dir: &Path, est: Estimator, prior: &str) -> PathBuf {
        let a = crate::cli::train::tests::args_with(dir, est, prior);
        let out = a.out.clone();
        train_run(a).unwrap();
        out
    }

    fn args(dir: &Path, cal: &Path, readings: &str) -> Args {
        let r = dir.join("r.csv");
        std::fs::write(&r, readings).unwrap();
        Args {
            blob: cal.to_path_buf(),
            readings: r,
            corrected_with: Default::default(),
            out: dir.join("e.csv"),
            json: Some(dir.join("e.json")),
            zone: 0,
            result: Some(dir.join("e-result.json")),
            result_zones: vec![],
            exports: Default::default(),
        }
    }

    #[test]
    fn applies_the_blob_as_the_device_does_and_flags_an_unknown_material() {
        let dir = tempfile::tempdir().unwrap();
        let cal = blob(dir.path(), Estimator::ScaleFree, "merl");
        // A MERL material's readings (in the prior), and light from one LED only (unlike any).
        let inst = crate::forward::optics::Instrument::patent_profile();
        let mat = crate::forward::brdf::NbrdfSet::merl().by_name("white-paint", inst.spectral_weights).unwrap();
        let v = crate::forward::optics::simulate_readings(&inst, &mat, false);
        let row: Vec<String> = v.iter().map(|x| (*x as f32).to_string()).collect();
        let text = format!("a,b,c,d,e,f,g\n{}\n5,0.001,0.001,0.001,0.001,0.001,0.001\n", row.join(","));
        run(args(dir.path(), &cal, &text)).unwrap();
        let j: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("e.json")).unwrap()).unwrap();
        assert_eq!(j["bins_deg"].as_array().unwrap().len(), 81);
        let pts = j["points"].as_array().unwrap();
        assert_eq!(pts.len(), 2);
        assert_eq!(pts[0]["flags"].as_array().unwrap().len(), 0);
        assert_eq!(pts[1]["flags"][0], "out-of-prior");
        // Bit for bit the library's function on the blob's matrix.
        let bytes = std::fs::read(&cal).unwrap();
        let view = BlobView::parse(&bytes).unwrap();
        let mut w = vec![0.0f32; 81 * 7];
        view.copy_matrix(0, &mut w);
        let v32: Vec<f32> = row.iter().map(|x| x.parse().unwrap()).collect();
        let mut out = vec![0.0f32; 81];
        // The scale-free kinds train in the root form by default.
        assert!(view.root_form());
        brdf_meter::kernel::scale_free::estimate_scale_free_root(&w, &v32, &mut out);
        let got: Vec<f32> = pts[0]["rho"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as f32).collect();
        assert_eq!(got, out);
        // The point schema: no line or pixel in these readings, the zone asked for.
        assert_eq!(j["schema"], crate::output::points::SCHEMA);
        assert!(pts[0]["line"].is_null() && pts[0]["pixel"].is_null() && pts[0]["zone"] == 0, "{}", pts[0]);
        assert_eq!(pts[0]["u_rho"].as_array().unwrap().len(), 81);
        let csv = std::fs::read_to_string(dir.path().join("e.csv")).unwrap();
        assert_eq!(csv.lines().count(), 4, "the schema's comment, the header, two points");
        assert!(csv.starts_with("# brdf-meter/points schema_version 3; source estimate;"));
        let header = csv.lines().nth(1).unwrap();
        assert_eq!(header.split(',').count(), 5 + 2 * 81 + 2 * brdf_meter::shape::READINGS + 7);
        assert!(header.starts_with("line,pixel,zone,cluster,flags,rho_25,"), "{header}");
        assert!(csv.lines().nth(3).unwrap().starts_with(",,0,0,out-of-prior,"));
    }

    #[test]
    fn plot_bird_and_astm_of_offline_estimates_and_a_bad_plot_name_is_refused_first() {
        let dir = tempfile::tempdir().unwrap();
        let cal = blob(dir.path(), Estimator::ScaleFree, "merl");
        let inst = crate::forward::optics::Instrument::patent_profile();
        let set = crate::forward::brdf::NbrdfSet::merl();
        let mut text = String::new();
        for name in ["white-paint", "blue-acrylic", "gold-metallic-paint"] {
            let mat = set.by_name(name, inst.spectral_weights).unwrap();
            let v = crate::forward::optics::simulate_readings(&inst, &mat, false);
            text.push_str(&v.iter().map(|x| (*x as f32).to_string()).collect::<Vec<_>>().join(","));
            text.push('\n');
        }
        let mut a = args(dir.path(), &cal, &text);
        a.exports = crate::cli::exports::ExportArgs {
            plot: Some(dir.path().join("p.svg")),
            plot_points: vec![0, 2],
            bird: Some(dir.path().join("e.bird.json")),
            astm: Some(dir.path().join("e.astm")),
            result_astm: Some(dir.path().join("result.astm")),
            result_bird: Some(dir.path().join("result.bird.json")),
            view_deg: 45.0,
            solid_angle_sr: Some(1e-3),
        };
        run(a.clone()).unwrap();
        // The result's mean BRDF as one table: the result document's values.
        let t = crate::output::astm_e1392::read(&dir.path().join("result.astm")).unwrap();
        let r: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("e-result.json")).unwrap()).unwrap();
        let brdf = t.vars.iter().position(|v| v == "brdf").unwrap();
        for (row, want) in t.rows.iter().zip(r["brdf"]["value"].as_array().unwrap()) {
            let want = want.as_f64().unwrap() / std::f64::consts::PI;
            assert!((row[brdf] - want).abs() <= 1e-6 * want.abs().max(1e-9), "{} vs {want}", row[brdf]);
        }
        assert_eq!(t.rows.len(), 81);
        let sample = t.header.iter().find(|(k, _)| k == "SAMPLE").map(|(_, v)| v.as_str());
        assert_eq!(sample, Some("mean of 3 point(s): zone(s) 0, pixels 0-7; u is the combined standard uncertainty"));
        let expanded = t.header.iter().find(|(k, _)| k == "GLOSS_GU_EXPANDED").map(|(_, v)| v.as_str());
        let g = &r["readings"][0];
        let want =
            format!("U {} at k = {:.2} (95.45 %): interval ", g["expanded_u"], g["coverage_factor"].as_f64().unwrap());
        assert!(expanded.is_some_and(|e| e.starts_with(&want)), "{expanded:?} against {want}");
        // And as one BiRD file: the same mean, no line or point, its
        // coverage in the ad hoc section.
        let (mean, view) = crate::output::bird::read(&dir.path().join("result.bird.json")).unwrap();
        assert_eq!((mean.len(), view), (1, 45.0));
        for ((x, u), (want, want_u)) in mean[0]
            .reflectance
            .iter()
            .zip(&mean[0].uncertainty)
            .zip(r["brdf"]["value"].as_array().unwrap().iter().zip(r["brdf"]["u"].as_array().unwrap()))
        {
            let (want, want_u) = (want.as_f64().unwrap(), want_u.as_f64().unwrap());
            assert!((x - want).abs() <= 1e-9 * want.abs().max(1e-9), "{x} vs {want}");
            assert!((u - want_u).abs() <= 1e-9 * want_u.abs().max(1e-9), "{u} vs {want_u}");
        }
        let doc: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("result.bird.json")).unwrap()).unwrap();
        assert!(crate::output::bird::check_required(&doc).is_empty());
        let names: Vec<&str> =
            doc["data"]["variables"].as_array().unwrap().iter().map(|v| v["name"].as_str().unwrap()).collect();
        assert_eq!(names, ["theta_i", "phi_i", "theta_r", "phi_r", "BRDF", "uBRDF"]);
        let coverage = &doc["metadata"]["adhoc_section"]["result"];
        let (k, big_u) = (
            coverage["coverage_factor"].as_array().unwrap(),
            coverage["expanded_uncertainty_BRDF"].as_array().unwrap(),
        );
        assert_eq!((k.len(), big_u.len()), (81, 81));
        for ((k, big_u), row) in k.iter().zip(big_u).zip(doc["data"]["values"].as_array().unwrap()) {
            let u = row[5].as_f64().unwrap();
            assert!((k.as_f64().unwrap() * u - big_u.as_f64().unwrap()).abs() <= 1e-12 + 1e-9 * u, "{k} {u} {big_u}");
        }
        assert_eq!(coverage["readings"], r["readings"]);
        let svg = std::fs::read_to_string(dir.path().join("p.svg")).unwrap();
        assert_eq!(svg.matches("<polygon").count(), 2);
        assert!(svg.contains("line 0 point 2"));
        let (back, view) = crate::output::bird::read(&dir.path().join("e.bird.json")).unwrap();
        assert_eq!((back.len(), view), (3, 45.0));
        let e: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("e.json")).unwrap()).unwrap();
        for (k, p) in back.iter().enumerate() {
            let rho: Vec<f64> = e["points"][k]["rho"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
            for (x, y) in p.reflectance.iter().zip(&rho) {
                assert!((x - y).abs() <= 1e-6 * y.abs().max(1e-9), "{x} vs {y}");
            }
        }
        for k in 0..3 {
            let t = crate::output::astm_e1392::read(&dir.path().join(format!("e-l0-p{k}.astm"))).unwrap();
            assert_eq!(t.rows.len(), 81);
        }
        // A plot name the command cannot write is refused before any output.
        let out = tempfile::tempdir().unwrap();
        let mut b = args(out.path(), &cal, &text);
        b.exports.plot = Some(out.path().join("p.pdf"));
        let err = format!("{:#}", run(b).unwrap_err());
        assert!(err.contains("--plot") && err.contains(".svg or .png"), "{err}");
        assert!(!out.path().join("e.csv").exists());
        // A point the readings do not have, also refused before any output.
        let mut c = args(out.path(), &cal, &text);
        c.exports = crate::cli::exports::ExportArgs { plot_points: vec![7], ..a.exports };
        let err = format!("{:#}", run(c).unwrap_err());
        assert!(err.contains("--plot-points 7: line 0 has points 0..=2"), "{err}");
        assert!(!out.path().join("e.csv").exists());
    }

    #[test]
    fn readings_with_comment_lines_and_index_columns_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let r = dir.path().join("r.csv");
        std::fs::write(&r, "# points of a simulated line\nline,pixel,a,b\n# a comment between rows\n2,5,0.5,0.25\n")
            .unwrap();
        let rows = read_readings(&r, 2).unwrap();
        assert_eq!(rows, vec![ReadingsRow { line: Some(2), pixel: Some(5), v: vec![0.5, 0.25] }]);
    }

    #[test]
    fn bad_input_gets_a_clear_error_and_writes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let cal = blob(dir.path(), Estimator::ScaleFree, "merl");
        for (text, why) in [
            ("1,2,3,4,5,6,7\n1,2,3\n", "r.csv:2: 3 column(s), but the blob is for m = 7"),
            ("1,2,3,4,5,6,7\n1,2,x,4,5,6,7\n", "r.csv:2: column 3: \"x\" is not a number"),
            ("a,b,c,d,e,f,g\n", "no readings"),
        ] {
            let e = format!("{:#}", run(args(dir.path(), &cal, text)).unwrap_err());
            assert!(e.contains(why), "{e}");
            assert!(!dir.path().join("e.csv").exists() && !dir.path().join("e.json").exists());
        }
        // A blob for another m: an instrument with 5 LEDs.
        let e = format!("{:#}", run(args(dir.path(), &cal, "1,2,3,4,5\n")).unwrap_err());
        assert!(e.contains("r.csv:1: 5 column(s), but the blob is for m = 7"), "{e}");
        let e = format!("{:#}", run(Args { zone: 3, ..args(dir.path(), &cal, "1,2,3,4,5,6,7\n") }).unwrap_err());
        assert!(e.contains("--zone 3"), "{e}");
        assert!(!dir.path().join("e.csv").exists());
    }
}
