//! The f32 gate: a trained matrix goes into a blob only if the device's f32
//! kernel reproduces its f64 estimates on the prior's readings within
//! [`F32_TOLERANCE`], after a power-of-two rescaling (folded into the white
//! reference) if W leaves f32's range; otherwise training refuses with the
//! zone, the measured error, the tolerance and what to do.
use crate::calibration::estimators::scale_free::ScaleFreeMap;
use nalgebra::{DMatrix, DVector};

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

/// The f32 gate: evaluates `W v` for the prior's readings (`readings`, m x
/// K: the training pairs' noise-free readings) through the device kernel
/// and accepts when within [`F32_TOLERANCE`] of f64. When W's entries or the
/// products leave f32's normal range, it retries with W's columns rescaled
/// by powers of two (exact; folded into the white reference by
/// `crate::calibration::train::train`); otherwise it refuses with the
/// measured error.
pub fn f32_gate(w: &DMatrix<f64>, readings: &DMatrix<f64>) -> Result<F32Plan, F32Refusal> {
    let m = w.ncols();
    let vs: Vec<DVector<f64>> = readings.column_iter().map(|c| c.into_owned()).collect();
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

/// The scale-free form of the gate: the device's own function
/// (`brdf_meter::kernel::scale_free::estimate_scale_free`, or its root
/// form's) on the readings
/// against the map's f64 estimate; the relative error, or a refusal.
pub fn scale_free_gate(map: &ScaleFreeMap, readings: &DMatrix<f64>, root: bool) -> Result<f64, f64> {
    let (n, m) = map.w.shape();
    let w32 = map.w_f32();
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    let mut out = vec![0.0f32; n];
    for v in readings.column_iter() {
        let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
        if root {
            brdf_meter::kernel::scale_free::estimate_scale_free_root(&w32, &v32, &mut out);
        } else {
            brdf_meter::kernel::scale_free::estimate_scale_free(&w32, &v32, &mut out);
        }
        let e64 = map.estimate(&DVector::from_iterator(m, v32.iter().map(|x| *x as f64)), root);
        for j in 0..n {
            worst = worst.max((out[j] as f64 - e64[j]).abs());
            scale = scale.max(e64[j].abs());
        }
    }
    let rel = if scale > 0.0 { worst / scale } else { worst };
    if rel.is_finite() && rel <= F32_TOLERANCE { Ok(rel) } else { Err(rel) }
}
