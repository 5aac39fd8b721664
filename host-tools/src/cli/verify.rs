//! `host-tools verify`: read a certified gloss standard, on the device or
//! from logged readings, and say zone by zone whether the instrument reads
//! it within what the instrument and the certificate state
//! (`calibration::verify_gloss`: the normalised error E_n). Nothing is
//! written but the report; a zone that does not agree makes the command
//! fail, so a script that checks an instrument stops on it.
use crate::calibration::verify_gloss::{GlossStandard, StatedGloss, verify_gloss};
use crate::cli::certificate::CertificateUncertainty;
use crate::cli::standard_source::{OnDevice, Source, logged_estimates, read_standard_on_device};
use crate::device::measurement_result::chosen_zones;
use anyhow::{Context, bail};
use brdf_meter::blob::BlobView;
use brdf_meter::gloss::SPECULAR_GU;
use std::path::PathBuf;

/// Verify a calibration on a certified gloss standard (a working standard
/// of another gloss level than the black glass it was standardised on):
/// per zone, the normalised error of the mean reading.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The calibration the device runs (signed or unsigned).
    #[arg(long, value_name = "CAL")]
    pub blob: PathBuf,
    /// The standard's certified gloss at the instrument's geometry, GU.
    #[arg(long, value_name = "GU")]
    pub gloss_gu: f64,
    /// Its uncertainty from the certificate, GU: the standard uncertainty
    /// (k = 1), or with --gloss-k the expanded uncertainty U it prints.
    #[arg(long, value_name = "U", default_value_t = 0.0)]
    pub gloss_u: f64,
    /// The coverage factor the certificate states --gloss-u at (e.g. 2):
    /// the standard uncertainty is then U / k, and E_n takes U as printed
    /// (without it, U = 2 u).
    #[arg(long, value_name = "K")]
    pub gloss_k: Option<f64>,
    /// Where the standard's readings come from.
    #[command(flatten)]
    pub source: Source,
    /// The calibration logged readings were corrected with, when not this one.
    #[command(flatten)]
    pub corrected_with: crate::cli::corrected_with::CorrectedWith,
    /// Lines of the standard to read on the device.
    #[arg(long, default_value_t = 16)]
    pub lines: u32,
    /// The zones to verify (comma separated). Default: the zones at the
    /// centre of the line, where the pixels view the standard at the
    /// instrument's nominal angle. A standard other than a mirror reads
    /// differently at pixels that view it at other angles (the handheld's
    /// view at 41.5 to 48 deg along its line), so a certificate for the
    /// nominal geometry holds at the centre; the black glass reads alike
    /// everywhere and may be verified on every zone.
    #[arg(long, value_name = "Z,...", value_delimiter = ',')]
    pub zones: Vec<usize>,
    /// A scene for a simulated device: the standard under the
    /// calibration's instrument (`--scene-surface` on the instrument's own
    /// scene).
    #[command(flatten)]
    pub scene: crate::cli::sim_scene::SimSceneArgs,
    /// Also write every zone's verdict as JSON here.
    #[arg(long, value_name = "PATH")]
    pub report: Option<PathBuf>,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    a.corrected_with.check_logged(a.source.readings.is_some())?;
    let u = CertificateUncertainty { u: a.gloss_u, k: a.gloss_k, flags: ("--gloss-u", "--gloss-k") };
    let standard = u.checked(|s| GlossStandard::new(a.gloss_gu, s, u.coverage_factor()))?;
    let file = crate::device::provision::read_blob_to_decode(&a.blob)?;
    let view = BlobView::parse(&file).expect("read_blob_to_decode checked it");
    let verified = chosen_zones(&view, &a.zones, "--zones")?;
    let chosen = |pixel: usize| verified.contains(&view.zone_of_pixel(pixel));
    // The calibration's uncertainties: `verify_gloss` adds the references'
    // as `measure` states a mean's.
    let stated = |pixel: usize, g: f32, u: f32, flags: u8| StatedGloss { pixel, gu: g, u_gu: u, flags };
    let v = match &a.source.readings {
        Some(path) => {
            let points = logged_estimates(path, &view, &a.scene, &a.corrected_with)?
                .into_iter()
                .filter(|(_, p, _)| chosen(*p))
                .map(|(_, pixel, e)| stated(pixel, e.readings[SPECULAR_GU], e.reading_sigma[SPECULAR_GU], e.flag_bits));
            verify_gloss(&view, points, standard).with_context(|| format!("{}", path.display()))?
        }
        None => {
            let on = OnDevice { source: &a.source, scene: &a.scene, lines: a.lines, blob_path: &a.blob };
            let points = read_standard_on_device(&on, view.as_bytes(), "standard")?;
            let points = points
                .iter()
                .map(|p| stated(usize::from(p.point), p.readings[SPECULAR_GU], p.reading_sigma[SPECULAR_GU], p.flags));
            verify_gloss(&view, points, standard).context("the device's readings of the standard")?
        }
    };
    print!("{}", v.table());
    if let Some(r) = &a.report {
        crate::output::io::write_json(r, &v)?;
        println!("wrote {}", r.display());
    }
    if !v.agrees {
        let bad: Vec<String> = v.zones.iter().filter(|z| !z.agrees).map(|z| z.zone.to_string()).collect();
        bail!(
            "calibration {:#010x} does not read the standard certified at {} GU within what both state, in zone(s) {}: \
             standardise it again (the white tile, then the black glass) and verify again; if it still does not \
             agree, calibrate the unit again",
            v.crc,
            standard.gu,
            bad.join(", ")
        );
    }
    println!("calibration {:#010x} reads the standard within what both state in every zone verified", v.crc);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// From logged readings: the calibration reads what it reads, so a
    /// standard certified at that agrees and one certified far from it
    /// does not, and the command fails with the report written.
    #[test]
    fn a_standard_agrees_or_the_command_fails_with_its_report() {
        let dir = tempfile::tempdir().unwrap();
        let blob = brdf_meter::test_blobs::test_blob_with_gloss(9, 5, 2, 8, 0.5, None);
        let cal = dir.path().join("cal.blob");
        std::fs::write(&cal, &blob).unwrap();
        let mut csv = String::from("line,pixel,L1,L2,L3,L4,L5\n");
        for l in 0..4 {
            for px in 0..8 {
                let v: Vec<String> = (0..5).map(|i| (0.1 + 0.02 * i as f32 + 0.001 * px as f32).to_string()).collect();
                csv += &format!("{l},{px},{}\n", v.join(","));
            }
        }
        let readings = dir.path().join("tile.csv");
        std::fs::write(&readings, csv).unwrap();
        let args = |gu: f64, report: &Path| Args {
            blob: cal.clone(),
            gloss_gu: gu,
            gloss_u: 0.2,
            gloss_k: None,
            source: Source { port: None, tcp: None, readings: Some(readings.clone()) },
            corrected_with: Default::default(),
            lines: 16,
            scene: Default::default(),
            zones: vec![],
            report: Some(report.into()),
        };
        // What zone 0 reads.
        let view = BlobView::parse(&blob).unwrap();
        let e = crate::device::reference::PointEstimator::new(view, 0).unwrap();
        let g = f64::from(e.apply_pixel(0, &[0.1, 0.12, 0.14, 0.16, 0.18]).readings[SPECULAR_GU]);
        let ok = dir.path().join("ok.json");
        run(args(g, &ok)).unwrap();
        let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&ok).unwrap()).unwrap();
        assert_eq!(r["zones"].as_array().unwrap().len(), 2);
        assert_eq!(r["zones"][0]["agrees"], true, "{r}");
        let bad = dir.path().join("bad.json");
        let err = format!("{:#}", run(args(g * 10.0, &bad)).unwrap_err());
        assert!(err.contains("does not read the standard") && err.contains("zone(s) 0, 1"), "{err}");
        let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&bad).unwrap()).unwrap();
        assert_eq!(r["agrees"], false);
        // Only the zones asked for.
        let one = dir.path().join("one.json");
        run(Args { zones: vec![0], ..args(g, &one) }).unwrap();
        let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&one).unwrap()).unwrap();
        assert_eq!(r["zones"].as_array().unwrap().len(), 1);
        let e = run(Args { zones: vec![2], ..args(g, &one) }).unwrap_err().to_string();
        assert!(e.contains("--zones 2: the calibration has zones 0..=1"), "{e}");
        // Zones are judged from the pixels alone: the same readings
        // without a `line` column verify alike.
        let unlined = dir.path().join("tile-no-lines.csv");
        crate::cli::standard_source::write_without_line_column(&readings, &unlined);
        let same = dir.path().join("same.json");
        run(Args { source: Source { port: None, tcp: None, readings: Some(unlined) }, ..args(g, &same) }).unwrap();
        let (a, b): (serde_json::Value, serde_json::Value) = (
            serde_json::from_slice(&std::fs::read(&ok).unwrap()).unwrap(),
            serde_json::from_slice(&std::fs::read(&same).unwrap()).unwrap(),
        );
        assert_eq!(a["zones"], b["zones"]);
    }
}
