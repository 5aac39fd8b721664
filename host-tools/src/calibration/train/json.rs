//! What `train --json` writes: the matrices, per zone, of a linear or a
//! scale-free calibration.

use super::*;

/// What `train --json` writes for a linear calibration: zone 0 at the top
/// level, every zone below.
#[derive(Debug, Serialize)]
pub struct TrainJson {
    /// Estimator kind.
    pub estimator: String,
    /// Relative noise.
    pub noise_rel: f64,
    /// Bin centres, degrees (n).
    pub bins_deg: Vec<f64>,
    /// Zone 0's matrices, at the top level.
    #[serde(flatten)]
    pub zone0: ZoneMatrices,
    /// What the blob is.
    #[serde(flatten)]
    pub blob: BlobJson,
    /// Every zone.
    pub zones: Vec<ZoneJson>,
}

/// What both forms of `train --json` say of the blob written.
#[derive(Debug, Serialize)]
pub struct BlobJson {
    /// Largest relative f32 vs f64 difference on the prior.
    pub f32_rel_error: f64,
    /// Blob size in bytes.
    pub blob_bytes: usize,
    /// Blob CRC-32.
    pub blob_crc: u32,
    /// The peak resolution the blob records, deg (`crate::calibration::peak_resolution`; null: none).
    pub peak_resolution_deg: Option<f32>,
    /// Each pixel's peak resolution, deg: its own, or the calibration's
    /// when the blob records none for it (null: none).
    pub pixel_peak_resolution_deg: Vec<Option<f32>>,
}

/// One zone in `train --json`.
#[derive(Debug, Serialize)]
pub struct ZoneJson {
    /// First pixel.
    pub first_pixel: usize,
    /// Its matrices.
    #[serde(flatten)]
    pub matrices: ZoneMatrices,
}

/// A linear zone's matrices and summary in `train --json`.
#[derive(Debug, Serialize)]
pub struct ZoneMatrices {
    /// H: m rows of n.
    #[serde(rename = "H")]
    pub h: Vec<Vec<f64>>,
    /// W: n rows of m.
    #[serde(rename = "W")]
    pub w: Vec<Vec<f64>>,
    /// Predicted standard uncertainty per bin (n).
    pub uncertainty: Vec<f64>,
    /// Training summary.
    pub summary: EstimatorSummary,
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
    /// What the blob is.
    #[serde(flatten)]
    pub blob: BlobJson,
    /// The factors on a resolved peak's uncertainties, height then width
    /// (`crate::calibration::peak_factors`; null: none).
    pub peak_uncertainty_factors: Option<[f32; 2]>,
}

/// One zone in [`ScaleFreeJson`].
#[derive(Debug, Serialize)]
pub struct ScaleFreeZoneJson {
    /// First pixel.
    pub first_pixel: usize,
    /// Matrices `[W' | b]`, one per cluster.
    pub matrices: Vec<Vec<Vec<f64>>>,
    /// Uncertainty per unit scale, one per cluster.
    pub sigma_unit: Vec<Vec<f64>>,
    /// Centroids (K x m), empty unless piecewise.
    pub centroids: Vec<f32>,
    /// The out-of-prior statistic's form: "linear" (the shares) or
    /// "log-ratio" (their centred logarithms).
    pub out_of_prior_form: &'static str,
    /// Mean of the statistic's coordinates (m-1).
    pub out_of_prior_mean: Vec<f32>,
    /// Packed whitening G, the zone's threshold folded in (threshold 1).
    pub out_of_prior_g: Vec<f32>,
    /// Ridge chosen by cross-validation.
    pub ridge: f64,
    /// Its cross-validated peak-normalised error.
    pub cv_error: f64,
}

fn rows(a: &DMatrix<f64>) -> Vec<Vec<f64>> {
    a.row_iter().map(|r| r.iter().copied().collect()).collect()
}

/// Zone `z`'s matrices, `e` its linear estimator.
fn zone_matrices(z: &TrainedZone, e: &LinearEstimator) -> ZoneMatrices {
    ZoneMatrices {
        h: rows(&z.h),
        w: rows(&e.w),
        uncertainty: e.uncertainty.iter().copied().collect(),
        summary: e.summary.clone(),
    }
}

impl Trained {
    /// The worst-conditioned linear zone and its summary: what limits the
    /// calibration (and what the blob's training summary records); `None`
    /// for a scale-free calibration.
    pub fn worst_zone(&self) -> Option<(usize, &EstimatorSummary)> {
        self.zones
            .iter()
            .enumerate()
            .filter_map(|(z, tz)| tz.linear().map(|e| (z, &e.summary)))
            .max_by(|a, b| a.1.condition_system.total_cmp(&b.1.condition_system))
    }

    /// What the JSON says of the blob (`view`, this calibration's).
    fn blob_json(&self, view: &BlobView<'_>) -> BlobJson {
        BlobJson {
            f32_rel_error: self.f32_rel_error,
            blob_bytes: self.blob.len(),
            blob_crc: view.crc(),
            peak_resolution_deg: view.peak_resolution_deg(),
            pixel_peak_resolution_deg: (0..view.dims().pixels).map(|p| view.peak_resolution_at(p)).collect(),
        }
    }

    /// The inspection JSON.
    pub fn to_json(&self) -> serde_json::Value {
        let view = BlobView::parse(&self.blob).expect("validated when built");
        let kind = kind_name(view.estimator()).to_string();
        let value = if let Some(z0) = self.zones[0].linear() {
            let zones: Vec<ZoneJson> = self
                .zones
                .iter()
                .filter_map(|z| {
                    z.linear().map(|e| ZoneJson { first_pixel: z.first_pixel, matrices: zone_matrices(z, e) })
                })
                .collect();
            serde_json::to_value(TrainJson {
                estimator: kind,
                noise_rel: z0.summary.noise_rel,
                bins_deg: self.bins_deg.clone(),
                zone0: zone_matrices(&self.zones[0], z0),
                blob: self.blob_json(&view),
                zones,
            })
        } else {
            serde_json::to_value(ScaleFreeJson {
                estimator: kind,
                bins_deg: self.bins_deg.clone(),
                zones: self
                    .zones
                    .iter()
                    .filter_map(|tz| {
                        tz.scale_free().map(|z| ScaleFreeZoneJson {
                            first_pixel: tz.first_pixel,
                            matrices: z.maps.iter().map(|mp| rows(&mp.w)).collect(),
                            sigma_unit: z.maps.iter().map(|mp| mp.sigma_unit.iter().copied().collect()).collect(),
                            centroids: z.centroids.clone(),
                            out_of_prior_form: z.out_of_prior.form.name(),
                            out_of_prior_mean: z.out_of_prior.mean.clone(),
                            out_of_prior_g: z.out_of_prior.g.clone(),
                            ridge: z.ridge,
                            cv_error: z.cv_error,
                        })
                    })
                    .collect(),
                out_of_prior_threshold: self.out_of_prior_threshold.unwrap_or(f32::INFINITY),
                blob: self.blob_json(&view),
                peak_uncertainty_factors: view.peak_factors().map(|f| [f.height, f.width]),
            })
        };
        value.expect("the inspection JSON serialises")
    }
}
