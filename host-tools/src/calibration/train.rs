//! Training: H per zone + prior + noise model -> W per zone -> calibration blob.
//!
//! Each zone of pixels has its own system matrix (the optics as seen from the
//! zone's centre pixel, [`ZoneOptics`] from the forward model) and so its own
//! W; [`crate::forward::zone_optics::uniform_zones`] gives every zone the
//! same H, a scene one per position. The blob is
//! written by the one layout in `brdf_meter::blob` and parsed back before it
//! is returned. Before that, every zone's matrix goes through the f32 gate
//! ([`f32_gate`]): the device kernel (`brdf_meter::kernel`) is run on the
//! prior's samples and must stay within [`F32_TOLERANCE`] of f64, after a
//! power-of-two rescaling folded into the white reference if W leaves f32's
//! range; otherwise training refuses with the zone, the measured error, the
//! tolerance and what to do. The largest relative difference is recorded as
//! `f32_rel_error`.
use crate::calibration::estimators::{self, EstimatorInputs, EstimatorSummary, LinearEstimator, NoiseModel, kind_name};
use crate::calibration::gloss_rows::{self, GlossSection};
use crate::forward::prior::Prior;
use crate::forward::zone_optics::ZoneOptics;
use anyhow::{Context, bail, ensure};
use brdf_meter::blob::{BlobContents, BlobExtras, BlobView, Dims, EstimatorKind, TrainingSummary, write_blob_with};
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
    /// The view's angle, degrees: its mirror incidence is the specular
    /// direction of the gloss readings (`crate::forward::gloss`).
    pub view_deg: f64,
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
    /// Per zone, the power-of-two exponent of each reading folded into the
    /// blob's W and white reference by the f32 gate (all 0 unless W left
    /// f32's range): blob W = W 2^e_i, blob white = white 2^e_i.
    pub f32_exponents: Vec<Vec<i32>>,
    /// The calibration blob, already validated by `BlobView::parse`.
    pub blob: Vec<u8>,
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

    // The f32 gate, per zone: accept (possibly rescaled) or refuse with the reason.
    let mut plans = Vec::with_capacity(zones.len());
    for (z, tz) in zones.iter().enumerate() {
        match f32_gate(&tz.estimator.w, &tz.h, &spec.prior.samples) {
            Ok(p) => plans.push(p),
            Err(r) => {
                let advice = f32_advice(spec, z, r.rel_error);
                bail!(
                    "zone {z} (first pixel {}): the {} matrix cannot be evaluated in f32 on the device: {r}; {advice}",
                    tz.first_pixel,
                    kind_name(spec.estimator)
                );
            }
        }
    }
    let mut white = white;
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
    let f32_rel_error = plans.iter().map(|p| p.rel_error).fold(0.0, f64::max);
    let worst = |f: fn(&EstimatorSummary) -> f64| zones.iter().map(|z| f(&z.estimator.summary)).fold(0.0, f64::max);
    let summary = TrainingSummary {
        prior_samples: spec.prior.samples.ncols() as u32,
        // Finite in the blob: an infinite (singular) condition is stored as f32::MAX.
        condition: worst(|s| s.condition_system).min(f32::MAX as f64) as f32,
        regularisation: worst(|s| s.regularisation) as f32,
        predicted_rmse: (zones.iter().map(|z| z.estimator.summary.predicted_rmse).sum::<f64>() / zones.len() as f64)
            as f32,
        f32_rel_error: f32_rel_error as f32,
    };

    let grid_f32: Vec<f32> = spec.bins_deg.iter().map(|x| *x as f32).collect();
    let zone_start: Vec<u16> = zones.iter().map(|z| z.first_pixel as u16).collect();
    let uncertainty: Vec<f32> = zones.iter().flat_map(|z| z.estimator.uncertainty.iter().map(|x| *x as f32)).collect();
    let matrices: Vec<f32> = plans.iter().flat_map(|p| p.w32.iter().copied()).collect();
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
    let gloss = gloss_section(spec, &zones, &plans)?;
    let extras = BlobExtras { gloss: gloss.as_ref().map(GlossSection::data), ..BlobExtras::NONE };
    let mut blob = vec![0u8; dims.blob_len_with(&extras)];
    let len = write_blob_with(&contents, &extras, &mut blob)
        .map_err(|e| anyhow::anyhow!("the calibration blob would be invalid: {e}"))?;
    blob.truncate(len);
    BlobView::parse(&blob).map_err(|e| anyhow::anyhow!("the written blob does not parse: {e}"))?;
    let f32_exponents = plans.into_iter().map(|p| p.exponents).collect();
    Ok(Trained { dims, bins_deg: spec.bins_deg.to_vec(), zones, summary, f32_rel_error, f32_exponents, blob })
}

/// The gloss section of a linear calibration: per zone the rows `A W_g`
/// (`W_g` the same kind trained on the prior augmented with the gloss
/// standards, `gloss_rows`' module doc; with the f32 gate's power-of-two
/// column factors of the blob's W), `A E_g A^T` from that estimator's full
/// error covariance under the augmented prior, and the zone's reading
/// of the black glass through the blob's own matrices. A zone that does
/// not see the standard gets no reading (NaN reference and block, the
/// device streams NaN for its points); `None` when the grid does not cover
/// the specular aperture about the view or no zone sees the standard. The
/// stated uncertainties are scaled per reading by
/// `gloss_rows::uncertainty_factors` of the prior's samples held out in
/// folds (each fold read by rows trained without it).
fn gloss_section(
    spec: &TrainSpec<'_>,
    zones: &[TrainedZone],
    plans: &[F32Plan],
) -> anyhow::Result<Option<GlossSection>> {
    let Ok(a) = gloss_rows::weights(spec.bins_deg, spec.view_deg) else { return Ok(None) };
    let standards = gloss_rows::gloss_standards(spec.bins_deg, spec.view_deg);
    let samples = &spec.prior.samples;
    let mut out = GlossSection { reference: Vec::new(), blocks: Vec::new() };
    for (z, ((tz, zo), plan)) in zones.iter().zip(&spec.zones).zip(plans).enumerate() {
        let rows = |r_pp: &DMatrix<f64>| {
            linear_rows(spec, &tz.h, &zo.centres_deg, r_pp, &standards, plan, &a)
                .with_context(|| format!("zone {z}: the gloss rows' estimator on the augmented prior"))
        };
        let (mut block, s) = rows(&spec.prior.r_pp)?;
        let Some(s) = s else {
            out.push_no_reading(block.len());
            continue;
        };
        // The uncertainty's scale factors from held-out prior samples: each
        // fold's rows trained on the other folds (equal weights).
        let mut zs = Vec::new();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(z as u64 ^ 0x6105);
        for fold in 0..gloss_rows::HELD_OUT_FOLDS {
            let train: Vec<usize> = (0..samples.ncols()).filter(|k| k % gloss_rows::HELD_OUT_FOLDS != fold).collect();
            if train.is_empty() || train.len() == samples.ncols() {
                continue;
            }
            let cols: Vec<DVector<f64>> = train.iter().map(|k| samples.column(*k).into_owned()).collect();
            let st = DMatrix::from_columns(&cols);
            let r_fold = &st * st.transpose() / train.len() as f64;
            let (fb, fs) = rows(&r_fold)?;
            let Some(fs) = fs else { continue };
            let q = (crate::forward::gloss::ASSIGNED_GU / f64::from(fs)) as f32;
            for k in (0..samples.ncols()).filter(|k| k % gloss_rows::HELD_OUT_FOLDS == fold) {
                let rho = samples.column(k).into_owned();
                let Some(truth) = crate::forward::gloss::true_readings(&rho, spec.bins_deg, spec.view_deg) else {
                    continue;
                };
                let v = &tz.h * &rho;
                for _ in 0..gloss_rows::HELD_OUT_DRAWS {
                    let x = plan.readings(&gloss_rows::noisy(&v, spec.noise_rel, &mut rng));
                    zs.push(gloss_rows::z_scores(&fb, &x, q, 1.0, &truth));
                }
            }
        }
        gloss_rows::scale_block(&mut block, tz.h.nrows(), gloss_rows::uncertainty_factors(&zs));
        out.reference.push(s);
        out.blocks.extend(block);
    }
    Ok(out.if_any_reading())
}

/// One zone's gloss block from the rows' estimator trained on `r_pp`
/// augmented with the `standards`, and the zone's reading of the black
/// glass through it (`None` when it does not see it).
fn linear_rows(
    spec: &TrainSpec<'_>,
    h: &DMatrix<f64>,
    centres_deg: &[f64],
    r_pp: &DMatrix<f64>,
    standards: &DMatrix<f64>,
    plan: &F32Plan,
    a: &DMatrix<f64>,
) -> anyhow::Result<(Vec<f32>, Option<f32>)> {
    let r_pp = gloss_rows::augmented_r_pp(r_pp, standards);
    let noise = NoiseModel::Relative(spec.noise_rel);
    let inputs = EstimatorInputs {
        h,
        r_pp: &r_pp,
        prior_samples: spec.prior.samples.ncols() + standards.ncols(),
        noise: noise.clone(),
        bins_deg: spec.bins_deg,
        centres_deg,
    };
    let est = estimators::build(spec.estimator, &inputs)?;
    let r_nn = noise.covariance(h, &r_pp)?;
    let e = estimators::error_covariance(&est.w, h, &r_pp, &r_nn);
    let (n, m) = est.w.shape();
    let w_blob = DMatrix::from_fn(n, m, |j, i| est.w[(j, i)] * 2f64.powi(plan.exponents[i]));
    let block = gloss_rows::block(a, &w_blob, &e);
    let v = gloss_rows::black_glass_readings(h, spec.bins_deg, spec.view_deg);
    let s = gloss_rows::standard_reading(&block, &plan.readings(&v));
    Ok((block, s))
}

/// The device's f32 tolerance: the largest `|f32 kernel - f64|` over the
/// prior's samples, relative to the largest f64 estimate (the estimate's
/// scale), that a blob may carry.
///
/// Why 1e-3: it is 20 times below the patent's 2 % measurement noise, so f32
/// adds at most 0.25 % to the error budget in quadrature, and it is far above
/// what a well-posed W needs. The f32 kernel's error per bin is bounded by
/// `gamma_(m+2) (|W||v|)_j` (`gamma_k = k u / (1 - k u)`, u = 2^-24: rounding
/// of W, of v, and of m multiply-adds), so relative to the scale it is at most
/// `gamma_(m+2) kappa_c`, where `kappa_c = max_j (|W||v|)_j / max_j |W v|`
/// is the cancellation of the product. For m = 7 that passes for
/// `kappa_c` up to about 1.1e3 and is refused beyond about 1e4 (the measured
/// error is what decides; rounding errors rarely all align). Power-of-two
/// scaling cannot change f32's relative rounding, so the only cure for a large
/// `kappa_c` is a better-posed W: more noise in training (smaller gains on
/// the weak directions) or better optics.
pub const F32_TOLERANCE: f64 = 1e-3;

/// How a zone's W is put into f32 for the device.
#[derive(Clone, Debug, PartialEq)]
pub struct F32Plan {
    /// The blob's W, row-major n x m: `W[j][i] 2^exponents[i]` rounded to f32.
    pub w32: Vec<f32>,
    /// Power-of-two exponent per reading, folded into the white reference
    /// (`white 2^e_i`), so the device's corrected reading is `v_i 2^-e_i`
    /// exactly and `W' v' = W v`. All 0 unless W leaves f32's range.
    pub exponents: Vec<i32>,
    /// Measured `max |f32 - f64| / max |f64|` over the prior's samples.
    pub rel_error: f64,
    /// A-priori bound `gamma_(m+2) kappa_c` of the same quantity.
    pub bound: f64,
}

impl F32Plan {
    /// The device's corrected readings for f64 readings `v` (the white
    /// reference's power-of-two factors applied, then rounded to f32).
    pub fn readings(&self, v: &DVector<f64>) -> Vec<f32> {
        v.iter().zip(&self.exponents).map(|(x, e)| (x * 2f64.powi(-e)) as f32).collect()
    }
}

/// Why the f32 gate refused a matrix.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error(
    "f32 evaluation differs from f64 by {rel_error:.2e} of the estimate's scale on the prior's samples, \
     tolerance {tolerance:.0e} ({reason})"
)]
pub struct F32Refusal {
    /// Measured relative error (inf when the device result is not finite).
    pub rel_error: f64,
    /// The tolerance ([`F32_TOLERANCE`]).
    pub tolerance: f64,
    /// Cancellation `kappa_c` of the product.
    pub cancellation: f64,
    /// Why: cancellation or range.
    pub reason: String,
}

/// The f32 gate: evaluates `W v` for the prior's samples (`v = H rho`) through
/// the device kernel and accepts when within [`F32_TOLERANCE`] of f64. When
/// W's entries or the products leave f32's normal range, it retries with
/// W's columns rescaled by powers of two (exact; folded into the white
/// reference by [`train`]); otherwise it refuses with the measured error.
pub fn f32_gate(w: &DMatrix<f64>, h: &DMatrix<f64>, samples: &DMatrix<f64>) -> Result<F32Plan, F32Refusal> {
    let m = w.ncols();
    let vs: Vec<DVector<f64>> = (0..samples.ncols()).map(|c| h * samples.column(c)).collect();
    let gamma = (m + 2) as f64 * f64::from(f32::EPSILON) / 2.0;
    let gamma = gamma / (1.0 - gamma);
    // Cancellation of the product, from f64.
    let wabs = w.abs();
    let (mut mag, mut scale) = (0.0f64, 0.0f64);
    for v in &vs {
        mag = mag.max((&wabs * v.abs()).max());
        scale = scale.max((w * v).amax());
    }
    let cancellation = if scale > 0.0 { mag / scale } else { 1.0 };
    let bound = gamma * cancellation;
    let zero = vec![0i32; m];
    let first = f32_measure(w, &vs, &zero);
    if first.1 && first.0 <= F32_TOLERANCE {
        return Ok(F32Plan { w32: scaled_w32(w, &zero), exponents: zero, rel_error: first.0, bound });
    }
    // Out of range? Equilibrate each column's largest entry to [1, 2).
    let out_of_range = !first.1
        || w.iter().any(|x| *x != 0.0 && !((*x as f32).is_normal()))
        || vs.iter().flat_map(|v| v.iter()).any(|x| *x != 0.0 && !((*x as f32).is_normal()));
    if out_of_range {
        let exps: Vec<i32> = (0..m)
            .map(|i| {
                let cmax = w.column(i).amax();
                if cmax > 0.0 && cmax.is_finite() { -(cmax.log2().floor() as i32) } else { 0 }
            })
            .collect();
        let second = f32_measure(w, &vs, &exps);
        if second.1 && second.0 <= F32_TOLERANCE {
            return Ok(F32Plan { w32: scaled_w32(w, &exps), exponents: exps, rel_error: second.0, bound });
        }
        return Err(F32Refusal {
            rel_error: if second.1 { second.0 } else { f64::INFINITY },
            tolerance: F32_TOLERANCE,
            cancellation,
            reason: format!(
                "W or the readings leave f32's normal range and power-of-two rescaling of the readings \
                 did not bring the error within tolerance ({:.2e}); cancellation {cancellation:.2e}",
                second.0
            ),
        });
    }
    Err(F32Refusal {
        rel_error: first.0,
        tolerance: F32_TOLERANCE,
        cancellation,
        reason: format!(
            "the estimate cancels {cancellation:.2e}-fold (max |W||v| / max |W v|), so f32 rounding reaches \
             {bound:.1e}; scaling cannot change f32's relative precision"
        ),
    })
}

/// W with column i scaled by 2^exps[i], row-major f32.
fn scaled_w32(w: &DMatrix<f64>, exps: &[i32]) -> Vec<f32> {
    let (n, m) = w.shape();
    let mut out = Vec::with_capacity(n * m);
    for j in 0..n {
        for i in 0..m {
            out.push((w[(j, i)] * 2f64.powi(exps[i])) as f32);
        }
    }
    out
}

/// (max |f32 kernel - f64| / max |f64|, all finite) with the readings scaled
/// by 2^-exps[i] and W's columns by 2^exps[i].
fn f32_measure(w: &DMatrix<f64>, vs: &[DVector<f64>], exps: &[i32]) -> (f64, bool) {
    let n = w.nrows();
    let w32 = scaled_w32(w, exps);
    let mut out = vec![0.0f32; n];
    let (mut worst, mut scale, mut finite) = (0.0f64, 0.0f64, true);
    for v in vs {
        let v32: Vec<f32> = v.iter().zip(exps).map(|(x, e)| (x * 2f64.powi(-e)) as f32).collect();
        brdf_meter::kernel::mat_vec_f32_slice(&w32, &v32, &mut out);
        let e64 = w * v;
        for j in 0..n {
            finite &= out[j].is_finite();
            worst = worst.max((out[j] as f64 - e64[j]).abs());
            scale = scale.max(e64[j].abs());
        }
    }
    (if scale > 0.0 { worst / scale } else { worst }, finite)
}

/// What to do when zone `z` is refused: the smallest relative noise (in
/// half-decade steps up to 0.5) at which the Wiener matrix passes the gate.
fn f32_advice(spec: &TrainSpec<'_>, z: usize, err: f64) -> String {
    let zo = &spec.zones[z];
    let mut s = spec.noise_rel.max(1e-6);
    while s <= 0.5 {
        s *= 10f64.sqrt();
        let inputs = EstimatorInputs {
            h: &zo.h,
            r_pp: &spec.prior.r_pp,
            prior_samples: spec.prior.samples.ncols(),
            noise: NoiseModel::Relative(s),
            bins_deg: spec.bins_deg,
            centres_deg: &zo.centres_deg,
        };
        if let Ok(e) = estimators::build(EstimatorKind::Wiener, &inputs)
            && let Ok(p) = f32_gate(&e.w, &zo.h, &spec.prior.samples)
        {
            return format!(
                "retrain the wiener estimator with --noise {s:.2e} or more (f32 error {:.1e} there, {err:.1e} now), \
                 or use an instrument whose LEDs are better spread",
                p.rel_error
            );
        }
    }
    "no Wiener noise level up to 0.5 passes: the optics are too ill-conditioned for the device; spread the LEDs or \
     coarsen the angle grid"
        .into()
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
    /// The worst-conditioned zone and its summary: what limits the
    /// calibration (and what the blob's training summary records).
    pub fn worst_zone(&self) -> (usize, &EstimatorSummary) {
        self.zones
            .iter()
            .map(|z| &z.estimator.summary)
            .enumerate()
            .max_by(|a, b| a.1.condition_system.total_cmp(&b.1.condition_system))
            .expect("training yields at least one zone")
    }

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
    use crate::forward::grid::AngleGrid;
    use crate::forward::optics::{Instrument, system_matrix};
    use crate::forward::prior::PriorSpec;
    use crate::forward::zone_optics::uniform_zones;
    use std::path::Path;

    fn patent_spec(
        prior: &Prior,
        grid: &AngleGrid,
        zones: usize,
        pixels: usize,
        kind: EstimatorKind,
    ) -> TrainSpec<'static> {
        let inst = Instrument::patent_profile();
        let zs = uniform_zones(&inst, grid, zones, pixels, false).unwrap();
        let bins: &'static [f64] = Box::leak(grid.bins_deg().to_vec().into_boxed_slice());
        let prior: &'static Prior = Box::leak(Box::new(prior.clone()));
        TrainSpec {
            bins_deg: bins,
            zones: zs,
            pixels,
            view_deg: inst.view_deg,
            prior,
            noise_rel: 0.02,
            estimator: kind,
            far_field: false,
            led_order: None,
            white: None,
        }
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
