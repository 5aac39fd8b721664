//! `host-tools estimate`: apply a calibration blob to logged readings
//! offline, exactly as the device does: the same library functions in f32
//! (`brdf_meter::kernel` for the linear kinds, `brdf_meter::kernel::scale_free` for
//! the scale-free kinds and the out-of-prior statistic), the same guard
//! (`brdf_meter::estimate::guard_estimate`) and flags.
//!
//! Input: one row per point, m white-corrected readings in the blob's LED
//! order (a header row is optional). Output: CSV (point, flags, the n bin
//! values, the n per-bin standard uncertainties, the gloss readings and
//! their standard uncertainties, `brdf_meter::gloss`) and optionally JSON
//! `{"bins_deg": [...], "points": [{"rho": [...], "sigma": [...], "readings": [...],
//! "reading_sigma": [...], "flags": [...]}]}` (a reading the blob does not
//! carry is NaN in the CSV, null in the JSON).
//! Everything is checked and computed before anything is written.
use crate::device::reference::{PointEstimate, PointEstimator};
use anyhow::{Context, bail, ensure};
use brdf_meter::blob::BlobView;
use brdf_meter::gloss;
use brdf_meter::protocol::flags;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Apply a calibration blob to readings offline, exactly as the device does.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The calibration blob.
    #[arg(long, value_name = "CAL")]
    pub blob: PathBuf,
    /// Readings CSV: one row per point, m white-corrected readings in the blob's LED order.
    #[arg(long, value_name = "R.csv")]
    pub readings: PathBuf,
    /// Output CSV.
    #[arg(long, value_name = "E.csv")]
    pub out: PathBuf,
    /// Also write JSON here.
    #[arg(long, value_name = "E.json")]
    pub json: Option<PathBuf>,
    /// Zone whose matrices to use (the readings' pixels are in it).
    #[arg(long, default_value_t = 0)]
    pub zone: usize,
}

/// Reads the readings CSV: every row exactly `m` numbers; a non-numeric
/// first row is a header. Errors name file:line and the field.
pub fn read_readings(path: &Path, m: usize) -> anyhow::Result<Vec<Vec<f32>>> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_path(path)
        .with_context(|| format!("{}: cannot open the readings", path.display()))?;
    let mut rows = Vec::new();
    for (row, rec) in rdr.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: malformed CSV", path.display()))?;
        let line = rec.position().map_or(0, |p| p.line());
        if row == 0 && rec.iter().all(|f| f.parse::<f64>().is_err()) {
            continue; // the header
        }
        if rec.len() != m {
            bail!(
                "{}:{line}: {} column(s), but the blob is for m = {m} readings per point (one column per LED, in the blob's LED order)",
                path.display(),
                rec.len()
            );
        }
        let mut v = Vec::with_capacity(m);
        for (i, f) in rec.iter().enumerate() {
            let x: f32 = f
                .parse()
                .map_err(|_| anyhow::anyhow!("{}:{line}: column {}: {f:?} is not a number", path.display(), i + 1))?;
            v.push(x);
        }
        rows.push(v);
    }
    ensure!(!rows.is_empty(), "{}: no readings (one row of {m} numbers per point)", path.display());
    Ok(rows)
}

#[derive(Serialize)]
struct JsonOut<'a> {
    bins_deg: Vec<f32>,
    points: &'a [PointEstimate],
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let bytes = std::fs::read(&a.blob).with_context(|| format!("{}: cannot read the blob", a.blob.display()))?;
    let view = BlobView::parse(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", a.blob.display()))?;
    let app = PointEstimator::new(view, a.zone).with_context(|| format!("--zone {}", a.zone))?;
    let rows = read_readings(&a.readings, app.m())?;
    let points: Vec<PointEstimate> = rows.iter().map(|v| app.apply(v)).collect();
    let d = view.dims();
    let bins: Vec<f32> = (0..d.n).map(|j| view.grid_deg(j)).collect();
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["point".to_string(), "flags".to_string()];
    header.extend(bins.iter().map(|b| format!("rho_{b}")));
    header.extend(bins.iter().map(|b| format!("sigma_{b}")));
    header.extend(gloss::NAMES.iter().map(|r| r.to_string()));
    header.extend(gloss::NAMES.iter().map(|r| format!("u_{r}")));
    w.write_record(&header)?;
    for (i, p) in points.iter().enumerate() {
        let mut rec = vec![i.to_string(), p.flags.join("|")];
        rec.extend(p.rho.iter().map(|x| x.to_string()));
        rec.extend(p.sigma.iter().map(|x| x.to_string()));
        rec.extend(p.readings.iter().chain(&p.reading_sigma).map(|x| x.to_string()));
        w.write_record(&rec)?;
    }
    let csv_bytes = w.into_inner().map_err(|e| anyhow::anyhow!("CSV: {e}"))?;
    let json = a
        .json
        .as_ref()
        .map(|_| serde_json::to_vec_pretty(&JsonOut { bins_deg: bins.clone(), points: &points }))
        .transpose()?;
    crate::output::io::write_atomic(&a.out, &csv_bytes).with_context(|| format!("writing {}", a.out.display()))?;
    if let (Some(p), Some(j)) = (&a.json, &json) {
        crate::output::io::write_atomic(p, j).with_context(|| format!("writing {}", p.display()))?;
    }
    let flagged = points.iter().filter(|p| p.flag_bits & flags::OUT_OF_PRIOR != 0).count();
    println!(
        "{} point(s), {} estimator, zone {}: {flagged} out-of-prior; wrote {}{}",
        points.len(),
        crate::calibration::estimators::kind_name(view.estimator()),
        app.zone(),
        a.out.display(),
        a.json.as_ref().map_or(String::new(), |p| format!(", {}", p.display()))
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::train::{Estimator, run as train_run};

    fn blob(dir: &Path, est: Estimator, prior: &str) -> PathBuf {
        let a = crate::cli::train_measured::tests::args(dir, est, prior);
        let out = a.out.clone();
        train_run(a).unwrap();
        out
    }

    fn args(dir: &Path, cal: &Path, readings: &str) -> Args {
        let r = dir.join("r.csv");
        std::fs::write(&r, readings).unwrap();
        Args { blob: cal.to_path_buf(), readings: r, out: dir.join("e.csv"), json: Some(dir.join("e.json")), zone: 0 }
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
        brdf_meter::kernel::scale_free::estimate_scale_free(&w, &v32, &mut out);
        let got: Vec<f32> = pts[0]["rho"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as f32).collect();
        assert_eq!(got, out);
        let csv = std::fs::read_to_string(dir.path().join("e.csv")).unwrap();
        assert_eq!(csv.lines().count(), 3);
        assert_eq!(csv.lines().next().unwrap().split(',').count(), 2 + 2 * 81 + 2 * brdf_meter::shape::READINGS);
        assert!(csv.lines().nth(2).unwrap().starts_with("1,out-of-prior,"));
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
