//! Training's part of the gloss readings (`brdf_meter::gloss`): per zone
//! and cluster, the rows `A W` of the linear readings and their error
//! covariance `A E A^T`, and the calibration on the gloss standard: each
//! zone's reading `S_z` of the simulated black glass through its own
//! estimator, by the device's own function, so a black glass reads the
//! standard's assigned value (100 GU) on the device.
//!
//! `A` is `crate::forward::gloss::reading_weights` (the definitions); `E`
//! the estimator's error covariance (per unit scale for the scale-free
//! kinds, whose `[W' | b]` takes the readings with the last replaced by
//! their scale: the same kernel input the device uses for the rows).
use crate::forward::brdf::SmoothDielectric;
use crate::forward::brdf::smooth_dielectric::BLACK_GLASS_INDEX;
use crate::forward::gloss::{ASSIGNED_GU, reading_weights, true_rho};
use anyhow::Context;
use brdf_meter::gloss::{LINEAR, block_len, cov_index};
use nalgebra::{DMatrix, DVector};

/// What `train` says when a calibration carries no gloss readings.
pub const NO_GLOSS_NOTE: &str = "no gloss readings in this calibration (the device streams NaN): the angle grid does not \
     cover the 8 deg specular aperture about the view, or a zone does not see the black-glass standard's mirror \
     reflection (no LED ray within a bin of the specular direction from that zone)";

/// The gloss section training writes.
#[derive(Clone, Debug, PartialEq)]
pub struct GlossSection {
    /// Per zone, the standard's specular linear reading (Z).
    pub reference: Vec<f32>,
    /// Per zone and cluster, the block (rows then packed covariance).
    pub blocks: Vec<f32>,
}

impl GlossSection {
    /// The blob's view of it.
    pub fn data(&self) -> brdf_meter::blob::GlossData<'_> {
        brdf_meter::blob::GlossData {
            assigned_gu: ASSIGNED_GU as f32,
            refractive_index: BLACK_GLASS_INDEX as f32,
            reference: &self.reference,
            blocks: &self.blocks,
        }
    }
}

/// One zone and cluster's block: rows `A W` (LINEAR x m), the packed
/// `A E A^T` and the square roots of its first two diagonal entries.
pub fn block(a: &DMatrix<f64>, w: &DMatrix<f64>, e: &DMatrix<f64>) -> Vec<f32> {
    let m = w.ncols();
    let rows = a * w;
    let cov = a * e * a.transpose();
    let mut out = Vec::with_capacity(block_len(m));
    out.extend(rows.transpose().iter().map(|x| *x as f32));
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

/// The black glass's corrected readings through zone optics `h`.
pub fn black_glass_readings(h: &DMatrix<f64>, bins: &[f64], view_deg: f64) -> DVector<f64> {
    let step = if bins.len() > 1 { bins[1] - bins[0] } else { 1.0 };
    h * true_rho(&SmoothDielectric::black_glass(), bins, view_deg, step)
}

/// The zone's reading `S_z` of the standard: the device's own linear
/// reading `L_0` (f32, `brdf_meter::gloss::readings` with q = 1) of the
/// black glass's readings `v` (already the kernel input `x`), through
/// `block`. `None` for a reading that is not positive: the zone does not
/// see the standard's mirror reflection (no LED ray near the specular
/// direction from where it looks), so no gloss scale can be set and the
/// calibration carries no gloss readings.
pub fn standard_reading(block: &[f32], x: &[f32]) -> Option<f32> {
    let (r, _) = brdf_meter::gloss::readings(block, x, 1.0, 1.0);
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
