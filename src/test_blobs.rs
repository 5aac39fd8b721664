//! Valid calibration blobs with deterministic contents, for the tests of the
//! library, of host-tools and of tests/ (one builder for all of them). Built
//! with `std` (host users) and for this crate's own tests; never in firmware.
use crate::blob::{BlobContents, Dims, EstimatorKind, TrainingSummary, write_blob};

/// A valid blob with deterministic contents for tests: `zones` equal zones of
/// `pixels`, white references around 1000, matrices from `seed`.
pub fn test_blob(n: usize, m: usize, zones: usize, pixels: usize, seed: f32) -> Vec<u8> {
    let dims = Dims { n, m, zones, pixels };
    let white: Vec<f32> = (0..pixels * m).map(|k| 900.0 + ((k * 37) % 200) as f32).collect();
    let mats: Vec<f32> = (0..zones * n * m).map(|k| ((k as f32 + seed) * 0.731).sin() * 0.5).collect();
    let order: Vec<u8> = (0..m as u8).rev().collect();
    test_blob_with(dims, &order, &white, &mats)
}

/// A valid blob for tests with the given LED order (m), white references
/// (P x m) and matrices (Z x n x m); grid, zones and uncertainty as in
/// [`test_blob`]. Panics if the contents do not make a valid blob.
pub fn test_blob_with(dims: Dims, order: &[u8], white: &[f32], mats: &[f32]) -> Vec<u8> {
    let Dims { n, zones, pixels, .. } = dims;
    let grid: Vec<f32> = (0..n).map(|i| 25.0 + 40.0 * i as f32 / n.max(2) as f32).collect();
    let zone_start: Vec<u16> = (0..zones).map(|z| (z * pixels / zones) as u16).collect();
    let unc: Vec<f32> = (0..zones * n).map(|k| 0.01 + 0.001 * (k % 17) as f32).collect();
    let c = BlobContents {
        dims,
        noise_rel: 0.02,
        estimator: EstimatorKind::Wiener,
        far_field: false,
        summary: TrainingSummary { prior_samples: 16, condition: 10.0, regularisation: 0.0, predicted_rmse: 0.1, f32_rel_error: 1e-6 },
        grid_deg: &grid,
        led_order: order,
        zone_start: &zone_start,
        white,
        uncertainty: &unc,
        matrices: mats,
    };
    let mut out = vec![0u8; dims.blob_len()];
    let len = write_blob(&c, &mut out).expect("test blob is valid");
    out.truncate(len);
    out
}
