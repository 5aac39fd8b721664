//! The per-pixel accuracy map of a calibration kind on a scene: how true
//! every pixel of the line reads, as a user of the instrument sees it.
//!
//! - **BRDF error on held-out materials.** The prior's samples are split into
//!   folds (`--folds` = its size: leave one material out); for each fold a
//!   calibration is trained by the production path (`calibration::train`)
//!   on the other folds, and every material of the fold is simulated as the
//!   scene's surface with every effect the scene lists (noise, saturation and
//!   the shorter exposures included) for `lines` lines, read by the device's
//!   own arithmetic (`device::reference::expected_line`, bit for bit the
//!   firmware's) and compared with its truth at each pixel's own view. The
//!   error of a point is the RMS over the bins relative to the truth's peak;
//!   a (material, pixel) scores its mean over the lines. Linear
//!   interpolation between the LEDs' centre angles at the pixel reads the
//!   same corrected readings beside it.
//! - **Gloss on held-out materials.** The same points' gloss readings
//!   (each (material, pixel) its mean over the lines) against the
//!   material's reading by the definitions in three dimensions at the
//!   pixel's own view, relative error split at 300 GU of the truth as
//!   `accuracy` splits it; interpolation's profile read by the in-plane
//!   definitions beside it.
//! - **Gloss standards.** A calibration trained on the whole prior reads the
//!   black-glass standard (mean, spread over lines, the line mean's spread,
//!   "no reading", saturation) and a set of gloss tiles, dielectrics with
//!   Ward or GGX roughness from a few to ~95 GU ([`gloss_tiles`], none of
//!   them in any prior), against their readings by the definition at each
//!   pixel's own view; the tiles' BRDF too, beside interpolation's: the
//!   map's surfaces of families no prior holds.
//! - **Stated uncertainty.** The share of the held-out materials' and the
//!   tiles' bins within k = 2 of the uncertainty the frame states for them
//!   (`BlobView::point_uncertainty`, what `measure` writes).
//! - **Flags and saturation** per pixel over the held-out materials, and
//!   whether the out-of-prior flag predicts error ([`FlagScore`]): of the
//!   points (each line of each pixel) worse than 0.10 of their peak,
//!   the share flagged, and of the rest, on the held-out materials and on
//!   the tiles; and per material, so the report can say which materials
//!   hold the bad points and whether the flag is raised on them
//!   ([`report::read_worst`]).
//! - **Specular peaks** of the held-out points ([`peaks`]): height error,
//!   the share the calibration does not resolve, the resolved heights'
//!   coverage.
//! - **The scene's own surface**, read as the tiles are: the surface the
//!   instrument is set up to read, on which a flag costs most.
pub mod peaks;
pub mod report;
pub mod unseen;

use crate::calibration::estimators::interpolation;
use crate::calibration::estimators::scale_free::peak_error;
use crate::calibration::train::{TrainSpec, ZonePairs, train_on};
use crate::device::reference::expected_line;
use crate::evaluation::metrology::metrics::{FlagScore, GLOSS_SPLIT_GU, K, Spread};
use crate::evaluation::metrology::{NearestSample, Nearness};
use crate::evaluation::pixel_error::quantiles;
use crate::forward::brdf::{Brdf, Ggx, SmoothDielectric, Ward, binned_reflectance_at};
use crate::forward::gloss::{model_readings, profile_scaled_readings};
use crate::forward::pairs::Criterion;
use crate::forward::prior_models::{PriorModels, SampleModel};
use crate::forward::scene::pipeline::{Simulator, pixel_view};
use crate::forward::scene::{Scene, training_optics};
use anyhow::Context;
use brdf_meter::acquire::AcqConfig;
use brdf_meter::blob::{BlobView, EstimatorKind};
use brdf_meter::protocol::flags;
use nalgebra::DVector;
use peaks::{PeakSummary, PeakTally, PixelPeaks};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;

/// What the map is asked.
#[derive(Clone, Debug)]
pub struct MapSpec {
    /// The instrument (and its effects) the materials are simulated with.
    pub scene: Scene,
    /// Zones of the calibrations.
    pub zones: usize,
    /// Estimator kind.
    pub kind: EstimatorKind,
    /// Training criterion.
    pub criterion: Criterion,
    /// The piecewise kind's cluster count (`None`: by cross-validation).
    pub clusters: Option<usize>,
    /// The out-of-prior flag's false-alarm rate on held-out prior samples
    /// (as `train --false-alarm`).
    pub false_alarm: f64,
    /// The prior (its reflection models are the held-out materials).
    pub prior: PriorModels,
    /// Folds over the prior's samples.
    pub folds: usize,
    /// Lines simulated per held-out material.
    pub lines: u64,
    /// Lines of the black glass and of each tile.
    pub gloss_lines: u64,
    /// The acquisition's shorter exposures (the device's settings).
    pub acq: AcqConfig,
    /// Seed of the fold split.
    pub seed: u64,
    /// Surfaces of the user's own, read by the calibration on the whole
    /// prior ([`unseen`]).
    pub unseen: Option<unseen::UnseenSpec>,
}

/// One pixel's row of the map.
#[derive(Clone, Debug, Serialize)]
pub struct PixelRow {
    /// Pixel.
    pub pixel: usize,
    /// Its view's polar angle, degrees.
    pub view_deg: f64,
    /// Its zone.
    pub zone: usize,
    /// Held-out BRDF error over the materials: median, 90th percentile, worst.
    pub error: [f64; 3],
    /// Linear interpolation's.
    pub interpolation: [f64; 3],
    /// Share of the held-out points flagged out of prior.
    pub out_of_prior: f64,
    /// Share of the held-out points flagged saturated.
    pub saturated: f64,
    /// The black glass's mean gloss reading over its lines, GU (NaN: no reading).
    pub black_glass_gu: f64,
    /// Its standard deviation over the lines, GU.
    pub black_glass_sd_gu: f64,
    /// Whether the black glass saturated the pixel on any line.
    pub black_glass_saturated: bool,
    /// The tiles' mean |reading - definition| at this pixel, GU (each tile's mean over lines).
    pub tiles_mean_abs_gu: f64,
    /// The tiles' worst.
    pub tiles_max_abs_gu: f64,
    /// The pixel's peak resolution, deg (the blob's, per pixel where it
    /// records one; NaN: none).
    pub peak_resolution_deg: f64,
    /// Share of its held-out points' specular peaks it does not resolve
    /// (no uncertainty stated for them; NaN: no peaks).
    pub peaks_unresolved: f64,
}

/// One material's errors (its mean over the lines at every pixel).
#[derive(Clone, Debug, Serialize)]
pub struct MaterialRow {
    /// Name.
    pub name: String,
    /// Per pixel, the estimator's error.
    pub error: Vec<f64>,
    /// Per pixel, interpolation's.
    pub interpolation: Vec<f64>,
    /// Per pixel, its gloss by the definitions in three dimensions, GU.
    pub gloss_true: Vec<f64>,
    /// Per pixel, the device's mean gloss reading over the lines, GU (NaN: no reading).
    pub gloss: Vec<f64>,
    /// Per pixel, interpolation's (its profile by the in-plane definitions), GU.
    pub gloss_interpolation: Vec<f64>,
    /// Per pixel, the share of the bins (over the lines) within k = 2 of
    /// their stated uncertainty.
    pub bin_coverage: Vec<f64>,
    /// Per pixel, the absolute error of the mean haze (HU) and distinctness
    /// (%) readings over the lines against the definitions in three
    /// dimensions (NaN: no reading): the device's, then interpolation's.
    pub haze_distinctness_error: [Vec<[f64; 2]>; 2],
    /// Per pixel and reading (gloss, haze, distinctness), the share of the
    /// lines whose reading is within k = 2 of the uncertainty the frame
    /// states for it (NaN: no line has the reading).
    pub reading_coverage: Vec<[f64; 3]>,
    /// Its points (every line of every pixel) worse than `BAD_ERROR` and
    /// not, and of each how many the out-of-prior flag raised: whether a
    /// material the calibration reads badly is read badly everywhere, and
    /// whether the flag says so ([`report`]'s materials read worst).
    pub flag: FlagScore,
    /// The prior sample nearest it among those its calibration trained
    /// on, at the scene's view (`folds::nearest`; `None`: none left).
    pub nearest_training: Option<NearestSample>,
}

impl MaterialRow {
    /// Its nearest training sample's distance and its error (median over
    /// the pixels), for [`Nearness`].
    fn nearness(&self) -> Option<(f64, f64)> {
        self.nearest_training.as_ref().map(|n| (n.distance, Spread::of(&self.error).median))
    }
}

/// How near `rows` are to the prior samples that read them.
fn nearness_of(rows: &[MaterialRow]) -> Option<Nearness> {
    Nearness::of(&rows.iter().filter_map(MaterialRow::nearness).collect::<Vec<_>>())
}

/// Per reading (gloss, haze, distinctness), the share of every (material,
/// pixel, line) with a reading that is within k = 2 of its stated
/// uncertainty (NaN: none), each (material, pixel) weighing alike.
fn reading_coverage(rows: &[MaterialRow]) -> [f64; 3] {
    std::array::from_fn(|r| {
        let v: Vec<f64> =
            rows.iter().flat_map(|m| m.reading_coverage.iter().map(move |c| c[r])).filter(|c| c.is_finite()).collect();
        if v.is_empty() { f64::NAN } else { v.iter().sum::<f64>() / v.len() as f64 }
    })
}

/// Haze (HU) and distinctness (% points) absolute errors over every
/// (material, pixel) with a reading: median and 90th percentile each.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct HazeDistinctnessErrors {
    /// Haze, HU: [median, 90th].
    pub haze_hu: [f64; 2],
    /// Distinctness, % points: [median, 90th].
    pub distinctness_pct: [f64; 2],
}

impl HazeDistinctnessErrors {
    /// Over the rows' per-pixel errors: the device's (`which` 0) or
    /// interpolation's (1).
    fn of(rows: &[MaterialRow], which: usize) -> Self {
        let q = |r: usize| {
            let v: Vec<f64> = rows
                .iter()
                .flat_map(|m| m.haze_distinctness_error[which].iter().map(move |e| e[r]))
                .filter(|e| e.is_finite())
                .collect();
            let q = quantiles(&v);
            [q[0], q[1]]
        };
        Self { haze_hu: q(0), distinctness_pct: q(1) }
    }
}

/// Gloss readings' relative error over every (material, pixel) with a
/// reading: median and 90th percentile, and how many, split at
/// [`GLOSS_SPLIT_GU`] of the truth as `accuracy` splits them.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct GlossErrors {
    /// Up to the split: [median, 90th], relative.
    pub low: [f64; 2],
    /// Points up to the split.
    pub low_count: usize,
    /// Above it.
    pub high: [f64; 2],
    /// Points above it.
    pub high_count: usize,
}

impl GlossErrors {
    /// Over `(truth, reading)` pairs; readings that are not finite are left out.
    pub fn of(points: impl Iterator<Item = (f64, f64)>) -> Self {
        let (mut low, mut high) = (Vec::new(), Vec::new());
        for (t, r) in points.filter(|(t, r)| r.is_finite() && t.is_finite() && *t > 0.0) {
            let e = (r - t).abs() / t;
            if t <= GLOSS_SPLIT_GU { low.push(e) } else { high.push(e) }
        }
        let q = |v: &[f64]| {
            let q = quantiles(v);
            [q[0], q[1]]
        };
        Self { low: q(&low), low_count: low.len(), high: q(&high), high_count: high.len() }
    }
}

/// A set of materials read on the whole line: over every (material,
/// pixel), each its mean over the lines.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct LineSummary {
    /// BRDF error / peak: median, 90th percentile, worst.
    pub error: [f64; 3],
    /// Linear interpolation's.
    pub interpolation: [f64; 3],
    /// Gloss readings' relative error.
    pub gloss: GlossErrors,
    /// Interpolation's.
    pub gloss_interpolation: GlossErrors,
    /// Haze and distinctness readings' absolute errors: the device's, then
    /// interpolation's.
    pub haze_distinctness: [HazeDistinctnessErrors; 2],
    /// Share of the bins within k = 2 of their stated uncertainty.
    pub bin_coverage: f64,
    /// Its 95 % interval, resampling the materials
    /// (`evaluation::coverage_interval`).
    pub bin_coverage_interval: Option<[f64; 2]>,
    /// Per reading (gloss, haze, distinctness), the share within k = 2 of
    /// its stated uncertainty.
    pub reading_coverage: [f64; 3],
}

impl LineSummary {
    /// Over `rows`.
    pub fn of(rows: &[MaterialRow]) -> Self {
        let all = |f: fn(&MaterialRow) -> &Vec<f64>| rows.iter().flat_map(|r| f(r).iter().copied()).collect::<Vec<_>>();
        let gloss_of = |f: fn(&MaterialRow) -> &Vec<f64>| {
            GlossErrors::of(rows.iter().flat_map(|r| r.gloss_true.iter().copied().zip(f(r).iter().copied())))
        };
        let covered = all(|r| &r.bin_coverage);
        Self {
            error: quantiles(&all(|r| &r.error)),
            interpolation: quantiles(&all(|r| &r.interpolation)),
            gloss: gloss_of(|r| &r.gloss),
            gloss_interpolation: gloss_of(|r| &r.gloss_interpolation),
            haze_distinctness: [HazeDistinctnessErrors::of(rows, 0), HazeDistinctnessErrors::of(rows, 1)],
            bin_coverage: covered.iter().sum::<f64>() / covered.len().max(1) as f64,
            // Each material's pixels weigh alike (each the same lines and bins).
            bin_coverage_interval: crate::evaluation::coverage_interval::coverage_interval(
                &rows
                    .iter()
                    .map(|r| (r.bin_coverage.iter().sum::<f64>(), r.bin_coverage.len() as f64))
                    .collect::<Vec<_>>(),
                COVERAGE_INTERVAL_SEED,
            ),
            reading_coverage: reading_coverage(rows),
        }
    }
}

/// The whole map.
#[derive(Clone, Debug, Serialize)]
pub struct PixelMap {
    /// Scene name.
    pub scene: String,
    /// Estimator kind.
    pub kind: String,
    /// Zones.
    pub zones: usize,
    /// Folds.
    pub folds: usize,
    /// Lines per material.
    pub lines: u64,
    /// Per pixel.
    pub pixels: Vec<PixelRow>,
    /// Per held-out material.
    pub materials: Vec<MaterialRow>,
    /// Over every (material, pixel): median, 90th, worst.
    pub error: [f64; 3],
    /// Interpolation's.
    pub interpolation: [f64; 3],
    /// Gloss readings of the held-out materials.
    pub gloss: GlossErrors,
    /// Their haze and distinctness readings: the device's, then
    /// interpolation's.
    pub haze_distinctness: [HazeDistinctnessErrors; 2],
    /// Interpolation's.
    pub gloss_interpolation: GlossErrors,
    /// Share of every held-out bin within k = 2 of its stated uncertainty.
    pub bin_coverage: f64,
    /// Its 95 % interval, resampling the materials.
    pub bin_coverage_interval: Option<[f64; 2]>,
    /// Per reading (gloss, haze, distinctness), the share of the held-out
    /// readings within k = 2 of their stated uncertainty.
    pub reading_coverage: [f64; 3],
    /// Whether the out-of-prior flag predicts the held-out points' error.
    pub flag: FlagScore,
    /// How near the held-out materials are to the prior samples their
    /// fold trained on, at the scene's view (`folds::nearest`; a
    /// material's error: its median over the pixels).
    pub held_out_nearness: Option<Nearness>,
    /// The held-out points' specular peaks.
    pub peaks: PeakSummary,
    /// Each calibration's out-of-prior statistic as its training chose it:
    /// the held-out folds', then the whole prior's (`none` without a flag).
    pub flag_statistics: Vec<String>,
    /// The whole prior's calibration's own measure of its flag in training,
    /// on kinds of material held out whole (what `train` prints), by the
    /// prior's weights; `None` for a kind without that evidence.
    pub flag_in_training: Option<crate::calibration::estimators::out_of_prior::FlagScore<f64>>,
    /// The black glass: mean GU range over the pixels [min, max], the
    /// largest per-pixel spread, the line mean's spread, pixels without a
    /// reading, pixels saturated.
    pub black_glass: BlackGlassSummary,
    /// The tiles: mean and worst |delta GU| over every (tile, pixel).
    pub tiles: [f64; 2],
    /// The tiles' BRDF estimates: surfaces of families no prior holds.
    pub tiles_brdf: TilesBrdf,
    /// The scene's own surface.
    pub own_surface: OwnSurface,
    /// The tiles' truths at the line's centre pixel, GU.
    pub tile_gu: Vec<(String, f64)>,
    /// The unseen set, when asked for.
    pub unseen: Option<unseen::UnseenSet>,
}

/// A surface's BRDF estimates over the line (every pixel, each its mean
/// over the surface's lines), by the calibration on the whole prior.
#[derive(Clone, Debug, Serialize)]
pub struct SurfaceBrdf {
    /// BRDF error / peak: median, 90th percentile, worst.
    pub error: [f64; 3],
    /// Linear interpolation's on the same readings.
    pub interpolation: [f64; 3],
    /// Share of the bins within k = 2 of their stated uncertainty.
    pub bin_coverage: f64,
    /// Share of the points flagged out of prior.
    pub out_of_prior: f64,
    /// Whether the flag predicts their error.
    pub flag: FlagScore,
}

impl SurfaceBrdf {
    fn of<'a>(scores: impl Iterator<Item = &'a SurfacePixel> + Clone) -> Self {
        let mean = |v: Vec<f64>| v.iter().sum::<f64>() / v.len().max(1) as f64;
        Self {
            error: quantiles(&scores.clone().map(|x| x.error).collect::<Vec<_>>()),
            interpolation: quantiles(&scores.clone().map(|x| x.interpolation).collect::<Vec<_>>()),
            bin_coverage: mean(scores.clone().map(|x| x.covered).collect()),
            out_of_prior: mean(scores.clone().map(|x| x.out_of_prior).collect()),
            flag: scores.fold(FlagScore::default(), |a, x| a.merged(x.flag)),
        }
    }
}

/// The gloss tiles' BRDF estimates: surfaces of families no prior holds.
#[derive(Clone, Debug, Serialize)]
pub struct TilesBrdf {
    /// Over every (tile, pixel).
    #[serde(flatten)]
    pub all: SurfaceBrdf,
    /// Per tile, its error over the pixels: median, 90th percentile, worst.
    pub per_tile: Vec<(String, [f64; 3])>,
}

/// The scene's own surface (its `surface.brdf`), read over the line.
#[derive(Clone, Debug, Serialize)]
pub struct OwnSurface {
    /// The surface, as the scene writes it (JSON).
    pub surface: String,
    /// Its estimates.
    #[serde(flatten)]
    pub brdf: SurfaceBrdf,
}

/// The black glass over the line.
#[derive(Clone, Debug, Serialize)]
pub struct BlackGlassSummary {
    /// Lowest and highest per-pixel mean reading, GU.
    pub mean_range_gu: [f64; 2],
    /// Largest per-pixel standard deviation over lines, GU.
    pub max_pixel_sd_gu: f64,
    /// Standard deviation of the line's mean over lines, GU.
    pub line_mean_sd_gu: f64,
    /// Pixels without a reading.
    pub no_reading: usize,
    /// Pixels saturated on some line.
    pub saturated: usize,
    /// Share of its points flagged out of prior (a mirror: no measured
    /// prior holds one).
    pub out_of_prior: f64,
}

/// The gloss tiles the map reads: polished dielectrics roughened by Ward
/// and by GGX, over dark and mid bases (none of them in the rows' prior,
/// whose GGX tiles have index 1.5 and other roughnesses).
pub fn gloss_tiles() -> Vec<(String, Arc<dyn Brdf>)> {
    let mut out: Vec<(String, Arc<dyn Brdf>)> = Vec::new();
    for alpha in [0.035, 0.05, 0.08, 0.12, 0.2] {
        out.push((format!("ward rho_s 0.05 alpha {alpha}"), Arc::new(Ward::new(0.1, 0.05, alpha).expect("tile"))));
    }
    let f0 = ((1.55f64 - 1.0) / (1.55 + 1.0)).powi(2);
    for alpha in [0.045, 0.065, 0.1, 0.15, 0.25] {
        out.push((format!("ggx f0 {f0:.3} alpha {alpha}"), Arc::new(Ggx::new(0.2, 1.0, alpha, f0).expect("tile"))));
    }
    out
}

/// One surface simulated with the scene's every effect for `lines` lines,
/// read as the device reads it; per line and pixel the estimate and the
/// corrected readings.
struct Read {
    /// `[line][pixel]`.
    points: Vec<Vec<crate::device::reference::ExpectedPoint>>,
}

fn read_surface(
    spec: &MapSpec,
    brdf: Arc<dyn Brdf>,
    blob: &BlobView<'_>,
    lines: u64,
    seed: u64,
) -> anyhow::Result<Read> {
    // Lines 0.. of the scene (its LEDs drift with the frames since
    // calibration), each surface with its own noise draw.
    let mut scene = spec.scene.clone();
    if scene.noise().is_some() {
        crate::forward::scene::readings::set_noise_seed(&mut scene, seed)?;
    }
    let sim = Simulator::with_surface(&scene, brdf)?;
    let fs = scene.instrument.sensor.full_scale as u16;
    let points = (0..lines)
        .map(|l| {
            let frames = sim.raw_frames(l)?;
            Ok(expected_line(blob, &frames, fs, &spec.acq))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(Read { points })
}

/// A scene's surface as one line of JSON, without the fields it leaves to
/// their defaults.
fn surface_text(b: &crate::forward::brdf::BrdfSpec) -> String {
    match serde_json::to_value(b) {
        Ok(serde_json::Value::Object(mut m)) => {
            m.retain(|_, v| !v.is_null());
            serde_json::Value::Object(m).to_string()
        }
        _ => String::new(),
    }
}

/// Surface `b` read over the line for `lines` lines (noise seed `seed`) by
/// `blob`, and per pixel its BRDF scores (each the mean over the lines).
fn score_lines(
    spec: &MapSpec,
    geo: &LineGeometry,
    b: &Arc<dyn Brdf>,
    blob: &BlobView<'_>,
    lines: u64,
    seed: u64,
) -> anyhow::Result<(Read, Vec<SurfacePixel>)> {
    let read = read_surface(spec, b.clone(), blob, lines, seed)?;
    let scores = (0..geo.views.len())
        .map(|px| {
            let t = truth_at(b.as_ref(), &geo.views[px], &geo.grid);
            let lines = read.points.len().max(1) as f64;
            let mut acc = SurfacePixel::default();
            for line in &read.points {
                let sc = PointScore::of(blob, &geo.bins32, &t, &line[px], &geo.interp[px]);
                acc.error += sc.error / lines;
                acc.interpolation += sc.interpolation / lines;
                acc.covered += sc.covered / lines;
                let flagged = line[px].flags & flags::OUT_OF_PRIOR != 0;
                acc.out_of_prior += f64::from(u8::from(flagged)) / lines;
                acc.flag.add(sc.error, flagged);
            }
            acc
        })
        .collect();
    Ok((read, scores))
}

/// A surface's truth at a pixel's view: its binned reflectance factor on the grid.
fn truth_at(b: &dyn Brdf, view: &nalgebra::Vector3<f64>, grid: &crate::forward::grid::AngleGrid) -> DVector<f64> {
    DVector::from_iterator(
        grid.n(),
        grid.bins_deg().iter().map(|t| binned_reflectance_at(b, *t, view, grid.step_deg())),
    )
}

/// One point read against its truth.
struct PointScore {
    /// The estimate's BRDF error: RMS over the bins / the truth's peak.
    error: f64,
    /// Linear interpolation's, on the same corrected readings.
    interpolation: f64,
    /// Share of the bins within k = 2 of the uncertainty the frame states
    /// (`BlobView::point_uncertainty`, what `measure` writes).
    covered: f64,
    /// Those uncertainties, per bin.
    u: Vec<f32>,
    /// Interpolation's profile (its gloss is read from it).
    profile: DVector<f64>,
}

impl PointScore {
    fn of(
        blob: &BlobView<'_>,
        bins_deg: &[f32],
        truth: &DVector<f64>,
        pt: &crate::device::reference::ExpectedPoint,
        interp: &nalgebra::DMatrix<f64>,
    ) -> Self {
        let n = truth.len();
        let est = DVector::from_iterator(n, pt.values.iter().map(|x| f64::from(*x)));
        let profile = interp * DVector::from_iterator(pt.corrected.len(), pt.corrected.iter().map(|x| f64::from(*x)));
        let table = blob.band_table(bins_deg, &pt.values);
        let u: Vec<f32> = (0..n)
            .map(|j| {
                blob.point_uncertainty(table, (pt.zone as usize, pt.cluster as usize), j, pt.values[j], pt.sigma_scale)
            })
            .collect();
        let inside = (0..n).filter(|&j| (est[j] - truth[j]).abs() <= K * f64::from(u[j])).count();
        Self {
            error: peak_error(&est, truth),
            interpolation: peak_error(&profile, truth),
            covered: inside as f64 / n.max(1) as f64,
            u,
            profile,
        }
    }
}

/// A gloss tile read over its lines by the calibration on the whole prior.
struct TileRead {
    read: Read,
    /// Per pixel, its gloss by the definitions in three dimensions, GU.
    gloss_truth: Vec<Option<f64>>,
    /// Per pixel, its BRDF scores (each the mean over the lines).
    brdf: Vec<SurfacePixel>,
}

/// One surface's BRDF at one pixel (a tile's, the scene's own), each
/// figure its mean over the lines.
#[derive(Clone, Copy, Debug, Default)]
struct SurfacePixel {
    error: f64,
    interpolation: f64,
    covered: f64,
    out_of_prior: f64,
    flag: FlagScore,
}

/// The seed of the coverage's bootstrap interval: one map, one interval.
const COVERAGE_INTERVAL_SEED: u64 = 2813;

/// One pixel's counts over its held-out points.
#[derive(Clone, Copy, Debug, Default)]
struct PixelCounts {
    /// Points flagged out of prior.
    out_of_prior: usize,
    /// Points flagged saturated.
    saturated: usize,
    /// Points.
    points: usize,
    /// Points whose estimate has a specular peak where the truth has one.
    peaks: usize,
    /// Of them, peaks the pixel does not resolve.
    unresolved: usize,
}

impl PixelCounts {
    fn add(&mut self, o: Self) {
        self.out_of_prior += o.out_of_prior;
        self.saturated += o.saturated;
        self.points += o.points;
        self.peaks += o.peaks;
        self.unresolved += o.unresolved;
    }
}

/// Per pixel of the line: its view, and linear interpolation's weights
/// between the LEDs' centre angles there; the scene's grid.
struct LineGeometry {
    /// The prior's samples on the grid at the scene's view (columns): what
    /// a material's nearest training sample is sought among.
    prior: nalgebra::DMatrix<f64>,
    views: Vec<nalgebra::Vector3<f64>>,
    interp: Vec<nalgebra::DMatrix<f64>>,
    grid: crate::forward::grid::AngleGrid,
    /// The grid's bins as the device holds them (f32).
    bins32: Vec<f32>,
}

/// Material `b` (named `name`) read on the whole line by `blob` for the
/// spec's lines (noise seed `seed`): its row (with the flag's score over
/// its points), per pixel its flag counts, and its peaks.
fn read_material(
    spec: &MapSpec,
    geo: &LineGeometry,
    name: &str,
    b: &Arc<dyn Brdf>,
    blob: &BlobView<'_>,
    seed: u64,
) -> anyhow::Result<MaterialRead> {
    let p = geo.views.len();
    let mut peaks = PeakTally::default();
    let read = read_surface(spec, b.clone(), blob, spec.lines, seed)?;
    let mut err = vec![0.0; p];
    let mut ierr = vec![0.0; p];
    let mut fl = vec![PixelCounts::default(); p];
    let (mut g_true, mut g_est, mut g_int) = (vec![0.0; p], vec![0.0; p], vec![0.0; p]);
    // Per pixel, the mean haze and distinctness over the lines: the device's and interpolation's.
    let (mut hd_est, mut hd_int) = (vec![[0.0f64; 2]; p], vec![[0.0f64; 2]; p]);
    let mut hd_true = vec![[0.0f64; 2]; p];
    let mut covered = vec![0.0; p];
    // Per pixel and reading: lines with the reading, and of them within k = 2.
    let mut readings_in = vec![[(0usize, 0usize); 3]; p];
    let mut flag = FlagScore::default();
    for (px, ((e, ie), c)) in err.iter_mut().zip(&mut ierr).zip(&mut fl).enumerate() {
        let true_readings = model_readings(b.as_ref(), &geo.views[px]);
        g_true[px] = true_readings[brdf_meter::gloss::SPECULAR_GU];
        hd_true[px] = [true_readings[brdf_meter::gloss::HAZE_HU], true_readings[brdf_meter::gloss::DISTINCTNESS]];
        let view_deg = geo.views[px].z.clamp(-1.0, 1.0).acos().to_degrees();
        let truth = truth_at(b.as_ref(), &geo.views[px], &geo.grid);
        let truth32: Vec<f32> = truth.iter().map(|x| *x as f32).collect();
        for line in &read.points {
            let pt = &line[px];
            let score = PointScore::of(blob, &geo.bins32, &truth, pt, &geo.interp[px]);
            let profile: Vec<f32> = score.profile.iter().map(|x| *x as f32).collect();
            let at = PixelPeaks {
                view_deg,
                resolution_deg: blob.peak_resolution_at(px).map(f64::from),
                factors: blob.peak_factors(),
            };
            if let Some(unresolved) = peaks.add(&geo.bins32, &truth32, pt, &score.u, &profile, at) {
                c.peaks += 1;
                c.unresolved += usize::from(unresolved);
            }
            *e += score.error / spec.lines as f64;
            *ie += score.interpolation / spec.lines as f64;
            covered[px] += score.covered / spec.lines as f64;
            g_est[px] += f64::from(pt.readings[brdf_meter::gloss::SPECULAR_GU]) / spec.lines as f64;
            let li = profile_scaled_readings(&score.profile, geo.grid.bins_deg(), view_deg);
            g_int[px] += li.map_or(f64::NAN, |l| l[0]) / spec.lines as f64;
            for (r, k) in [brdf_meter::gloss::HAZE_HU, brdf_meter::gloss::DISTINCTNESS].into_iter().enumerate() {
                hd_est[px][r] += f64::from(pt.readings[k]) / spec.lines as f64;
                hd_int[px][r] += li.map_or(f64::NAN, |l| l[k]) / spec.lines as f64;
            }
            for (k, (n, inside)) in readings_in[px].iter_mut().enumerate() {
                let (r, u) = (f64::from(pt.readings[k]), f64::from(pt.reading_sigma[k]));
                if r.is_finite() && true_readings[k].is_finite() {
                    *n += 1;
                    // An uncertainty that is not stated (NaN) covers nothing.
                    *inside += usize::from((r - true_readings[k]).abs() <= 2.0 * u);
                }
            }
            let flagged = pt.flags & flags::OUT_OF_PRIOR != 0;
            c.out_of_prior += usize::from(flagged);
            flag.add(score.error, flagged);
            c.saturated += usize::from(pt.flags & flags::SATURATED != 0);
            c.points += 1;
        }
    }
    let row = MaterialRow {
        name: name.to_string(),
        error: err,
        interpolation: ierr,
        gloss_true: g_true,
        gloss: g_est,
        gloss_interpolation: g_int,
        bin_coverage: covered,
        haze_distinctness_error: [&hd_est, &hd_int]
            .map(|read| read.iter().zip(&hd_true).map(|(r, t)| [(r[0] - t[0]).abs(), (r[1] - t[1]).abs()]).collect()),
        reading_coverage: readings_in
            .iter()
            .map(|px| px.map(|(n, inside)| if n == 0 { f64::NAN } else { inside as f64 / n as f64 }))
            .collect(),
        flag,
        nearest_training: None,
    };
    Ok((row, fl, peaks))
}

/// A held-out material's row (with its flag score), per pixel its counts
/// and its peaks.
type MaterialRead = (MaterialRow, Vec<PixelCounts>, PeakTally);

/// The map.
pub fn run(spec: &MapSpec, progress: &dyn Fn(&str)) -> anyhow::Result<PixelMap> {
    let scene = &spec.scene;
    let inst = &scene.instrument;
    let grid = inst.grid().context("the scene's angle grid")?;
    let p = inst.pixels();
    let optics = training_optics(scene, spec.zones, None)?;
    let train_spec = TrainSpec {
        bins_deg: grid.bins_deg(),
        zones: optics.zones.clone(),
        pixels: optics.pixels,
        view_deg: inst.view_deg,
        prior: &spec.prior,
        noise_rel: optics.noise_level.max(1e-6),
        estimator: spec.kind,
        criterion: spec.criterion,
        false_alarm: spec.false_alarm,
        clusters: spec.clusters,
        root: crate::calibration::train::Form::default_for(spec.kind) == crate::calibration::train::Form::Root,
        far_field: !scene.has("near-field"),
        led_order: None,
        white: Some(optics.white.clone()),
        linearity: optics.linearity.as_ref().map(|l| l.correction),
        max_blob_len: crate::calibration::train::board_blob_capacity(),
    };
    progress("sample pairs of every zone");
    let all_pairs = ZonePairs::build(&train_spec);
    let materials: Vec<usize> =
        (0..spec.prior.len()).filter(|&k| matches!(spec.prior.samples[k].model, SampleModel::Brdf(_))).collect();
    let mut order = materials.clone();
    order.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(spec.seed));
    let folds = spec.folds.clamp(1, order.len().max(1));
    let views: Vec<nalgebra::Vector3<f64>> = (0..p).map(|px| pixel_view(scene, px)).collect();
    let interp: Vec<nalgebra::DMatrix<f64>> = (0..p)
        .map(|px| {
            let c: Vec<f64> = (0..inst.m()).map(|k| scene.led_incidence_deg(k, px as f64)).collect();
            interpolation::weights(grid.bins_deg(), &c).map_err(|e| anyhow::anyhow!("{e}"))
        })
        .collect::<anyhow::Result<_>>()?;
    let bins32 = grid.bins_deg().iter().map(|x| *x as f32).collect();
    let prior = nalgebra::DMatrix::from_columns(
        &spec.prior.samples.iter().map(|s| s.model.on_grid(&grid, inst.view_deg)).collect::<Vec<_>>(),
    );
    let geo = LineGeometry { prior, views, interp, grid: grid.clone(), bins32 };
    let mut rows: Vec<MaterialRow> = Vec::new();
    let mut pixel_counts = vec![PixelCounts::default(); p];
    let mut held_out_flag = FlagScore::default();
    let mut held_out_peaks = PeakTally::default();
    let mut flag_statistics = Vec::with_capacity(folds + 1);
    let statistic = |b: &BlobView<'_>| crate::calibration::estimators::out_of_prior::statistic_name(b).to_string();
    for f in 0..folds {
        let held: Vec<usize> = order.iter().enumerate().filter(|(i, _)| i % folds == f).map(|(_, k)| *k).collect();
        progress(&format!("fold {}/{folds}: training without {} material(s)", f + 1, held.len()));
        let trained = train_on(&train_spec, &all_pairs.without(&held)).with_context(|| format!("fold {f}"))?;
        let blob = BlobView::parse(&trained.blob).map_err(|e| anyhow::anyhow!("{e}"))?;
        flag_statistics.push(statistic(&blob));
        let results: Vec<MaterialRead> = held
            .par_iter()
            .map(|&k| {
                let s = &spec.prior.samples[k];
                let SampleModel::Brdf(b) = &s.model else { unreachable!("only models are held out") };
                read_material(spec, &geo, &s.name, b, &blob, k as u64)
            })
            .collect::<anyhow::Result<_>>()?;
        for ((mut row, fl, pk), k) in results.into_iter().zip(&held) {
            // The nearest sample its fold trained on.
            let v = geo.prior.column(*k).into_owned();
            row.nearest_training = NearestSample::in_prior(&spec.prior, &geo.prior, (&v, v.amax()), &held);
            held_out_flag = held_out_flag.merged(row.flag);
            held_out_peaks = held_out_peaks.merged(pk);
            for (acc, x) in pixel_counts.iter_mut().zip(fl) {
                acc.add(x);
            }
            rows.push(row);
        }
    }
    rows.sort_by(|a, b| a.name.cmp(&b.name));
    // Gloss: a calibration on the whole prior.
    progress("gloss: training on the whole prior, reading the black glass and the tiles");
    let full = train_on(&train_spec, &all_pairs)?;
    let blob = BlobView::parse(&full.blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    flag_statistics.push(statistic(&blob));
    let bg = read_surface(spec, Arc::new(SmoothDielectric::black_glass()), &blob, spec.gloss_lines, 1_000_003)?;
    let unseen = match &spec.unseen {
        Some(set) => {
            progress(&format!("reading the {} surface(s) of {}", set.materials.len(), set.source));
            Some(unseen::read(spec, &geo, set, &blob)?)
        }
        None => None,
    };
    let tiles = gloss_tiles();
    let tile_reads: Vec<TileRead> = tiles
        .par_iter()
        .enumerate()
        .map(|(i, (_, b))| {
            let (read, brdf) = score_lines(spec, &geo, b, &blob, spec.gloss_lines.clamp(1, 8), 2_000_003 + i as u64)?;
            let gloss_truth = (0..p).map(|px| Some(model_readings(b.as_ref(), &geo.views[px])[0])).collect();
            Ok(TileRead { read, gloss_truth, brdf })
        })
        .collect::<anyhow::Result<_>>()?;
    // The scene's own surface, the one the instrument is set up to read: a
    // flag raised on it costs more than one that misses (inspection is
    // taught on it).
    progress("reading the scene's own surface");
    let own: Arc<dyn Brdf> =
        Arc::from(scene.surface.brdf.build_for(scene.instrument.spectral_weights).context("the scene's surface.brdf")?);
    let (_, own_scores) = score_lines(spec, &geo, &own, &blob, spec.gloss_lines.clamp(1, 8), 3_000_017)?;
    let own_surface =
        OwnSurface { surface: surface_text(&scene.surface.brdf), brdf: SurfaceBrdf::of(own_scores.iter()) };
    let black_glass_out_of_prior = bg.points.iter().flatten().filter(|pt| pt.flags & flags::OUT_OF_PRIOR != 0).count()
        as f64
        / bg.points.iter().map(Vec::len).sum::<usize>().max(1) as f64;
    let all_tiles = || tile_reads.iter().flat_map(|t| t.brdf.iter());
    let tiles_brdf = TilesBrdf {
        all: SurfaceBrdf::of(all_tiles()),
        per_tile: tiles
            .iter()
            .zip(&tile_reads)
            .map(|((n, _), t)| (n.clone(), quantiles(&t.brdf.iter().map(|x| x.error).collect::<Vec<_>>())))
            .collect(),
    };
    let mean_sd = |xs: &[f64]| {
        let n = xs.len() as f64;
        let m = xs.iter().sum::<f64>() / n;
        (m, (xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt())
    };
    let gu = |pt: &crate::device::reference::ExpectedPoint| f64::from(pt.readings[brdf_meter::gloss::SPECULAR_GU]);
    let mut pixels = Vec::with_capacity(p);
    for px in 0..p {
        let e: Vec<f64> = rows.iter().map(|r| r.error[px]).collect();
        let i: Vec<f64> = rows.iter().map(|r| r.interpolation[px]).collect();
        let bgv: Vec<f64> = bg.points.iter().map(|l| gu(&l[px])).collect();
        let (bm, bsd) = mean_sd(&bgv);
        let mut dev = Vec::new();
        for TileRead { read, gloss_truth: truth, .. } in &tile_reads {
            let r: Vec<f64> = read.points.iter().map(|l| gu(&l[px])).collect();
            if let Some(t) = truth[px] {
                dev.push((mean_sd(&r).0 - t).abs());
            }
        }
        let c = pixel_counts[px];
        pixels.push(PixelRow {
            pixel: px,
            view_deg: geo.views[px].z.acos().to_degrees(),
            zone: blob.zone_of_pixel(px),
            error: quantiles(&e),
            interpolation: quantiles(&i),
            out_of_prior: c.out_of_prior as f64 / c.points.max(1) as f64,
            saturated: c.saturated as f64 / c.points.max(1) as f64,
            black_glass_gu: bm,
            black_glass_sd_gu: bsd,
            black_glass_saturated: bg.points.iter().any(|l| l[px].flags & flags::SATURATED != 0),
            tiles_mean_abs_gu: if dev.is_empty() { f64::NAN } else { dev.iter().sum::<f64>() / dev.len() as f64 },
            tiles_max_abs_gu: dev.iter().copied().fold(f64::NAN, f64::max),
            peak_resolution_deg: blob.peak_resolution_at(px).map_or(f64::NAN, f64::from),
            peaks_unresolved: if c.peaks == 0 { f64::NAN } else { c.unresolved as f64 / c.peaks as f64 },
        });
    }
    let held_out = LineSummary::of(&rows);
    let line_means: Vec<f64> = bg
        .points
        .iter()
        .map(|l| {
            let v: Vec<f64> = l.iter().map(gu).filter(|x| x.is_finite()).collect();
            v.iter().sum::<f64>() / v.len().max(1) as f64
        })
        .collect();
    let finite_bg: Vec<f64> = pixels.iter().map(|r| r.black_glass_gu).filter(|x| x.is_finite()).collect();
    let black_glass = BlackGlassSummary {
        mean_range_gu: [
            finite_bg.iter().copied().fold(f64::INFINITY, f64::min),
            finite_bg.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ],
        max_pixel_sd_gu: pixels.iter().map(|r| r.black_glass_sd_gu).fold(0.0, f64::max),
        line_mean_sd_gu: mean_sd(&line_means).1,
        no_reading: pixels.iter().filter(|r| !r.black_glass_gu.is_finite()).count(),
        saturated: pixels.iter().filter(|r| r.black_glass_saturated).count(),
        out_of_prior: black_glass_out_of_prior,
    };
    let devs: Vec<f64> = pixels.iter().map(|r| r.tiles_mean_abs_gu).filter(|x| x.is_finite()).collect();
    let tile_gu = tiles
        .iter()
        .zip(&tile_reads)
        .map(|((n, _), t)| (n.clone(), t.gloss_truth[p / 2].unwrap_or(f64::NAN)))
        .collect();
    Ok(PixelMap {
        scene: scene.name.clone(),
        kind: crate::calibration::estimators::kind_name(spec.kind).into(),
        zones: spec.zones,
        folds,
        lines: spec.lines,
        error: held_out.error,
        interpolation: held_out.interpolation,
        gloss: held_out.gloss,
        gloss_interpolation: held_out.gloss_interpolation,
        haze_distinctness: held_out.haze_distinctness,
        bin_coverage: held_out.bin_coverage,
        bin_coverage_interval: held_out.bin_coverage_interval,
        reading_coverage: held_out.reading_coverage,
        flag: held_out_flag,
        held_out_nearness: nearness_of(&rows),
        peaks: held_out_peaks.summary(),
        flag_statistics,
        flag_in_training: full.flag_on_kinds.map(|f| f.weights),
        unseen,
        black_glass,
        tiles: [
            devs.iter().sum::<f64>() / devs.len().max(1) as f64,
            pixels.iter().map(|r| r.tiles_max_abs_gu).filter(|x| x.is_finite()).fold(0.0, f64::max),
        ],
        tile_gu,
        tiles_brdf,
        own_surface,
        pixels,
        materials: rows,
    })
}
