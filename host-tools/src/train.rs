//! Training: H per zone + prior + noise model -> W per zone -> calibration blob.
//!
//! Each zone of pixels has its own system matrix (the optics as seen from the
//! zone's centre pixel) and so its own W; [`uniform_zones`] gives every zone
//! the same H until a scene model supplies one per position. The blob is
//! written by the one layout in `brdf_meter::blob` and parsed back before it
//! is returned. Before that, the f32 matrices are checked against f64 on the
//! prior's samples through the device kernel (`brdf_meter::kernel`), and the
//! largest relative difference is recorded as `f32_rel_error`.
use crate::estimators::{self, EstimatorInputs, EstimatorSummary, LinearEstimator, NoiseModel, kind_name};
use crate::grid::AngleGrid;
use crate::optics::{Instrument, system_matrix};
use crate::prior::Prior;
use anyhow::{Context, bail, ensure};
use brdf_meter::blob::{BlobContents, BlobView, Dims, EstimatorKind, MAX_PIXELS, TrainingSummary, write_blob};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// The optics of one zone.
#[derive(Clone, Debug)]
pub struct ZoneOptics {
    /// First pixel of the zone.
    pub first_pixel: usize,
    /// System matrix, m x n.
    pub h: DMatrix<f64>,
    /// Incidence angle of each LED's centre ray at the zone's centre, degrees (m).
    pub centres_deg: Vec<f64>,
}

/// Everything training needs.
#[derive(Clone, Debug)]
pub struct TrainSpec<'a> {
    /// Bin centres, degrees (n).
    pub bins_deg: &'a [f64],
    /// One entry per zone, first pixels strictly ascending from 0.
    pub zones: Vec<ZoneOptics>,
    /// Pixels P of the line sensor.
    pub pixels: usize,
    /// The prior (R_pp and its samples).
    pub prior: &'a Prior,
    /// Relative measurement noise (the patent's 0.02).
    pub noise_rel: f64,
    /// Which estimator.
    pub estimator: EstimatorKind,
    /// Whether H was modelled far-field (recorded in the blob).
    pub far_field: bool,
    /// LED fired for reading i (a permutation of 0..m); `None` = 0..m.
    pub led_order: Option<Vec<u8>>,
    /// White reference, P x m; `None` = 1.0 everywhere (a simulated sensor
    /// that is already white-normalised).
    pub white: Option<Vec<f32>>,
}

/// One zone's trained estimator.
#[derive(Clone, Debug)]
pub struct TrainedZone {
    /// First pixel.
    pub first_pixel: usize,
    /// H, m x n.
    pub h: DMatrix<f64>,
    /// The estimator (W n x m in f64, uncertainty, summary).
    pub estimator: LinearEstimator,
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
    /// The summary written into the blob.
    pub summary: TrainingSummary,
    /// Largest relative difference between f32 and f64 evaluation on the prior.
    pub f32_rel_error: f64,
    /// The calibration blob, already validated by `BlobView::parse`.
    pub blob: Vec<u8>,
}

/// Zones of equal width, each with the same optics (the instrument's point).
pub fn uniform_zones(inst: &Instrument, grid: &AngleGrid, zones: usize, pixels: usize, far_field: bool) -> anyhow::Result<Vec<ZoneOptics>> {
    ensure!(pixels >= 1 && pixels <= MAX_PIXELS, "pixels = {pixels}: must be 1..={MAX_PIXELS}");
    ensure!(zones >= 1 && zones <= pixels, "zones = {zones}: must be 1..=pixels ({pixels})");
    let h = system_matrix(inst, grid, far_field).context("computing the system matrix H")?;
    let centres = inst.centre_angles_deg();
    Ok((0..zones).map(|z| ZoneOptics { first_pixel: z * pixels / zones, h: h.clone(), centres_deg: centres.clone() }).collect())
}

/// Trains every zone and writes the blob.
pub fn train(spec: &TrainSpec<'_>) -> anyhow::Result<Trained> {
    let n = spec.bins_deg.len();
    ensure!(!spec.zones.is_empty(), "no zones to train");
    let m = spec.zones[0].h.nrows();
    ensure!(spec.noise_rel.is_finite() && spec.noise_rel >= 0.0, "noise {} must be finite and >= 0", spec.noise_rel);
    ensure!(spec.prior.n() == n, "the prior has {} bins, the grid {n}", spec.prior.n());
    let dims = Dims { n, m, zones: spec.zones.len(), pixels: spec.pixels };
    for (z, zo) in spec.zones.iter().enumerate() {
        ensure!(zo.h.shape() == (m, n), "zone {z}: H is {}x{}, expected {m}x{n}", zo.h.nrows(), zo.h.ncols());
        ensure!(zo.centres_deg.len() == m, "zone {z}: {} centre angles for {m} LEDs", zo.centres_deg.len());
    }
    let led_order = spec.led_order.clone().unwrap_or_else(|| (0..m as u8).collect());
    let white = spec.white.clone().unwrap_or_else(|| vec![1.0; spec.pixels * m]);

    let mut zones = Vec::with_capacity(spec.zones.len());
    for (z, zo) in spec.zones.iter().enumerate() {
        let inputs = EstimatorInputs {
            h: &zo.h,
            r_pp: &spec.prior.r_pp,
            prior_samples: spec.prior.samples.ncols(),
            noise: NoiseModel::Relative(spec.noise_rel),
            bins_deg: spec.bins_deg,
            centres_deg: &zo.centres_deg,
        };
        let est = estimators::build(spec.estimator, &inputs)
            .with_context(|| format!("zone {z}: training the {} estimator", kind_name(spec.estimator)))?;
        zones.push(TrainedZone { first_pixel: zo.first_pixel, h: zo.h.clone(), estimator: est });
    }

    let f32_rel_error = zones.iter().map(|z| f32_check(&z.estimator, &z.h, &spec.prior.samples)).fold(0.0, f64::max);
    let worst = |f: fn(&EstimatorSummary) -> f64| zones.iter().map(|z| f(&z.estimator.summary)).fold(0.0, f64::max);
    let summary = TrainingSummary {
        prior_samples: spec.prior.samples.ncols() as u32,
        // Finite in the blob: an infinite (singular) condition is stored as f32::MAX.
        condition: worst(|s| s.condition_system).min(f32::MAX as f64) as f32,
        regularisation: worst(|s| s.regularisation) as f32,
        predicted_rmse: (zones.iter().map(|z| z.estimator.summary.predicted_rmse).sum::<f64>() / zones.len() as f64) as f32,
        f32_rel_error: f32_rel_error as f32,
    };

    let grid_f32: Vec<f32> = spec.bins_deg.iter().map(|x| *x as f32).collect();
    let zone_start: Vec<u16> = zones.iter().map(|z| z.first_pixel as u16).collect();
    let uncertainty: Vec<f32> = zones.iter().flat_map(|z| z.estimator.uncertainty.iter().map(|x| *x as f32)).collect();
    let matrices: Vec<f32> = zones.iter().flat_map(|z| z.estimator.w_f32_row_major()).collect();
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
    let mut blob = vec![0u8; dims.blob_len()];
    let len = write_blob(&contents, &mut blob).map_err(|e| anyhow::anyhow!("the calibration blob would be invalid: {e}"))?;
    blob.truncate(len);
    BlobView::parse(&blob).map_err(|e| anyhow::anyhow!("the written blob does not parse: {e}"))?;
    if f32_rel_error > 1e-3 {
        bail!(
            "the f32 matrices differ from f64 by {f32_rel_error:.2e} (relative) on the prior's samples: \
             the problem is too ill-conditioned for f32; use more noise or a better-conditioned instrument"
        );
    }
    Ok(Trained { dims, bins_deg: spec.bins_deg.to_vec(), zones, summary, f32_rel_error, blob })
}

/// Largest |f32 kernel - f64| of `W H rho` over the samples, relative to the
/// largest f64 estimate. The f32 path is the device's: f32 W and readings
/// through `brdf_meter::kernel::estimate_into`.
fn f32_check(est: &LinearEstimator, h: &DMatrix<f64>, samples: &DMatrix<f64>) -> f64 {
    let w32 = est.w_f32_row_major();
    let n = est.n();
    let mut out = vec![0.0f32; n];
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    for c in 0..samples.ncols() {
        let v: DVector<f64> = h * samples.column(c);
        let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
        brdf_meter::kernel::estimate_into(&w32, &v32, &mut out);
        let e64 = &est.w * &v;
        for j in 0..n {
            worst = worst.max((out[j] as f64 - e64[j]).abs());
            scale = scale.max(e64[j].abs());
        }
    }
    if scale > 0.0 { worst / scale } else { 0.0 }
}

/// What `train --json` writes: zone 0 at the top level, every zone below.
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

fn rows(a: &DMatrix<f64>) -> Vec<Vec<f64>> {
    a.row_iter().map(|r| r.iter().copied().collect()).collect()
}

impl Trained {
    /// The inspection JSON.
    pub fn to_json(&self) -> TrainJson {
        let zones: Vec<ZoneJson> = self
            .zones
            .iter()
            .map(|z| ZoneJson {
                first_pixel: z.first_pixel,
                h: rows(&z.h),
                w: rows(&z.estimator.w),
                uncertainty: z.estimator.uncertainty.iter().copied().collect(),
                summary: z.estimator.summary.clone(),
            })
            .collect();
        let z0 = &self.zones[0];
        let view = BlobView::parse(&self.blob).expect("validated when built");
        TrainJson {
            estimator: kind_name(z0.estimator.kind).into(),
            noise_rel: z0.estimator.summary.noise_rel,
            bins_deg: self.bins_deg.clone(),
            h: rows(&z0.h),
            w: rows(&z0.estimator.w),
            uncertainty: z0.estimator.uncertainty.iter().copied().collect(),
            summary: z0.estimator.summary.clone(),
            f32_rel_error: self.f32_rel_error,
            blob_bytes: self.blob.len(),
            blob_crc: view.crc(),
            zones,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prior::PriorSpec;
    use std::path::Path;

    fn patent_spec(prior: &Prior, grid: &AngleGrid, zones: usize, pixels: usize, kind: EstimatorKind) -> TrainSpec<'static> {
        let inst = Instrument::patent_profile();
        let zs = uniform_zones(&inst, grid, zones, pixels, false).unwrap();
        let bins: &'static [f64] = Box::leak(grid.bins_deg().to_vec().into_boxed_slice());
        let prior: &'static Prior = Box::leak(Box::new(prior.clone()));
        TrainSpec { bins_deg: bins, zones: zs, pixels, prior, noise_rel: 0.02, estimator: kind, far_field: false, led_order: None, white: None }
    }

    #[test]
    fn blob_carries_the_trained_matrices_and_round_trips() {
        let grid = AngleGrid::patent();
        let prior = PriorSpec::patent().build(&grid, 45.0, Path::new(".")).unwrap();
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
            assert_eq!(w, t.zones[z].estimator.w_f32_row_major());
            assert_eq!(v.uncertainty(z, 40), t.zones[z].estimator.uncertainty[40] as f32);
        }
        assert_eq!(v.grid_deg(80), 65.0);
        assert_eq!(v.white(127, 6), 1.0);
        let j = serde_json::to_value(t.to_json()).unwrap();
        assert_eq!(j["bins_deg"].as_array().unwrap().len(), 81);
        assert_eq!(j["H"].as_array().unwrap().len(), 7);
        assert_eq!(j["H"][0].as_array().unwrap().len(), 81);
        assert_eq!(j["W"].as_array().unwrap().len(), 81);
        assert_eq!(j["W"][0].as_array().unwrap().len(), 7);
        assert_eq!(j["uncertainty"].as_array().unwrap().len(), 81);
    }

    #[test]
    fn every_estimator_trains_on_the_patent_profile_except_the_square_inverse() {
        let grid = AngleGrid::patent();
        let prior = PriorSpec::patent().build(&grid, 45.0, Path::new(".")).unwrap();
        for kind in [EstimatorKind::Wiener, EstimatorKind::WienerNoiseFree, EstimatorKind::PseudoInverse, EstimatorKind::Interpolation] {
            let t = train(&patent_spec(&prior, &grid, 1, 16, kind)).unwrap();
            assert_eq!(BlobView::parse(&t.blob).unwrap().estimator(), kind);
        }
        let e = train(&patent_spec(&prior, &grid, 1, 16, EstimatorKind::Inverse)).unwrap_err();
        assert!(format!("{e:#}").contains("square"), "{e:#}");
    }

    #[test]
    fn zones_take_their_own_h() {
        let grid = AngleGrid::patent();
        let prior = PriorSpec::patent().build(&grid, 45.0, Path::new(".")).unwrap();
        let mut spec = patent_spec(&prior, &grid, 2, 8, EstimatorKind::Wiener);
        // Zone 1 sees the far-field optics: its W must differ.
        let inst = Instrument::patent_profile();
        spec.zones[1].h = system_matrix(&inst, &grid, true).unwrap();
        let t = train(&spec).unwrap();
        let d = (&t.zones[0].estimator.w - &t.zones[1].estimator.w).amax();
        assert!(d > 1e-3, "{d}");
        assert!(uniform_zones(&inst, &grid, 9, 8, false).is_err());
    }
}
