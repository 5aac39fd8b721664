//! A calibration trained for a simulated scene: what the QEMU instrument's
//! demo loads and the system tests provision, trained by the same path as
//! `host-tools train --scene` (the link only carries the blob; it never trains).
use crate::calibration::train::{TrainSpec, Trained, board_blob_capacity, train};
use crate::forward::pairs::Criterion;
use crate::forward::prior_measured::PriorMix;
use crate::forward::prior_models::PriorModels;
use crate::forward::scene::{Scene, training_optics};
use anyhow::Context;
use brdf_meter::blob::EstimatorKind;

/// Trains a calibration of `kind` for `scene` on `prior` with `criterion`:
/// `zones` zones of the scene's optics (relative noise `noise_rel`), its
/// white reference, the out-of-prior threshold (scale-free kinds) at a
/// 5 % false-alarm rate.
pub fn train_scene(
    scene: &Scene,
    zones: usize,
    noise_rel: f64,
    kind: EstimatorKind,
    prior: &PriorModels,
    criterion: Criterion,
) -> anyhow::Result<Trained> {
    train_scene_for_slot(scene, zones, noise_rel, kind, prior, criterion, board_blob_capacity())
}

/// [`train_scene`] for a device whose calibration slot takes at most
/// `max_blob_len` bytes of blob (the piecewise kind's cluster count is
/// chosen among those whose blob fits).
pub fn train_scene_for_slot(
    scene: &Scene,
    zones: usize,
    noise_rel: f64,
    kind: EstimatorKind,
    prior: &PriorModels,
    criterion: Criterion,
    max_blob_len: usize,
) -> anyhow::Result<Trained> {
    let inst = &scene.instrument;
    let grid = inst.grid().context("the scene's angle grid")?;
    let optics = training_optics(scene, zones, Some(noise_rel))?;
    train(&TrainSpec {
        bins_deg: grid.bins_deg(),
        zones: optics.zones,
        pixels: optics.pixels,
        view_deg: inst.view_deg,
        prior,
        noise_rel,
        estimator: kind,
        criterion,
        false_alarm: 0.05,
        clusters: None,
        root: crate::calibration::train::Form::default_for(kind) == crate::calibration::train::Form::Root,
        far_field: !scene.has("near-field"),
        led_order: None,
        white: Some(optics.white),
        linearity: optics.linearity.map(|l| l.correction),
        max_blob_len,
    })
}

/// The prior named `arg` (`patent`, `merl`, ...) for `scene`'s instrument.
pub fn scene_prior(scene: &Scene, arg: &str) -> anyhow::Result<PriorModels> {
    let inst = &scene.instrument;
    let grid = inst.grid().context("the scene's angle grid")?;
    PriorMix::parse(arg)?
        .models(&grid, inst.view_deg, inst.spectral_weights)
        .with_context(|| format!("the {arg} prior"))
}

/// Trains a calibration for `scene` with host-tools' training: `zones` zones,
/// the scene's white reference, the patent prior with its plain criterion and
/// `noise_rel` relative noise (Wiener, eq. 22).
pub fn train_for_scene(scene: &Scene, zones: usize, noise_rel: f64) -> anyhow::Result<Trained> {
    let prior = scene_prior(scene, "patent")?;
    train_scene(scene, zones, noise_rel, EstimatorKind::Wiener, &prior, Criterion::Plain)
}

/// Trains a scale-free calibration for `scene` (piecewise when `piecewise`)
/// on the built-in measured prior (the MERL materials), as
/// `host-tools train --scene S --prior merl --estimator scale-free[-piecewise]`
/// does.
pub fn train_scale_free_for_scene(
    scene: &Scene,
    zones: usize,
    noise_rel: f64,
    piecewise: bool,
) -> anyhow::Result<Trained> {
    let prior = scene_prior(scene, "merl")?;
    let kind = if piecewise { EstimatorKind::ScaleFreePiecewise } else { EstimatorKind::ScaleFree };
    train_scene(scene, zones, noise_rel, kind, &prior, Criterion::PeakRelative)
}

/// Trains a calibration of `kind` for `scene` on the measured samples
/// `prior` (for example the MERL set without the materials under test),
/// peak-relative. Returns the blob.
pub fn train_measured_for_scene(
    scene: &Scene,
    zones: usize,
    noise_rel: f64,
    kind: EstimatorKind,
    prior: &PriorModels,
) -> anyhow::Result<Vec<u8>> {
    Ok(train_scene(scene, zones, noise_rel, kind, prior, Criterion::PeakRelative)?.blob)
}
