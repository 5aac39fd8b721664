//! What a blob holds, borrowed: what the writer takes and the view hands out.

use super::*;
use crate::acquire::linearity::Linearity;
use crate::kernel::scale_free::OutOfPriorForm;

/// The gloss section of a blob (`crate::gloss`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlossData<'a> {
    /// The gloss standard's assigned value, GU.
    pub assigned_gu: f32,
    /// The standard's refractive index (a record).
    pub refractive_index: f32,
    /// The standard's specular linear reading through the estimator: per
    /// pixel (P, format version 4) or per zone (Z, version 3).
    pub reference: &'a [f32],
    /// Per zone and cluster, `crate::gloss::block_len(m)` values (Z x K
    /// blocks, or Z x K_g with `centroids`).
    pub blocks: &'a [f32],
    /// The gloss rows' own centroids, Z x K_g x m (flag bit 9), or empty:
    /// a point's block is then its BRDF cluster's.
    pub centroids: &'a [f32],
    /// How the root form's rows are read (flag bit 10 for
    /// [`crate::gloss::RootReadings::Deficit`], which needs the root
    /// form); the linear form's fourth row is the shoulders'.
    pub root_readings: crate::gloss::RootReadings,
}

impl GlossData<'_> {
    /// The block of a point in zone `z` whose BRDF cluster is `c` and
    /// readings `v` (m values), the rows having `k` clusters per zone (the
    /// blob's [`BlobView::gloss_clusters`]): its own gloss cluster's
    /// ([`crate::kernel::select_cluster`] on the zone's gloss centroids)
    /// when the rows have centroids, else cluster `c`'s.
    pub fn block(&self, z: usize, c: usize, k: usize, v: &[f32]) -> &[f32] {
        let m = v.len();
        let own = if self.centroids.is_empty() { &[][..] } else { &self.centroids[z * k * m..(z + 1) * k * m] };
        let c = crate::gloss::cluster_of(own, c, v);
        let bl = crate::gloss::block_len(m);
        &self.blocks[(z * k + c) * bl..(z * k + c + 1) * bl]
    }

    /// The reference pixel `p` (in zone `z`) is read with.
    pub fn reference_for(&self, p: usize, z: usize, pixels: usize) -> f32 {
        if self.reference.len() == pixels { self.reference[p] } else { self.reference[z] }
    }
}

/// The out-of-prior data of a blob.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutOfPriorData<'a> {
    /// Threshold on the statistic (`crate::kernel::scale_free`).
    pub threshold: f32,
    /// Which statistic the model is for.
    pub form: OutOfPriorForm,
    /// Per zone, [`out_of_prior_len`] values: mean, then packed G.
    pub data: &'a [f32],
    /// What a flagged point's per-bin unit uncertainty is multiplied by
    /// (finite, >= 1; 1 writes nothing: the blob is byte for byte as
    /// before).
    pub band_factor: f32,
}

/// What format version 2 adds to [`BlobContents`]; [`BlobExtras::NONE`]
/// writes version 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlobExtras<'a> {
    /// K, matrices per zone (1 unless the estimator is piecewise).
    pub clusters: usize,
    /// Centroids, Z x K x m (piecewise only; empty otherwise).
    pub centroids: &'a [f32],
    /// The out-of-prior section, if any.
    pub out_of_prior: Option<OutOfPriorData<'a>>,
    /// The gloss section, if any (format version 3).
    pub gloss: Option<GlossData<'a>>,
    /// The root form (header flag bit 3, format version 2 and up): the
    /// kernel's outputs `t` are roots, every value is `t^2 / s` with `s` the
    /// readings' scale (`crate::estimate`, `crate::gloss::readings_root`).
    pub root_form: bool,
    /// The peak resolution, deg (header flag bit 6, format version 2 and
    /// up; finite, > 0): the module docs.
    pub peak_resolution_deg: Option<f32>,
    /// Each pixel's peak resolution, deg (P values, or empty for none;
    /// header flag bit 7, with `peak_resolution_deg` only): the module docs.
    pub pixel_peak_resolution_deg: &'a [f32],
    /// The second per-bin uncertainty table, for broad estimates (as the
    /// first: Z x K x n; empty for none; header flag bit 8): the module docs.
    pub broad_uncertainty: &'a [f32],
    /// The sensor's linearity correction (header flag bit 11, format
    /// version 2 and up): the module docs.
    pub linearity: Option<Linearity>,
    /// The specular peak's uncertainty factors (header flag bit 12, with
    /// `peak_resolution_deg` only): the module docs.
    pub peak_factors: Option<PeakFactors>,
    /// The white reference's relative standard uncertainty (header flag
    /// bit 13; a standardised calibration's): the module docs.
    pub white_uncertainty: Option<f32>,
    /// The gloss scale's relative standard uncertainty (header flag bit 14,
    /// with `gloss` only; a calibration standardised on the black glass):
    /// the module docs.
    pub gloss_uncertainty: Option<f32>,
}

impl BlobExtras<'_> {
    /// Nothing added.
    pub const NONE: BlobExtras<'static> = BlobExtras {
        clusters: 1,
        centroids: &[],
        out_of_prior: None,
        gloss: None,
        root_form: false,
        peak_resolution_deg: None,
        pixel_peak_resolution_deg: &[],
        broad_uncertainty: &[],
        linearity: None,
        peak_factors: None,
        white_uncertainty: None,
        gloss_uncertainty: None,
    };
}

/// Everything a blob holds, borrowed; what [`write_blob`] writes.
#[derive(Clone, Copy, Debug)]
pub struct BlobContents<'a> {
    /// Dimensions.
    pub dims: Dims,
    /// Relative noise level the matrices were trained for.
    pub noise_rel: f32,
    /// Estimator that produced the matrices.
    pub estimator: EstimatorKind,
    /// Whether the optics were modelled far-field.
    pub far_field: bool,
    /// Training summary.
    pub summary: TrainingSummary,
    /// Angle grid in degrees, n values ascending.
    pub grid_deg: &'a [f32],
    /// LED fired for reading i, m values, a permutation of 0..m.
    pub led_order: &'a [u8],
    /// First pixel of each zone, Z values.
    pub zone_start: &'a [u16],
    /// White reference, P x m row-major (pixel-major).
    pub white: &'a [f32],
    /// Predicted standard uncertainty, Z x n.
    pub uncertainty: &'a [f32],
    /// W for each zone, Z x n x m.
    pub matrices: &'a [f32],
}
