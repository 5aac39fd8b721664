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
    let prior = PriorSpec::patent().build(&grid, inst.view_deg, std::path::Path::new(".")).context("building the patent prior")?;
    let optics = training_optics(scene, zones)?;
    train(&TrainSpec {
        bins_deg: grid.bins_deg(),
        zones: optics.zones,
        pixels: optics.pixels,
        prior: &prior,
        noise_rel,
        estimator: EstimatorKind::Wiener,
        far_field: false,
        led_order: None,
        white: Some(optics.white),
    })
}
