//! Valid calibration blobs with deterministic contents, for the tests of the
//! library, of host-tools and of tests/ (one builder for all of them). Built
//! with `std` (host users) and for this crate's own tests; never in firmware.
use crate::blob::{BlobContents, BlobExtras, Dims, EstimatorKind, TrainingSummary, write_blob_with};
use crate::signed::{PublicKeyBytes, public_key, sign};

/// The DEVELOPMENT KEY - NOT FOR PRODUCTION: its checked-in secret seed, which
/// every test that provisions a calibration signs with (the default firmware
/// build trusts its public half).
pub const DEV_SECRET: [u8; 32] = parse_seed(include_str!("../host-tools/keys/dev-NOT-FOR-PRODUCTION.key"));

/// The 64 hex digits of the first line of `text` that is not a `#` comment.
const fn parse_seed(text: &str) -> [u8; 32] {
    let b = text.as_bytes();
    let mut i = 0;
    // Skip comment lines.
    while i < b.len() && b[i] == b'#' {
        while b[i] != b'\n' {
            i += 1;
        }
        i += 1;
    }
    let mut seed = [0u8; 32];
    let mut j = 0;
    while j < 32 {
        seed[j] = hex_digit(b[i + 2 * j]) << 4 | hex_digit(b[i + 2 * j + 1]);
        j += 1;
    }
    seed
}

const fn hex_digit(c: u8) -> u8 {
    match c {
        b'0'..=b'9' => c - b'0',
        b'a'..=b'f' => c - b'a' + 10,
        _ => panic!("the development key file is not lower-case hex"),
    }
}

/// The development key's public half.
pub fn dev_public_key() -> PublicKeyBytes {
    public_key(&DEV_SECRET)
}

/// A trusted-key list holding only the development key, for stores opened
/// in tests (independent of the keys this build trusts).
pub fn dev_trusted() -> &'static [PublicKeyBytes] {
    static KEYS: std::sync::OnceLock<[PublicKeyBytes; 1]> = std::sync::OnceLock::new();
    KEYS.get_or_init(|| [dev_public_key()])
}

/// `blob` signed with the development key: what tests provision.
pub fn sign_for_tests(blob: &[u8]) -> Vec<u8> {
    let mut image = blob.to_vec();
    image.extend_from_slice(&sign(blob, &DEV_SECRET));
    image
}

/// The sections of a test blob, owned, so a test can change one before
/// encoding (the blob format's own tests corrupt them one at a time).
#[derive(Clone, Debug, PartialEq)]
pub struct TestBlobParts {
    /// Sizes.
    pub dims: Dims,
    /// Angle grid, n ascending values.
    pub grid: Vec<f32>,
    /// LED order, m.
    pub order: Vec<u8>,
    /// First pixel of each zone.
    pub zones: Vec<u16>,
    /// White references, P x m.
    pub white: Vec<f32>,
    /// Uncertainty, Z x n.
    pub unc: Vec<f32>,
    /// Matrices, Z x n x m.
    pub mats: Vec<f32>,
    /// The peak resolution in the header (`None`: none, a version 1 blob).
    pub peak_resolution_deg: Option<f32>,
}

impl TestBlobParts {
    /// `zones` equal zones of `pixels`, white references around 1000,
    /// matrices from `seed`.
    pub fn new(n: usize, m: usize, zones: usize, pixels: usize, seed: f32) -> Self {
        let white: Vec<f32> = (0..pixels * m).map(|k| 900.0 + ((k * 37) % 200) as f32).collect();
        let mats: Vec<f32> = (0..zones * n * m).map(|k| ((k as f32 + seed) * 0.731).sin() * 0.5).collect();
        let order: Vec<u8> = (0..m as u8).rev().collect();
        Self::with(Dims { n, m, zones, pixels }, order, white, mats)
    }

    /// The given LED order (m), white references (P x m) and matrices
    /// (Z x n x m); grid, zones and uncertainty as in [`Self::new`].
    pub fn with(dims: Dims, order: Vec<u8>, white: Vec<f32>, mats: Vec<f32>) -> Self {
        let Dims { n, zones, pixels, .. } = dims;
        Self {
            dims,
            grid: (0..n).map(|i| 25.0 + 40.0 * i as f32 / n.max(2) as f32).collect(),
            order,
            zones: (0..zones).map(|z| (z * pixels / zones) as u16).collect(),
            white,
            unc: (0..zones * n).map(|k| 0.01 + 0.001 * (k % 17) as f32).collect(),
            mats,
            peak_resolution_deg: None,
        }
    }

    /// The blob writer's view of these parts.
    pub fn contents(&self) -> BlobContents<'_> {
        BlobContents {
            dims: self.dims,
            noise_rel: 0.02,
            estimator: EstimatorKind::Wiener,
            far_field: false,
            summary: TrainingSummary {
                prior_samples: 16,
                condition: 10.0,
                regularisation: 0.0,
                predicted_rmse: 0.1,
                f32_rel_error: 1e-6,
            },
            grid_deg: &self.grid,
            led_order: &self.order,
            zone_start: &self.zones,
            white: &self.white,
            uncertainty: &self.unc,
            matrices: &self.mats,
        }
    }

    /// The encoded blob. Panics if the parts do not make a valid blob.
    pub fn encode(&self) -> Vec<u8> {
        let ex = BlobExtras { peak_resolution_deg: self.peak_resolution_deg, ..BlobExtras::NONE };
        let mut out = vec![0u8; self.dims.blob_len_with(&ex)];
        let len = write_blob_with(&self.contents(), &ex, &mut out).expect("test blob is valid");
        out.truncate(len);
        out
    }
}

/// A valid blob with deterministic contents for tests: `zones` equal zones of
/// `pixels`, white references around 1000, matrices from `seed`.
pub fn test_blob(n: usize, m: usize, zones: usize, pixels: usize, seed: f32) -> Vec<u8> {
    TestBlobParts::new(n, m, zones, pixels, seed).encode()
}

/// [`test_blob`] with a gloss section (format version 4, one reference per
/// pixel, linear rows with positive weights, so positive readings read a
/// positive gloss): zone `dark_zone`, when given, reads no gloss (its
/// references and blocks NaN).
pub fn test_blob_with_gloss(
    n: usize,
    m: usize,
    zones: usize,
    pixels: usize,
    seed: f32,
    dark_zone: Option<usize>,
) -> Vec<u8> {
    let parts = TestBlobParts::new(n, m, zones, pixels, seed);
    let bl = crate::gloss::block_len(m);
    let mut blocks: Vec<f32> = (0..zones * bl).map(|i| 0.01 * (i % 7) as f32 + 0.01).collect();
    let mut reference: Vec<f32> = (0..pixels).map(|p| 0.04 + 0.001 * p as f32).collect();
    if let Some(z) = dark_zone {
        blocks[z * bl..(z + 1) * bl].fill(f32::NAN);
        let (first, end) = (parts.zones[z] as usize, parts.zones.get(z + 1).map_or(pixels, |x| *x as usize));
        reference[first..end].fill(f32::NAN);
    }
    let g = crate::blob::GlossData {
        assigned_gu: 100.0,
        refractive_index: 1.567,
        reference: &reference,
        blocks: &blocks,
        centroids: &[],
        root_readings: crate::gloss::RootReadings::Shoulders,
    };
    let ex = BlobExtras { gloss: Some(g), ..BlobExtras::NONE };
    let mut out = vec![0u8; parts.dims.blob_len_with(&ex)];
    let len = write_blob_with(&parts.contents(), &ex, &mut out).expect("test blob is valid");
    out.truncate(len);
    out
}

/// A valid blob for tests with the given LED order (m), white references
/// (P x m) and matrices (Z x n x m); grid, zones and uncertainty as in
/// [`test_blob`]. Panics if the contents do not make a valid blob.
pub fn test_blob_with(dims: Dims, order: &[u8], white: &[f32], mats: &[f32]) -> Vec<u8> {
    TestBlobParts::with(dims, order.to_vec(), white.to_vec(), mats.to_vec()).encode()
}

/// [`test_blob`] signed with the development key, ready to provision.
pub fn signed_test_blob(n: usize, m: usize, zones: usize, pixels: usize, seed: f32) -> Vec<u8> {
    sign_for_tests(&test_blob(n, m, zones, pixels, seed))
}
