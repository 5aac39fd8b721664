//! A calibration trained for a simulated scene: what the QEMU instrument's
//! demo loads and the system tests provision, trained by the same path as
//! `host-tools train --scene` (the link only carries the blob; it never trains).
use crate::calibration::train::{TrainSpec, Trained, train};
use crate::forward::prior::PriorSpec;
use crate::forward::scene::{Scene, training_optics};
use anyhow::Context;
use brdf_meter::blob::EstimatorKind;

/// Trains a calibration for `scene` with host-tools' training: `zones` zones,
/// each with the system matrix at its centre pixel, the scene's white
/// reference, the patent prior and `noise_rel` relative noise (Wiener, eq. 22).
pub fn train_for_scene(scene: &Scene, zones: usize, noise_rel: f64) -> anyhow::Result<Trained> {
    let inst = &scene.instrument;
    let grid = inst.grid().context("the scene's angle grid")?;
    let prior = PriorSpec::patent()
        .build(&grid, inst.view_deg, std::path::Path::new("."))
        .context("building the patent prior")?;
    let optics = training_optics(scene, zones)?;
    train(&TrainSpec {
        bins_deg: grid.bins_deg(),
        zones: optics.zones,
        pixels: optics.pixels,
        view_deg: inst.view_deg,
        prior: &prior,
        noise_rel,
        estimator: EstimatorKind::Wiener,
        far_field: false,
        led_order: None,
        white: Some(optics.white),
    })
}

/// Trains a scale-free calibration for `scene` (piecewise when `piecewise`)
/// on the built-in measured prior (the MERL materials), as
/// `host-tools train --scene S --prior merl --estimator scale-free[-piecewise]`
/// does: the zones' optics and white reference from the scene, the
/// out-of-prior threshold at a 5 % false-alarm rate.
pub fn train_scale_free_for_scene(
    scene: &Scene,
    zones: usize,
    noise_rel: f64,
    piecewise: bool,
) -> anyhow::Result<crate::calibration::train_scale_free::TrainedScaleFree> {
    use crate::forward::prior_measured::{PriorMix, weighted_prior};
    let inst = &scene.instrument;
    let grid = inst.grid().context("the scene's angle grid")?;
    let (samples, _) = PriorMix::parse("merl")?
        .samples(&grid, inst.view_deg, inst.spectral_weights)
        .context("building the MERL prior")?;
    let prior = weighted_prior(&samples);
    let optics = training_optics(scene, zones)?;
    let spec = TrainSpec {
        bins_deg: grid.bins_deg(),
        zones: optics.zones,
        pixels: optics.pixels,
        view_deg: inst.view_deg,
        prior: &prior,
        noise_rel,
        estimator: if piecewise { EstimatorKind::ScaleFreePiecewise } else { EstimatorKind::ScaleFree },
        far_field: false,
        led_order: None,
        white: Some(optics.white),
    };
    crate::calibration::train_scale_free::train_scale_free(&spec, &samples, 0.05)
}

/// Trains a calibration of `kind` for `scene` on the measured samples
/// `samples` (for example the MERL set without the materials under test):
/// the linear kinds on their `R_pp` (`prior_measured::weighted_prior`), the
/// scale-free kinds on the samples themselves (out-of-prior threshold at a
/// 5 % false-alarm rate). Returns the blob.
pub fn train_measured_for_scene(
    scene: &Scene,
    zones: usize,
    noise_rel: f64,
    kind: EstimatorKind,
    samples: &crate::calibration::estimators::scale_free::WeightedSamples,
) -> anyhow::Result<Vec<u8>> {
    let inst = &scene.instrument;
    let grid = inst.grid().context("the scene's angle grid")?;
    let prior = crate::forward::prior_measured::weighted_prior(samples);
    let optics = training_optics(scene, zones)?;
    let spec = TrainSpec {
        bins_deg: grid.bins_deg(),
        zones: optics.zones,
        pixels: optics.pixels,
        view_deg: inst.view_deg,
        prior: &prior,
        noise_rel,
        estimator: kind,
        far_field: false,
        led_order: None,
        white: Some(optics.white),
    };
    Ok(match kind {
        EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise => {
            crate::calibration::train_scale_free::train_scale_free(&spec, samples, 0.05)?.blob
        }
        _ => train(&spec)?.blob,
    })
}
