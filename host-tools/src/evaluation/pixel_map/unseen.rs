//! The map's unseen set (`pixel-map --set`): measured surfaces of the
//! user's own, each read on the whole line by the calibration trained on
//! the whole prior (what `train` writes for the scene), with the figures
//! the held-out materials get, beside linear interpolation's. A surface
//! that is also a prior sample is left out and named: the calibration has
//! seen it, and the held-out figures already read it without. Each of the
//! rest is named with the prior sample nearest it, so a set of near twins
//! of the prior's materials is seen for what it is.
use super::peaks::{PeakSummary, PeakTally};
use super::{LineGeometry, LineSummary, MapSpec, MaterialRead, MaterialRow, read_material};
use crate::evaluation::metrology::folds::matching;
use crate::evaluation::metrology::metrics::{FlagErrors, FlagScore};
use crate::evaluation::metrology::{NearestSample, Nearness};
use crate::forward::brdf::Brdf;
use crate::forward::prior_models::SampleModel;
use brdf_meter::blob::BlobView;
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;

/// Surfaces to read: where they come from (for the report) and (name, model).
#[derive(Clone, Debug)]
pub struct UnseenSpec {
    /// The `--set` argument.
    pub source: String,
    /// The surfaces.
    pub materials: Vec<(String, Arc<dyn Brdf>)>,
}

/// The unseen set's figures.
#[derive(Clone, Debug, Serialize)]
pub struct UnseenSet {
    /// The `--set` argument.
    pub source: String,
    /// Surfaces left out because they are prior samples.
    pub in_prior: Vec<String>,
    /// Over every (surface, pixel) of the rest.
    pub summary: LineSummary,
    /// Whether the out-of-prior flag predicts their points' error.
    pub flag: FlagScore,
    /// Their points' median error, flagged and not ([`FlagErrors::medians`]).
    pub flag_error_medians: [f64; 2],
    /// Their points' specular peaks.
    pub peaks: PeakSummary,
    /// Per surface (each with the prior sample nearest it).
    pub materials: Vec<MaterialRow>,
    /// How near the surfaces are to the prior (the estimator's error of a
    /// surface: its median over the pixels).
    pub nearness: Option<Nearness>,
}

/// Reads `set` with `blob` (the calibration on the whole prior).
pub(super) fn read(
    spec: &MapSpec,
    geo: &LineGeometry,
    set: &UnseenSpec,
    blob: &BlobView<'_>,
) -> anyhow::Result<UnseenSet> {
    let view_deg = spec.scene.instrument.view_deg;
    let on_grid: Vec<nalgebra::DVector<f64>> =
        set.materials.iter().map(|(_, b)| SampleModel::Brdf(b.clone()).on_grid(&geo.grid, view_deg)).collect();
    let (seen, unseen): (Vec<_>, Vec<_>) =
        set.materials.iter().zip(&on_grid).enumerate().partition(|(_, (_, v))| !matching(v, &geo.prior).is_empty());
    let nearest_training: Vec<Option<NearestSample>> =
        unseen.iter().map(|(_, (_, v))| NearestSample::in_prior(&spec.prior, &geo.prior, (v, v.amax()), &[])).collect();
    let reads: Vec<MaterialRead> = unseen
        .par_iter()
        .map(|(i, ((name, b), _))| read_material(spec, geo, name, b, blob, 3_000_003 + *i as u64))
        .collect::<anyhow::Result<_>>()?;
    let flag = reads.iter().fold(FlagScore::default(), |a, r| a.merged(r.0.flag));
    let flag_error_medians = reads.iter().fold(FlagErrors::default(), |a, r| a.merged(&r.0.flag_errors)).medians();
    let peaks = reads.iter().fold(PeakTally::default(), |a, r| a.merged(r.2.clone())).summary();
    let materials: Vec<MaterialRow> = reads
        .into_iter()
        .zip(nearest_training)
        .map(|(r, nearest_training)| MaterialRow { nearest_training, ..r.0 })
        .collect();
    let nearness = super::nearness_of(&materials);
    Ok(UnseenSet {
        source: set.source.clone(),
        in_prior: seen.into_iter().map(|(_, ((n, _), _))| n.clone()).collect(),
        summary: LineSummary::of(&materials),
        flag,
        flag_error_medians,
        peaks,
        materials,
        nearness,
    })
}
