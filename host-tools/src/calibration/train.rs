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

/// The prior as `R_pp` over a zone's pairs (their truths with the
/// criterion's weights): what the H-based kinds predict their
/// uncertainty with.
fn pairs_r_pp(pairs: &Pairs) -> DMatrix<f64> {
    let sw = DVector::from_iterator(pairs.len(), pairs.weights.iter().map(|w| w.sqrt()));
    let mut s = pairs.truth.clone();
    for (j, mut c) in s.column_iter_mut().enumerate() {
        c *= sw[j];
    }
    &s * s.transpose()
}

fn linear_zones(spec: &TrainSpec<'_>, kind: EstimatorKind, pairs: &[Pairs]) -> anyhow::Result<Vec<TrainedZone>> {
    let k = spec.prior.len();
    let mut out = Vec::with_capacity(spec.zones.len());
    for (z, (zo, p)) in spec.zones.iter().zip(pairs).enumerate() {
        let at = || format!("zone {z}: training the {} estimator", kind_name(kind));
        let est = match kind {
            EstimatorKind::Wiener => pairs_wiener::build(p, zo.h(), k, spec.noise_rel).with_context(at)?,
            EstimatorKind::LogWiener => {
                bail!("the log-wiener estimator has no device form; it is evaluated in `tradeoff`")
            }
            _ => {
                let r_pp = pairs_r_pp(p);
                let inputs = EstimatorInputs {
                    h: zo.h(),
                    r_pp: &r_pp,
                    prior_samples: k,
                    noise: NoiseModel::Relative(spec.noise_rel),
                    bins_deg: spec.bins_deg,
                    centres_deg: zo.centres_deg(),
                };
                estimators::build(kind, &inputs).with_context(at)?
            }
        };
        out.push(TrainedZone { first_pixel: zo.first_pixel, h: zo.h().clone(), estimator: ZoneEstimator::Linear(est) });
    }
    Ok(out)
}

fn scale_free_zones(spec: &TrainSpec<'_>, pairs: &[Pairs], most: usize) -> anyhow::Result<Vec<TrainedZone>> {
    ensure!(spec.noise_rel > 0.0, "scale-free training needs a noise level > 0 (got {})", spec.noise_rel);
    ensure!(
        spec.false_alarm > 0.0 && spec.false_alarm < 1.0,
        "the out-of-prior false-alarm rate {} must be in (0, 1)",
        spec.false_alarm
    );
    let piecewise = spec.estimator == EstimatorKind::ScaleFreePiecewise;
    let bins32: Vec<f32> = spec.bins_deg.iter().map(|x| *x as f32).collect();
    let opts = ScaleFreeOptions {
        piecewise,
        false_alarm: spec.false_alarm,
        root: spec.root,
        band_bins: Some(&bins32),
        ..Default::default()
    };
    // The counts tried: scored per zone, the ridge with them.
    let counts: Vec<usize> = match (piecewise, spec.clusters) {
        (false, _) => vec![1],
        (true, Some(k)) => {
            ensure!(
                (2..=brdf_meter::blob::MAX_CLUSTERS).contains(&k),
                "{k} clusters: the piecewise kind takes 2..={}",
                brdf_meter::blob::MAX_CLUSTERS
            );
            vec![k]
        }
        (true, None) => scale_free::CLUSTER_COUNTS.iter().copied().filter(|k| *k <= most.max(2)).collect(),
    };
    use rayon::prelude::*;
    let scores: Vec<Vec<scale_free::CountScore>> = pairs
        .par_iter()
        .enumerate()
        .map(|(z, p)| {
            scale_free::score_counts(p, &opts, &counts)
                .with_context(|| format!("zone {z}: cross-validating the scale-free estimator"))
        })
        .collect::<anyhow::Result<_>>()?;
    // The count: the most accurate on random folds of those that read kinds
    // of material held out whole no worse than the fewest clusters do,
    // summed over the zones.
    let best = scale_free::guarded_count(&scores);
    // Each zone's training pixels' views: where their held-out peaks are sought.
    let views: Vec<Vec<f64>> = spec.zones.iter().map(|zo| zo.pixels.iter().map(|p| p.theta_o_deg).collect()).collect();
    let mut trained: Vec<ScaleFreeZone> = pairs
        .par_iter()
        .zip(&scores)
        .enumerate()
        .map(|(z, (p, c))| {
            let opts = ScaleFreeOptions { peak_views_deg: views.get(z).map(Vec::as_slice), ..opts };
            scale_free::train_with(p, &opts, c[best].ridge, counts[best], c[best].random)
                .with_context(|| format!("zone {z}: training the scale-free estimator"))
        })
        .collect::<anyhow::Result<_>>()?;
    // The blob holds one out-of-prior form: the one whose flagged held-out
    // readings were the worse estimated, over all zones.
    let form = crate::calibration::estimators::out_of_prior::choose_form(trained.iter().map(|z| &z.out_of_prior_forms));
    for z in &mut trained {
        z.use_out_of_prior_form(form);
    }
    Ok(spec
        .zones
        .iter()
        .zip(trained)
        .map(|(zo, t)| TrainedZone {
            first_pixel: zo.first_pixel,
            h: zo.h().clone(),
            estimator: ZoneEstimator::ScaleFree(t),
        })
        .collect())
}

/// The f32 gate, per zone: accept (possibly rescaled) or refuse with the reason.
fn gate(spec: &TrainSpec<'_>, zones: &[TrainedZone], raw: &[Pairs]) -> anyhow::Result<Vec<F32Plan>> {
    let mut plans = Vec::with_capacity(zones.len());
    for (z, (tz, p)) in zones.iter().zip(raw).enumerate() {
        match &tz.estimator {
            ZoneEstimator::Linear(e) => match f32_gate(&e.w, &p.readings) {
                Ok(plan) => plans.push(plan),
                Err(r) => {
                    let advice = f32_advice(spec, z, &raw[z], r.rel_error);
                    bail!(
                        "zone {z} (first pixel {}): the {} matrix cannot be evaluated in f32 on the device: {r}; {advice}",
                        tz.first_pixel,
                        kind_name(spec.estimator)
                    );
                }
            },
            ZoneEstimator::ScaleFree(sz) => {
                let mut rel = 0.0f64;
                for (c, map) in sz.maps.iter().enumerate() {
                    rel = rel.max(scale_free_gate(map, &p.readings, sz.root).map_err(|e| {
                        anyhow::anyhow!(
                            "zone {z}, cluster {c}: f32 evaluation differs from f64 by {e:.2e} of the estimate's scale \
                             (tolerance {F32_TOLERANCE:.0e}); retrain with more noise (--noise)"
                        )
                    })?);
                }
                let m = p.m();
                plans.push(F32Plan { w32: Vec::new(), exponents: vec![0; m], rel_error: rel, bound: 0.0 });
            }
        }
    }
    Ok(plans)
}

/// The white reference with each zone's f32 exponents folded in.
fn rescaled_white(
    spec: &TrainSpec<'_>,
    zones: &[TrainedZone],
    plans: &[F32Plan],
    m: usize,
) -> anyhow::Result<Vec<f32>> {
    let mut white = spec.white.clone().unwrap_or_else(|| vec![1.0; spec.pixels * m]);
    for (z, p) in plans.iter().enumerate() {
        if p.exponents.iter().all(|e| *e == 0) {
            continue;
        }
        let end = zones.get(z + 1).map_or(spec.pixels, |n| n.first_pixel);
        for px in zones[z].first_pixel..end {
            for i in 0..m {
                let x = (f64::from(white[px * m + i]) * 2f64.powi(p.exponents[i])) as f32;
                ensure!(
                    x.is_normal() && x > 0.0,
                    "zone {z}: W leaves f32's range and the power-of-two rescaling 2^{} of reading {i} would make the \
                     white reference of pixel {px} {x:e}, not a normal f32; retrain with more noise (--noise) or a \
                     better-conditioned instrument",
                    p.exponents[i]
                );
                white[px * m + i] = x;
            }
        }
    }
    Ok(white)
}

fn summary(spec: &TrainSpec<'_>, zones: &[TrainedZone], clusters: usize, f32_rel_error: f64) -> TrainingSummary {
    let linear: Vec<&EstimatorSummary> = zones.iter().filter_map(|z| z.linear().map(|e| &e.summary)).collect();
    let sf: Vec<&ScaleFreeZone> = zones.iter().filter_map(|z| z.scale_free()).collect();
    let worst = |f: fn(&EstimatorSummary) -> f64| linear.iter().map(|s| f(s)).fold(0.0, f64::max);
    let n = spec.bins_deg.len() as f64;
    let predicted = if sf.is_empty() {
        linear.iter().map(|s| s.predicted_rmse).sum::<f64>() / linear.len().max(1) as f64
    } else {
        // Each map's tables alike (the sharp and the broad estimates' when it has both).
        let rms = |t: &nalgebra::DVector<f64>| (t.norm_squared() / n).sqrt();
        sf.iter()
            .flat_map(|z| &z.maps)
            .map(|mp| mp.sigma_broad.as_ref().map_or(rms(&mp.sigma_unit), |b| 0.5 * (rms(&mp.sigma_unit) + rms(b))))
            .sum::<f64>()
            / (sf.len() * clusters) as f64
    };
    TrainingSummary {
        prior_samples: spec.prior.len() as u32,
        // Finite in the blob: an infinite (singular) condition is stored as f32::MAX.
        condition: worst(|s| s.condition_system).min(f32::MAX as f64) as f32,
        regularisation: if sf.is_empty() {
            worst(|s| s.regularisation) as f32
        } else {
            sf.iter().map(|z| z.ridge).fold(0.0, f64::max) as f32
        },
        predicted_rmse: predicted as f32,
        f32_rel_error: f32_rel_error as f32,
    }
}

/// The gloss section: per zone (and cluster) the rows of the linear
/// readings fitted from sample pairs of the prior mixed with the gloss
/// standards (`gloss_rows`' module doc), on the kind's own kernel input
/// (with the f32 gate's power-of-two factors of the blob's W), their error
/// covariance scaled by held-out folds, and the zone's reading of the black
/// glass at its centre through them. A zone that does not see the standard
/// gets no reading (NaN reference and block: the device streams NaN for its
/// points); `None` when the grid does not cover a pixel's specular aperture
/// or no zone sees the standard.
///
/// The piecewise kind's rows are fitted per cluster, and which clusters is
/// chosen here ([`gloss_clusters`]): the maps' own, or clusters of the
/// rows' own (`brdf_meter::blob`, flag bit 9), at most `most` of them.
fn gloss_section(
    spec: &TrainSpec<'_>,
    zones: &[TrainedZone],
    zone_pairs: &ZonePairs,
    plans: &[F32Plan],
    most: usize,
) -> anyhow::Result<Option<GlossSection>> {
    let mut prepared = Vec::with_capacity(zones.len());
    for (z, zo) in spec.zones.iter().enumerate() {
        match ZoneGloss::new(zone_pairs, z, zo) {
            Some(g) => prepared.push(g),
            None => return Ok(None),
        }
    }
    let own = gloss_clusters(zones, &prepared, plans, most);
    let root_readings = if zones.iter().any(root_of) {
        brdf_meter::gloss::RootReadings::Deficit
    } else {
        brdf_meter::gloss::RootReadings::Shoulders
    };
    let mut out = GlossSection { reference: Vec::new(), blocks: Vec::new(), centroids: Vec::new(), root_readings };
    for (z, (((tz, zo), plan), g)) in zones.iter().zip(&spec.zones).zip(plans).zip(&prepared).enumerate() {
        let m = zo.h().nrows();
        let cents = own.map(|k| scale_free::reading_centroids(&g.aug, k, GLOSS_CLUSTER_SEED));
        let k = own.unwrap_or_else(|| tz.scale_free().map_or(1, |s| s.maps.len()));
        let end = zones.get(z + 1).map_or(spec.pixels, |n| n.first_pixel);
        let zone_pixels = end - zo.first_pixel;
        let Some((mut blocks, s)) = gloss_rows_of(tz, &g.aug, &g.target, plan, &g.bg, cents.as_deref())
            .with_context(|| format!("zone {z}: the gloss rows"))?
        else {
            out.push_no_reading(zone_pixels, k * brdf_meter::gloss::block_len(m));
            if own.is_some() {
                // Finite centroids for a zone without a reading (the blob's rule).
                out.centroids.extend(std::iter::repeat_n(0.0, k * m));
            }
            continue;
        };
        // The uncertainty's scale factors from held-out samples: each
        // fold's rows fitted on the other folds, read by the device's function.
        // The black glass is in every fold's fit: it sets the scale, as it
        // does on the device (a fold without it would misread every sample
        // by its misreading of the glass and inflate every factor).
        let mut zs = Vec::new();
        g.held_out(z, false, |fold, tr, tt| {
            let Ok(Some((fb, fs))) = gloss_rows_of(tz, tr, tt, plan, &g.bg, cents.as_deref()) else { return };
            let q = (crate::forward::gloss::ASSIGNED_GU / f64::from(fs)) as f32;
            for (k, noisy) in fold {
                let t = g.target.column(k);
                let d = if t[2] > 0.0 { 100.0 * (t[2] - t[3]) / t[2] } else { f64::NAN };
                let truth = [t[0], t[1], d];
                let (c, x, sc) = gloss_input(tz, plan, cents.as_deref(), noisy);
                let z = gloss_rows::z_scores(&fb[c], &x, q, sc, &truth, root_of(tz));
                zs.push(gloss_rows::HeldOutZ { cluster: c, family: g.family(k), z });
            }
        });
        for (c, b) in blocks.iter_mut().enumerate() {
            gloss_rows::scale_block(b, m, gloss_rows::cluster_uncertainty_factors(&zs, c));
        }
        // Each pixel's own reading of the standard through its zone's rows
        // (the centre's where a pixel cannot see it), so the black glass
        // reads its assigned value at every pixel.
        for p in zo.first_pixel..end {
            let v = gloss_rows::black_glass_readings(zo.pixel(p));
            let (c, x, _) = gloss_input(tz, plan, cents.as_deref(), &v);
            out.reference.push(gloss_rows::standard_reading(&blocks[c], &x, root_of(tz)).unwrap_or(s));
        }
        out.blocks.extend(blocks.into_iter().flatten());
        out.centroids.extend(cents.into_iter().flatten());
    }
    Ok(out.if_any_reading())
}

/// The seed of the gloss rows' own k-means.
const GLOSS_CLUSTER_SEED: u64 = 0x61c1;

/// One zone's pairs for its gloss rows: the prior's mixed with the gloss
/// standards', lit, weighted by the reading's size and held to the black
/// glass; their targets; the black glass's sample and readings.
struct ZoneGloss {
    aug: Pairs,
    target: DMatrix<f64>,
    glass: usize,
    /// The first sample of the standards (the prior's are below it).
    first_standard: usize,
    bg: DVector<f64>,
}

impl ZoneGloss {
    /// `None` when the pairs carry no gloss targets (the grid does not
    /// cover a pixel's specular aperture).
    fn new(zone_pairs: &ZonePairs, z: usize, zo: &ZoneOptics) -> Option<Self> {
        let aug = zone_pairs.prior[z].joined(&zone_pairs.standards[z], gloss_rows::STANDARDS_WEIGHT);
        // A pair that reads no light cannot be learnt from (it has no scale).
        let lit: Vec<usize> = (0..aug.len()).filter(|&k| aug.readings.column(k).sum() > 0.0).collect();
        let aug = aug.columns(&lit);
        let target = gloss_rows::targets(&aug)?;
        let aug = gloss_rows::reading_weighted(&aug, &target);
        let first_standard = zone_pairs.prior[z].sample.iter().copied().max().map_or(0, |x| x + 1);
        let glass = first_standard + gloss_rows::BLACK_GLASS_STANDARD;
        let aug = gloss_rows::anchored(&aug, glass);
        Some(Self { aug, target, glass, first_standard, bg: gloss_rows::black_glass_readings(&zo.centre) })
    }

    /// The family of pair `k`'s sample.
    fn family(&self, k: usize) -> gloss_rows::Family {
        if self.aug.sample[k] >= self.first_standard {
            gloss_rows::Family::Standard
        } else if self.aug.variant[k] == 0 {
            gloss_rows::Family::AsTheyAre
        } else {
            gloss_rows::Family::Variant
        }
    }

    /// Calls `read` once per held-out fold of the samples (the black glass
    /// in every fold's fit; with `by_kind`, each fold a kind of material,
    /// `scale_free::kind_folds`, or by sample where the pairs cannot be
    /// normalised to find their kinds) with the fold's held-out pairs, each
    /// [`gloss_rows::HELD_OUT_DRAWS`] times with its own noise (the same
    /// draws on every call for zone `z`), and the other folds' pairs and
    /// targets.
    fn held_out(
        &self,
        z: usize,
        by_kind: bool,
        mut read: impl FnMut(Vec<(usize, &DVector<f64>)>, &Pairs, &DMatrix<f64>),
    ) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(z as u64 ^ 0x6105);
        let folds = gloss_rows::HELD_OUT_FOLDS;
        let kinds = if by_kind { scale_free::kind_folds(&self.aug, 0x6105).ok() } else { None };
        let fold_of = |k: usize| {
            (self.aug.sample[k] != self.glass)
                .then_some(kinds.as_ref().map_or(self.aug.sample[k] % folds, |f| f[k] % folds))
        };
        for fold in 0..folds {
            let train_idx: Vec<usize> = (0..self.aug.len()).filter(|&k| fold_of(k) != Some(fold)).collect();
            let test_idx: Vec<usize> = (0..self.aug.len()).filter(|&k| fold_of(k) == Some(fold)).collect();
            if train_idx.is_empty() || test_idx.is_empty() {
                continue;
            }
            let tr = self.aug.columns(&train_idx);
            let tt = DMatrix::from_columns(&train_idx.iter().map(|&k| self.target.column(k)).collect::<Vec<_>>());
            let draws: Vec<(usize, DVector<f64>)> = test_idx
                .iter()
                .flat_map(|&k| {
                    let v = self.aug.readings.column(k).into_owned();
                    let var = self.aug.noise_var.column(k).into_owned();
                    (0..gloss_rows::HELD_OUT_DRAWS).map(|_| (k, noisy(&v, &var, &mut rng))).collect::<Vec<_>>()
                })
                .collect();
            read(draws.iter().map(|(k, v)| (*k, v)).collect(), &tr, &tt);
        }
    }

    /// The rows' held-out error with `clusters` of their own (`None`: the
    /// maps'): the criterion they are fitted for, the weighted mean square
    /// of the gloss reading's error relative to its size
    /// (`gloss_rows::reading_weighted`), over the held-out folds.
    fn held_out_error(&self, z: usize, tz: &TrainedZone, plan: &F32Plan, clusters: Option<usize>) -> f64 {
        let (mut sum, mut weight) = (0.0, 0.0);
        self.held_out(z, true, |fold, tr, tt| {
            let cents = clusters.map(|k| scale_free::reading_centroids(tr, k, GLOSS_CLUSTER_SEED));
            let Ok(Some((fb, fs))) = gloss_rows_of(tz, tr, tt, plan, &self.bg, cents.as_deref()) else { return };
            let q = (crate::forward::gloss::ASSIGNED_GU / f64::from(fs)) as f32;
            for (k, noisy) in fold {
                let (c, x, sc) = gloss_input(tz, plan, cents.as_deref(), noisy);
                let (r, _) = gloss_rows::device_readings(&fb[c], &x, q, sc, root_of(tz));
                let e = f64::from(r[brdf_meter::gloss::SPECULAR_GU]) - self.target[(0, k)];
                if e.is_finite() {
                    sum += self.aug.weights[k] * e * e;
                    weight += self.aug.weights[k];
                }
            }
        });
        if weight > 0.0 { sum / weight } else { f64::INFINITY }
    }
}

/// Which clusters the piecewise kind's gloss rows are fitted per: `None`,
/// the maps' own, or `Some(K_g)` clusters of the rows' own (k-means of the
/// readings' shares, as the maps'), whichever reads the gloss of the
/// samples held out of the rows' fit best, summed over the zones
/// ([`ZoneGloss::held_out_error`]), K_g among the counts the maps are
/// offered (`scale_free::CLUSTER_COUNTS`, at most `most`). The gloss
/// reading is a flux through the gloss window, and what decides how a
/// flux is read from the LEDs (how wide a lobe is where the mirror
/// direction passes from one LED to the next) need not be what decides
/// the BRDF's maps: with a prior that also holds each material stretched
/// across the plane, the handheld's maps read best with 2 clusters, whose
/// rows read the gloss tiles at its facet edges 7 GU off. The other kinds
/// have one set of rows per zone: `None`.
fn gloss_clusters(zones: &[TrainedZone], prepared: &[ZoneGloss], plans: &[F32Plan], most: usize) -> Option<usize> {
    use rayon::prelude::*;
    let piecewise = zones.iter().all(|z| z.scale_free().is_some_and(|s| !s.centroids.is_empty()));
    if !piecewise {
        return None;
    }
    let options: Vec<Option<usize>> = std::iter::once(None)
        .chain(scale_free::CLUSTER_COUNTS.iter().copied().filter(|k| *k <= most).map(Some))
        .collect();
    if options.len() == 1 {
        return None;
    }
    // Per option, each zone's error (in zone order, so the sums do not
    // depend on how rayon splits the work).
    let per_zone: Vec<Vec<f64>> = options
        .iter()
        .map(|o| {
            (0..zones.len()).into_par_iter().map(|z| prepared[z].held_out_error(z, &zones[z], &plans[z], *o)).collect()
        })
        .collect();
    chosen_gloss_clusters(&options, &per_zone)
}

/// [`gloss_clusters`]' choice among `options` (the first `None`, the
/// maps' clusters) from each option's held-out error per zone: the maps'
/// own unless the best count of the rows' own leaves at most
/// [`OWN_GLOSS_CLUSTERS_GAIN`] of their error, summed over the zones the
/// maps' clusters read at all. A zone that holds no held-out reading (it
/// cannot see the standard: an infinite error) says nothing about either
/// choice, and would make every option's sum infinite.
fn chosen_gloss_clusters(options: &[Option<usize>], per_zone: &[Vec<f64>]) -> Option<usize> {
    let read = |e: &[f64]| -> f64 { e.iter().zip(&per_zone[0]).filter(|(_, m)| m.is_finite()).map(|(x, _)| x).sum() };
    let maps = read(&per_zone[0]);
    if !maps.is_finite() || maps <= 0.0 {
        return None;
    }
    // The maps' own clusters unless clusters of the rows' own read clearly
    // better: their own cost the device a second cluster choice per point
    // and the blob a table. Among equal errors, the fewest clusters.
    let own = options[1..].iter().zip(&per_zone[1..]).map(|(o, e)| (*o, read(e))).fold(
        None,
        |best: Option<(Option<usize>, f64)>, s| match best {
            Some(b) if b.1 <= s.1 => Some(b),
            _ => Some(s),
        },
    );
    match own {
        Some((k, e)) if e.is_finite() && e <= OWN_GLOSS_CLUSTERS_GAIN * maps => k,
        _ => None,
    }
}

/// How much of the maps' held-out error the gloss rows' own clusters may
/// leave to be taken ([`gloss_clusters`]): three quarters. The kinds held
/// out make a noisy estimate (one kind may be half the prior): on the
/// handheld the rows' own clusters leave half of it (0.51 for the product's
/// 16 zones), on the patent profile 0.82 to 1.0 (the whole prior and the
/// five folds of the `gloss_readings` test), where taking them at 0.9 left
/// held-out MERL's gloss covered 93.5 % at k = 2 and its distinctness
/// 90.5 % (94.5 and 94.5 % with the maps' clusters) for no gain in error.
const OWN_GLOSS_CLUSTERS_GAIN: f64 = 0.75;

/// The gloss rows' cluster of readings `v` (the device's choice,
/// `brdf_meter::gloss::cluster_of`, among the rows' own `centroids` or
/// else the maps' cluster) with the kernel's input and scale
/// ([`kernel_input`]).
fn gloss_input(
    tz: &TrainedZone,
    plan: &F32Plan,
    centroids: Option<&[f32]>,
    v: &DVector<f64>,
) -> (usize, Vec<f32>, f32) {
    let (c, x, s) = kernel_input(tz, plan, v);
    (brdf_meter::gloss::cluster_of(centroids.unwrap_or(&[]), c, &plan.readings(v)), x, s)
}

/// One zone's gloss blocks (per cluster) fitted on `pairs` for `target`,
/// and the zone's reading of the black glass (readings `bg`) through them;
/// `None` when it does not see it.
fn gloss_rows_of(
    tz: &TrainedZone,
    pairs: &Pairs,
    target: &DMatrix<f64>,
    plan: &F32Plan,
    bg: &DVector<f64>,
    centroids: Option<&[f32]>,
) -> anyhow::Result<Option<(Vec<Vec<f32>>, f32)>> {
    let blocks: Vec<Vec<f32>> = match &tz.estimator {
        ZoneEstimator::Linear(_) => {
            let map = pairs_wiener::linear_map(pairs, target)?;
            // The device's readings are `v 2^-e`: the rows take them with `2^e`.
            let (r, m) = map.g.shape();
            let g = DMatrix::from_fn(r, m, |j, i| map.g[(j, i)] * 2f64.powi(plan.exponents[i]));
            vec![gloss_rows::block(&g, &map.err)]
        }
        ZoneEstimator::ScaleFree(sz) => {
            // The root form reads the peak's deficit over its shoulders
            // as a root of its own (`brdf_meter::gloss::RootReadings`).
            let deficit;
            let target = if sz.root {
                deficit = gloss_rows::deficit_target(target);
                &deficit
            } else {
                target
            };
            match centroids {
                Some(c) => scale_free::fit_target_with(pairs, target, sz, c)?,
                None => scale_free::fit_target(pairs, target, sz)?,
            }
        }
        .iter()
        .map(|mp| gloss_rows::block(&mp.w, &mp.err_unit))
        .collect(),
    };
    let (c, x, _) = gloss_input(tz, plan, centroids, bg);
    Ok(gloss_rows::standard_reading(&blocks[c], &x, root_of(tz)).map(|s| (blocks, s)))
}

/// The device's cluster, kernel input and scale for readings `v`: the
/// readings as the device corrects them (`v 2^-e`), and for the scale-free
/// kinds with the last replaced by their scale.
/// In the root form the input is over `sqrt(s)` and the scale returned is
/// `sqrt(s)` (`brdf_meter::gloss::readings_root`'s arguments).
fn kernel_input(tz: &TrainedZone, plan: &F32Plan, v: &DVector<f64>) -> (usize, Vec<f32>, f32) {
    let mut x = plan.readings(v);
    match &tz.estimator {
        ZoneEstimator::Linear(_) => (0, x, 1.0),
        ZoneEstimator::ScaleFree(sz) => {
            let c = if sz.centroids.is_empty() { 0 } else { brdf_meter::kernel::select_cluster(&sz.centroids, &x) };
            let s = brdf_meter::kernel::scale_free::scale(&x);
            let m = x.len();
            x[m - 1] = s;
            if sz.root {
                let (sqrt_s, r) = brdf_meter::kernel::root_scales(s);
                brdf_meter::kernel::scale_input(&mut x, r);
                (c, x, sqrt_s)
            } else {
                (c, x, s)
            }
        }
    }
}

/// Whether a zone's gloss rows are in the root form.
fn root_of(tz: &TrainedZone) -> bool {
    tz.scale_free().is_some_and(|z| z.root)
}

/// One noisy draw of readings `v` with variances `var`.
fn noisy(v: &DVector<f64>, var: &DVector<f64>, rng: &mut rand_chacha::ChaCha8Rng) -> DVector<f64> {
    use rand_distr::{Distribution, Normal};
    let nd = Normal::new(0.0, 1.0).expect("unit normal");
    DVector::from_fn(v.len(), |i, _| v[i] + var[i].max(0.0).sqrt() * nd.sample(rng))
}

/// What to do when zone `z` is refused: the smallest relative noise (in
/// half-decade steps up to 0.5, rounded up to the three digits it is
/// printed with) at which the Wiener matrix passes the gate with a
/// two-fold margin: a heavily cancelling matrix's f32 error moves with the
/// last digit of its noise, so the advice is not made on the edge.
fn f32_advice(spec: &TrainSpec<'_>, z: usize, raw: &Pairs, err: f64) -> String {
    let zo = &spec.zones[z];
    let mut s = spec.noise_rel.max(1e-6);
    while s <= 0.5 {
        s *= 10f64.sqrt();
        // Printed to three significant digits, rounded up.
        let digits = 10f64.powf(s.log10().floor() - 2.0);
        let printed = (s / digits).ceil() * digits;
        let mut p = raw.weighted(spec.criterion);
        p.noise_var = raw.readings.map(|v| (printed * v).powi(2));
        if let Ok(e) = pairs_wiener::build(&p, zo.h(), spec.prior.len(), printed)
            && let Ok(plan) = f32_gate(&e.w, &raw.readings)
            && plan.rel_error <= 0.5 * F32_TOLERANCE
        {
            return format!(
                "retrain the wiener estimator with --noise {printed:.2e} or more (f32 error {:.1e} there, {err:.1e} now), \
                 or use an instrument whose LEDs are better spread",
                plan.rel_error
            );
        }
    }
    "no Wiener noise level up to 0.5 passes: the optics are too ill-conditioned for the device; spread the LEDs or \
     coarsen the angle grid"
        .into()
}

/// What `train --json` writes for a linear calibration: zone 0 at the top
/// level, every zone below.
#[derive(Debug, Serialize)]
pub struct TrainJson {
    /// Estimator kind.
    pub estimator: String,
    /// Relative noise.
    pub noise_rel: f64,
    /// Bin centres, degrees (n).
    pub bins_deg: Vec<f64>,
    /// Zone 0's H: m rows of n.
    #[serde(rename = "H")]
    pub h: Vec<Vec<f64>>,
    /// Zone 0's W: n rows of m.
    #[serde(rename = "W")]
    pub w: Vec<Vec<f64>>,
    /// Zone 0's predicted standard uncertainty per bin (n).
    pub uncertainty: Vec<f64>,
    /// Zone 0's training summary.
    pub summary: EstimatorSummary,
    /// Largest relative f32 vs f64 difference on the prior.
    pub f32_rel_error: f64,
    /// Blob size in bytes.
    pub blob_bytes: usize,
    /// Blob CRC-32.
    pub blob_crc: u32,
    /// The peak resolution the blob records, deg (`crate::calibration::peak_resolution`; null: none).
    pub peak_resolution_deg: Option<f32>,
    /// Each pixel's peak resolution, deg: its own, or the calibration's
    /// when the blob records none for it (null: none).
    pub pixel_peak_resolution_deg: Vec<Option<f32>>,
    /// Every zone.
    pub zones: Vec<ZoneJson>,
}

/// One zone in `train --json`.
#[derive(Debug, Serialize)]
pub struct ZoneJson {
    /// First pixel.
    pub first_pixel: usize,
    /// H: m rows of n.
    #[serde(rename = "H")]
    pub h: Vec<Vec<f64>>,
    /// W: n rows of m.
    #[serde(rename = "W")]
    pub w: Vec<Vec<f64>>,
    /// Predicted standard uncertainty per bin.
    pub uncertainty: Vec<f64>,
    /// Summary.
    pub summary: EstimatorSummary,
}

/// What `train --json` writes for a scale-free calibration.
#[derive(Debug, Serialize)]
pub struct ScaleFreeJson {
    /// Estimator kind.
    pub estimator: String,
    /// Bin centres.
    pub bins_deg: Vec<f64>,
    /// Per zone: matrices (n rows of m: the last column multiplies the scale),
    /// uncertainty per unit scale, centroids, out-of-prior data.
    pub zones: Vec<ScaleFreeZoneJson>,
    /// The out-of-prior threshold.
    pub out_of_prior_threshold: f32,
    /// f32 vs f64 on the prior.
    pub f32_rel_error: f64,
    /// Blob size in bytes.
    pub blob_bytes: usize,
    /// Blob CRC-32.
    pub blob_crc: u32,
    /// The peak resolution the blob records, deg (`crate::calibration::peak_resolution`; null: none).
    pub peak_resolution_deg: Option<f32>,
    /// Each pixel's peak resolution, deg: its own, or the calibration's
    /// when the blob records none for it (null: none).
    pub pixel_peak_resolution_deg: Vec<Option<f32>>,
    /// The factors on a resolved peak's uncertainties, height then width
    /// (`crate::calibration::peak_factors`; null: none).
    pub peak_uncertainty_factors: Option<[f32; 2]>,
}

/// One zone in [`ScaleFreeJson`].
#[derive(Debug, Serialize)]
pub struct ScaleFreeZoneJson {
    /// First pixel.
    pub first_pixel: usize,
    /// Matrices `[W' | b]`, one per cluster.
    pub matrices: Vec<Vec<Vec<f64>>>,
    /// Uncertainty per unit scale, one per cluster.
    pub sigma_unit: Vec<Vec<f64>>,
    /// Centroids (K x m), empty unless piecewise.
    pub centroids: Vec<f32>,
    /// The out-of-prior statistic's form: "linear" (the shares) or
    /// "log-ratio" (their centred logarithms).
    pub out_of_prior_form: &'static str,
    /// Mean of the statistic's coordinates (m-1).
    pub out_of_prior_mean: Vec<f32>,
    /// Packed whitening G, the zone's threshold folded in (threshold 1).
    pub out_of_prior_g: Vec<f32>,
    /// Ridge chosen by cross-validation.
    pub ridge: f64,
    /// Its cross-validated peak-normalised error.
    pub cv_error: f64,
}

fn rows(a: &DMatrix<f64>) -> Vec<Vec<f64>> {
    a.row_iter().map(|r| r.iter().copied().collect()).collect()
}

impl Trained {
    /// The worst-conditioned linear zone and its summary: what limits the
    /// calibration (and what the blob's training summary records); `None`
    /// for a scale-free calibration.
    pub fn worst_zone(&self) -> Option<(usize, &EstimatorSummary)> {
        self.zones
            .iter()
            .enumerate()
            .filter_map(|(z, tz)| tz.linear().map(|e| (z, &e.summary)))
            .max_by(|a, b| a.1.condition_system.total_cmp(&b.1.condition_system))
    }

    /// The inspection JSON.
    pub fn to_json(&self) -> serde_json::Value {
        let view = BlobView::parse(&self.blob).expect("validated when built");
        let kind = kind_name(view.estimator()).to_string();
        let value = if let Some(z0) = self.zones[0].linear() {
            let zones: Vec<ZoneJson> = self
                .zones
                .iter()
                .filter_map(|z| {
                    z.linear().map(|e| ZoneJson {
                        first_pixel: z.first_pixel,
                        h: rows(&z.h),
                        w: rows(&e.w),
                        uncertainty: e.uncertainty.iter().copied().collect(),
                        summary: e.summary.clone(),
                    })
                })
                .collect();
            serde_json::to_value(TrainJson {
                estimator: kind,
                noise_rel: z0.summary.noise_rel,
                bins_deg: self.bins_deg.clone(),
                h: rows(&self.zones[0].h),
                w: rows(&z0.w),
                uncertainty: z0.uncertainty.iter().copied().collect(),
                summary: z0.summary.clone(),
                f32_rel_error: self.f32_rel_error,
                blob_bytes: self.blob.len(),
                blob_crc: view.crc(),
                peak_resolution_deg: view.peak_resolution_deg(),
                pixel_peak_resolution_deg: (0..view.dims().pixels).map(|p| view.peak_resolution_at(p)).collect(),
                zones,
            })
        } else {
            serde_json::to_value(ScaleFreeJson {
                estimator: kind,
                bins_deg: self.bins_deg.clone(),
                zones: self
                    .zones
                    .iter()
                    .filter_map(|tz| {
                        tz.scale_free().map(|z| ScaleFreeZoneJson {
                            first_pixel: tz.first_pixel,
                            matrices: z.maps.iter().map(|mp| rows(&mp.w)).collect(),
                            sigma_unit: z.maps.iter().map(|mp| mp.sigma_unit.iter().copied().collect()).collect(),
                            centroids: z.centroids.clone(),
                            out_of_prior_form: z.out_of_prior.form.name(),
                            out_of_prior_mean: z.out_of_prior.mean.clone(),
                            out_of_prior_g: z.out_of_prior.g.clone(),
                            ridge: z.ridge,
                            cv_error: z.cv_error,
                        })
                    })
                    .collect(),
                out_of_prior_threshold: self.out_of_prior_threshold.unwrap_or(f32::INFINITY),
                f32_rel_error: self.f32_rel_error,
                blob_bytes: self.blob.len(),
                blob_crc: view.crc(),
                peak_resolution_deg: view.peak_resolution_deg(),
                pixel_peak_resolution_deg: (0..view.dims().pixels).map(|p| view.peak_resolution_at(p)).collect(),
                peak_uncertainty_factors: view.peak_factors().map(|f| [f.height, f.width]),
            })
        };
        value.expect("the inspection JSON serialises")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::grid::AngleGrid;
    use crate::forward::optics::{Instrument, system_matrix};
    use crate::forward::prior_measured::PriorMix;
    use crate::forward::reading_noise::ReadingNoise;
    use crate::forward::zone_optics::uniform_zones;

    /// The gloss rows take clusters of their own only when those leave at
    /// most three quarters of the maps' error, summed over the zones the
    /// maps' rows read; a zone without a reading decides nothing.
    #[test]
    fn the_gloss_rows_own_clusters_are_taken_only_when_clearly_better_where_rows_read() {
        let options = [None, Some(2), Some(3), Some(4)];
        let inf = f64::INFINITY;
        // Clearly better: the best count of their own; at a tie, the fewest.
        let e = [vec![1.0, 1.0], vec![1.2, 1.0], vec![0.5, 0.4], vec![0.4, 0.5]];
        assert_eq!(chosen_gloss_clusters(&options, &e), Some(3));
        // Better, but not by a quarter: the maps'.
        let e = [vec![1.0, 1.0], vec![0.8, 0.8], vec![0.9, 0.9], vec![1.0, 1.0]];
        assert_eq!(chosen_gloss_clusters(&options, &e), None);
        // A zone without a reading (infinite under every option) is left
        // out of every sum; before, it made every sum infinite and
        // `inf <= 0.75 inf` took the first count of their own.
        let e = [vec![1.0, inf], vec![1.0, inf], vec![0.9, inf], vec![1.1, inf]];
        assert_eq!(chosen_gloss_clusters(&options, &e), None);
        let e = [vec![1.0, inf], vec![1.0, inf], vec![0.5, inf], vec![1.1, inf]];
        assert_eq!(chosen_gloss_clusters(&options, &e), Some(3));
        // A count of their own that reads a zone the maps' read not at all
        // is no better there; one that fails where the maps' read loses.
        let e = [vec![1.0, 1.0], vec![0.1, inf], vec![1.0, 1.0], vec![1.0, 1.0]];
        assert_eq!(chosen_gloss_clusters(&options, &e), None);
        // No zone read at all: the maps'.
        let e = [vec![inf, inf], vec![0.1, 0.1], vec![0.1, 0.1], vec![0.1, 0.1]];
        assert_eq!(chosen_gloss_clusters(&options, &e), None);
    }

    /// A form's name in reports is the one `--form` takes.
    #[test]
    fn a_forms_name_is_the_one_the_command_line_takes() {
        for f in [Form::Root, Form::Linear] {
            let value = clap::ValueEnum::to_possible_value(&f).unwrap();
            assert_eq!(value.get_name(), f.name());
            assert_eq!(Form::of_root(f == Form::Root), f);
        }
    }

    fn patent_spec(
        prior: &PriorModels,
        grid: &AngleGrid,
        zones: usize,
        pixels: usize,
        kind: EstimatorKind,
    ) -> TrainSpec<'static> {
        let inst = Instrument::patent_profile();
        let zs = uniform_zones(&inst, grid, zones, pixels, false, 0.02).unwrap();
        let bins: &'static [f64] = Box::leak(grid.bins_deg().to_vec().into_boxed_slice());
        let prior: &'static PriorModels = Box::leak(Box::new(prior.clone()));
        TrainSpec::new(bins, zs, pixels, inst.view_deg, prior, 0.02, kind)
    }

    fn patent_prior(grid: &AngleGrid) -> PriorModels {
        PriorMix::parse("patent").unwrap().models(grid, 45.0, crate::forward::brdf::nbrdf::LUMINANCE).unwrap()
    }

    #[test]
    fn blob_carries_the_trained_matrices_and_round_trips() {
        let grid = AngleGrid::patent();
        let prior = patent_prior(&grid);
        let t = train(&patent_spec(&prior, &grid, 4, 128, EstimatorKind::Wiener)).unwrap();
        let v = BlobView::parse(&t.blob).unwrap();
        assert_eq!(v.dims(), Dims { n: 81, m: 7, zones: 4, pixels: 128 });
        assert_eq!(v.estimator(), EstimatorKind::Wiener);
        assert_eq!(v.noise_rel(), 0.02f32);
        assert_eq!(v.zone_start(3), 96);
        assert_eq!(v.summary().prior_samples, 16);
        assert!(v.summary().predicted_rmse > 0.0);
        assert!(v.summary().f32_rel_error < 1e-4, "{}", v.summary().f32_rel_error);
        for z in 0..4 {
            let mut w = vec![0.0; 81 * 7];
            v.copy_matrix(z, &mut w);
            let e = t.zones[z].linear().unwrap();
            assert_eq!(w, e.w_f32_row_major());
            assert_eq!(v.uncertainty(z, 40), e.uncertainty[40] as f32);
        }
        assert_eq!(v.grid_deg(80), 65.0);
        assert_eq!(v.white(127, 6), 1.0);
        let j = t.to_json();
        assert_eq!(j["bins_deg"].as_array().unwrap().len(), 81);
        assert_eq!(j["H"].as_array().unwrap().len(), 7);
        assert_eq!(j["H"][0].as_array().unwrap().len(), 81);
        assert_eq!(j["W"].as_array().unwrap().len(), 81);
        assert_eq!(j["W"][0].as_array().unwrap().len(), 7);
        assert_eq!(j["uncertainty"].as_array().unwrap().len(), 81);
        assert_eq!(j["peak_resolution_deg"].as_f64().map(|x| x as f32), v.peak_resolution_deg());
        // Every pixel alike (the same in-plane optics): each takes the calibration's.
        assert_eq!(j["pixel_peak_resolution_deg"], serde_json::json!(vec![v.peak_resolution_deg(); 128]));
    }

    #[test]
    fn every_estimator_trains_on_the_patent_profile_except_the_square_inverse() {
        let grid = AngleGrid::patent();
        let prior = patent_prior(&grid);
        for kind in [
            EstimatorKind::Wiener,
            EstimatorKind::WienerNoiseFree,
            EstimatorKind::PseudoInverse,
            EstimatorKind::Interpolation,
        ] {
            let t = train(&patent_spec(&prior, &grid, 1, 16, kind)).unwrap();
            assert_eq!(BlobView::parse(&t.blob).unwrap().estimator(), kind);
        }
        let e = train(&patent_spec(&prior, &grid, 1, 16, EstimatorKind::Inverse)).unwrap_err();
        assert!(format!("{e:#}").contains("square"), "{e:#}");
    }

    #[test]
    fn the_patent_profiles_wiener_is_eq_22_of_the_table_5_prior() {
        // Pairs with the patent's plain criterion on in-plane optics give
        // the H-based W (so the reproduction and its Table 6 stand).
        let grid = AngleGrid::patent();
        let inst = Instrument::patent_profile();
        let t = train(&patent_spec(&patent_prior(&grid), &grid, 1, 1, EstimatorKind::Wiener)).unwrap();
        let h = system_matrix(&inst, &grid, false).unwrap();
        let prior = crate::forward::prior::PriorSpec::patent().build(&grid, 45.0, std::path::Path::new(".")).unwrap();
        let inputs = EstimatorInputs {
            h: &h,
            r_pp: &prior.r_pp,
            prior_samples: 16,
            noise: NoiseModel::Relative(0.02),
            bins_deg: grid.bins_deg(),
            centres_deg: &inst.centre_angles_deg(),
        };
        let classic = estimators::build(EstimatorKind::Wiener, &inputs).unwrap();
        let w = &t.zones[0].linear().unwrap().w;
        let d = (w - &classic.w).amax() / classic.w.amax();
        assert!(d < 1e-9, "{d:e}");
    }

    #[test]
    fn zones_take_their_own_h() {
        let grid = AngleGrid::patent();
        let prior = patent_prior(&grid);
        let mut spec = patent_spec(&prior, &grid, 2, 8, EstimatorKind::Wiener);
        // Zone 1 sees the far-field optics: its W must differ.
        let inst = Instrument::patent_profile();
        let far = system_matrix(&inst, &grid, true).unwrap();
        spec.zones[1] =
            ZoneOptics::from_h(4, far, inst.centre_angles_deg(), 45.0, &grid, ReadingNoise::relative(0.02, 7));
        let t = train(&spec).unwrap();
        let d = (&t.zones[0].linear().unwrap().w - &t.zones[1].linear().unwrap().w).amax();
        assert!(d > 1e-3, "{d}");
        assert!(uniform_zones(&inst, &grid, 9, 8, false, 0.02).is_err());
    }
}
