//! Training's part of the gloss readings (`brdf_meter::gloss`): per zone
//! and cluster, the rows of the linear readings and their error covariance,
//! and the calibration on the gloss standard: each zone's reading `S_z` of
//! the simulated black glass through its own rows, by the device's own
//! function, so a black glass reads the standard's assigned value (100 GU)
//! on the device.
//!
//! # Every pixel its own definition
//! The readings are defined about each pixel's own specular direction (its
//! view's polar angle, `crate::forward::pairs::PixelOptics::theta_o_deg`),
//! each on the scale of the black glass seen from that pixel: the rows are
//! fitted from sample pairs whose target is, per pair, the definitions'
//! linear readings at the pair's pixel divided by the black glass's `L_0`
//! there, times the assigned 100 ([`targets`]). A black glass is therefore
//! 100 GU at every pixel by definition, and the zone's rows learn to read it
//! so wherever in the zone the pixel is; `S_z` (read at the zone's centre)
//! is then close to 100 and only corrects what the fit leaves.
//!
//! # The rows' own prior
//! No prior of the BRDF estimators holds a mirror, so rows trained on one
//! misread the black glass and every reading inherits that through `S_z`.
//! The rows are therefore fitted on the estimator's prior mixed at equal
//! weight ([`STANDARDS_WEIGHT`]) with a family of gloss standards
//! ([`standards`]): polished dielectrics (the black glass among them), bare
//! and over diffuse bases, and rough dielectric tiles. The pairs are
//! weighted by the error of the reading relative to its own size (with a
//! floor, [`GLOSS_FLOOR_GU`]): a metal's 2000 GU do not decide the rows a
//! 20 GU tile is read with.
//!
//! # The stated uncertainty
//! The fit's error covariance is too small for materials outside the prior
//! and leaves out the standard's own misreading, which every gloss and haze
//! reading inherits through `q`. Training holds the prior's samples out in
//! [`HELD_OUT_FOLDS`] folds, fits each fold's rows (and their reading of
//! the standard) on the others, reads the held-out samples by the device's
//! function and scales each cluster's covariance per reading so that
//! [`COVERAGE`] of the held-out points it selected fall within
//! [`COVERAGE_K`] u ([`cluster_uncertainty_factors`], [`scale_block`]),
//! in each family of samples on its own ([`Family`]): the materials as they
//! are, their variants, the standards. Pooled, the easier variants and
//! standards bought the materials' coverage: on the handheld 95 % of the
//! pool was covered and 91-92 % of the materials as they are.
//! Training data only: the test set never enters it.
use crate::calibration::families::covering_each_family;
use crate::forward::brdf::smooth_dielectric::BLACK_GLASS_INDEX;
use crate::forward::brdf::{Brdf, Ggx, SmoothDielectric};
use crate::forward::gloss::{ASSIGNED_GU, reading_weights};
use crate::forward::pairs::{Pairs, PixelOptics};
use crate::forward::prior_models::{PriorModels, SampleModel};
use anyhow::Context;
use brdf_meter::gloss::{LINEAR, RootReadings, block_len, cov_index};
use nalgebra::{DMatrix, DVector};
use std::sync::Arc;

/// What `train` says when a calibration carries no gloss readings.
pub const NO_GLOSS_NOTE: &str = "no gloss readings in this calibration (the device streams NaN): the angle grid does not \
     cover the 8 deg specular aperture about the view, or no zone sees the black-glass standard's mirror \
     reflection (no LED ray within a bin of the specular direction from any zone)";

/// What `train` says about the zones of a calibration with gloss readings
/// that have none (empty when every zone has them).
pub fn zones_without_reading_note(view: &brdf_meter::blob::BlobView<'_>) -> Option<String> {
    let mut block = vec![0.0f32; block_len(view.dims().m)];
    let none: Vec<String> = (0..view.dims().zones)
        .filter(|z| view.copy_gloss(*z, 0, &mut block).is_some_and(|(_, _, s)| s.is_nan()))
        .map(|z| z.to_string())
        .collect();
    (!none.is_empty()).then(|| {
        format!(
            "no gloss reading in zone(s) {} of {} (the device streams NaN for their points): they do not see the \
             black-glass standard's mirror reflection (no LED ray within a bin of the specular direction)",
            none.join(", "),
            view.dims().zones
        )
    })
}

/// The gloss section training writes.
#[derive(Clone, Debug, PartialEq)]
pub struct GlossSection {
    /// Per pixel, the standard's specular linear reading through its
    /// zone's rows there (P; blob format version 4).
    pub reference: Vec<f32>,
    /// Per zone and cluster, the block (rows then packed covariance).
    pub blocks: Vec<f32>,
    /// The rows' own centroids, per zone K_g x m, or empty: a point's
    /// block is then its BRDF cluster's (`brdf_meter::blob`, flag bit 9).
    pub centroids: Vec<f32>,
    /// How the rows are read: the root form's fourth row is fitted to the
    /// peak's deficit ([`deficit_target`]) and read in the second form
    /// (`RootReadings::Deficit`), the linear form's to the shoulders.
    pub root_readings: RootReadings,
}

impl GlossSection {
    /// Appends a zone without a reading (it cannot see the standard): its
    /// `pixels` references and its `values` block values NaN, the blob's
    /// marker (`brdf_meter::blob`), so the device streams NaN readings for
    /// its points.
    pub fn push_no_reading(&mut self, pixels: usize, values: usize) {
        self.reference.extend(std::iter::repeat_n(f32::NAN, pixels));
        self.blocks.extend(std::iter::repeat_n(f32::NAN, values));
    }

    /// The section, or `None` when no zone has a reading (nothing to carry).
    pub fn if_any_reading(self) -> Option<Self> {
        self.reference.iter().any(|s| !s.is_nan()).then_some(self)
    }

    /// The blob's view of it.
    pub fn data(&self) -> brdf_meter::blob::GlossData<'_> {
        brdf_meter::blob::GlossData {
            assigned_gu: ASSIGNED_GU as f32,
            refractive_index: BLACK_GLASS_INDEX as f32,
            reference: &self.reference,
            blocks: &self.blocks,
            centroids: &self.centroids,
            root_readings: self.root_readings,
        }
    }
}

/// One zone and cluster's block: rows `G` (LINEAR x m), the packed
/// covariance `cov` (LINEAR x LINEAR) and the square roots of its first two
/// diagonal entries.
pub fn block(g: &DMatrix<f64>, cov: &DMatrix<f64>) -> Vec<f32> {
    let m = g.ncols();
    let mut out = Vec::with_capacity(block_len(m));
    out.extend(g.transpose().iter().map(|x| *x as f32));
    let mut packed = vec![0.0f32; brdf_meter::gloss::COV_LEN];
    for i in 0..LINEAR {
        for j in i..LINEAR {
            let c = 0.5 * (cov[(i, j)] + cov[(j, i)]);
            packed[cov_index(i, j)] = if i == j { c.max(0.0) as f32 } else { c as f32 };
        }
    }
    out.extend(packed);
    out.extend([cov[(0, 0)].max(0.0).sqrt() as f32, cov[(1, 1)].max(0.0).sqrt() as f32]);
    out
}

/// The black glass's noise-free readings at a pixel: as the instrument
/// measures it when the pixel knows (`PixelOptics::standard`), else its
/// sample-pair readings.
pub fn black_glass_readings(px: &PixelOptics) -> DVector<f64> {
    if let Some(v) = &px.standard {
        return v.clone();
    }
    let model = SampleModel::Brdf(Arc::new(SmoothDielectric::black_glass()));
    px.readings(&model, &px.truth(&model))
}

/// The rows' target (LINEAR x K): per pair, the definitions' linear
/// readings at its pixel's own view on the black glass's scale there
/// (`crate::forward::pairs::PixelOptics::gloss_target`); `None` when the
/// pairs were built without them or a profile's grid does not cover its
/// specular aperture.
pub fn targets(pairs: &Pairs) -> Option<DMatrix<f64>> {
    pairs.gloss.clone()
}

/// The root form's target: the linear readings with the shoulders' row
/// replaced by the peak's deficit over them, `max(L_2 - L_3, 0)`
/// (`brdf_meter::gloss::RootReadings::Deficit`: a broad lobe's
/// distinctness is then the square of a small root, learnt as such from
/// the broad samples, not the difference of two near-equal roots).
pub fn deficit_target(target: &DMatrix<f64>) -> DMatrix<f64> {
    let mut out = target.clone();
    for k in 0..out.ncols() {
        out[(3, k)] = (target[(2, k)] - target[(3, k)]).max(0.0);
    }
    out
}

/// The floor of the rows' relative criterion, GU: a pair's weight is divided
/// by `(G + floor)^2`, G its gloss reading, so the rows are fitted for the
/// reading's error relative to its size, and a matt sample (a few GU) is not
/// read to a tenth of a GU at a glossy one's expense.
pub const GLOSS_FLOOR_GU: f64 = 10.0;

/// The pairs reweighted for the rows: each pair's weight divided by
/// `(G + GLOSS_FLOOR_GU)^2`, `G` its target gloss (row 0 of `target`).
pub fn reading_weighted(pairs: &Pairs, target: &DMatrix<f64>) -> Pairs {
    let mut out = pairs.clone();
    for (k, w) in out.weights.iter_mut().enumerate() {
        let g = target[(0, k)].max(0.0) + GLOSS_FLOOR_GU;
        *w /= g * g;
    }
    let total: f64 = out.weights.iter().sum();
    out.weights.iter_mut().for_each(|w| *w /= total);
    out
}

/// The zone's reading `S_z` of the standard: the device's own linear
/// reading `L_0` (f32, the device's function with q = 1) of the
/// black glass's readings `v` (already the kernel input `x`), through
/// `block`. `None` for a reading that is not positive: the zone does not
/// see the standard's mirror reflection (no LED ray near the specular
/// direction from where it looks), so no gloss scale can be set and the
/// zone has no gloss reading ([`GlossSection::push_no_reading`]).
pub fn standard_reading(block: &[f32], x: &[f32], root: bool) -> Option<f32> {
    let (r, _) = device_readings(block, x, 1.0, 1.0, root);
    let s = r[brdf_meter::gloss::SPECULAR_GU];
    (s.is_finite() && s > 0.0).then_some(s)
}

/// The weights of the definitions, or why the grid cannot carry them.
pub fn weights(bins: &[f64], view_deg: f64) -> anyhow::Result<DMatrix<f64>> {
    reading_weights(bins, view_deg).with_context(|| {
        format!(
            "the angle grid {:?}..{:?} deg does not cover the 8 deg specular aperture about {view_deg} deg",
            bins.first(),
            bins.last()
        )
    })
}

/// Refractive indices of the smooth dielectrics in the rows' prior (glass,
/// lacquers and plastics, the black-glass standard among them).
pub const STANDARD_INDICES: [f64; 4] = [1.45, 1.5, BLACK_GLASS_INDEX, 1.7];
/// Albedos of the diffuse base under the dielectric surface (0: bare, as
/// the black glass; then dark to white glossy paints).
pub const STANDARD_BASE_ALBEDOS: [f64; 4] = [0.0, 0.05, 0.3, 0.9];
/// GGX roughnesses of the rough dielectric tiles in the rows' prior (from
/// a near-mirror lacquer to a satin finish).
pub const TILE_ROUGHNESS: [f64; 5] = [0.02, 0.04, 0.08, 0.15, 0.3];
/// Diffuse albedos of those tiles.
pub const TILE_ALBEDOS: [f64; 2] = [0.05, 0.5];

/// The gloss standards added to the rows' prior, as models: every smooth
/// dielectric of [`STANDARD_INDICES`] over every base of
/// [`STANDARD_BASE_ALBEDOS`], and rough GGX tiles (index 1.5, every
/// roughness of [`TILE_ROUGHNESS`] over every albedo of [`TILE_ALBEDOS`]).
pub fn standards() -> PriorModels {
    let mut out: Vec<(String, Arc<dyn Brdf>)> = Vec::new();
    for n in STANDARD_INDICES {
        for a in STANDARD_BASE_ALBEDOS {
            let b = SmoothDielectric::over_base(n, a).expect("standards in range");
            out.push((format!("standard:n={n},base={a}"), Arc::new(b)));
        }
    }
    let f0 = ((1.5f64 - 1.0) / (1.5 + 1.0)).powi(2);
    for alpha in TILE_ROUGHNESS {
        for a in TILE_ALBEDOS {
            let b = Ggx::new(a, 1.0, alpha, f0).expect("tiles in range");
            out.push((format!("tile:ggx,alpha={alpha},rho_d={a}"), Arc::new(b)));
        }
    }
    PriorModels::from_brdfs("gloss standards", out)
}

/// The black glass's position among [`standards`]' samples: its index in
/// [`STANDARD_INDICES`] over the bare base (the first albedo).
pub const BLACK_GLASS_STANDARD: usize = {
    let mut i = 0;
    while STANDARD_INDICES[i] != BLACK_GLASS_INDEX {
        i += 1;
    }
    i * STANDARD_BASE_ALBEDOS.len()
};

/// The share of the rows' criterion given to the black glass's own pairs.
/// Every reading is scaled by the rows' reading of the black glass (as a
/// gloss meter is set on its standard), so a fit that misreads the glass
/// by a third misreads every surface by a third: the fit is held to the
/// standard, and the rest of the criterion shares what is left.
pub const BLACK_GLASS_SHARE: f64 = 0.5;

/// The pairs with those of sample `standard` (the black glass) holding
/// [`BLACK_GLASS_SHARE`] of the weight (unchanged when it has none).
pub fn anchored(pairs: &Pairs, standard: usize) -> Pairs {
    let mut out = pairs.clone();
    let on: f64 = (0..out.len()).filter(|&k| out.sample[k] == standard).map(|k| out.weights[k]).sum();
    let off: f64 = (0..out.len()).filter(|&k| out.sample[k] != standard).map(|k| out.weights[k]).sum();
    if on <= 0.0 || off <= 0.0 {
        return out;
    }
    for k in 0..out.len() {
        out.weights[k] *=
            if out.sample[k] == standard { BLACK_GLASS_SHARE / on } else { (1.0 - BLACK_GLASS_SHARE) / off };
    }
    out
}

/// The weight of the standards' family in the rows' prior: the prior and
/// the standards are mixed as two families of equal weight (as
/// `prior_measured::PriorMix` mixes families, `a@0.5+b@0.5`), each
/// family's samples equally weighted within it.
pub const STANDARDS_WEIGHT: f64 = 0.5;

/// Folds of the held-out check that sets the uncertainty's scale factors.
pub const HELD_OUT_FOLDS: usize = 5;
/// Noise draws per held-out sample.
pub const HELD_OUT_DRAWS: usize = 4;
/// The coverage factor the stated uncertainty is calibrated for (U = k u,
/// the GUM's ~95 % convention).
pub const COVERAGE_K: f64 = 2.0;
/// The coverage it must reach on held-out training samples.
pub const COVERAGE: f64 = 0.95;

/// The device's readings of a point: `brdf_meter::gloss::readings`, or in
/// the root form `readings_root` with the deficit row training writes (`x`
/// then over `sqrt(s)` and `s` its `sqrt(s)`).
pub fn device_readings(
    block: &[f32],
    x: &[f32],
    q: f32,
    s: f32,
    root: bool,
) -> ([f32; brdf_meter::shape::READINGS], [f32; brdf_meter::shape::READINGS]) {
    if root {
        brdf_meter::gloss::readings_root(block, x, q, s, RootReadings::Deficit)
    } else {
        brdf_meter::gloss::readings(block, x, q, s)
    }
}

/// The standardised errors `(reading - truth) / u` of one point's readings
/// (gloss, haze, distinctness), from the device's own function; NaN where
/// either side has no reading.
pub fn z_scores(block: &[f32], x: &[f32], q: f32, s: f32, truth: &[f64; 3], root: bool) -> [f64; 3] {
    let (r, u) = device_readings(block, x, q, s, root);
    std::array::from_fn(|i| (f64::from(r[i]) - truth[i]) / f64::from(u[i]))
}

/// Per reading, the factor on the stated uncertainty that makes `COVERAGE`
/// of the held-out training points fall within `COVERAGE_K` of it: the
/// 95th percentile of `|z|` over `COVERAGE_K` (1 when there is none).
/// Set on training data only (each point's rows trained without it), so
/// the test set never enters the calibration.
pub fn uncertainty_factors(z: &[[f64; 3]]) -> [f64; 3] {
    std::array::from_fn(|r| {
        let mut a: Vec<f64> = z.iter().map(|x| x[r].abs()).filter(|x| x.is_finite()).collect();
        if a.is_empty() {
            return 1.0;
        }
        a.sort_by(f64::total_cmp);
        let i = ((COVERAGE * a.len() as f64).ceil() as usize).clamp(1, a.len()) - 1;
        let f = a[i] / COVERAGE_K;
        if f.is_finite() && f > 0.0 { f } else { 1.0 }
    })
}

/// The families of samples the rows' prior holds, each of which the stated
/// uncertainty must cover on its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Family {
    /// The prior's materials as they are (what the instrument is sold to read).
    AsTheyAre,
    /// Their rougher finishes and stretches across the plane
    /// (`crate::forward::prior_models::PriorModels::variants`).
    Variant,
    /// The gloss standards ([`standards`]).
    Standard,
}

/// One held-out point of the factors' check: the cluster that read it, its
/// sample's family and its standardised errors ([`z_scores`]).
#[derive(Clone, Copy, Debug)]
pub struct HeldOutZ {
    pub cluster: usize,
    pub family: Family,
    pub z: [f64; 3],
}

/// Cluster `c`'s factors from the held-out points `z` it selected: per
/// reading the largest of its families' [`uncertainty_factors`] (each
/// family with at least [`MIN_FAMILY_POINTS`](crate::calibration::families::MIN_FAMILY_POINTS) points) and all of its
/// points' together (where a family too small to set its own still
/// counts), so each family is covered on its own. Each
/// cluster's readings are covered on their own too, not by a factor that a
/// few clusters' errors (the mirror-like materials') set for all. A cluster
/// with fewer than [`MIN_CLUSTER_POINTS`] held-out points takes the
/// factors of all of them.
pub fn cluster_uncertainty_factors(z: &[HeldOutZ], c: usize) -> [f64; 3] {
    let own: Vec<HeldOutZ> = z.iter().filter(|p| p.cluster == c).copied().collect();
    family_factors(if own.len() >= MIN_CLUSTER_POINTS { &own } else { z })
}

/// Per reading, the largest factor of the pool `z` and of its families with
/// enough points to set one ([`covering_each_family`]).
fn family_factors(z: &[HeldOutZ]) -> [f64; 3] {
    let families = [Family::AsTheyAre, Family::Variant, Family::Standard]
        .map(|f| z.iter().filter(|p| p.family == f).map(|p| p.z).collect::<Vec<_>>());
    std::array::from_fn(|r| covering_each_family(&families, |pts| Some(uncertainty_factors(pts)[r])).unwrap_or(1.0))
}

/// Fewest held-out points a cluster's own uncertainty factors are set
/// from: as many as a family's
/// (`crate::calibration::families::MIN_FAMILY_POINTS`).
pub const MIN_CLUSTER_POINTS: usize = crate::calibration::families::MIN_FAMILY_POINTS;

/// Scales a block's covariance and standard deviations by the factors
/// `f` (gloss, haze, distinctness: the distinctness factor on both the peak
/// and the shoulders), so the device's stated `u` is `f u`.
pub fn scale_block(block: &mut [f32], m: usize, f: [f64; 3]) {
    let fl = [f[0], f[1], f[2], f[2]];
    let c = &mut block[LINEAR * m..];
    for i in 0..LINEAR {
        for j in i..LINEAR {
            c[cov_index(i, j)] = (f64::from(c[cov_index(i, j)]) * fl[i] * fl[j]) as f32;
        }
    }
    let sd = &mut c[brdf_meter::gloss::COV_LEN..];
    sd[0] = (f64::from(sd[0]) * f[0]) as f32;
    sd[1] = (f64::from(sd[1]) * f[1]) as f32;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::grid::AngleGrid;

    #[test]
    fn the_standards_hold_the_black_glass_and_targets_are_on_its_scale() {
        let s = standards();
        assert_eq!(
            s.len(),
            STANDARD_INDICES.len() * STANDARD_BASE_ALBEDOS.len() + TILE_ROUGHNESS.len() * TILE_ALBEDOS.len()
        );
        // The rows are held to the sample at BLACK_GLASS_STANDARD: it is the bare black glass.
        assert_eq!(s.samples[BLACK_GLASS_STANDARD].name, format!("standard:n={BLACK_GLASS_INDEX},base=0"));
        // At any view, the black glass's own target is 100 GU.
        let g = AngleGrid::patent();
        for view in [42.0f64, 45.0, 47.5] {
            let t = view.to_radians();
            let px = PixelOptics::from_h(
                0.0,
                crate::forward::optics::system_matrix(&crate::forward::optics::Instrument::patent_profile(), &g, false)
                    .unwrap(),
                nalgebra::Vector3::new(t.sin(), 0.0, t.cos()),
                vec![0.0; 7],
                crate::forward::reading_noise::ReadingNoise::relative(0.0, 7),
                &g,
            );
            let bg = PriorModels::from_brdfs(
                "bg",
                vec![("bg".into(), Arc::new(SmoothDielectric::black_glass()) as Arc<dyn Brdf>)],
            );
            let pairs = Pairs::build_with_gloss(std::slice::from_ref(&px), &bg);
            let t = targets(&pairs).unwrap();
            assert!((t[(0, 0)] - 100.0).abs() < 1e-9, "view {view}: {}", t[(0, 0)]);
        }
    }

    fn held(cluster: usize, family: Family, z: f64) -> HeldOutZ {
        HeldOutZ { cluster, family, z: [z; 3] }
    }

    #[test]
    fn each_cluster_with_enough_points_sets_its_own_factors() {
        // Cluster 0: |z| 0.1..4.0 (40 points); cluster 1: |z| 1..40 (40);
        // cluster 2: 39 points, too few, so the pooled factors.
        let mut z: Vec<HeldOutZ> = Vec::new();
        for i in 1..=40 {
            z.push(held(0, Family::AsTheyAre, f64::from(i) / 10.0));
            z.push(held(1, Family::AsTheyAre, f64::from(i)));
        }
        z.extend((1..=39).map(|i| held(2, Family::AsTheyAre, f64::from(i) / 10.0)));
        assert_eq!(cluster_uncertainty_factors(&z, 0), [3.8 / COVERAGE_K; 3]);
        assert_eq!(cluster_uncertainty_factors(&z, 1), [38.0 / COVERAGE_K; 3]);
        let pooled = uncertainty_factors(&z.iter().map(|p| p.z).collect::<Vec<_>>());
        assert_eq!(cluster_uncertainty_factors(&z, 2), pooled);
        assert!(pooled[0] > 3.8 / COVERAGE_K && pooled[0] < 38.0 / COVERAGE_K);
    }

    #[test]
    fn easy_variants_and_standards_do_not_buy_the_materials_coverage() {
        // The materials as they are: |z| 0.1..4.0 (40), their 95th 3.8.
        // Twice as many variants and as many standards, all |z| 0.1: pooled,
        // the 95th percentile of the 160 would be 3.2 and cover only 34 of
        // the 40 materials; each family on its own covers 38 of them.
        let mut z: Vec<HeldOutZ> = (1..=40).map(|i| held(0, Family::AsTheyAre, f64::from(i) / 10.0)).collect();
        z.extend((0..80).map(|_| held(0, Family::Variant, 0.1)));
        z.extend((0..40).map(|_| held(0, Family::Standard, 0.1)));
        let pooled = uncertainty_factors(&z.iter().map(|p| p.z).collect::<Vec<_>>());
        assert_eq!(pooled, [3.2 / COVERAGE_K; 3]);
        assert_eq!(cluster_uncertainty_factors(&z, 0), [3.8 / COVERAGE_K; 3]);
        // A family too small to set its own still counts in the pool: 39
        // standards of |z| 9 next to 40 easy materials set the pool's 9.
        let mut z: Vec<HeldOutZ> = (0..40).map(|_| held(0, Family::AsTheyAre, 0.1)).collect();
        z.extend((0..39).map(|_| held(0, Family::Standard, 9.0)));
        assert_eq!(cluster_uncertainty_factors(&z, 0), [9.0 / COVERAGE_K; 3]);
    }

    #[test]
    fn uncertainty_factors_reach_the_coverage_and_scale_the_block() {
        // |z| = 0.1, 0.2, ... 10.0 (100 points): the 95th is 9.5, over k = 2.
        let z: Vec<[f64; 3]> = (1..=100).map(|i| [f64::from(i) / 10.0, -f64::from(i) / 20.0, f64::NAN]).collect();
        let f = uncertainty_factors(&z);
        assert_eq!(f, [9.5 / COVERAGE_K, 4.75 / COVERAGE_K, 1.0]);
        let m = 2;
        let mut block = vec![1.0f32; brdf_meter::gloss::block_len(m)];
        scale_block(&mut block, m, [2.0, 3.0, 0.5]);
        let c = &block[LINEAR * m..];
        assert_eq!(c[cov_index(0, 0)], 4.0);
        assert_eq!(c[cov_index(0, 1)], 6.0);
        assert_eq!(c[cov_index(2, 3)], 0.25);
        assert_eq!(c[cov_index(1, 3)], 1.5);
        assert_eq!(&c[brdf_meter::gloss::COV_LEN..], &[2.0, 3.0]);
        assert_eq!(&block[..LINEAR * m], &[1.0; 8], "the rows are untouched");
    }
}
