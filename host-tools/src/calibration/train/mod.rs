//! Training, one path for every estimator kind:
//!
//! ```text
//! zone optics (centre + training pixels) + prior models
//!   -> sample pairs per zone (crate::forward::pairs), weighted for the criterion
//!   -> the kind's estimator per zone (Wiener and the scale-free kinds from
//!      the pairs; the H-based baselines from the zone's centre H)
//!   -> the f32 gate (crate::calibration::f32_gate)
//!   -> the gloss section (crate::calibration::gloss_rows)
//!   -> the calibration blob (brdf_meter::blob), parsed back before it is returned,
//!      with its peak resolution (crate::calibration::peak_resolution)
//! ```
//!
//! Each zone of pixels has its own optics ([`ZoneOptics`], from the forward
//! model): its sample pairs are taken at up to
//! `crate::forward::zone_optics::MAX_TRAINING_PIXELS` of its pixels, each
//! with its own rays, view and noise, so one zone's matrix serves every
//! pixel of it. The piecewise kind's cluster count is chosen once for the
//! whole calibration (the blob holds K matrices per zone): the count whose
//! cross-validated error summed over the zones is least.
//!
//! Where it lives: this file, the specification and the path from pairs to
//! blob ([`train`]); `zones`, each zone's estimator, the f32 gate's plans
//! and the training summary; `gloss`, the gloss section's rows and the
//! clusters they are fitted on; `json`, what `train --json` writes.

mod gloss;
mod json;
#[cfg(test)]
mod tests;
mod zones;

pub use json::{BlobJson, ScaleFreeJson, ScaleFreeZoneJson, TrainJson, ZoneJson, ZoneMatrices};

use gloss::gloss_section;
use zones::{gate, linear_zones, rescaled_white, scale_free_zones, summary};

use crate::calibration::estimators::scale_free::{self, ScaleFreeOptions, ScaleFreeZone};
use crate::calibration::estimators::{
    self, EstimatorInputs, EstimatorSummary, LinearEstimator, NoiseModel, kind_name, pairs_wiener,
};
use crate::calibration::f32_gate::scale_free_gate;
pub use crate::calibration::f32_gate::{F32_TOLERANCE, F32Plan, F32Refusal, f32_gate};
use crate::calibration::gloss_rows::{self, GlossSection};
use crate::calibration::peak_resolution;
use crate::forward::pairs::{Criterion, Pairs, PixelOptics};
use crate::forward::prior_models::PriorModels;
use crate::forward::zone_optics::ZoneOptics;
use anyhow::{Context, bail, ensure};
use brdf_meter::blob::{
    BlobContents, BlobExtras, BlobView, Dims, EstimatorKind, OutOfPriorData, TrainingSummary, write_blob_with,
};
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use serde::Serialize;

/// Everything training needs.
#[derive(Clone, Debug)]
pub struct TrainSpec<'a> {
    /// Bin centres, degrees (n).
    pub bins_deg: &'a [f64],
    /// One entry per zone, first pixels strictly ascending from 0.
    pub zones: Vec<ZoneOptics>,
    /// Pixels P of the line sensor.
    pub pixels: usize,
    /// The instrument's nominal view, degrees (the H-based kinds' prior is
    /// taken at it).
    pub view_deg: f64,
    /// The prior's samples.
    pub prior: &'a PriorModels,
    /// The relative noise level the blob records (the pairs carry each
    /// pixel's own noise model).
    pub noise_rel: f64,
    /// Which estimator.
    pub estimator: EstimatorKind,
    /// The error training minimises.
    pub criterion: Criterion,
    /// The out-of-prior flag's false-alarm rate on held-out prior samples
    /// (scale-free kinds).
    pub false_alarm: f64,
    /// The piecewise kind's cluster count, fixed (`None`: of
    /// `scale_free::CLUSTER_COUNTS`, by `scale_free::guarded_count`):
    /// what fits a calibration of many zones into its flash slot.
    pub clusters: Option<usize>,
    /// The root form (the scale-free kinds: every estimate and reading
    /// within its definition by construction, `brdf_meter::blob`).
    pub root: bool,
    /// Whether H was modelled far-field (recorded in the blob).
    pub far_field: bool,
    /// LED fired for reading i (a permutation of 0..m); `None` = 0..m.
    pub led_order: Option<Vec<u8>>,
    /// White reference, P x m; `None` = 1.0 everywhere (a simulated sensor
    /// that is already white-normalised).
    pub white: Option<Vec<f32>>,
    /// The sensor's linearity correction the white and the readings take
    /// (`brdf_meter::acquire::Linearity`), when the sensor needs one.
    pub linearity: Option<brdf_meter::acquire::Linearity>,
    /// The most bytes of blob the device's calibration slot takes: a
    /// cluster count chosen in training (`clusters` `None`) is taken only if
    /// its blob fits, else the choice is made again among fewer. A fixed
    /// count is not checked here (provisioning refuses a blob too large).
    /// The product's board: [`board_blob_capacity`].
    pub max_blob_len: usize,
}

/// The most bytes of (unsigned) blob one of the board's calibration slots
/// holds: the slot less its header and the signature's trailer.
pub fn board_blob_capacity() -> usize {
    brdf_meter::shape::board::SLOT_LEN as usize - brdf_meter::store::SLOT_HEADER_LEN - brdf_meter::signed::TRAILER_LEN
}

impl<'a> TrainSpec<'a> {
    /// A specification with the settings a caller rarely changes: the
    /// plain criterion, a 5 % false-alarm rate, the cluster count by
    /// cross-validation, the kind's default form, near-field optics, LEDs
    /// fired in order and a sensor already white-normalised.
    pub fn new(
        bins_deg: &'a [f64],
        zones: Vec<ZoneOptics>,
        pixels: usize,
        view_deg: f64,
        prior: &'a PriorModels,
        noise_rel: f64,
        estimator: EstimatorKind,
    ) -> Self {
        Self {
            bins_deg,
            zones,
            pixels,
            view_deg,
            prior,
            noise_rel,
            estimator,
            criterion: Criterion::Plain,
            false_alarm: 0.05,
            clusters: None,
            root: Form::default_for(estimator) == Form::Root,
            far_field: false,
            led_order: None,
            white: None,
            linearity: None,
            max_blob_len: board_blob_capacity(),
        }
    }
}

/// The form a calibration is trained in (`brdf_meter::blob`'s root form).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Form {
    /// Roots of the values, squared on the device: no estimate is negative
    /// and every reading lies within its definition (the scale-free kinds).
    Root,
    /// The values themselves (the patent's form; an estimate may go
    /// negative where the prior's shapes do not fit the surface).
    Linear,
}

impl Form {
    /// The form a kind is trained in unless asked otherwise: root for the
    /// scale-free kinds, linear for the others (the patent's estimators).
    pub fn default_for(kind: EstimatorKind) -> Self {
        if scale_free_kind(kind) { Self::Root } else { Self::Linear }
    }

    /// The form a blob's root-form flag says it is in.
    pub fn of_blob(view: &brdf_meter::blob::BlobView<'_>) -> Self {
        Self::of_root(view.root_form())
    }

    /// The form of a calibration trained with `root` set or not.
    pub fn of_root(root: bool) -> Self {
        if root { Self::Root } else { Self::Linear }
    }

    /// Its name, as `--form` takes it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Root => "root",
            Self::Linear => "linear",
        }
    }
}

/// Whether `kind` is one of the scale-free kinds (trained on the readings
/// the instrument takes, in the root form by default) rather than one of
/// the patent's estimators (defined by H).
fn scale_free_kind(kind: EstimatorKind) -> bool {
    matches!(kind, EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise)
}

/// One zone's trained estimator.
#[derive(Clone, Debug)]
#[allow(
    clippy::large_enum_variant,
    reason = "a calibration holds at most a few dozen zones, and both variants' matrices are on the heap"
)]
pub enum ZoneEstimator {
    /// `rho = W v`.
    Linear(LinearEstimator),
    /// `rho = [W' | b] [v', s]`, per cluster.
    ScaleFree(ScaleFreeZone),
}

/// One zone's training result.
#[derive(Clone, Debug)]
pub struct TrainedZone {
    /// First pixel.
    pub first_pixel: usize,
    /// H at the zone's centre, m x n.
    pub h: DMatrix<f64>,
    /// The estimator.
    pub estimator: ZoneEstimator,
}

impl TrainedZone {
    /// The linear estimator (`None` for a scale-free zone).
    pub fn linear(&self) -> Option<&LinearEstimator> {
        match &self.estimator {
            ZoneEstimator::Linear(e) => Some(e),
            ZoneEstimator::ScaleFree(_) => None,
        }
    }

    /// The scale-free estimator (`None` for a linear zone).
    pub fn scale_free(&self) -> Option<&ScaleFreeZone> {
        match &self.estimator {
            ZoneEstimator::ScaleFree(z) => Some(z),
            ZoneEstimator::Linear(_) => None,
        }
    }
}

/// Training's result: the zones and the blob bytes.
#[derive(Clone, Debug)]
pub struct Trained {
    /// Blob dimensions.
    pub dims: Dims,
    /// Bin centres, degrees.
    pub bins_deg: Vec<f64>,
    /// Zones.
    pub zones: Vec<TrainedZone>,
    /// Matrices per zone (K; 1 unless piecewise).
    pub clusters: usize,
    /// The summary written into the blob.
    pub summary: TrainingSummary,
    /// Largest relative difference between f32 and f64 evaluation on the prior.
    pub f32_rel_error: f64,
    /// Per zone, the power-of-two exponent of each reading folded into the
    /// blob's W and white reference by the f32 gate (all 0 unless W left
    /// f32's range): blob W = W 2^e_i, blob white = white 2^e_i.
    pub f32_exponents: Vec<Vec<i32>>,
    /// The out-of-prior threshold (scale-free kinds), or `None`.
    pub out_of_prior_threshold: Option<f32>,
    /// What the flag is worth on kinds of material held out of training,
    /// over every zone (root-form scale-free kinds), or `None` (also when
    /// no kind could be held out).
    pub flag_on_kinds: Option<crate::calibration::estimators::out_of_prior::FlagOnKinds>,
    /// The calibration blob, already validated by `BlobView::parse`.
    pub blob: Vec<u8>,
    /// Cluster counts chosen first whose blob the slot would not take
    /// (`TrainSpec::max_blob_len`), with their blob's length in bytes: the
    /// count was chosen again among fewer.
    pub slot_refused: Vec<(usize, usize)>,
}

/// Every zone's sample pairs: of the prior, and of the gloss standards the
/// gloss rows are fitted on besides it. Built once, they serve any subset
/// of the prior's samples (a held-out evaluation trains a calibration per
/// fold from [`ZonePairs::without`]).
#[derive(Clone, Debug)]
pub struct ZonePairs {
    /// Per zone, the prior's pairs (the prior's own weights).
    pub prior: Vec<Pairs>,
    /// Per zone, the gloss standards' pairs.
    pub standards: Vec<Pairs>,
}

impl ZonePairs {
    /// The pairs of `spec`'s zones and prior. The scale-free kinds' pairs
    /// are what the instrument reads (a reflection model by its rays); the
    /// patent's estimators are defined by H, so where H describes the
    /// optics (in-plane) their pairs are `H rho` and give the patent's
    /// eq. 20/22 (`crate::forward::pairs`).
    pub fn build(spec: &TrainSpec<'_>) -> Self {
        let standards = gloss_rows::standards();
        let pixels = |zo: &ZoneOptics| -> Vec<PixelOptics> {
            if scale_free_kind(spec.estimator) {
                zo.pixels.clone()
            } else {
                zo.pixels.iter().map(PixelOptics::read_by_h_in_plane).collect()
            }
        };
        let pixels: Vec<Vec<PixelOptics>> = spec.zones.iter().map(pixels).collect();
        Self {
            prior: pixels.iter().map(|px| Pairs::build_with_gloss(px, spec.prior)).collect(),
            standards: pixels.iter().map(|px| Pairs::build_with_gloss(px, &standards)).collect(),
        }
    }

    /// The same without the prior's samples `held_out` (indices into the prior).
    pub fn without(&self, held_out: &[usize]) -> Self {
        Self {
            prior: self.prior.iter().map(|p| p.of_samples(|s| !held_out.contains(&s))).collect(),
            standards: self.standards.clone(),
        }
    }
}

/// Trains every zone and writes the blob.
pub fn train(spec: &TrainSpec<'_>) -> anyhow::Result<Trained> {
    train_on(spec, &ZonePairs::build(spec))
}

/// [`train`] on pairs already built for `spec`'s zones (the prior's may
/// be a subset of `spec.prior`'s samples).
pub fn train_on(spec: &TrainSpec<'_>, zone_pairs: &ZonePairs) -> anyhow::Result<Trained> {
    let mut most = usize::MAX;
    let mut refused = Vec::new();
    loop {
        let mut t = train_counts(spec, zone_pairs, most)?;
        // A count chosen here whose blob the slot does not take: chosen
        // again among fewer (the pairs are kept; only the maps are fitted
        // again).
        let chosen = spec.clusters.is_none() && spec.estimator == EstimatorKind::ScaleFreePiecewise;
        if t.blob.len() <= spec.max_blob_len || !chosen || t.clusters <= 2 {
            t.slot_refused = refused;
            return Ok(t);
        }
        refused.push((t.clusters, t.blob.len()));
        most = t.clusters - 1;
    }
}

/// [`train_on`] choosing the piecewise kind's count among those up to `most`.
fn train_counts(spec: &TrainSpec<'_>, zone_pairs: &ZonePairs, most: usize) -> anyhow::Result<Trained> {
    let n = spec.bins_deg.len();
    ensure!(!spec.zones.is_empty(), "no zones to train");
    ensure!(!spec.prior.is_empty(), "the prior has no samples");
    let m = spec.zones[0].h().nrows();
    ensure!(spec.noise_rel.is_finite() && spec.noise_rel >= 0.0, "noise {} must be finite and >= 0", spec.noise_rel);
    let dims = Dims { n, m, zones: spec.zones.len(), pixels: spec.pixels };
    for (z, zo) in spec.zones.iter().enumerate() {
        let h = zo.h();
        ensure!(h.shape() == (m, n), "zone {z}: H is {}x{}, expected {m}x{n}", h.nrows(), h.ncols());
        ensure!(zo.centres_deg().len() == m, "zone {z}: {} centre angles for {m} LEDs", zo.centres_deg().len());
    }
    ensure!(
        zone_pairs.prior.len() == spec.zones.len(),
        "pairs for {} zones, {} zones",
        zone_pairs.prior.len(),
        spec.zones.len()
    );
    let raw = &zone_pairs.prior;
    for (z, p) in raw.iter().enumerate() {
        if let Some((k, _)) = p.truth.iter().enumerate().find(|(_, x)| !x.is_finite() || **x < 0.0) {
            let s = p.sample[k / n];
            bail!(
                "prior sample {s} ({}), zone {z}: a value on the grid is not a finite, non-negative reflectance factor",
                spec.prior.samples[s].name
            );
        }
    }
    ensure!(
        !spec.root || scale_free_kind(spec.estimator),
        "the root form is for the scale-free kinds; train the {} estimator in the linear form (--form linear)",
        kind_name(spec.estimator)
    );
    let pairs: Vec<Pairs> = raw.iter().map(|p| p.weighted(spec.criterion)).collect();
    let zones = match spec.estimator {
        EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise => scale_free_zones(spec, &pairs, most)?,
        kind => linear_zones(spec, kind, &pairs)?,
    };
    let clusters = match &zones[0].estimator {
        ZoneEstimator::ScaleFree(z) => z.maps.len(),
        ZoneEstimator::Linear(_) => 1,
    };
    let plans = gate(spec, &zones, raw)?;
    let white = rescaled_white(spec, &zones, &plans, m)?;
    let f32_rel_error = plans.iter().map(|p| p.rel_error).fold(0.0, f64::max);
    let summary = summary(spec, &zones, clusters, f32_rel_error);
    let grid_f32: Vec<f32> = spec.bins_deg.iter().map(|x| *x as f32).collect();
    let zone_start: Vec<u16> = zones.iter().map(|z| z.first_pixel as u16).collect();
    let led_order = spec.led_order.clone().unwrap_or_else(|| (0..m as u8).collect());
    let (mut uncertainty, mut matrices, mut centroids, mut oop) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    // The broad estimates' table, when every zone's maps have one.
    let mut broad = Vec::new();
    for (tz, plan) in zones.iter().zip(&plans) {
        match &tz.estimator {
            ZoneEstimator::Linear(e) => {
                uncertainty.extend(e.uncertainty.iter().map(|x| *x as f32));
                matrices.extend_from_slice(&plan.w32);
            }
            ZoneEstimator::ScaleFree(z) => {
                for map in &z.maps {
                    uncertainty.extend(map.sigma_unit.iter().map(|x| *x as f32));
                    if let Some(b) = &map.sigma_broad {
                        broad.extend(b.iter().map(|x| *x as f32));
                    }
                    matrices.extend(map.w_f32());
                }
                centroids.extend_from_slice(&z.centroids);
                oop.extend_from_slice(&z.out_of_prior.mean);
                oop.extend_from_slice(&z.out_of_prior.g);
            }
        }
    }
    // Every zone flags in one form with its threshold folded into its G
    // (`scale_free_zones`), so the first zone's threshold and form are all
    // zones'.
    let threshold = zones.iter().find_map(|z| z.scale_free()).map(|s| (s.out_of_prior.threshold, s.out_of_prior.form));
    // One band factor for every zone, from all their held-out evidence (a
    // zone holds too few flagged readings for its own).
    let band_factor = crate::calibration::estimators::out_of_prior::band_factor(
        zones.iter().filter_map(|z| z.scale_free()).map(|s| &s.out_of_prior),
    ) as f32;
    let contents = BlobContents {
        dims,
        noise_rel: spec.noise_rel as f32,
        estimator: spec.estimator,
        far_field: spec.far_field,
        summary,
        grid_deg: &grid_f32,
        led_order: &led_order,
        zone_start: &zone_start,
        white: &white,
        uncertainty: &uncertainty,
        matrices: &matrices,
    };
    let base = BlobExtras {
        clusters,
        centroids: &centroids,
        out_of_prior: threshold.map(|(threshold, form)| OutOfPriorData { threshold, form, data: &oop, band_factor }),
        gloss: None,
        root_form: spec.root,
        peak_resolution_deg: None,
        pixel_peak_resolution_deg: &[],
        broad_uncertainty: if broad.len() == uncertainty.len() { &broad } else { &[] },
        linearity: spec.linearity,
        peak_factors: None,
        // Training's white is the model's, exact; a standardisation states its own.
        white_uncertainty: None,
        gloss_uncertainty: None,
    };
    let chosen = gloss_section(spec, &zones, zone_pairs, &plans, most)?;
    let mut blob = with_gloss(&contents, base, chosen.as_ref(), spec, &plans, &zones)?;
    // The rows' own clusters make the gloss section larger: where that
    // takes the blob over the slot, the rows keep the maps' clusters before
    // the maps are offered fewer (`train_on`).
    if chosen.as_ref().is_some_and(|g| !g.centroids.is_empty()) && blob.len() > spec.max_blob_len {
        let maps = gloss_section(spec, &zones, zone_pairs, &plans, 1)?;
        blob = with_gloss(&contents, base, maps.as_ref(), spec, &plans, &zones)?;
    }
    let f32_exponents = plans.into_iter().map(|p| p.exponents).collect();
    let flag_on_kinds = (spec.root && threshold.is_some())
        .then(|| {
            crate::calibration::estimators::out_of_prior::flag_on_kinds(
                zones.iter().filter_map(|z| z.scale_free()).map(|s| &s.out_of_prior),
            )
        })
        .filter(|f| f.readings > 0);
    Ok(Trained {
        dims,
        bins_deg: spec.bins_deg.to_vec(),
        zones,
        clusters,
        summary,
        f32_rel_error,
        f32_exponents,
        out_of_prior_threshold: threshold.map(|t| t.0),
        flag_on_kinds,
        blob,
        slot_refused: Vec::new(),
    })
}

/// The blob of `contents` and `base` with `gloss`, and with it the peak
/// resolution: what the device makes of the black glass, so it is
/// measured on the blob itself, then recorded in it; and the factors on
/// the resolved peaks' uncertainties, set on the `zones`' held-out peaks
/// judged at that resolution (`crate::calibration::peak_factors`).
fn with_gloss(
    contents: &BlobContents<'_>,
    base: BlobExtras<'_>,
    gloss: Option<&GlossSection>,
    spec: &TrainSpec<'_>,
    plans: &[F32Plan],
    zones: &[TrainedZone],
) -> anyhow::Result<Vec<u8>> {
    let extras = BlobExtras { gloss: gloss.map(GlossSection::data), ..base };
    let blob = written(contents, &extras)?;
    if gloss.is_none() {
        return Ok(blob);
    }
    let view = BlobView::parse(&blob).map_err(|e| anyhow::anyhow!("the written blob does not parse: {e}"))?;
    let (widest, own) = peak_resolution::recorded(&peak_resolution::black_glass_widths(&view, &spec.zones, plans)?);
    if widest.is_none() {
        return Ok(blob);
    }
    let with_resolution = BlobExtras { peak_resolution_deg: widest, pixel_peak_resolution_deg: &own, ..extras };
    let resolved = written(contents, &with_resolution)?;
    let view = BlobView::parse(&resolved).map_err(|e| anyhow::anyhow!("the written blob does not parse: {e}"))?;
    let peaks =
        zones.iter().zip(&spec.zones).filter_map(|(tz, zo)| Some((tz.scale_free()?, zo))).flat_map(|(sf, zo)| {
            sf.held_out_peaks.iter().map(move |p| {
                let pixel = zo.pixels[p.pixel].pixel.round() as usize;
                (p, view.peak_resolution_at(pixel).map(f64::from))
            })
        });
    match crate::calibration::peak_factors::factors(peaks) {
        Some(f) => written(contents, &BlobExtras { peak_factors: Some(f), ..with_resolution }),
        None => Ok(resolved),
    }
}

/// The blob of `contents` and `extras`, parsed back.
fn written(contents: &BlobContents<'_>, extras: &BlobExtras<'_>) -> anyhow::Result<Vec<u8>> {
    let mut blob = vec![0u8; contents.dims.blob_len_with(extras)];
    let len = write_blob_with(contents, extras, &mut blob)
        .map_err(|e| anyhow::anyhow!("the calibration blob would be invalid: {e}"))?;
    blob.truncate(len);
    BlobView::parse(&blob).map_err(|e| anyhow::anyhow!("the written blob does not parse: {e}"))?;
    Ok(blob)
}
