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
//!
//! Where it lives: this file, what the map is asked and [`run`]; `rows`,
//! what it holds (its rows and summaries, what the report and the JSON
//! show); `read`, one surface read at every pixel as the device reads it
//! and scored; `peaks`, `unseen` and `report` as named.
pub mod peaks;
mod read;
pub mod report;
mod rows;
pub mod unseen;

pub use rows::{
    BlackGlassSummary, GlossErrors, HazeDistinctnessErrors, LineSummary, MaterialRow, OwnSurface, PixelMap, PixelRow,
    SurfaceBrdf, TilesBrdf, gloss_tiles,
};

use read::{LineGeometry, PixelCounts, SurfacePixel, TileRead, read_material, read_surface, score_lines, surface_text};
use rows::nearness_of;

use crate::calibration::estimators::interpolation;
use crate::calibration::estimators::scale_free::peak_error;
use crate::calibration::train::{TrainSpec, ZonePairs, train_on};
use crate::device::reference::expected_line;
use crate::evaluation::metrology::metrics::{FlagErrors, FlagScore, GLOSS_SPLIT_GU, K, Spread};
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

/// The seed of the coverage's bootstrap interval: one map, one interval.
const COVERAGE_INTERVAL_SEED: u64 = 2813;

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
    let mut held_out_flag_errors = FlagErrors::default();
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
            held_out_flag_errors = held_out_flag_errors.merged(&row.flag_errors);
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
        result_coverage: held_out.result_coverage,
        flag: held_out_flag,
        flag_error_medians: held_out_flag_errors.medians(),
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
