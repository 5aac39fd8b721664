//! What the map holds: a row per pixel and per material, and the summaries
//! of the standards, the tiles and the scene's own surface.

use super::*;

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
    /// Per reading, whether the result a user states of it covers the
    /// truth (1 or 0; NaN: no result): the mean over the centre zones'
    /// points with `U` as `measure` states it
    /// (`crate::device::measurement_result`), against the truth's mean
    /// over their pixels.
    pub result_covered: [f64; 3],
    /// Its points (every line of every pixel) worse than `BAD_ERROR` and
    /// not, and of each how many the out-of-prior flag raised: whether a
    /// material the calibration reads badly is read badly everywhere, and
    /// whether the flag says so ([`report`]'s materials read worst).
    pub flag: FlagScore,
    /// The same points' errors, the flagged apart from the rest (not
    /// written per material: the summaries' medians are).
    #[serde(skip)]
    pub flag_errors: FlagErrors,
    /// The prior sample nearest it among those its calibration trained
    /// on, at the scene's view (`folds::nearest`; `None`: none left).
    pub nearest_training: Option<NearestSample>,
}

impl MaterialRow {
    /// Its nearest training sample's distance and its error (median over
    /// the pixels), for [`Nearness`].
    pub(super) fn nearness(&self) -> Option<(f64, f64)> {
        self.nearest_training.as_ref().map(|n| (n.distance, Spread::of(&self.error).median))
    }
}

/// How near `rows` are to the prior samples that read them.
pub(super) fn nearness_of(rows: &[MaterialRow]) -> Option<Nearness> {
    Nearness::of(&rows.iter().filter_map(MaterialRow::nearness).collect::<Vec<_>>())
}

/// Per reading (gloss, haze, distinctness), the share of every (material,
/// pixel, line) with a reading that is within k = 2 of its stated
/// uncertainty (NaN: none), each (material, pixel) weighing alike.
pub(super) fn reading_coverage(rows: &[MaterialRow]) -> [f64; 3] {
    std::array::from_fn(|r| {
        let v: Vec<f64> =
            rows.iter().flat_map(|m| m.reading_coverage.iter().map(move |c| c[r])).filter(|c| c.is_finite()).collect();
        if v.is_empty() { f64::NAN } else { v.iter().sum::<f64>() / v.len() as f64 }
    })
}

/// Per reading, the share of the materials whose result covers the truth
/// (NaN: none has the result).
pub(super) fn result_coverage(rows: &[MaterialRow]) -> [f64; 3] {
    std::array::from_fn(|r| {
        let v: Vec<f64> = rows.iter().map(|m| m.result_covered[r]).filter(|c| c.is_finite()).collect();
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
    pub(super) fn of(rows: &[MaterialRow], which: usize) -> Self {
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
    /// Per reading, the share of the materials whose result covers the truth.
    pub result_coverage: [f64; 3],
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
            result_coverage: result_coverage(rows),
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
    /// Per reading, the share of the held-out materials whose result (the
    /// centre zones' mean, `U` as `measure` states it) covers the truth.
    pub result_coverage: [f64; 3],
    /// Whether the out-of-prior flag predicts the held-out points' error.
    pub flag: FlagScore,
    /// The held-out points' median error, flagged and not
    /// ([`FlagErrors::medians`]).
    pub flag_error_medians: [f64; 2],
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
    pub(super) fn of<'a>(scores: impl Iterator<Item = &'a SurfacePixel> + Clone) -> Self {
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
