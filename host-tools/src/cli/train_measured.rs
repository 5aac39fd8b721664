//! `host-tools train` with a measured or mixed prior (`--prior merl`, files,
//! directories, `merl@0.8+patent@0.2`) or a scale-free estimator: the
//! weighted samples of `prior_measured`, then `train` (linear kinds, R_pp of
//! the weighted samples) or `train_scale_free` (format 2 blob).
use super::train::Args;
use crate::calibration::estimators::kind_name;
use crate::calibration::train::{TrainSpec, train};
use crate::calibration::train_scale_free::train_scale_free;
use crate::forward::grid::AngleGrid;
use crate::forward::optics::Instrument;
use crate::forward::prior_measured::{PriorMix, weighted_prior};
use anyhow::{Context, ensure};
use brdf_meter::blob::{BlobView, EstimatorKind};

/// Runs `train` for a measured/mixed prior or a scale-free kind.
pub fn run(
    a: Args,
    scene: Option<crate::forward::scene::Scene>,
    noise: f64,
    inst: Instrument,
    grid: AngleGrid,
) -> anyhow::Result<()> {
    let kind: EstimatorKind = a.estimator.into();
    ensure!(a.false_alarm > 0.0 && a.false_alarm < 1.0, "--false-alarm {}: must be in (0, 1)", a.false_alarm);
    let mix = PriorMix::parse(&a.prior)?;
    let (ws, _) = mix.samples(&grid, inst.view_deg, inst.spectral_weights).context("building the prior")?;
    let (zones, pixels, white, far_field) = super::train::zone_optics(&a, scene.as_ref(), &inst, &grid)?;
    let prior = weighted_prior(&ws);
    let spec = TrainSpec {
        bins_deg: grid.bins_deg(),
        zones,
        pixels,
        view_deg: inst.view_deg,
        prior: &prior,
        noise_rel: noise,
        estimator: kind,
        far_field,
        led_order: None,
        white,
    };
    let families: Vec<String> = mix.families.iter().map(|(l, _, w)| format!("{l} (weight {w})")).collect();
    let (blob, json) = if matches!(kind, EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise) {
        let t = train_scale_free(&spec, &ws, a.false_alarm)?;
        let j = a.json.as_ref().map(|_| serde_json::to_value(t.to_json(kind, grid.bins_deg()))).transpose()?;
        let z0 = &t.zones[0];
        println!(
            "trained {} for {} zone(s) x {} pixels: n = {}, m = {}, K = {}, prior {} samples from {}, noise {noise}",
            kind_name(kind),
            t.dims.zones,
            t.dims.pixels,
            t.dims.n,
            t.dims.m,
            z0.maps.len(),
            ws.samples.ncols(),
            families.join(" + ")
        );
        println!(
            "zone 0: ridge {:.0e} (cross-validated peak-normalised error {:.4}); out-of-prior threshold {:.2} at {:.0} % false alarms on held-out samples; f32 vs f64 {:.1e}",
            z0.ridge,
            z0.cv_error,
            t.threshold,
            100.0 * a.false_alarm,
            t.f32_rel_error
        );
        (t.blob, j)
    } else {
        let t = train(&spec)?;
        let j = a.json.as_ref().map(|_| serde_json::to_value(t.to_json())).transpose()?;
        let s = &t.zones[0].estimator.summary;
        println!(
            "trained {} for {} zone(s) x {} pixels: n = {}, m = {}, prior {} samples (rank {}) from {}, noise {noise}; predicted RMSE {:.4}",
            kind_name(kind),
            t.dims.zones,
            t.dims.pixels,
            t.dims.n,
            t.dims.m,
            s.prior_samples,
            s.prior_rank,
            families.join(" + "),
            s.predicted_rmse
        );
        (t.blob, j)
    };
    // Sign before writing anything, as `train` does for the linear kinds.
    let out = match &a.sign {
        Some(key) => crate::calibration::signing::sign_blob(&blob, &crate::calibration::signing::read_secret(key)?),
        None => blob.clone(),
    };
    crate::output::io::write_atomic(&a.out, &out).with_context(|| format!("writing {}", a.out.display()))?;
    if let (Some(p), Some(j)) = (&a.json, &json) {
        crate::output::io::write_json(p, j).with_context(|| format!("writing {}", p.display()))?;
    }
    let view = BlobView::parse(&blob).expect("validated");
    if !view.has_gloss() {
        println!("{}", crate::calibration::gloss_rows::NO_GLOSS_NOTE);
    } else if let Some(note) = crate::calibration::gloss_rows::zones_without_reading_note(&view) {
        println!("{note}");
    }
    println!("wrote {} ({} bytes, format {}, CRC {:#010x})", a.out.display(), blob.len(), view.version(), view.crc());
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::train::{Args, Estimator, run as train_run};
    use brdf_meter::blob::{BlobView, EstimatorKind};
    use std::path::Path;

    pub(crate) fn args(dir: &Path, estimator: Estimator, prior: &str) -> Args {
        Args {
            out: dir.join("cal.blob"),
            json: Some(dir.join("cal.json")),
            zones: 1,
            pixels: 8,
            noise: Some(0.02),
            estimator,
            prior: prior.into(),
            instrument: None,
            far_field: false,
            scene: None,
            false_alarm: 0.05,
            sign: None,
        }
    }

    #[test]
    fn measured_and_mixed_priors_train_every_kind_into_the_right_format() {
        let dir = tempfile::tempdir().unwrap();
        for (est, prior, kind, version) in [
            // Format 3: every kind carries the gloss section on the patent profile.
            (Estimator::ScaleFree, "merl", EstimatorKind::ScaleFree, 3),
            (Estimator::ScaleFreePiecewise, "merl@0.9+patent@0.1", EstimatorKind::ScaleFreePiecewise, 3),
            (Estimator::Wiener, "merl", EstimatorKind::Wiener, 3),
        ] {
            train_run(args(dir.path(), est, prior)).unwrap();
            let blob = std::fs::read(dir.path().join("cal.blob")).unwrap();
            let v = BlobView::parse(&blob).unwrap();
            assert_eq!((v.estimator(), v.version()), (kind, version), "{prior}");
            assert!(v.has_gloss());
            assert_eq!(v.out_of_prior_threshold().is_some(), kind != EstimatorKind::Wiener);
            assert!(dir.path().join("cal.json").exists());
        }
    }

    #[test]
    fn bad_priors_are_refused_and_nothing_is_written() {
        let dir = tempfile::tempdir().unwrap();
        for (prior, why) in
            [("merl+patent", "needs its weight"), ("merl@0.5+patent@0.4", "sum to"), ("nope.xyz", "not `patent`")]
        {
            let e = format!("{:#}", train_run(args(dir.path(), Estimator::ScaleFree, prior)).unwrap_err());
            assert!(e.contains(why), "{prior}: {e}");
        }
        // Fewer samples than the cross-validation needs.
        std::fs::write(dir.path().join("a.csv"), "20,1.0\n70,2.0\n").unwrap();
        let e = format!(
            "{:#}",
            train_run(args(dir.path(), Estimator::ScaleFree, &dir.path().join("a.csv").display().to_string()))
                .unwrap_err()
        );
        assert!(e.contains("at least"), "{e}");
        assert!(!dir.path().join("cal.blob").exists());
    }
}
