//! `host-tools measure`: measure lines, write every point as CSV and JSON
//! (the point schema, `output::points`), print a per-line summary (gloss
//! readings, flags), and on request plot chosen points and write the
//! standard files (BiRD JSON, ASTM E1392).
use crate::device::link::{Endpoint, PointRecord};
use anyhow::{Context, bail};
use brdf_meter::blob::BlobView;
use brdf_meter::protocol::{BinRange, Encoding, StreamFormat};
use std::path::PathBuf;

/// Measure N lines; write one row (CSV) / object (JSON) per point in the
/// point schema (docs/point-schema.md): its BRDF vector with the
/// calibration's predicted per-bin uncertainty, gloss readings and
/// specular peak with theirs.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The device.
    #[command(flatten)]
    pub device: Endpoint,
    /// The calibration blob the device runs (for the angle grid and the
    /// per-bin uncertainty; checked against the device's by CRC): the signed
    /// file provisioned, or the unsigned blob it was signed from.
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
    /// The result as JSON: each gloss reading's mean over the points of
    /// `--result-zones` with its uncertainty budget, U at k = 2 and its
    /// coverage interval, and each zone's along the line.
    #[arg(long, value_name = "PATH", default_value = "out/measure-result.json")]
    pub result: PathBuf,
    /// The zones the result is over (comma separated). Default: the zones
    /// at the centre of the line, where the pixels view the surface at the
    /// instrument's nominal geometry (the handheld's view at 41.5 to 48 deg
    /// along its line, and a surface other than a mirror reads differently
    /// at each).
    #[arg(long, value_name = "Z,...", value_delimiter = ',')]
    pub result_zones: Vec<usize>,
    /// A scene for a simulated device.
    #[command(flatten)]
    pub scene: crate::cli::sim_scene::SimSceneArgs,
    /// Plot and standard files.
    #[command(flatten)]
    pub exports: crate::cli::exports::ExportArgs,
    /// How the values travel: `sigma16` (16-bit, error at most 1/256 of each
    /// bin's uncertainty), `f32` (bit for bit) or `corrected` (the corrected
    /// readings; the host computes the estimate with the blob, bit for bit).
    #[arg(long, value_enum, default_value_t = EncodingArg::Sigma16)]
    pub encoding: EncodingArg,
    /// Only these bins: FIRST:STEP:COUNT (0-based), e.g. 0:2:41.
    #[arg(long, value_name = "FIRST:STEP:COUNT")]
    pub bins: Option<String>,
}

/// `--encoding`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EncodingArg {
    /// 16-bit multiples of a step under 1/128 of each bin's uncertainty.
    Sigma16,
    /// f32 values.
    F32,
    /// The corrected readings.
    Corrected,
}

impl From<EncodingArg> for Encoding {
    fn from(e: EncodingArg) -> Self {
        match e {
            EncodingArg::Sigma16 => Encoding::Sigma16,
            EncodingArg::F32 => Encoding::F32,
            EncodingArg::Corrected => Encoding::Corrected,
        }
    }
}

/// Parses `--bins FIRST:STEP:COUNT` for a calibration of `n` bins.
pub fn parse_bins(spec: &str, n: usize) -> anyhow::Result<BinRange> {
    let parts: Vec<&str> = spec.split(':').collect();
    let num = |s: &str| s.trim().parse::<u16>().ok();
    let r = match parts.as_slice() {
        [f, s, c] => num(f).zip(num(s)).zip(num(c)).map(|((first, step), count)| BinRange { first, step, count }),
        _ => None,
    }
    .with_context(|| format!("--bins {spec}: expected FIRST:STEP:COUNT, e.g. 0:2:41"))?;
    if !r.fits(n) {
        bail!("--bins {spec}: needs at least one bin, a step of at least 1, and its last bin below {n}");
    }
    Ok(r)
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    if a.lines == 0 {
        bail!("--lines must be at least 1");
    }
    a.exports.check()?;
    let bytes = crate::device::provision::read_blob_to_decode(&a.blob)?;
    let view = BlobView::parse(&bytes).expect("read_blob_to_decode checked it");
    let result_zones = crate::device::measurement_result::chosen_zones(&view, &a.result_zones, "--result-zones")?;
    let mut c = crate::device::link::Client::new(a.device.open()?)?;
    let info = c.info().context("asking the device for its information")?;
    crate::device::provision::check_device_runs(info.calibration, view.crc(), &a.blob)?;
    if let Some(k) = a.exports.plot_points.iter().find(|&&k| k >= usize::from(info.pixels)) {
        bail!("--plot-points {k}: the device has points 0..={} on a line; choose among them", info.pixels - 1);
    }
    a.scene.load(&mut c, &info, &view, a.lines)?;
    c.timeout = std::time::Duration::from_secs(10);
    c.set_calibration(&bytes)?;
    c.format = StreamFormat {
        encoding: a.encoding.into(),
        bins: a.bins.as_deref().map(|b| parse_bins(b, view.dims().n)).transpose()?,
    };
    let progress = crate::output::progress::bar(u64::from(a.lines) * u64::from(info.pixels), "points");
    let points = c.measure_observed(a.lines, &mut |_| progress.inc(1));
    progress.finish_and_clear();
    let points: Vec<PointRecord> = points.context("measuring")?;
    let stated = crate::device::measurement::calibration_points(&view, &points, a.exports.view_deg);
    let result = crate::device::measurement_result::measurement_result(&view, &result_zones, &stated);
    let files = stated.with_standards_of(&view);
    files.write(&a.csv, Some(&a.json))?;
    result.write(&a.result)?;
    let flagged = points.iter().filter(|p| p.flags != 0).count();
    print!(
        "{}",
        crate::device::measurement_summary::table(&crate::device::measurement_summary::summarise(
            crate::device::measurement::summary_points(&points)
        ))
    );
    print!("{}", result.table());
    println!(
        "measured {} lines, {} points ({} flagged{}): {}, {} and {}",
        a.lines,
        points.len(),
        flagged,
        crate::output::points::unresolved_note(files.unresolved_peaks()),
        a.csv.display(),
        a.json.display(),
        a.result.display()
    );
    let export = a.exports.info(
        "host-tools measure",
        format!("BRDF meter{}", if info.simulated { " (simulated sensor, QEMU)" } else { "" }),
        crate::cli::exports::calibration_label(&view),
    );
    let title = format!("BRDF profiles, {} ({})", a.blob.display(), export.calibration);
    a.exports.write_and_say(&files.profiles(), &result, &export, &title)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bin_subsets_parse_and_bad_ones_are_named() {
        assert_eq!(parse_bins("0:2:41", 81).unwrap(), BinRange { first: 0, step: 2, count: 41 });
        assert_eq!(parse_bins("80:1:1", 81).unwrap(), BinRange { first: 80, step: 1, count: 1 });
        for bad in ["0:2:42", "0:0:3", "1:1:0", "a:1:1", "1:1", "-1:1:1"] {
            let e = parse_bins(bad, 81).unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
    }
}
