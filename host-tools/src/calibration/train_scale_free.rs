//! Training of the scale-free estimator kinds into a calibration blob
//! (format version 2): per zone the `[W' | b]` matrix (K of them for the
//! piecewise kind, with centroids), the uncertainty per unit scale, and the
//! out-of-prior mean, whitening and threshold. The f32 gate runs the
//! device's own function (`brdf_meter::kernel::scale_free::estimate_scale_free`) on
//! the prior's samples against f64, as [`crate::calibration::train::f32_gate`] does for W.
use crate::calibration::estimators::scale_free::{
    ScaleFreeOptions, ScaleFreeZone, WeightedSamples, maps_for_zone, train_zone,
};
use crate::calibration::gloss_rows::{self, GlossSection};
use crate::calibration::train::{F32_TOLERANCE, TrainSpec};
use anyhow::{Context, ensure};
use brdf_meter::blob::{
    BlobContents, BlobExtras, BlobView, Dims, EstimatorKind, OutOfPriorData, TrainingSummary, write_blob_with,
};
use nalgebra::DVector;
use rand::SeedableRng;
use serde::Serialize;

/// A trained scale-free calibration.
#[derive(Clone, Debug)]
pub struct TrainedScaleFree {
    /// Blob dimensions.
    pub dims: Dims,
    /// Per zone.
    pub zones: Vec<ScaleFreeZone>,
    /// Largest `max |f32 - f64| / max |f64|` over the prior's samples.
    pub f32_rel_error: f64,
    /// The blob's out-of-prior threshold.
    pub threshold: f32,
    /// The blob, validated by `BlobView::parse`.
    pub blob: Vec<u8>,
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
}

/// One zone in [`ScaleFreeJson`].
#[derive(Debug, Serialize)]
pub struct ScaleFreeZoneJson {
    /// Matrices `[W' | b]`, one per cluster.
    pub matrices: Vec<Vec<Vec<f64>>>,
    /// Uncertainty per unit scale, one per cluster.
    pub sigma_unit: Vec<Vec<f64>>,
    /// Centroids (K x m), empty unless piecewise.
    pub centroids: Vec<f32>,
    /// Mean of `u'`.
    pub out_of_prior_mean: Vec<f32>,
    /// Packed whitening G.
    pub out_of_prior_g: Vec<f32>,
    /// Ridge chosen by cross-validation.
    pub ridge: f64,
    /// Its cross-validated peak-normalised error.
    pub cv_error: f64,
}

/// Trains every zone of `spec` (its estimator must be a scale-free kind)
/// from the weighted samples `prior` and writes the blob.
pub fn train_scale_free(
    spec: &TrainSpec<'_>,
    prior: &WeightedSamples,
    false_alarm: f64,
) -> anyhow::Result<TrainedScaleFree> {
    let piecewise = match spec.estimator {
        EstimatorKind::ScaleFree => false,
        EstimatorKind::ScaleFreePiecewise => true,
        k => anyhow::bail!("{k:?} is not a scale-free estimator"),
    };
    let n = spec.bins_deg.len();
    ensure!(!spec.zones.is_empty(), "no zones to train");
    let m = spec.zones[0].h.nrows();
    ensure!(prior.samples.nrows() == n, "the prior has {} bins, the grid {n}", prior.samples.nrows());
    ensure!(
        spec.noise_rel > 0.0 && spec.noise_rel.is_finite(),
        "scale-free training needs a noise level > 0 (got {})",
        spec.noise_rel
    );
    let dims = Dims { n, m, zones: spec.zones.len(), pixels: spec.pixels };
    let opts = ScaleFreeOptions { noise_rel: spec.noise_rel, piecewise, false_alarm, ..Default::default() };
    let mut zones = Vec::with_capacity(spec.zones.len());
    for (z, zo) in spec.zones.iter().enumerate() {
        ensure!(zo.h.shape() == (m, n), "zone {z}: H is {}x{}, expected {m}x{n}", zo.h.nrows(), zo.h.ncols());
        zones.push(
            train_zone(&zo.h, prior, &opts).with_context(|| format!("zone {z}: training the scale-free estimator"))?,
        );
    }
    // The f32 gate on the device's function.
    let mut f32_rel_error = 0.0f64;
    for (z, (zo, tz)) in spec.zones.iter().zip(&zones).enumerate() {
        for (c, map) in tz.maps.iter().enumerate() {
            let w32 = map.w_f32();
            let (mut worst, mut scale) = (0.0f64, 0.0f64);
            let mut out = vec![0.0f32; n];
            for k in 0..prior.samples.ncols() {
                let v = &zo.h * prior.samples.column(k);
                let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
                brdf_meter::kernel::scale_free::estimate_scale_free(&w32, &v32, &mut out);
                let e64 = map.estimate(&DVector::from_iterator(m, v32.iter().map(|x| *x as f64)));
                for j in 0..n {
                    worst = worst.max((out[j] as f64 - e64[j]).abs());
                    scale = scale.max(e64[j].abs());
                }
            }
            let rel = if scale > 0.0 { worst / scale } else { worst };
            ensure!(
                rel.is_finite() && rel <= F32_TOLERANCE,
                "zone {z}, cluster {c}: f32 evaluation differs from f64 by {rel:.2e} of the estimate's scale (tolerance {F32_TOLERANCE:.0e}); retrain with more noise (--noise)"
            );
            f32_rel_error = f32_rel_error.max(rel);
        }
    }
    let k = zones[0].maps.len();
    let threshold = zones.iter().map(|z| z.out_of_prior.threshold).fold(0.0f32, f32::max);
    let led_order: Vec<u8> = spec.led_order.clone().unwrap_or_else(|| (0..m as u8).collect());
    let white = spec.white.clone().unwrap_or_else(|| vec![1.0; spec.pixels * m]);
    let grid: Vec<f32> = spec.bins_deg.iter().map(|x| *x as f32).collect();
    let zone_start: Vec<u16> = spec.zones.iter().map(|z| z.first_pixel as u16).collect();
    let mut uncertainty = Vec::with_capacity(dims.zones * k * n);
    let mut matrices = Vec::with_capacity(dims.zones * k * n * m);
    let mut centroids = Vec::new();
    let mut oop = Vec::new();
    for tz in &zones {
        ensure!(tz.maps.len() == k, "every zone must have the same number of clusters");
        for map in &tz.maps {
            uncertainty.extend(map.sigma_unit.iter().map(|x| *x as f32));
            matrices.extend(map.w_f32());
        }
        centroids.extend_from_slice(&tz.centroids);
        oop.extend_from_slice(&tz.out_of_prior.mean);
        oop.extend_from_slice(&tz.out_of_prior.g);
    }
    let predicted =
        zones.iter().flat_map(|z| &z.maps).map(|mp| (mp.sigma_unit.norm_squared() / n as f64).sqrt()).sum::<f64>()
            / (zones.len() * k) as f64;
    let summary = TrainingSummary {
        prior_samples: prior.samples.ncols() as u32,
        condition: 0.0,
        regularisation: zones.iter().map(|z| z.ridge).fold(0.0, f64::max) as f32,
        predicted_rmse: predicted as f32,
        f32_rel_error: f32_rel_error as f32,
    };
    let contents = BlobContents {
        dims,
        noise_rel: spec.noise_rel as f32,
        estimator: spec.estimator,
        far_field: spec.far_field,
        summary,
        grid_deg: &grid,
        led_order: &led_order,
        zone_start: &zone_start,
        white: &white,
        uncertainty: &uncertainty,
        matrices: &matrices,
    };
    let gloss = gloss_section(spec, &zones, prior)?;
    let extras = BlobExtras {
        clusters: k,
        centroids: &centroids,
        out_of_prior: Some(OutOfPriorData { threshold, data: &oop }),
        gloss: gloss.as_ref().map(GlossSection::data),
    };
    let mut blob = vec![0u8; dims.blob_len_with(&extras)];
    let len = write_blob_with(&contents, &extras, &mut blob)
        .map_err(|e| anyhow::anyhow!("the calibration blob would be invalid: {e}"))?;
    blob.truncate(len);
    BlobView::parse(&blob).map_err(|e| anyhow::anyhow!("the written blob does not parse: {e}"))?;
    Ok(TrainedScaleFree { dims, zones, f32_rel_error, threshold, blob })
}

/// The gloss section of a scale-free calibration: per zone and cluster the
/// rows `A [W_g' | b_g]` (the same kernel input as the estimate: the
/// readings with the last replaced by their scale; the maps refitted with
/// the zone's ridge and clusters on the prior augmented with the gloss
/// standards, `gloss_rows`' module doc) and their `A E A^T` per unit scale;
/// each zone's reading of the black glass by the device's rule (its cluster,
/// its scale). A zone that does not see the standard gets no reading (NaN
/// reference and blocks); `None` when the grid does not cover the specular
/// aperture or no zone sees the standard.
fn gloss_section(
    spec: &TrainSpec<'_>,
    zones: &[ScaleFreeZone],
    prior: &WeightedSamples,
) -> anyhow::Result<Option<GlossSection>> {
    let Ok(a) = gloss_rows::weights(spec.bins_deg, spec.view_deg) else { return Ok(None) };
    let standards = gloss_rows::gloss_standards(spec.bins_deg, spec.view_deg);
    let mut out = GlossSection { reference: Vec::new(), blocks: Vec::new() };
    for (z, (zo, tz)) in spec.zones.iter().zip(zones).enumerate() {
        // A zone that sees no light from a standard cannot learn from it (its
        // readings have no scale); such a zone cannot read the standard either.
        let no_reading = tz.maps.len() * brdf_meter::gloss::block_len(zo.h.nrows());
        let seen: Vec<_> = standards.column_iter().filter(|c| (&zo.h * c).sum() > 0.0).collect();
        if seen.is_empty() {
            out.push_no_reading(no_reading);
            continue;
        }
        let seen = nalgebra::DMatrix::from_columns(&seen);
        let Some((mut blocks, s)) = scale_free_rows(spec, zo, tz, prior, &seen, &a)
            .with_context(|| format!("zone {z}: the gloss rows' maps on the augmented prior"))?
        else {
            out.push_no_reading(no_reading);
            continue;
        };
        // The uncertainty's scale factors from held-out prior samples: each
        // fold's rows trained on the other folds.
        let k = prior.samples.ncols();
        let mut zs = Vec::new();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(z as u64 ^ 0x6105);
        for fold in 0..gloss_rows::HELD_OUT_FOLDS {
            let train: Vec<usize> = (0..k).filter(|i| i % gloss_rows::HELD_OUT_FOLDS != fold).collect();
            if train.is_empty() || train.len() == k {
                continue;
            }
            let Ok(Some((fb, fs))) = scale_free_rows(spec, zo, tz, &prior.subset(&train), &seen, &a) else { continue };
            let q = (crate::forward::gloss::ASSIGNED_GU / f64::from(fs)) as f32;
            for i in (0..k).filter(|i| i % gloss_rows::HELD_OUT_FOLDS == fold) {
                let rho = prior.samples.column(i).into_owned();
                let Some(truth) = crate::forward::gloss::true_readings(&rho, spec.bins_deg, spec.view_deg) else {
                    continue;
                };
                let v = &zo.h * &rho;
                for _ in 0..gloss_rows::HELD_OUT_DRAWS {
                    let noisy = gloss_rows::noisy(&v, spec.noise_rel, &mut rng);
                    let (c, x, sc) = kernel_input(tz, &noisy);
                    zs.push(gloss_rows::z_scores(&fb[c], &x, q, sc, &truth));
                }
            }
        }
        let f = gloss_rows::uncertainty_factors(&zs);
        for b in &mut blocks {
            gloss_rows::scale_block(b, zo.h.nrows(), f);
        }
        out.reference.push(s);
        out.blocks.extend(blocks.into_iter().flatten());
    }
    Ok(out.if_any_reading())
}

/// The device's cluster, kernel input (the readings with the last replaced
/// by their scale) and scale for readings `v`.
fn kernel_input(tz: &ScaleFreeZone, v: &DVector<f64>) -> (usize, Vec<f32>, f32) {
    let mut x: Vec<f32> = v.iter().map(|t| *t as f32).collect();
    let c = if tz.centroids.is_empty() { 0 } else { brdf_meter::kernel::select_cluster(&tz.centroids, &x) };
    let s = brdf_meter::kernel::scale_free::scale(&x);
    let m = x.len();
    x[m - 1] = s;
    (c, x, s)
}

/// One zone's gloss blocks (per cluster) from maps refitted on `prior`
/// augmented with `standards`, and the zone's reading of the black glass
/// through them (`None` when it does not see it).
fn scale_free_rows(
    spec: &TrainSpec<'_>,
    zo: &crate::forward::zone_optics::ZoneOptics,
    tz: &ScaleFreeZone,
    prior: &WeightedSamples,
    standards: &nalgebra::DMatrix<f64>,
    a: &nalgebra::DMatrix<f64>,
) -> anyhow::Result<Option<(Vec<Vec<f32>>, f32)>> {
    let augmented = gloss_rows::augmented_samples(prior, standards);
    let maps = maps_for_zone(&zo.h, &augmented, tz, spec.noise_rel)?;
    let blocks: Vec<Vec<f32>> = maps.iter().map(|mp| gloss_rows::block(a, &mp.w, &mp.err_unit)).collect();
    let v = gloss_rows::black_glass_readings(&zo.h, spec.bins_deg, spec.view_deg);
    let (c, x, _) = kernel_input(tz, &v);
    Ok(gloss_rows::standard_reading(&blocks[c], &x).map(|s| (blocks, s)))
}

impl TrainedScaleFree {
    /// The inspection JSON.
    pub fn to_json(&self, kind: EstimatorKind, bins_deg: &[f64]) -> ScaleFreeJson {
        ScaleFreeJson {
            estimator: crate::calibration::estimators::kind_name(kind).into(),
            bins_deg: bins_deg.to_vec(),
            zones: self
                .zones
                .iter()
                .map(|z| ScaleFreeZoneJson {
                    matrices: z
                        .maps
                        .iter()
                        .map(|mp| mp.w.row_iter().map(|r| r.iter().copied().collect()).collect())
                        .collect(),
                    sigma_unit: z.maps.iter().map(|mp| mp.sigma_unit.iter().copied().collect()).collect(),
                    centroids: z.centroids.clone(),
                    out_of_prior_mean: z.out_of_prior.mean.clone(),
                    out_of_prior_g: z.out_of_prior.g.clone(),
                    ridge: z.ridge,
                    cv_error: z.cv_error,
                })
                .collect(),
            out_of_prior_threshold: self.threshold,
            f32_rel_error: self.f32_rel_error,
        }
    }
}
