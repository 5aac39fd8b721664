//! The calibration blob: what training produces and the device runs on.
//!
//! One versioned, little-endian binary layout, defined only here. The host
//! writes it with [`write_blob`]; the device (and the host, to check what it is
//! about to provision) reads it with [`BlobView::parse`], which rejects
//! anything malformed with a precise [`BlobError`].
//!
//! # Layout, format version 1
//! Every section starts on a 4-byte boundary, so a blob placed at a 4-byte
//! aligned address can be read in place as `f32` slices.
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `b"BRDW"` |
//! | 4 | 2 | format version (1) |
//! | 6 | 2 | header length (64) |
//! | 8 | 2 | n, angle bins |
//! | 10 | 2 | m, LEDs (readings per point) |
//! | 12 | 2 | Z, zones of pixels |
//! | 14 | 2 | P, pixels of the line sensor |
//! | 16 | 4 | relative noise level used in training (f32) |
//! | 20 | 2 | estimator kind ([`EstimatorKind`]) |
//! | 22 | 2 | flags (bit 0: far-field model); other bits must be 0 |
//! | 24 | 20 | training summary ([`TrainingSummary`]) |
//! | 44 | 4 | total length of the blob in bytes, CRC included |
//! | 48 | 16 | reserved, must be 0 |
//! | 64 | 4n | angle grid, degrees, strictly ascending (f32) |
//! | .. | m, padded to 4 | LED order: the LED fired for reading i |
//! | .. | 2Z, padded to 4 | first pixel of each zone (ascending, first is 0) |
//! | .. | 4Pm | white reference per pixel and LED: dark-corrected reading of a perfect diffuser |
//! | .. | 4Zn | predicted standard uncertainty per zone and bin |
//! | .. | 4Znm | W per zone, row-major n x m |
//! | end-4 | 4 | CRC-32 (ISO-HDLC) of everything before it |
//!
//! # Format version 2
//! Written only when a blob needs it (a scale-free estimator, K > 1 clusters
//! or the out-of-prior data); everything else is still written as version 1,
//! byte for byte as before, and version 1 blobs are read as before.
//! Version 2 is version 1 with:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 20 | 2 | estimator kind: also 6 (scale-free) and 7 (scale-free piecewise) |
//! | 22 | 2 | flags: bit 0 far-field, bit 1 out-of-prior section present, bit 3 the root form (below), bit 4 the out-of-prior section is for the log-ratio statistic (with bit 1 only), bit 5 the header holds the out-of-prior band factor (with bit 1 only; below), bit 6 the header holds the peak resolution (below), bit 7 the per-pixel peak resolutions follow (with bit 6 only; below), bit 8 the second per-bin uncertainty table follows (below), bit 9 the gloss rows have clusters of their own (format version 3 and up, the piecewise kind only; below), bit 11 the sensor's linearity correction follows (below), bit 12 the specular peak's uncertainty factors follow (with bit 6 only; below) |
//! | 48 | 2 | K, matrices per zone (1 unless piecewise; piecewise needs K >= 2) |
//! | 50 | 2 | K_g, the gloss rows' clusters per zone (2..=64, with bit 9 only; else 0) |
//! | 52 | 4 | out-of-prior threshold on the statistic (f32, > 0 with bit 1, else 0) |
//! | 56 | 4 | out-of-prior band factor (f32, finite, >= 1, with bit 5 only; else 0) |
//! | 60 | 4 | peak resolution, deg (f32, finite, > 0, with bit 6 only; else 0) |
//!
//! and sections sized by K: the uncertainty is Z x K x n (for the scale-free
//! kinds per unit scale: the device multiplies by the point's scale), the
//! matrices Z x K x n x m (zone-major, then cluster), then
//!
//! | size | field |
//! |---|---|
//! | 4ZKm (piecewise only) | centroids per zone, K x m, in `v / sum|v|` space |
//! | 4Z(m-1 + m(m-1)/2) (bit 1 only) | per zone: prior mean of the statistic's coordinates (m-1; `u' = v'/s`, or with bit 4 the centred log shares), then the packed lower-triangular whitening G (`crate::kernel::scale_free`) |
//!
//! | 4P (bit 7 only) | per pixel, the peak resolution, deg (below) |
//! | 4ZKn (bit 8 only) | the second per-bin uncertainty table, for broad estimates (below) |
//! | 68 (bit 11 only) | the sensor's linearity correction: 17 factors, one per octave of counts (below) |
//! | 8 (bit 12 only) | the specular peak's uncertainty factors: height, width (below) |
//!
//! before the CRC (these after the gloss section, when the blob has
//! one). A scale-free matrix is `[W' | b]`: its last column
//! multiplies the readings' scale (`crate::kernel::scale_free`).
//!
//! ## The peak resolution (flag bit 6)
//! The full width at half maximum of the calibration's estimate of the
//! black-glass standard, a mirror spike (the widest over the pixels): the
//! narrowest lobe the calibration puts out, as a spectrometer's bandwidth
//! is the width it reads a line with. The device does not use it; the host
//! reads a specular peak narrower than it allows as not resolved
//! (`host_tools::output::peak`). Training writes it whenever the blob has
//! a gloss section (the standard's readings are training's); a blob
//! without it reads as before.
//!
//! With flag bit 7 the blob also holds each pixel's own resolution, the
//! width its own estimate of the black glass comes out with: a pixel's
//! matrices are its zone's, but where the mirror direction falls between
//! the LEDs moves along the line, and with it the narrowest lobe the pixel
//! puts out (0.74 to 1.16 deg on the handheld). Each value is finite, > 0
//! and at most the header's (the widest), or NaN for a pixel whose estimate
//! of the standard has no width, which is then judged at the header's
//! value ([`BlobView::peak_resolution_at`]). The host judges a point's peak
//! at its pixel's resolution; the device does not use them.
//!
//! ## The specular peak's uncertainty factors (flag bit 12)
//! Two f32, finite and > 0: what the host multiplies the first-order
//! standard uncertainty of a resolved specular peak's height and of its
//! width by (`host_tools::output::peak`). The first-order values take the
//! peak bin's per-bin uncertainty for the height, but the per-bin table is
//! set over every held-out estimate, and a bin is an estimate's peak only
//! where its errors are largest; training sets the factors so that the
//! resolved peaks of samples held out of it are covered at k = 2 as each
//! bin is ([`PeakFactors`]). The device does not use them. A blob without
//! the flag states the first-order values (factors 1); firmware from before
//! it rejects such a blob as having a reserved flag set, and keeps its last
//! good calibration.
//!
//! ## The second uncertainty table (flag bit 8)
//! Laid out as the first (Z x K x n, per unit scale for the scale-free
//! kinds; finite, >= 0). With it the first table is for points whose
//! estimate is sharp and the second for those whose estimate is broad
//! (`crate::band`: the half-maximum width about the estimate's highest
//! value, at least `crate::band::BROAD_WIDTH_DEG`); without it the first
//! is every point's. The device does not use the second (it streams each
//! point's scale; the sigma16 encoding's step is the first table's), so
//! only the host's stated uncertainty depends on it
//! ([`BlobView::point_uncertainty`]).
//!
//! ## The sensor's linearity (flag bit 11)
//! The factor at each of [`crate::acquire::linearity::LINEARITY_KNOTS`]
//! knots, `2^0 .. 2^16` counts, of the correction the device applies to
//! every exposure's dark-corrected signal before it scales and
//! white-calibrates it ([`crate::acquire::Linearity`]: finite, within
//! [`crate::acquire::linearity::FACTOR_RANGE`], and the corrected response
//! increasing). The white reference is then the white tile's corrected
//! reading too. The host measures the factors at the factory from an
//! exposure sweep; the handheld's sensor (a response `c = FS (x / FS)^1.01`)
//! read dark samples 2-4 % low against the white without it. A blob
//! without the flag is read as before, bit for bit; firmware from before
//! it rejects such a blob as having a reserved flag set, and keeps its
//! last good calibration.
//!
//! ## The root form (flag bit 3, the scale-free kinds)
//! A scale-free calibration may be trained in the root form: its matrices
//! give roots `t = W x` (x the kernel's input as always) of `rho s` (s the
//! readings' scale), and the device squares them, `rho_j = t_j^2 / s`, so an
//! estimate is never negative; the gloss rows likewise give roots of the
//! linear readings (`crate::gloss::readings_root`). The device evaluates
//! `W (x / sqrt s)` and squares: `m` multiplies and one square root more
//! than the linear form, then one multiply per value. The uncertainty is of
//! the roots per unit scale, `sigma_j`; a point's standard uncertainty of
//! `rho_j` is `sigma_j (2 sqrt(rho_j s) + sqrt(2) s sigma_j)` (the point's
//! `sigma_scale` is `s`): larger where the estimate is large, as the errors
//! of a lobe are. Another kind with the flag is refused (reserved), as is
//! the flag by a firmware that does not know it.
//!
//! # Format version 3
//! Version 2 (every field and section as above, also for the version 1
//! kinds) with the gloss section: written only when a calibration carries
//! gloss readings; a blob without them is written as version 1 or 2,
//! byte for byte as before. Header flag bit 2 says the section is present
//! (it must be set in version 3 and is refused in 1 and 2). The section
//! follows the out-of-prior data, before the CRC:
//!
//! | size | field |
//! |---|---|
//! | 4 | the gloss standard's assigned value, GU (finite, > 0; 100 for the black-glass standard) |
//! | 4 | the standard's refractive index at the sodium D line (finite, > 1; 1.567), a record of what it was |
//! | 4Z | per zone, the standard's specular linear reading `S_z` through the zone's estimator (finite, > 0) |
//! | 4ZK(4m + 12) | per zone, then cluster: the rows `A W` of the 4 linear readings (4 x m, row-major), then their error covariance packed row by row (upper triangle, 10 values; per unit scale for the scale-free kinds; diagonal >= 0), then the square roots of its first two diagonal entries (>= 0) |
//!
//! What the values mean and how the device combines them: `crate::gloss`.
//! A device running a version 1 or 2 blob streams NaN readings ("no
//! reading").
//!
//! ## The gloss rows' own clusters (flag bit 9)
//! Without it a point's gloss block is its BRDF cluster's (`ZK` blocks).
//! With it the gloss rows have `K_g` clusters of their own (header offset
//! 50): the section holds `Z K_g` blocks, then per zone the gloss
//! centroids, `K_g x m` in the same space as the matrices' centroids
//! (`4 Z K_g m` bytes, finite), and a point's block is the one
//! [`crate::kernel::select_cluster`] picks from its zone's gloss centroids
//! ([`GlossData::block`]). The gloss readings are a flux through the
//! gloss window, and what decides how a flux is read from the facets (how
//! wide a lobe is where the mirror direction passes from one LED to the
//! next) is not what decides the BRDF's maps: a prior that holds materials
//! stretched across the plane reads the BRDF best with 2 clusters, which
//! read the gloss tiles at the handheld's facet edges 7 GU off, where 4
//! read them within 3.4 (`host-tools pixel-map`). A zone without a reading
//! has NaN blocks as before and finite centroids (zeros).
//!
//! ## The deficit row (flag bit 10)
//! With the root form (flag bit 3) and the gloss section only. The layout
//! is unchanged; the fourth row of every gloss block gives the root of the
//! peak's deficit over its shoulders, `max(L_2 - L_3, 0)`, instead of the
//! root of the shoulders' `L_3`, distinctness is `100 (t_3 / t_2)^2`, and
//! the gloss and haze uncertainties are the standard deviation of a
//! square, not its first order ([`crate::gloss::RootReadings`]). Reading a broad lobe's near-zero
//! deficit directly, instead of as the difference of two near-equal roots,
//! read the handheld's held-out MERL distinctness within 1.0 / 15.4 %
//! points (median / 90th) where the two roots read 1.9 / 19.4, and the
//! scene's own broad Ward surface (truth 0.5 %) 8-19 % where they read
//! 17-28 % in its worst zones (`host-tools pixel-map`, `estimate`). A blob without the
//! flag is read as before, bit for bit.
//!
//! A zone that cannot read the standard (no LED ray near the specular
//! direction from where it looks) has no reading: its `S_z` is NaN and so
//! is every value of its blocks (all of them or none; the NaN rules above
//! hold for the other zones). The device then streams NaN readings for
//! that zone's points by the same arithmetic as the others' (`q` and the
//! rows are NaN), so a zone's "no reading" costs nothing per point.
//!
//! # Format version 4
//! Version 3 with one gloss reference per **pixel** instead of per zone:
//! the section's `4Z` references become `4P`, pixel `p` reading the
//! standard's `S_p` through its zone's rows (everything else, the blocks
//! included, is version 3's). Training writes it: a zone's matrices serve
//! all its pixels (they are fitted on sample pairs from up to five of them,
//! each with its own rays, view and noise), but the black glass's mirror
//! reflection moves across the LED dies from pixel to pixel, so a zone's one
//! reference would read the standard 70 to 120 GU along the line; with each
//! pixel's own it reads 100 at every pixel by construction. A zone without
//! a reading has NaN references at every one of its pixels.
//!
//! This is the form the product's calibration takes ("every pixel its own
//! geometry"): per-zone matrices, trained for the zone's pixels, plus
//! per-pixel gloss references. Measured on the handheld
//! (`host-tools pixel-map`, held-out MERL materials): the BRDF error is flat
//! from 16 zones up (per-pixel matrices, 124 zones, are no better), while
//! the calibration slot holds 16 zones x 4 clusters of the piecewise kind
//! (205 KB with both uncertainty tables and each pixel's peak resolution)
//! but not 32 x 4 (over 364 KB); the device's cost per point does not
//! depend on the zones (a zone only selects a matrix). docs/handheld.md
//! ("A calibration that follows the pixel") has the table.
//!
//! # Compatibility rules
//! - A parser accepts exactly the format versions it knows; a new field that
//!   old firmware could misread bumps the version.
//! - Reserved bytes and flag bits are zero in version 1 so that a later version
//!   can give them meaning without ambiguity.

use crate::acquire::linearity::{LINEARITY_KNOTS, Linearity, LinearityError};
use crate::kernel::scale_free::OutOfPriorForm;
use core::fmt;

/// First four bytes of every blob.
pub const MAGIC: [u8; 4] = *b"BRDW";
/// The newest format version this library writes and reads (it also reads
/// [`FORMAT_VERSION_1`] to [`FORMAT_VERSION_3`], and writes the oldest a
/// blob fits).
pub const FORMAT_VERSION: u16 = 4;
/// The format version of the gloss section with one reference per zone.
pub const FORMAT_VERSION_3: u16 = 3;
/// The format version that added K clusters and the out-of-prior data, still
/// written for blobs that need no gloss section.
pub const FORMAT_VERSION_2: u16 = 2;
/// The first format version, still written for blobs that need nothing newer.
pub const FORMAT_VERSION_1: u16 = 1;
/// Length of the fixed header.
pub const HEADER_LEN: usize = 64;
/// Largest number of angle bins a blob may carry.
pub const MAX_BINS: usize = 1024;
/// Largest number of LEDs a blob may carry.
pub const MAX_LEDS: usize = 64;
/// Largest number of pixels a blob may carry.
pub const MAX_PIXELS: usize = 4096;

const FLAG_FAR_FIELD: u16 = 1;
const FLAG_OUT_OF_PRIOR: u16 = 2;
const FLAG_GLOSS: u16 = 4;
const FLAG_ROOT: u16 = 8;
/// The out-of-prior model is for the log-ratio statistic (with
/// `FLAG_OUT_OF_PRIOR` only). Firmware from before it rejects such a blob
/// as having a reserved flag set, and keeps its last good calibration.
const FLAG_LOG_RATIO: u16 = 16;
/// The header holds the out-of-prior band factor at offset 56 (with
/// `FLAG_OUT_OF_PRIOR` only). Firmware from before it rejects such a blob
/// as having a reserved flag set, and keeps its last good calibration.
const FLAG_BAND_FACTOR: u16 = 32;
/// The header holds the peak resolution at offset 60. Firmware from before
/// it rejects such a blob as having a reserved flag set, and keeps its last
/// good calibration.
const FLAG_PEAK_RESOLUTION: u16 = 64;
/// A per-pixel peak resolution section follows the gloss section (with
/// `FLAG_PEAK_RESOLUTION` only). Firmware from before it rejects such a
/// blob as having a reserved flag set, and keeps its last good calibration.
const FLAG_PIXEL_RESOLUTION: u16 = 128;
/// The second per-bin uncertainty table (broad estimates) follows the
/// per-pixel resolutions. Firmware from before it rejects such a blob as
/// having a reserved flag set, and keeps its last good calibration.
const FLAG_BROAD_BAND: u16 = 256;
/// The gloss rows have clusters of their own: K_g at header offset 50, the
/// gloss centroids after the blocks (with `FLAG_GLOSS` and the piecewise
/// kind only). Firmware from before it rejects such a blob as having a
/// reserved flag set, and keeps its last good calibration.
const FLAG_GLOSS_CLUSTERS: u16 = 512;
/// The root form's gloss rows are read in the second form: the fourth row
/// is the root of the peak's deficit over its shoulders, not of the
/// shoulders, and gloss and haze state the square's standard deviation
/// (with `FLAG_GLOSS` and `FLAG_ROOT` only; `crate::gloss::RootReadings`). Firmware from before it rejects
/// such a blob as having a reserved flag set, and keeps its last good
/// calibration.
const FLAG_DEFICIT_READINGS: u16 = 1024;
/// The sensor's linearity correction follows the second uncertainty table.
/// Firmware from before it rejects such a blob as having a reserved flag
/// set, and keeps its last good calibration.
const FLAG_LINEARITY: u16 = 2048;
/// The specular peak's uncertainty factors follow the linearity correction
/// (with `FLAG_PEAK_RESOLUTION` only). Firmware from before it rejects
/// such a blob as having a reserved flag set, and keeps its last good
/// calibration.
const FLAG_PEAK_FACTORS: u16 = 4096;

/// What the host multiplies a resolved specular peak's first-order
/// standard uncertainties by (the module docs, flag bit 12): finite, > 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeakFactors {
    /// On the peak's height.
    pub height: f32,
    /// On its full width at half maximum.
    pub width: f32,
}
/// A peak resolution must be a finite width above zero.
fn check_peak_resolution(r: f32) -> Result<(), BlobError> {
    if !r.is_finite() {
        Err(BlobError::NonFinite { section: Section::Header, index: 60 })
    } else if r <= 0.0 {
        Err(BlobError::OutOfRange { section: Section::Header, index: 60 })
    } else {
        Ok(())
    }
}

/// A pixel's peak resolution: NaN (none of its own), or a finite width
/// above zero and at most the calibration's `widest`.
fn check_pixel_resolution(r: f32, widest: f32, p: usize) -> Result<(), BlobError> {
    if r.is_nan() {
        Ok(())
    } else if !r.is_finite() {
        Err(BlobError::NonFinite { section: Section::PeakResolution, index: p })
    } else if r <= 0.0 || r > widest {
        Err(BlobError::OutOfRange { section: Section::PeakResolution, index: p })
    } else {
        Ok(())
    }
}

/// Values of the gloss section before the per-zone data: the assigned value
/// and the refractive index.
const GLOSS_HEAD: usize = 2;

/// CRC used for blobs (and by the calibration store and wire protocol).
pub const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// Which estimator produced the matrices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u16)]
pub enum EstimatorKind {
    /// Wiener estimation with the noise term (patent eq. 22).
    Wiener = 0,
    /// Wiener estimation without noise (patent eq. 20).
    WienerNoiseFree = 1,
    /// Inverse of a square H (claim 3).
    Inverse = 2,
    /// Moore-Penrose pseudo-inverse (claim 4).
    PseudoInverse = 3,
    /// Linear interpolation between the measured angles (baseline).
    Interpolation = 4,
    /// Wiener estimation in a log-mapped space, linearised.
    LogWiener = 5,
    /// Scale-free affine Wiener: the shape from readings divided by their
    /// scale, multiplied back (`crate::kernel::scale_free`). Format version 2.
    ScaleFree = 6,
    /// Scale-free, one matrix per cluster of normalised readings, chosen by
    /// `crate::kernel::select_cluster`. Format version 2.
    ScaleFreePiecewise = 7,
}

impl EstimatorKind {
    /// Decodes the on-blob code.
    pub fn from_code(code: u16) -> Option<Self> {
        Some(match code {
            0 => Self::Wiener,
            1 => Self::WienerNoiseFree,
            2 => Self::Inverse,
            3 => Self::PseudoInverse,
            4 => Self::Interpolation,
            5 => Self::LogWiener,
            6 => Self::ScaleFree,
            7 => Self::ScaleFreePiecewise,
            _ => return None,
        })
    }
}

/// What training reports about the matrices it wrote (worst case over zones).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrainingSummary {
    /// Number of sample BRDFs in the prior.
    pub prior_samples: u32,
    /// Condition number of the matrix that was solved (worst zone).
    pub condition: f32,
    /// Relative regularisation actually applied (0 when none was needed).
    pub regularisation: f32,
    /// RMSE the Wiener error covariance predicts (mean over zones).
    pub predicted_rmse: f32,
    /// Largest relative difference between f32 and f64 evaluation on the prior.
    pub f32_rel_error: f32,
}

/// Where in the blob a problem was found. Also travels in the wire
/// protocol's typed errors (as `protocol::BlobSection`): never reorder the
/// variants, postcard encodes them by index.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Section {
    /// The fixed header.
    Header,
    /// The angle grid.
    Grid,
    /// The LED order.
    LedOrder,
    /// The zone map.
    Zones,
    /// The white reference.
    White,
    /// The per-bin uncertainty.
    Uncertainty,
    /// The matrices.
    Matrices,
    /// The piecewise estimator's centroids (format version 2).
    Centroids,
    /// The out-of-prior means, whitening matrices and threshold (format version 2).
    OutOfPrior,
    /// The gloss readings' reference values, rows and covariances (format version 3).
    Gloss,
    /// The per-pixel peak resolutions (header flag bit 7).
    PeakResolution,
    /// The sensor's linearity correction (header flag bit 11).
    Linearity,
    /// The specular peak's uncertainty factors (header flag bit 12).
    PeakFactors,
}

/// Why a blob was rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BlobError {
    /// Fewer bytes than the header (or the declared length) needs.
    TooShort {
        /// Bytes needed.
        need: usize,
        /// Bytes given.
        got: usize,
    },
    /// The first four bytes are not [`MAGIC`].
    BadMagic,
    /// A format version this parser does not know.
    UnsupportedVersion(u16),
    /// The header length field is not [`HEADER_LEN`].
    BadHeaderLen(u16),
    /// A dimension is zero or above its limit.
    BadDimension {
        /// Field name (`n`, `m`, `zones`, `pixels`).
        field: &'static str,
        /// Value found.
        value: u16,
    },
    /// The declared total length disagrees with the dimensions or the input.
    LengthMismatch {
        /// Length the dimensions imply.
        expected: usize,
        /// Length declared or given.
        got: usize,
    },
    /// The CRC does not match the content.
    CrcMismatch {
        /// CRC stored in the blob.
        stored: u32,
        /// CRC computed over the content.
        computed: u32,
    },
    /// Reserved bytes or flag bits are not zero.
    ReservedNotZero,
    /// Unknown estimator code.
    UnknownEstimator(u16),
    /// A value is NaN or infinite.
    NonFinite {
        /// Section holding it.
        section: Section,
        /// Index within the section.
        index: usize,
    },
    /// A value is out of its allowed range.
    OutOfRange {
        /// Section holding it.
        section: Section,
        /// Index within the section.
        index: usize,
    },
    /// The angle grid is not strictly ascending.
    GridNotAscending {
        /// First index that is not above its predecessor.
        index: usize,
    },
    /// The LED order is not a permutation of 0..m.
    BadLedOrder {
        /// Index of the offending entry.
        index: usize,
    },
    /// The zone map does not start at 0, ascend strictly and stay below P.
    BadZoneMap {
        /// Index of the offending entry.
        index: usize,
    },
    /// The output buffer given to [`write_blob`] is too small.
    BufferTooSmall {
        /// Bytes needed.
        need: usize,
    },
    /// The contents given to [`write_blob`] disagree with their dimensions.
    ContentMismatch {
        /// Which section.
        section: Section,
    },
}

impl fmt::Display for BlobError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::TooShort { need, got } => write!(f, "blob truncated: need {need} bytes, got {got}"),
            Self::BadMagic => write!(f, "not a calibration blob (magic is not \"BRDW\")"),
            Self::UnsupportedVersion(v) => {
                write!(
                    f,
                    "blob format version {v} is not supported (this build reads {FORMAT_VERSION_1} to {FORMAT_VERSION})"
                )
            }
            Self::BadHeaderLen(l) => write!(f, "header length {l} is not {HEADER_LEN}"),
            Self::BadDimension { field, value } => write!(f, "dimension {field} = {value} is zero or too large"),
            Self::LengthMismatch { expected, got } => {
                write!(f, "blob length {got} does not match the {expected} bytes its dimensions imply")
            }
            Self::CrcMismatch { stored, computed } => {
                write!(f, "CRC mismatch: stored {stored:#010x}, computed {computed:#010x} (blob corrupted)")
            }
            Self::ReservedNotZero => write!(f, "reserved header bytes or flag bits are not zero"),
            Self::UnknownEstimator(c) => write!(f, "unknown estimator code {c}"),
            Self::NonFinite { section, index } => write!(f, "non-finite value in {section:?} at index {index}"),
            Self::OutOfRange { section, index } => write!(f, "value out of range in {section:?} at index {index}"),
            Self::GridNotAscending { index } => write!(f, "angle grid not strictly ascending at index {index}"),
            Self::BadLedOrder { index } => write!(f, "LED order is not a permutation (index {index})"),
            Self::BadZoneMap { index } => write!(f, "zone map invalid at index {index}"),
            Self::BufferTooSmall { need } => write!(f, "output buffer too small: need {need} bytes"),
            Self::ContentMismatch { section } => write!(f, "{section:?} does not match the blob's dimensions"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for BlobError {}

/// Dimensions of a blob.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Dims {
    /// Angle bins.
    pub n: usize,
    /// LEDs, readings per point.
    pub m: usize,
    /// Zones of pixels.
    pub zones: usize,
    /// Pixels of the line sensor.
    pub pixels: usize,
}

/// Byte offsets of the sections, derived from the dimensions alone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Layout {
    grid: usize,
    led_order: usize,
    zones: usize,
    white: usize,
    uncertainty: usize,
    matrices: usize,
    centroids: usize,
    out_of_prior: usize,
    gloss: usize,
    /// The per-pixel peak resolutions (as long as the pixels, or empty).
    pixel_resolution: usize,
    /// The second uncertainty table (as long as the first, or empty).
    broad_uncertainty: usize,
    /// The linearity correction (its knots, or empty).
    linearity: usize,
    /// The peak's uncertainty factors (two, or empty).
    peak_factors: usize,
    crc: usize,
    total: usize,
    clusters: usize,
    /// References in the gloss section.
    gloss_refs: usize,
    /// The gloss rows' clusters per zone (K without flag bit 9).
    gloss_clusters: usize,
    /// Whether the gloss section ends with its own centroids (flag bit 9).
    gloss_centroids: bool,
}

const fn pad4(x: usize) -> usize {
    (x + 3) & !3
}

impl Dims {
    fn layout(&self) -> Layout {
        self.layout_with(&Extras::NONE)
    }

    fn layout_with(&self, x: &Extras) -> Layout {
        let k = x.clusters.max(1);
        let grid = HEADER_LEN;
        let led_order = grid + 4 * self.n;
        let zones = led_order + pad4(self.m);
        let white = zones + pad4(2 * self.zones);
        let uncertainty = white + 4 * self.pixels * self.m;
        let matrices = uncertainty + 4 * self.zones * k * self.n;
        let centroids = matrices + 4 * self.zones * k * self.n * self.m;
        let out_of_prior = centroids + if x.piecewise { 4 * self.zones * k * self.m } else { 0 };
        let gloss = out_of_prior + if x.out_of_prior { 4 * self.zones * out_of_prior_len(self.m) } else { 0 };
        let kg = if x.gloss_clusters > 0 { x.gloss_clusters } else { k };
        let pixel_resolution = gloss
            + if x.gloss {
                4 * (gloss_len(x.gloss_refs, self.zones, kg, self.m)
                    + if x.gloss_clusters > 0 { self.zones * kg * self.m } else { 0 })
            } else {
                0
            };
        let broad_uncertainty = pixel_resolution + if x.pixel_resolution { 4 * self.pixels } else { 0 };
        let linearity = broad_uncertainty + if x.broad_band { 4 * self.zones * k * self.n } else { 0 };
        let peak_factors = linearity + if x.linearity { 4 * LINEARITY_KNOTS } else { 0 };
        let crc = peak_factors + if x.peak_factors { 8 } else { 0 };
        Layout {
            grid,
            led_order,
            zones,
            white,
            uncertainty,
            matrices,
            centroids,
            out_of_prior,
            gloss,
            pixel_resolution,
            broad_uncertainty,
            linearity,
            peak_factors,
            crc,
            total: crc + 4,
            clusters: k,
            gloss_refs: if x.gloss { x.gloss_refs } else { 0 },
            gloss_clusters: kg,
            gloss_centroids: x.gloss && x.gloss_clusters > 0,
        }
    }

    /// Total length in bytes of a version 1 blob with these dimensions.
    pub fn blob_len(&self) -> usize {
        self.layout().total
    }

    /// Total length in bytes of a blob with these dimensions and `extras`.
    pub fn blob_len_with(&self, extras: &BlobExtras<'_>) -> usize {
        self.layout_with(&Extras::of(extras, EstimatorKind::Wiener, self)).total
    }

    fn check(&self) -> Result<(), BlobError> {
        let lim = |field, value: usize, max: usize| {
            if value == 0 || value > max {
                Err(BlobError::BadDimension { field, value: value.min(u16::MAX as usize) as u16 })
            } else {
                Ok(())
            }
        };
        lim("n", self.n, MAX_BINS)?;
        lim("m", self.m, MAX_LEDS)?;
        lim("pixels", self.pixels, MAX_PIXELS)?;
        lim("zones", self.zones, self.pixels)
    }
}

/// Largest number of clusters (matrices per zone) a blob may carry.
pub const MAX_CLUSTERS: usize = 64;

/// Values per zone of the out-of-prior section for m readings: the mean of
/// `u'` (m-1) and the packed whitening matrix (m(m-1)/2).
pub const fn out_of_prior_len(m: usize) -> usize {
    (m - 1) + m * (m - 1) / 2
}

/// Values of the gloss section for `refs` references (Z in format version
/// 3, P in version 4), Z zones, K clusters and m readings.
pub const fn gloss_len(refs: usize, zones: usize, clusters: usize, m: usize) -> usize {
    GLOSS_HEAD + refs + zones * clusters * crate::gloss::block_len(m)
}

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
    };
}

/// The layout-relevant part of the extras.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Extras {
    clusters: usize,
    piecewise: bool,
    out_of_prior: bool,
    gloss: bool,
    root_form: bool,
    /// References in the gloss section (P in version 4, Z in version 3).
    gloss_refs: usize,
    /// The header holds the peak resolution.
    peak_resolution: bool,
    /// The per-pixel resolutions follow.
    pixel_resolution: bool,
    /// The second uncertainty table follows.
    broad_band: bool,
    /// The gloss rows' own clusters per zone, K_g (flag bit 9), or 0.
    gloss_clusters: usize,
    /// The root form's fourth gloss row is the peak's deficit (flag bit 10).
    deficit_readings: bool,
    /// The sensor's linearity correction follows (flag bit 11).
    linearity: bool,
    /// The peak's uncertainty factors follow (flag bit 12).
    peak_factors: bool,
}

impl Extras {
    const NONE: Extras = Extras {
        clusters: 1,
        piecewise: false,
        out_of_prior: false,
        gloss: false,
        root_form: false,
        gloss_refs: 0,
        peak_resolution: false,
        pixel_resolution: false,
        broad_band: false,
        gloss_clusters: 0,
        deficit_readings: false,
        linearity: false,
        peak_factors: false,
    };

    fn of(x: &BlobExtras<'_>, kind: EstimatorKind, d: &Dims) -> Self {
        Extras {
            clusters: x.clusters,
            piecewise: kind == EstimatorKind::ScaleFreePiecewise || !x.centroids.is_empty(),
            out_of_prior: x.out_of_prior.is_some(),
            gloss: x.gloss.is_some(),
            root_form: x.root_form,
            gloss_refs: x.gloss.map_or(0, |g| g.reference.len()),
            peak_resolution: x.peak_resolution_deg.is_some(),
            pixel_resolution: !x.pixel_peak_resolution_deg.is_empty(),
            broad_band: !x.broad_uncertainty.is_empty(),
            gloss_clusters: x.gloss.map_or(0, |g| g.centroids.len() / (d.zones * d.m).max(1)),
            deficit_readings: x.gloss.is_some_and(|g| g.root_readings == crate::gloss::RootReadings::Deficit),
            linearity: x.linearity.is_some(),
            peak_factors: x.peak_factors.is_some(),
        }
    }

    fn needs_v2(&self, kind: EstimatorKind) -> bool {
        self.clusters != 1
            || self.piecewise
            || self.out_of_prior
            || self.root_form
            || self.peak_resolution
            || self.broad_band
            || self.linearity
            || self.peak_factors
            || matches!(kind, EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise)
    }

    /// K agrees with the kind: >= 2 for the piecewise kind, 1 otherwise.
    fn check(&self, kind: EstimatorKind) -> Result<(), BlobError> {
        let k = self.clusters;
        let ok = if kind == EstimatorKind::ScaleFreePiecewise {
            (2..=MAX_CLUSTERS).contains(&k)
        } else {
            k == 1 && !self.piecewise
        };
        if self.root_form && !matches!(kind, EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise) {
            return Err(BlobError::ReservedNotZero);
        }
        // The deficit row is a root: only the root form's gloss rows have it.
        if self.deficit_readings && !(self.gloss && self.root_form) {
            return Err(BlobError::ReservedNotZero);
        }
        if self.gloss_clusters != 0
            && (!self.gloss
                || kind != EstimatorKind::ScaleFreePiecewise
                || !(2..=MAX_CLUSTERS).contains(&self.gloss_clusters))
        {
            return Err(BlobError::BadDimension {
                field: "gloss clusters",
                value: self.gloss_clusters.min(u16::MAX as usize) as u16,
            });
        }
        if ok {
            Ok(())
        } else {
            Err(BlobError::BadDimension { field: "clusters", value: k.min(u16::MAX as usize) as u16 })
        }
    }
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

/// Writes `c` into `out` and returns the number of bytes written.
///
/// The result always parses: the same checks [`BlobView::parse`] applies are
/// applied here before anything is written.
pub fn write_blob(c: &BlobContents<'_>, out: &mut [u8]) -> Result<usize, BlobError> {
    write_blob_with(c, &BlobExtras::NONE, out)
}

/// [`write_blob`] with the sections of format version 2 (written as version
/// 1 when `extras` adds nothing and the estimator kind is a version 1 kind).
/// For K > 1, `c.uncertainty` is Z x K x n and `c.matrices` Z x K x n x m.
pub fn write_blob_with(c: &BlobContents<'_>, extras: &BlobExtras<'_>, out: &mut [u8]) -> Result<usize, BlobError> {
    let d = c.dims;
    d.check()?;
    let ex = Extras::of(extras, c.estimator, &d);
    ex.check(c.estimator)?;
    let v2 = ex.needs_v2(c.estimator);
    let lay = d.layout_with(&ex);
    let k = lay.clusters;
    let sized = |ok: bool, section| if ok { Ok(()) } else { Err(BlobError::ContentMismatch { section }) };
    sized(c.grid_deg.len() == d.n, Section::Grid)?;
    sized(c.led_order.len() == d.m, Section::LedOrder)?;
    sized(c.zone_start.len() == d.zones, Section::Zones)?;
    sized(c.white.len() == d.pixels * d.m, Section::White)?;
    sized(c.uncertainty.len() == d.zones * k * d.n, Section::Uncertainty)?;
    sized(!ex.broad_band || extras.broad_uncertainty.len() == d.zones * k * d.n, Section::Uncertainty)?;
    sized(c.matrices.len() == d.zones * k * d.n * d.m, Section::Matrices)?;
    sized(extras.centroids.len() == if ex.piecewise { d.zones * k * d.m } else { 0 }, Section::Centroids)?;
    if let Some(o) = &extras.out_of_prior {
        sized(d.m >= 2 && o.data.len() == d.zones * out_of_prior_len(d.m), Section::OutOfPrior)?;
    }
    if let Some(g) = &extras.gloss {
        let kg = lay.gloss_clusters;
        sized(
            (g.reference.len() == d.pixels || g.reference.len() == d.zones)
                && g.blocks.len() == d.zones * kg * crate::gloss::block_len(d.m)
                && g.centroids.len() == if ex.gloss_clusters > 0 { d.zones * kg * d.m } else { 0 },
            Section::Gloss,
        )?;
    }
    if let Some(r) = extras.peak_resolution_deg {
        check_peak_resolution(r)?;
    }
    if ex.pixel_resolution {
        sized(extras.pixel_peak_resolution_deg.len() == d.pixels, Section::PeakResolution)?;
        let widest =
            extras.peak_resolution_deg.ok_or(BlobError::ContentMismatch { section: Section::PeakResolution })?;
        for (p, r) in extras.pixel_peak_resolution_deg.iter().enumerate() {
            check_pixel_resolution(*r, widest, p)?;
        }
    }
    if ex.peak_factors && !ex.peak_resolution {
        return Err(BlobError::ContentMismatch { section: Section::PeakFactors });
    }
    if out.len() < lay.total {
        return Err(BlobError::BufferTooSmall { need: lay.total });
    }
    let out = &mut out[..lay.total];
    out.fill(0);
    out[0..4].copy_from_slice(&MAGIC);
    let version = if ex.gloss && ex.gloss_refs == d.pixels {
        FORMAT_VERSION
    } else if ex.gloss {
        FORMAT_VERSION_3
    } else if v2 {
        FORMAT_VERSION_2
    } else {
        FORMAT_VERSION_1
    };
    let v2 = v2 || ex.gloss;
    put_u16(out, 4, version);
    put_u16(out, 6, HEADER_LEN as u16);
    put_u16(out, 8, d.n as u16);
    put_u16(out, 10, d.m as u16);
    put_u16(out, 12, d.zones as u16);
    put_u16(out, 14, d.pixels as u16);
    put_f32(out, 16, c.noise_rel);
    put_u16(out, 20, c.estimator as u16);
    let oop_flag = match extras.out_of_prior {
        Some(OutOfPriorData { form: OutOfPriorForm::LogRatio, .. }) => FLAG_OUT_OF_PRIOR | FLAG_LOG_RATIO,
        Some(_) => FLAG_OUT_OF_PRIOR,
        None => 0,
    } | match extras.out_of_prior {
        Some(o) if o.band_factor != 1.0 => FLAG_BAND_FACTOR,
        _ => 0,
    };
    let gloss_flag = if ex.gloss { FLAG_GLOSS } else { 0 };
    let root_flag = if ex.root_form { FLAG_ROOT } else { 0 };
    let resolution_flag = if ex.peak_resolution { FLAG_PEAK_RESOLUTION } else { 0 }
        | if ex.pixel_resolution { FLAG_PIXEL_RESOLUTION } else { 0 }
        | if ex.broad_band { FLAG_BROAD_BAND } else { 0 }
        | if ex.gloss_clusters > 0 { FLAG_GLOSS_CLUSTERS } else { 0 }
        | if ex.deficit_readings { FLAG_DEFICIT_READINGS } else { 0 }
        | if ex.linearity { FLAG_LINEARITY } else { 0 }
        | if ex.peak_factors { FLAG_PEAK_FACTORS } else { 0 };
    put_u16(
        out,
        22,
        if c.far_field { FLAG_FAR_FIELD } else { 0 } | oop_flag | gloss_flag | root_flag | resolution_flag,
    );
    if v2 {
        put_u16(out, 48, k as u16);
        put_u16(out, 50, ex.gloss_clusters as u16);
        put_f32(out, 52, extras.out_of_prior.map_or(0.0, |o| o.threshold));
        if let Some(o) = extras.out_of_prior.filter(|o| o.band_factor != 1.0) {
            put_f32(out, 56, o.band_factor);
        }
        if let Some(r) = extras.peak_resolution_deg {
            put_f32(out, 60, r);
        }
    }
    put_u32(out, 24, c.summary.prior_samples);
    put_f32(out, 28, c.summary.condition);
    put_f32(out, 32, c.summary.regularisation);
    put_f32(out, 36, c.summary.predicted_rmse);
    put_f32(out, 40, c.summary.f32_rel_error);
    put_u32(out, 44, lay.total as u32);
    for (i, x) in c.grid_deg.iter().enumerate() {
        put_f32(out, lay.grid + 4 * i, *x);
    }
    out[lay.led_order..lay.led_order + d.m].copy_from_slice(c.led_order);
    for (i, z) in c.zone_start.iter().enumerate() {
        put_u16(out, lay.zones + 2 * i, *z);
    }
    let oop: &[f32] = extras.out_of_prior.map_or(&[], |o| o.data);
    let peak_factors = extras.peak_factors.map_or([0.0; 2], |f| [f.height, f.width]);
    if let Some(g) = &extras.gloss {
        put_f32(out, lay.gloss, g.assigned_gu);
        put_f32(out, lay.gloss + 4, g.refractive_index);
    }
    let (gref, gblocks, gcents): (&[f32], &[f32], &[f32]) =
        extras.gloss.map_or((&[], &[], &[]), |g| (g.reference, g.blocks, g.centroids));
    for (off, xs) in [
        (lay.gloss + 4 * GLOSS_HEAD, gref),
        (lay.gloss + 4 * (GLOSS_HEAD + lay.gloss_refs), gblocks),
        (lay.gloss + 4 * (GLOSS_HEAD + lay.gloss_refs + gblocks.len()), gcents),
        (lay.white, c.white),
        (lay.uncertainty, c.uncertainty),
        (lay.matrices, c.matrices),
        (lay.centroids, extras.centroids),
        (lay.out_of_prior, oop),
        (lay.pixel_resolution, extras.pixel_peak_resolution_deg),
        (lay.broad_uncertainty, extras.broad_uncertainty),
        (lay.linearity, extras.linearity.as_ref().map_or(&[][..], |l| &l.factors()[..])),
        (lay.peak_factors, &peak_factors[..if ex.peak_factors { 2 } else { 0 }]),
    ] {
        for (i, x) in xs.iter().enumerate() {
            put_f32(out, off + 4 * i, *x);
        }
    }
    let crc = CRC32.checksum(&out[..lay.crc]);
    put_u32(out, lay.crc, crc);
    // Validate what we wrote with the one parser, so a blob that would be
    // refused on the device is refused here, before it leaves the host.
    BlobView::parse(out)?;
    Ok(lay.total)
}

/// A validated blob, read in place.
#[derive(Clone, Copy, Debug)]
pub struct BlobView<'a> {
    bytes: &'a [u8],
    dims: Dims,
    lay: Layout,
}

impl<'a> BlobView<'a> {
    /// Validates `bytes` (exactly one blob, or a blob followed by unused bytes
    /// such as erased flash) and returns a view of it.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, BlobError> {
        if bytes.len() < HEADER_LEN {
            return Err(BlobError::TooShort { need: HEADER_LEN, got: bytes.len() });
        }
        if bytes[0..4] != MAGIC {
            return Err(BlobError::BadMagic);
        }
        let version = get_u16(bytes, 4);
        if !(FORMAT_VERSION_1..=FORMAT_VERSION).contains(&version) {
            return Err(BlobError::UnsupportedVersion(version));
        }
        let hl = get_u16(bytes, 6);
        if hl as usize != HEADER_LEN {
            return Err(BlobError::BadHeaderLen(hl));
        }
        let dims = Dims {
            n: get_u16(bytes, 8) as usize,
            m: get_u16(bytes, 10) as usize,
            zones: get_u16(bytes, 12) as usize,
            pixels: get_u16(bytes, 14) as usize,
        };
        dims.check()?;
        let flags = get_u16(bytes, 22);
        let code = get_u16(bytes, 20);
        let kind = EstimatorKind::from_code(code).ok_or(BlobError::UnknownEstimator(code))?;
        let ex = if version == FORMAT_VERSION_1 {
            if matches!(kind, EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise) {
                return Err(BlobError::UnknownEstimator(code));
            }
            Extras::NONE
        } else {
            let gloss = flags & FLAG_GLOSS != 0;
            Extras {
                clusters: get_u16(bytes, 48) as usize,
                piecewise: kind == EstimatorKind::ScaleFreePiecewise,
                out_of_prior: flags & FLAG_OUT_OF_PRIOR != 0,
                gloss,
                root_form: flags & FLAG_ROOT != 0,
                gloss_refs: match (gloss, version) {
                    (false, _) => 0,
                    (true, FORMAT_VERSION_3) => dims.zones,
                    (true, _) => dims.pixels,
                },
                peak_resolution: flags & FLAG_PEAK_RESOLUTION != 0,
                pixel_resolution: flags & FLAG_PIXEL_RESOLUTION != 0,
                broad_band: flags & FLAG_BROAD_BAND != 0,
                gloss_clusters: if flags & FLAG_GLOSS_CLUSTERS != 0 {
                    // Zero means "none" in `Extras`: with the bit it is a bad count.
                    match get_u16(bytes, 50) {
                        0 => return Err(BlobError::BadDimension { field: "gloss clusters", value: 0 }),
                        k => k as usize,
                    }
                } else {
                    0
                },
                deficit_readings: flags & FLAG_DEFICIT_READINGS != 0,
                linearity: flags & FLAG_LINEARITY != 0,
                peak_factors: flags & FLAG_PEAK_FACTORS != 0,
            }
        };
        // Versions 3 and 4 exist for the gloss section: they carry it, 2 never does.
        if (version >= FORMAT_VERSION_3) != ex.gloss {
            return Err(BlobError::ReservedNotZero);
        }
        ex.check(kind)?;
        if ex.out_of_prior && dims.m < 2 {
            return Err(BlobError::BadDimension { field: "m", value: dims.m as u16 });
        }
        let lay = dims.layout_with(&ex);
        let declared = get_u32(bytes, 44) as usize;
        if declared != lay.total {
            return Err(BlobError::LengthMismatch { expected: lay.total, got: declared });
        }
        if bytes.len() < lay.total {
            return Err(BlobError::TooShort { need: lay.total, got: bytes.len() });
        }
        let bytes = &bytes[..lay.total];
        let stored = get_u32(bytes, lay.crc);
        let computed = CRC32.checksum(&bytes[..lay.crc]);
        if stored != computed {
            return Err(BlobError::CrcMismatch { stored, computed });
        }
        // Semantic checks: a blob with a valid CRC can still be wrong if the
        // host that wrote it was; the device must never run on such a blob.
        let reserved_ok = if version == FORMAT_VERSION_1 {
            bytes[48..64].iter().all(|b| *b == 0) && flags & !FLAG_FAR_FIELD == 0
        } else {
            let band = flags & FLAG_BAND_FACTOR != 0;
            let known = FLAG_FAR_FIELD
                | FLAG_OUT_OF_PRIOR
                | FLAG_GLOSS
                | FLAG_ROOT
                | FLAG_LOG_RATIO
                | FLAG_BAND_FACTOR
                | FLAG_PEAK_RESOLUTION
                | FLAG_PIXEL_RESOLUTION
                | FLAG_BROAD_BAND
                | FLAG_GLOSS_CLUSTERS
                | FLAG_DEFICIT_READINGS
                | FLAG_LINEARITY
                | FLAG_PEAK_FACTORS;
            (ex.gloss_clusters > 0 || bytes[50..52].iter().all(|b| *b == 0))
                && (ex.peak_resolution || !(ex.pixel_resolution || ex.peak_factors))
                && (band || get_u32(bytes, 56) == 0)
                && (ex.peak_resolution || get_u32(bytes, 60) == 0)
                && flags & !known == 0
                && (ex.out_of_prior || (get_u32(bytes, 52) == 0 && flags & (FLAG_LOG_RATIO | FLAG_BAND_FACTOR) == 0))
        };
        if !reserved_ok {
            return Err(BlobError::ReservedNotZero);
        }
        let view = Self { bytes, dims, lay };
        if ex.out_of_prior {
            let t = get_f32(bytes, 52);
            if !t.is_finite() {
                return Err(BlobError::NonFinite { section: Section::OutOfPrior, index: 0 });
            }
            if t <= 0.0 {
                return Err(BlobError::OutOfRange { section: Section::OutOfPrior, index: 0 });
            }
            let f = view.out_of_prior_band_factor();
            if !f.is_finite() {
                return Err(BlobError::NonFinite { section: Section::Header, index: 56 });
            }
            if f < 1.0 {
                return Err(BlobError::OutOfRange { section: Section::Header, index: 56 });
            }
        }
        if let Some(r) = view.peak_resolution_deg() {
            check_peak_resolution(r)?;
            if ex.pixel_resolution {
                for p in 0..dims.pixels {
                    check_pixel_resolution(get_f32(bytes, lay.pixel_resolution + 4 * p), r, p)?;
                }
            }
        }
        let noise = view.noise_rel();
        if !noise.is_finite() {
            return Err(BlobError::NonFinite { section: Section::Header, index: 16 });
        }
        if noise < 0.0 {
            return Err(BlobError::OutOfRange { section: Section::Header, index: 16 });
        }
        let mut prev = f32::NEG_INFINITY;
        for i in 0..dims.n {
            let g = view.grid_deg(i);
            if !g.is_finite() {
                return Err(BlobError::NonFinite { section: Section::Grid, index: i });
            }
            if !(-90.0..=90.0).contains(&g) {
                return Err(BlobError::OutOfRange { section: Section::Grid, index: i });
            }
            if g <= prev {
                return Err(BlobError::GridNotAscending { index: i });
            }
            prev = g;
        }
        let mut seen = 0u64;
        for (i, &led) in view.led_order().iter().enumerate() {
            if led as usize >= dims.m || seen & (1 << led) != 0 {
                return Err(BlobError::BadLedOrder { index: i });
            }
            seen |= 1 << led;
        }
        let mut prev_start = None;
        for i in 0..dims.zones {
            let s = view.zone_start(i);
            let ok = match prev_start {
                None => s == 0,
                Some(p) => s > p && (s as usize) < dims.pixels,
            };
            if !ok {
                return Err(BlobError::BadZoneMap { index: i });
            }
            prev_start = Some(s);
        }
        view.check_finite(Section::White, lay.white, dims.pixels * dims.m, true)?;
        let k = lay.clusters;
        view.check_finite(Section::Uncertainty, lay.uncertainty, dims.zones * k * dims.n, false)?;
        // The second table, its values indexed on from the first's.
        let first = dims.zones * k * dims.n;
        view.check_finite(
            Section::Uncertainty,
            lay.broad_uncertainty,
            (lay.linearity - lay.broad_uncertainty) / 4,
            false,
        )
        .map_err(|e| match e {
            BlobError::NonFinite { section, index } => BlobError::NonFinite { section, index: first + index },
            BlobError::OutOfRange { section, index } => BlobError::OutOfRange { section, index: first + index },
            e => e,
        })?;
        view.check_finite(Section::Matrices, lay.matrices, dims.zones * k * dims.n * dims.m, false)?;
        view.check_finite(Section::Centroids, lay.centroids, (lay.out_of_prior - lay.centroids) / 4, false)?;
        view.check_finite(Section::OutOfPrior, lay.out_of_prior, (lay.gloss - lay.out_of_prior) / 4, false)?;
        if ex.gloss {
            view.check_gloss()?;
        }
        if ex.linearity {
            view.check_linearity()?;
        }
        view.check_finite(Section::PeakFactors, lay.peak_factors, (lay.crc - lay.peak_factors) / 4, true)?;
        Ok(view)
    }

    /// The gloss section's rules: everything finite; the assigned value and
    /// the references > 0, the refractive index > 1, the covariances'
    /// diagonals and standard deviations >= 0; except a zone without a
    /// reading, whose references (its pixels' in version 4, its own in
    /// version 3) and every value of its blocks are NaN (no mix). Indices
    /// count f32 values from the section's start.
    fn check_gloss(&self) -> Result<(), BlobError> {
        let (z, k, m, refs) = (self.dims.zones, self.lay.gloss_clusters, self.dims.m, self.lay.gloss_refs);
        let block = crate::gloss::block_len(m);
        let rows = crate::gloss::LINEAR * m;
        let diag = [0, 1, 2, 3].map(|i| rows + crate::gloss::cov_index(i, i));
        let sd = [rows + crate::gloss::COV_LEN, rows + crate::gloss::COV_LEN + 1];
        // Zone `zz` without a reading: the first value of its first block is
        // NaN (and then all of its values and references must be).
        let first_block = GLOSS_HEAD + refs;
        let no_reading = |zz: usize| get_f32(self.bytes, self.lay.gloss + 4 * (first_block + zz * k * block)).is_nan();
        let zone_of_ref = |r: usize| if refs == z { r } else { self.zone_of_pixel(r) };
        for i in 0..gloss_len(refs, z, k, m) {
            let x = get_f32(self.bytes, self.lay.gloss + 4 * i);
            let zone = match i {
                _ if i < GLOSS_HEAD => None,
                _ if i < first_block => Some(zone_of_ref(i - GLOSS_HEAD)),
                _ => Some((i - first_block) / (k * block)),
            };
            if zone.is_some_and(no_reading) {
                if !x.is_nan() {
                    return Err(BlobError::OutOfRange { section: Section::Gloss, index: i });
                }
                continue;
            }
            if !x.is_finite() {
                return Err(BlobError::NonFinite { section: Section::Gloss, index: i });
            }
            let ok = match i {
                0 => x > 0.0,
                1 => x > 1.0,
                _ if i < first_block => x > 0.0,
                _ => {
                    let at = (i - first_block) % block;
                    !(diag.contains(&at) || sd.contains(&at)) || x >= 0.0
                }
            };
            if !ok {
                return Err(BlobError::OutOfRange { section: Section::Gloss, index: i });
            }
        }
        // The rows' own centroids, after the blocks: finite in every zone.
        let cents = if self.lay.gloss_centroids { z * k * m } else { 0 };
        let first_centroid = gloss_len(refs, z, k, m);
        for i in first_centroid..first_centroid + cents {
            if !get_f32(self.bytes, self.lay.gloss + 4 * i).is_finite() {
                return Err(BlobError::NonFinite { section: Section::Gloss, index: i });
            }
        }
        Ok(())
    }

    fn check_finite(&self, section: Section, off: usize, count: usize, positive: bool) -> Result<(), BlobError> {
        for i in 0..count {
            let x = get_f32(self.bytes, off + 4 * i);
            if !x.is_finite() {
                return Err(BlobError::NonFinite { section, index: i });
            }
            if (positive && x <= 0.0) || (section == Section::Uncertainty && x < 0.0) {
                return Err(BlobError::OutOfRange { section, index: i });
            }
        }
        Ok(())
    }

    /// The linearity section's rules ([`Linearity::new`]'s), knot by knot
    /// in place.
    fn check_linearity(&self) -> Result<(), BlobError> {
        let mut last = f32::NAN;
        for index in 0..(self.lay.peak_factors - self.lay.linearity) / 4 {
            let f = get_f32(self.bytes, self.lay.linearity + 4 * index);
            match crate::acquire::linearity::fault(index, f, last) {
                None => last = f,
                Some(_) if !f.is_finite() => return Err(BlobError::NonFinite { section: Section::Linearity, index }),
                Some(LinearityError::OutOfRange { index } | LinearityError::NotMonotone { index }) => {
                    return Err(BlobError::OutOfRange { section: Section::Linearity, index });
                }
            }
        }
        Ok(())
    }

    /// The sensor's linearity correction (flag bit 11), when the blob has one.
    pub fn linearity(&self) -> Option<Linearity> {
        (self.lay.peak_factors != self.lay.linearity).then(|| Linearity::validated(self.linearity_factors()))
    }

    fn linearity_factors(&self) -> [f32; LINEARITY_KNOTS] {
        let mut f = [0.0; LINEARITY_KNOTS];
        for (k, x) in f.iter_mut().enumerate() {
            *x = get_f32(self.bytes, self.lay.linearity + 4 * k);
        }
        f
    }

    /// The blob's bytes (exactly its length).
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }
    /// The blob's CRC, which also identifies it.
    pub fn crc(&self) -> u32 {
        get_u32(self.bytes, self.lay.crc)
    }
    /// Dimensions.
    pub fn dims(&self) -> Dims {
        self.dims
    }
    /// Relative noise level used in training.
    pub fn noise_rel(&self) -> f32 {
        get_f32(self.bytes, 16)
    }
    /// Estimator that produced the matrices.
    pub fn estimator(&self) -> EstimatorKind {
        // Checked in parse.
        EstimatorKind::from_code(get_u16(self.bytes, 20)).unwrap_or(EstimatorKind::Wiener)
    }
    /// Whether the optics were modelled far-field.
    pub fn far_field(&self) -> bool {
        get_u16(self.bytes, 22) & FLAG_FAR_FIELD != 0
    }
    /// Training summary.
    pub fn summary(&self) -> TrainingSummary {
        TrainingSummary {
            prior_samples: get_u32(self.bytes, 24),
            condition: get_f32(self.bytes, 28),
            regularisation: get_f32(self.bytes, 32),
            predicted_rmse: get_f32(self.bytes, 36),
            f32_rel_error: get_f32(self.bytes, 40),
        }
    }
    /// Angle of bin `i`, degrees.
    pub fn grid_deg(&self, i: usize) -> f32 {
        assert!(i < self.dims.n);
        get_f32(self.bytes, self.lay.grid + 4 * i)
    }
    /// The LED fired for each reading.
    pub fn led_order(&self) -> &'a [u8] {
        &self.bytes[self.lay.led_order..self.lay.led_order + self.dims.m]
    }
    /// First pixel of zone `z`.
    pub fn zone_start(&self, z: usize) -> u16 {
        assert!(z < self.dims.zones);
        get_u16(self.bytes, self.lay.zones + 2 * z)
    }
    /// Zone that pixel `p` belongs to.
    pub fn zone_of_pixel(&self, p: usize) -> usize {
        let mut z = 0;
        while z + 1 < self.dims.zones && (self.zone_start(z + 1) as usize) <= p {
            z += 1;
        }
        z
    }
    /// White reference of pixel `p` under reading `i`.
    pub fn white(&self, p: usize, i: usize) -> f32 {
        assert!(p < self.dims.pixels && i < self.dims.m);
        get_f32(self.bytes, self.lay.white + 4 * (p * self.dims.m + i))
    }
    /// Predicted standard uncertainty of zone `z`, bin `j` (cluster 0; for
    /// the scale-free kinds per unit scale).
    pub fn uncertainty(&self, z: usize, j: usize) -> f32 {
        self.uncertainty_of(z, 0, j)
    }
    /// Predicted standard uncertainty of zone `z`, cluster `c`, bin `j`.
    pub fn uncertainty_of(&self, z: usize, c: usize, j: usize) -> f32 {
        assert!(z < self.dims.zones && c < self.lay.clusters && j < self.dims.n);
        get_f32(self.bytes, self.lay.uncertainty + 4 * ((z * self.lay.clusters + c) * self.dims.n + j))
    }
    /// Whether the blob carries the second uncertainty table (flag bit 8).
    pub fn has_broad_band(&self) -> bool {
        self.lay.linearity != self.lay.broad_uncertainty
    }
    /// The table the point of estimate `rho` (on the angles `bins_deg`:
    /// the grid's, or the subset a frame carries) takes: [`crate::band`].
    pub fn band_table(&self, bins_deg: &[f32], rho: &[f32]) -> crate::band::BandTable {
        crate::band::table_of(self.has_broad_band(), bins_deg, rho)
    }
    /// Predicted standard uncertainty of zone `z`, cluster `c`, bin `j` in
    /// `table` (the first table when the blob has no second).
    pub fn uncertainty_in(&self, table: crate::band::BandTable, z: usize, c: usize, j: usize) -> f32 {
        match table {
            crate::band::BandTable::Broad if self.has_broad_band() => {
                assert!(z < self.dims.zones && c < self.lay.clusters && j < self.dims.n);
                get_f32(self.bytes, self.lay.broad_uncertainty + 4 * ((z * self.lay.clusters + c) * self.dims.n + j))
            }
            _ => self.uncertainty_of(z, c, j),
        }
    }
    /// A point's standard uncertainty of bin `j`, from the table it takes
    /// ([`Self::band_table`]), its zone `z`, cluster `c`, estimate `rho` of
    /// the bin and `sigma_scale` (the frame's): the table's uncertainty
    /// times `|sigma_scale|`, or in the root form
    /// [`crate::kernel::scale_free::root_uncertainty`], which follows the
    /// point's own estimate.
    pub fn point_uncertainty(
        &self,
        table: crate::band::BandTable,
        (z, c): (usize, usize),
        j: usize,
        rho: f32,
        sigma_scale: f32,
    ) -> f32 {
        let u = self.uncertainty_in(table, z, c, j);
        if self.root_form() {
            crate::kernel::scale_free::root_uncertainty(u, rho, sigma_scale)
        } else {
            u * sigma_scale.abs()
        }
    }
    /// Element (j, i) of zone `z`'s matrix (cluster 0).
    pub fn w(&self, z: usize, j: usize, i: usize) -> f32 {
        assert!(z < self.dims.zones && j < self.dims.n && i < self.dims.m);
        get_f32(self.bytes, self.matrix_offset(z, 0) + 4 * (j * self.dims.m + i))
    }
    fn matrix_offset(&self, z: usize, c: usize) -> usize {
        self.lay.matrices + 4 * (z * self.lay.clusters + c) * self.dims.n * self.dims.m
    }
    /// Copies zone `z`'s matrix (row-major n x m; cluster 0) into `out`.
    pub fn copy_matrix(&self, z: usize, out: &mut [f32]) {
        self.copy_matrix_of(z, 0, out)
    }
    /// Copies zone `z`'s matrix of cluster `c` (row-major n x m) into `out`.
    pub fn copy_matrix_of(&self, z: usize, c: usize, out: &mut [f32]) {
        let nm = self.dims.n * self.dims.m;
        assert!(z < self.dims.zones && c < self.lay.clusters && out.len() == nm);
        let off = self.matrix_offset(z, c);
        for (k, o) in out.iter_mut().enumerate() {
            *o = get_f32(self.bytes, off + 4 * k);
        }
    }
    /// Zone `z`'s matrix (cluster 0) as an `f32` slice in place, when the
    /// blob sits at a 4-byte aligned address (little-endian targets only).
    #[cfg(target_endian = "little")]
    pub fn matrix_in_place(&self, z: usize) -> Option<&'a [f32]> {
        let nm = self.dims.n * self.dims.m;
        let off = self.matrix_offset(z, 0);
        bytemuck::try_cast_slice(self.bytes.get(off..off + 4 * nm)?).ok()
    }
    /// All zones' centroids (Z x K x m) as an `f32` slice in place (piecewise
    /// blobs at a 4-byte aligned address); `None` otherwise.
    #[cfg(target_endian = "little")]
    pub fn centroids_in_place(&self) -> Option<&'a [f32]> {
        if self.lay.out_of_prior == self.lay.centroids {
            return None;
        }
        bytemuck::try_cast_slice(self.bytes.get(self.lay.centroids..self.lay.out_of_prior)?).ok()
    }
    /// All zones' out-of-prior data (per zone: the mean, m-1, then the packed
    /// whitening matrix, m(m-1)/2) as an `f32` slice in place, when the blob
    /// carries it and sits at a 4-byte aligned address; `None` otherwise.
    #[cfg(target_endian = "little")]
    pub fn out_of_prior_in_place(&self) -> Option<&'a [f32]> {
        self.out_of_prior_threshold()?;
        bytemuck::try_cast_slice(self.bytes.get(self.lay.out_of_prior..self.lay.gloss)?).ok()
    }
    /// All zones' per-bin standard uncertainties (Z x K x n) as an `f32`
    /// slice in place, when the blob sits at a 4-byte aligned address.
    #[cfg(target_endian = "little")]
    pub fn uncertainty_in_place(&self) -> Option<&'a [f32]> {
        let len = 4 * self.dims.zones * self.lay.clusters * self.dims.n;
        bytemuck::try_cast_slice(self.bytes.get(self.lay.uncertainty..self.lay.uncertainty + len)?).ok()
    }
    /// The gloss section (`crate::gloss`) in place, when the blob carries it
    /// and sits at a 4-byte aligned address: (assigned value, refractive
    /// index, the references, the blocks Z x K_g and the rows' own
    /// centroids).
    #[cfg(target_endian = "little")]
    pub fn gloss_in_place(&self) -> Option<GlossData<'a>> {
        if !self.has_gloss() {
            return None;
        }
        let all: &'a [f32] =
            bytemuck::try_cast_slice(self.bytes.get(self.lay.gloss..self.lay.pixel_resolution)?).ok()?;
        let r = self.lay.gloss_refs;
        let blocks = self.dims.zones * self.lay.gloss_clusters * crate::gloss::block_len(self.dims.m);
        Some(GlossData {
            assigned_gu: all[0],
            refractive_index: all[1],
            reference: &all[GLOSS_HEAD..GLOSS_HEAD + r],
            blocks: &all[GLOSS_HEAD + r..GLOSS_HEAD + r + blocks],
            centroids: &all[GLOSS_HEAD + r + blocks..],
            root_readings: self.root_readings(),
        })
    }
    /// How the gloss rows are read in the root form (flag bit 10):
    /// [`crate::gloss::readings_root`]'s `form`.
    pub fn root_readings(&self) -> crate::gloss::RootReadings {
        if self.dims_flags() & FLAG_DEFICIT_READINGS != 0 {
            crate::gloss::RootReadings::Deficit
        } else {
            crate::gloss::RootReadings::Shoulders
        }
    }
    /// Whether the calibration is in the root form (flag bit 3): the
    /// kernel's outputs are roots `t`, the estimate `t^2 / s`.
    pub fn root_form(&self) -> bool {
        self.dims_flags() & FLAG_ROOT != 0
    }
    fn dims_flags(&self) -> u16 {
        get_u16(self.bytes, 22)
    }
    /// Whether the blob carries the gloss section.
    pub fn has_gloss(&self) -> bool {
        self.lay.pixel_resolution != self.lay.gloss
    }
    /// The gloss section's values copied out (any alignment): assigned value,
    /// refractive index, then the reference of zone `z`'s first pixel and the
    /// block of gloss cluster `c` (< [`Self::gloss_clusters`]) into `block`;
    /// `None` when the blob has no gloss section.
    pub fn copy_gloss(&self, z: usize, c: usize, block: &mut [f32]) -> Option<(f32, f32, f32)> {
        if !self.has_gloss() {
            return None;
        }
        let (zones, k, m) = (self.dims.zones, self.lay.gloss_clusters, self.dims.m);
        let bl = crate::gloss::block_len(m);
        assert!(z < zones && c < k && block.len() == bl);
        let at = |i: usize| get_f32(self.bytes, self.lay.gloss + 4 * i);
        let off = GLOSS_HEAD + self.lay.gloss_refs + (z * k + c) * bl;
        for (i, b) in block.iter_mut().enumerate() {
            *b = at(off + i);
        }
        Some((at(0), at(1), self.gloss_reference(self.zone_start(z) as usize).expect("the blob has the section")))
    }

    /// The gloss rows' clusters per zone: K_g when they have their own
    /// (flag bit 9), else K (a point's gloss block is its BRDF cluster's).
    pub fn gloss_clusters(&self) -> usize {
        self.lay.gloss_clusters
    }
    /// Whether the gloss rows have clusters of their own (flag bit 9).
    pub fn has_gloss_centroids(&self) -> bool {
        self.lay.gloss_centroids
    }
    /// Copies zone `z`'s gloss centroids (K_g x m) into `out`, when the
    /// gloss rows have their own (flag bit 9): a point's gloss cluster is
    /// the one [`crate::kernel::select_cluster`] picks among them. `false`
    /// (nothing copied) when they have none: a point's gloss block is then
    /// its BRDF cluster's.
    pub fn copy_gloss_centroids(&self, z: usize, out: &mut [f32]) -> bool {
        if !self.lay.gloss_centroids {
            return false;
        }
        let (k, m) = (self.lay.gloss_clusters, self.dims.m);
        assert!(z < self.dims.zones && out.len() == k * m);
        let at = self.lay.gloss + 4 * (gloss_len(self.lay.gloss_refs, self.dims.zones, k, m) + z * k * m);
        for (i, o) in out.iter_mut().enumerate() {
            *o = get_f32(self.bytes, at + 4 * i);
        }
        true
    }
    /// The gloss reference pixel `p` is read with: its own (format version
    /// 4) or its zone's (version 3); `None` without a gloss section.
    pub fn gloss_reference(&self, p: usize) -> Option<f32> {
        if !self.has_gloss() {
            return None;
        }
        assert!(p < self.dims.pixels);
        let r = if self.lay.gloss_refs == self.dims.pixels { p } else { self.zone_of_pixel(p) };
        Some(get_f32(self.bytes, self.lay.gloss + 4 * (GLOSS_HEAD + r)))
    }
    /// Format version of this blob (1 to 4).
    pub fn version(&self) -> u16 {
        get_u16(self.bytes, 4)
    }
    /// K, matrices per zone (1 unless piecewise).
    pub fn clusters(&self) -> usize {
        self.lay.clusters
    }
    /// Copies zone `z`'s centroids (K x m) into `out` (piecewise blobs only).
    pub fn copy_centroids(&self, z: usize, out: &mut [f32]) {
        let km = self.lay.clusters * self.dims.m;
        assert!(
            z < self.dims.zones
                && out.len() == km
                && self.lay.out_of_prior - self.lay.centroids == 4 * self.dims.zones * km
        );
        for (k, o) in out.iter_mut().enumerate() {
            *o = get_f32(self.bytes, self.lay.centroids + 4 * (z * km + k));
        }
    }
    /// The out-of-prior threshold, when the blob carries the section.
    pub fn out_of_prior_threshold(&self) -> Option<f32> {
        (get_u16(self.bytes, 22) & FLAG_OUT_OF_PRIOR != 0).then(|| get_f32(self.bytes, 52))
    }
    /// What a flagged point's per-bin unit uncertainty is multiplied by
    /// (header offset 56 with flag bit 5; 1 without): the band of a point
    /// the out-of-prior flag raised, as training measured it on held-out
    /// kinds of material the flag raised
    /// ([`crate::kernel::scale_free::flagged_sigma_scale`]).
    pub fn out_of_prior_band_factor(&self) -> f32 {
        if get_u16(self.bytes, 22) & FLAG_BAND_FACTOR != 0 { get_f32(self.bytes, 56) } else { 1.0 }
    }
    /// The peak resolution (deg; header offset 60 with flag bit 6), when
    /// the blob carries it: the module docs.
    pub fn peak_resolution_deg(&self) -> Option<f32> {
        (get_u16(self.bytes, 22) & FLAG_PEAK_RESOLUTION != 0).then(|| get_f32(self.bytes, 60))
    }

    /// The specular peak's uncertainty factors (flag bit 12), when the blob
    /// has them.
    pub fn peak_factors(&self) -> Option<PeakFactors> {
        let at = |i: usize| get_f32(self.bytes, self.lay.peak_factors + 4 * i);
        (self.lay.crc != self.lay.peak_factors).then(|| PeakFactors { height: at(0), width: at(1) })
    }

    /// Pixel `p`'s peak resolution (deg): its own (flag bit 7) when it has
    /// one, else the calibration's ([`Self::peak_resolution_deg`]).
    pub fn peak_resolution_at(&self, p: usize) -> Option<f32> {
        let own = (get_u16(self.bytes, 22) & FLAG_PIXEL_RESOLUTION != 0 && p < self.dims.pixels)
            .then(|| get_f32(self.bytes, self.lay.pixel_resolution + 4 * p))
            .filter(|r| !r.is_nan());
        own.or_else(|| self.peak_resolution_deg())
    }
    /// Which statistic the out-of-prior section is for, when the blob
    /// carries one.
    pub fn out_of_prior_form(&self) -> Option<OutOfPriorForm> {
        let flags = get_u16(self.bytes, 22);
        (flags & FLAG_OUT_OF_PRIOR != 0).then_some(if flags & FLAG_LOG_RATIO != 0 {
            OutOfPriorForm::LogRatio
        } else {
            OutOfPriorForm::Linear
        })
    }
    /// Copies zone `z`'s out-of-prior mean (m-1) and packed whitening matrix
    /// (m(m-1)/2); false when the blob carries no such section.
    pub fn copy_out_of_prior(&self, z: usize, mean: &mut [f32], g: &mut [f32]) -> bool {
        let m = self.dims.m;
        if self.out_of_prior_threshold().is_none() {
            return false;
        }
        assert!(z < self.dims.zones && mean.len() == m - 1 && g.len() == m * (m - 1) / 2);
        let off = self.lay.out_of_prior + 4 * z * out_of_prior_len(m);
        for (k, o) in mean.iter_mut().chain(g.iter_mut()).enumerate() {
            *o = get_f32(self.bytes, off + 4 * k);
        }
        true
    }
}

fn put_u16(b: &mut [u8], off: usize, v: u16) {
    b[off..off + 2].copy_from_slice(&v.to_le_bytes());
}
fn put_u32(b: &mut [u8], off: usize, v: u32) {
    b[off..off + 4].copy_from_slice(&v.to_le_bytes());
}
fn put_f32(b: &mut [u8], off: usize, v: f32) {
    put_u32(b, off, v.to_bits());
}
fn get_u16(b: &[u8], off: usize) -> u16 {
    u16::from_le_bytes([b[off], b[off + 1]])
}
fn get_u32(b: &[u8], off: usize) -> u32 {
    u32::from_le_bytes([b[off], b[off + 1], b[off + 2], b[off + 3]])
}
fn get_f32(b: &[u8], off: usize) -> f32 {
    f32::from_bits(get_u32(b, off))
}

#[cfg(test)]
mod tests {
    use super::*;

    // The one test-blob builder's owned parts, changed one at a time below.
    use crate::test_blobs::TestBlobParts as Owned;

    fn sample(n: usize, m: usize, zones: usize, pixels: usize) -> Owned {
        Owned::new(n, m, zones, pixels, 0.0)
    }

    fn contents(o: &Owned) -> BlobContents<'_> {
        o.contents()
    }

    fn encode(o: &Owned) -> Vec<u8> {
        let buf = o.encode();
        assert_eq!(buf.len(), o.dims.blob_len());
        buf
    }

    #[test]
    fn round_trip_preserves_every_field() {
        let o = sample(9, 7, 3, 16);
        let buf = encode(&o);
        let v = BlobView::parse(&buf).unwrap();
        assert_eq!(v.dims(), o.dims);
        assert_eq!(v.noise_rel(), 0.02);
        assert_eq!(v.estimator(), EstimatorKind::Wiener);
        assert!(!v.far_field());
        assert_eq!(v.summary(), contents(&o).summary);
        assert_eq!(v.led_order(), &o.order[..]);
        for i in 0..9 {
            assert_eq!(v.grid_deg(i), o.grid[i]);
        }
        for z in 0..3 {
            assert_eq!(v.zone_start(z), o.zones[z]);
            let mut w = vec![0.0; 63];
            v.copy_matrix(z, &mut w);
            assert_eq!(w, o.mats[z * 63..(z + 1) * 63]);
            assert_eq!(v.w(z, 4, 2), o.mats[z * 63 + 4 * 7 + 2]);
            assert_eq!(v.uncertainty(z, 5), o.unc[z * 9 + 5]);
        }
        assert_eq!(v.white(15, 6), o.white[15 * 7 + 6]);
        assert_eq!(v.zone_of_pixel(0), 0);
        assert_eq!(v.zone_of_pixel(4), 0);
        assert_eq!(v.zone_of_pixel(5), 1);
        assert_eq!(v.zone_of_pixel(15), 2);
    }

    #[test]
    fn trailing_erased_flash_is_ignored() {
        let o = sample(4, 3, 1, 2);
        let mut buf = encode(&o);
        let len = buf.len();
        buf.extend_from_slice(&[0xFF; 37]);
        assert_eq!(BlobView::parse(&buf).unwrap().as_bytes().len(), len);
    }

    #[test]
    fn every_single_byte_corruption_is_rejected() {
        let o = sample(6, 4, 2, 5);
        let buf = encode(&o);
        for pos in 0..buf.len() {
            for flip in [0x01u8, 0x80, 0xFF, 0x5A] {
                let mut bad = buf.clone();
                bad[pos] ^= flip;
                assert!(BlobView::parse(&bad).is_err(), "corruption at byte {pos} (xor {flip:#x}) accepted");
            }
        }
    }

    #[test]
    fn every_truncation_is_rejected() {
        let o = sample(5, 3, 2, 4);
        let buf = encode(&o);
        for len in 0..buf.len() {
            assert!(BlobView::parse(&buf[..len]).is_err(), "truncation to {len} accepted");
        }
    }

    #[test]
    fn semantic_errors_are_refused_even_with_a_good_crc() {
        let mut o = sample(4, 3, 2, 4);
        o.grid[2] = o.grid[1];
        let mut buf = vec![0u8; o.dims.blob_len()];
        assert_eq!(write_blob(&contents(&o), &mut buf), Err(BlobError::GridNotAscending { index: 2 }));
        let mut o = sample(4, 3, 2, 4);
        o.order[1] = o.order[0];
        assert_eq!(write_blob(&contents(&o), &mut buf), Err(BlobError::BadLedOrder { index: 1 }));
        let mut o = sample(4, 3, 2, 4);
        o.mats[7] = f32::NAN;
        assert_eq!(
            write_blob(&contents(&o), &mut buf),
            Err(BlobError::NonFinite { section: Section::Matrices, index: 7 })
        );
        let mut o = sample(4, 3, 2, 4);
        o.zones[1] = 9;
        assert_eq!(write_blob(&contents(&o), &mut buf), Err(BlobError::BadZoneMap { index: 1 }));
        let mut o = sample(4, 3, 2, 4);
        o.white[0] = 0.0;
        assert_eq!(
            write_blob(&contents(&o), &mut buf),
            Err(BlobError::OutOfRange { section: Section::White, index: 0 })
        );
    }

    #[test]
    fn content_of_the_wrong_size_is_refused() {
        let o = sample(4, 3, 2, 4);
        let mut c = contents(&o);
        c.matrices = &o.mats[1..];
        let mut buf = vec![0u8; o.dims.blob_len()];
        assert_eq!(write_blob(&c, &mut buf), Err(BlobError::ContentMismatch { section: Section::Matrices }));
        let mut small = vec![0u8; 10];
        assert_eq!(write_blob(&contents(&o), &mut small), Err(BlobError::BufferTooSmall { need: o.dims.blob_len() }));
    }

    #[test]
    fn in_place_matrix_matches_copy_when_aligned() {
        let o = sample(8, 7, 2, 4);
        let buf = encode(&o);
        // Copy into an f32-aligned buffer.
        let mut aligned = vec![0u32; buf.len() / 4];
        bytemuck::cast_slice_mut::<u32, u8>(&mut aligned).copy_from_slice(&buf);
        let v = BlobView::parse(bytemuck::cast_slice(&aligned)).unwrap();
        let w = v.matrix_in_place(1).unwrap();
        assert_eq!(w, &o.mats[56..112]);
    }

    /// `b` edited by `edit`, its CRC set again, parsed.
    fn resealed(mut b: Vec<u8>, edit: &dyn Fn(&mut Vec<u8>)) -> Result<(), BlobError> {
        edit(&mut b);
        let at = b.len() - 4;
        let crc = CRC32.checksum(&b[..at]);
        put_u32(&mut b, at, crc);
        BlobView::parse(&b).map(|_| ())
    }

    /// A piecewise blob (K = 3) with the out-of-prior section in `form`
    /// and `band_factor`.
    fn out_of_prior_blob(form: OutOfPriorForm, band_factor: f32) -> Vec<u8> {
        let o = sample(6, 4, 2, 5);
        let (unc, mats, cents, oop) = v2_extras(&o, 3);
        let mut c = contents(&o);
        c.estimator = EstimatorKind::ScaleFreePiecewise;
        c.uncertainty = &unc;
        c.matrices = &mats;
        let ex = BlobExtras {
            clusters: 3,
            centroids: &cents,
            out_of_prior: Some(OutOfPriorData { threshold: 12.5, form, data: &oop, band_factor }),
            ..BlobExtras::NONE
        };
        let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
        assert_eq!(write_blob_with(&c, &ex, &mut buf), Ok(buf.len()));
        buf
    }

    /// The same sample as [`out_of_prior_blob`], scale-free without the section.
    fn bare_scale_free_blob() -> Vec<u8> {
        let o = sample(6, 4, 2, 5);
        let mut bare = vec![0u8; o.dims.blob_len()];
        let mut cs = contents(&o);
        cs.estimator = EstimatorKind::ScaleFree;
        write_blob(&cs, &mut bare).unwrap();
        bare
    }

    fn v2_extras(o: &Owned, k: usize) -> (Vec<f32>, Vec<f32>, Vec<f32>, Vec<f32>) {
        let d = o.dims;
        let unc = (0..d.zones * k * d.n).map(|x| 0.001 * x as f32).collect();
        let mats = (0..d.zones * k * d.n * d.m).map(|x| (x as f32).cos()).collect();
        let cents = (0..d.zones * k * d.m).map(|x| 0.1 * x as f32).collect();
        let oop = (0..d.zones * out_of_prior_len(d.m)).map(|x| 1.0 + x as f32).collect();
        (unc, mats, cents, oop)
    }

    #[test]
    fn version_2_round_trips_piecewise_matrices_centroids_and_out_of_prior_data() {
        let o = sample(6, 4, 2, 5);
        let (unc, mats, cents, oop) = v2_extras(&o, 3);
        let buf = out_of_prior_blob(OutOfPriorForm::Linear, 1.0);
        let v = BlobView::parse(&buf).unwrap();
        assert_eq!((v.version(), v.clusters(), v.estimator()), (2, 3, EstimatorKind::ScaleFreePiecewise));
        assert_eq!(v.out_of_prior_threshold(), Some(12.5));
        let mut w = vec![0.0; 24];
        v.copy_matrix_of(1, 2, &mut w);
        assert_eq!(w, mats[(3 + 2) * 24..(3 + 3) * 24]);
        assert_eq!(v.uncertainty_of(1, 2, 5), unc[(3 + 2) * 6 + 5]);
        let mut ce = vec![0.0; 12];
        v.copy_centroids(1, &mut ce);
        assert_eq!(ce, cents[12..24]);
        let (mut mean, mut g) = (vec![0.0; 3], vec![0.0; 6]);
        assert!(v.copy_out_of_prior(1, &mut mean, &mut g));
        assert_eq!(mean, oop[9..12]);
        assert_eq!(g, oop[12..18]);
        for pos in 0..buf.len() {
            let mut bad = buf.clone();
            bad[pos] ^= 0x5A;
            assert!(BlobView::parse(&bad).is_err(), "corruption at byte {pos} accepted");
        }
        // Scale-free with one matrix per zone and no out-of-prior data.
        let buf = bare_scale_free_blob();
        let v = BlobView::parse(&buf).unwrap();
        assert_eq!((v.version(), v.clusters(), v.out_of_prior_threshold()), (2, 1, None));
        assert!(!v.copy_out_of_prior(0, &mut mean, &mut g));
        assert_eq!(v.out_of_prior_form(), None);
    }

    #[test]
    fn the_log_ratio_form_is_flag_bit_4_and_only_with_the_section() {
        let linear = out_of_prior_blob(OutOfPriorForm::Linear, 1.0);
        let log_ratio = out_of_prior_blob(OutOfPriorForm::LogRatio, 1.0);
        // The same bytes but the flag (and so the CRC).
        let differ: Vec<usize> = (0..linear.len()).filter(|i| linear[*i] != log_ratio[*i]).collect();
        assert!(differ.iter().all(|i| *i == 22 || *i >= linear.len() - 4), "{differ:?}");
        assert_eq!(get_u16(&log_ratio, 22) & !get_u16(&linear, 22), FLAG_LOG_RATIO);
        assert_eq!(BlobView::parse(&linear).unwrap().out_of_prior_form(), Some(OutOfPriorForm::Linear));
        assert_eq!(BlobView::parse(&log_ratio).unwrap().out_of_prior_form(), Some(OutOfPriorForm::LogRatio));
        // The form bit without the section is refused, with a good CRC.
        let bare = bare_scale_free_blob();
        let flags = get_u16(&bare, 22) | FLAG_LOG_RATIO;
        assert_eq!(resealed(bare, &|b| put_u16(b, 22, flags)), Err(BlobError::ReservedNotZero));
    }

    #[test]
    fn the_band_factor_is_flag_bit_5_at_offset_56_and_only_with_the_section() {
        let none = out_of_prior_blob(OutOfPriorForm::LogRatio, 1.0);
        let wide = out_of_prior_blob(OutOfPriorForm::LogRatio, 2.5);
        // A factor of 1 writes the blob as before: no flag, offset 56 zero.
        assert_eq!((get_u16(&none, 22) & FLAG_BAND_FACTOR, get_u32(&none, 56)), (0, 0));
        assert_eq!(BlobView::parse(&none).unwrap().out_of_prior_band_factor(), 1.0);
        // Otherwise the flag and the value, and nothing else but the CRC.
        let differ: Vec<usize> = (0..none.len()).filter(|i| none[*i] != wide[*i]).collect();
        assert!(differ.iter().all(|i| *i == 22 || (56..60).contains(i) || *i >= none.len() - 4), "{differ:?}");
        assert_eq!(get_u16(&wide, 22) & !get_u16(&none, 22), FLAG_BAND_FACTOR);
        assert_eq!(BlobView::parse(&wide).unwrap().out_of_prior_band_factor(), 2.5);
        // A factor below 1 or not finite is refused, with a good CRC.
        let bad = |x: f32| resealed(wide.clone(), &|b| put_f32(b, 56, x));
        assert_eq!(bad(0.5), Err(BlobError::OutOfRange { section: Section::Header, index: 56 }));
        assert_eq!(bad(f32::NAN), Err(BlobError::NonFinite { section: Section::Header, index: 56 }));
        assert_eq!(bad(1.0), Ok(()));
        // A value without the flag, or the flag without the section, is refused.
        assert_eq!(resealed(none, &|b| put_f32(b, 56, 2.0)), Err(BlobError::ReservedNotZero));
        let bare = bare_scale_free_blob();
        let flags = get_u16(&bare, 22) | FLAG_BAND_FACTOR;
        assert_eq!(resealed(bare, &|b| put_u16(b, 22, flags)), Err(BlobError::ReservedNotZero));
    }

    #[test]
    fn the_peak_resolution_is_flag_bit_6_at_offset_60_and_is_checked() {
        let o = sample(6, 4, 2, 5);
        let with = |r: Option<f32>| {
            let ex = BlobExtras { peak_resolution_deg: r, ..BlobExtras::NONE };
            let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
            write_blob_with(&contents(&o), &ex, &mut buf).map(|n| {
                buf.truncate(n);
                buf
            })
        };
        // None writes version 1 as before; a value writes version 2, the
        // flag and the value, and it reads back.
        let (bare, res) = (with(None).unwrap(), with(Some(0.75)).unwrap());
        assert_eq!(
            (get_u16(&bare, 4), BlobView::parse(&bare).unwrap().peak_resolution_deg()),
            (FORMAT_VERSION_1, None)
        );
        assert_eq!(get_u16(&res, 4), FORMAT_VERSION_2);
        assert_eq!(get_u16(&res, 22) & FLAG_PEAK_RESOLUTION, FLAG_PEAK_RESOLUTION);
        assert_eq!(BlobView::parse(&res).unwrap().peak_resolution_deg(), Some(0.75));
        // The writer refuses what the parser would.
        assert_eq!(with(Some(0.0)), Err(BlobError::OutOfRange { section: Section::Header, index: 60 }));
        assert_eq!(with(Some(f32::NAN)), Err(BlobError::NonFinite { section: Section::Header, index: 60 }));
        // So does the parser, with a good CRC: a bad value, a value without
        // the flag, the flag in a version 1 blob.
        let bad = |x: f32| resealed(res.clone(), &|b| put_f32(b, 60, x));
        assert_eq!(bad(-1.0), Err(BlobError::OutOfRange { section: Section::Header, index: 60 }));
        assert_eq!(bad(f32::INFINITY), Err(BlobError::NonFinite { section: Section::Header, index: 60 }));
        let flags = get_u16(&res, 22) & !FLAG_PEAK_RESOLUTION;
        assert_eq!(resealed(res.clone(), &|b| put_u16(b, 22, flags)), Err(BlobError::ReservedNotZero));
        let v1_flags = get_u16(&bare, 22) | FLAG_PEAK_RESOLUTION;
        assert_eq!(resealed(bare, &|b| put_u16(b, 22, v1_flags)), Err(BlobError::ReservedNotZero));
    }

    #[test]
    fn each_pixels_peak_resolution_is_flag_bit_7_after_the_last_section_and_is_checked() {
        let o = sample(6, 4, 2, 5);
        let with = |widest: Option<f32>, own: &[f32]| {
            let ex = BlobExtras { peak_resolution_deg: widest, pixel_peak_resolution_deg: own, ..BlobExtras::NONE };
            let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
            write_blob_with(&contents(&o), &ex, &mut buf).map(|n| {
                buf.truncate(n);
                buf
            })
        };
        let own = [0.5, f32::NAN, 0.75, 0.6, 0.7];
        let (bare, res) = (with(Some(0.75), &[]).unwrap(), with(Some(0.75), &own).unwrap());
        // The section is P values just before the CRC; nothing before it moves.
        assert_eq!(res.len(), bare.len() + 4 * 5);
        assert_eq!(res[64..bare.len() - 4], bare[64..bare.len() - 4]);
        assert_eq!(get_u16(&res, 22) & FLAG_PIXEL_RESOLUTION, FLAG_PIXEL_RESOLUTION);
        let v = BlobView::parse(&res).unwrap();
        // A pixel without its own (NaN) and one past the line take the header's.
        let at: Vec<Option<f32>> = (0..6).map(|p| v.peak_resolution_at(p)).collect();
        assert_eq!(at, [Some(0.5), Some(0.75), Some(0.75), Some(0.6), Some(0.7), Some(0.75)]);
        let b = BlobView::parse(&bare).unwrap();
        assert!((0..5).all(|p| b.peak_resolution_at(p) == Some(0.75)));
        // The writer refuses what the parser would: a width wider than the
        // calibration's, zero, infinite, the wrong count, no header value.
        let oor = |p| BlobError::OutOfRange { section: Section::PeakResolution, index: p };
        assert_eq!(with(Some(0.75), &[0.5, 0.5, 0.8, 0.5, 0.5]), Err(oor(2)));
        assert_eq!(with(Some(0.75), &[0.5, 0.0, 0.5, 0.5, 0.5]), Err(oor(1)));
        assert_eq!(
            with(Some(0.75), &[0.5, 0.5, 0.5, f32::INFINITY, 0.5]),
            Err(BlobError::NonFinite { section: Section::PeakResolution, index: 3 })
        );
        let mismatch = Err(BlobError::ContentMismatch { section: Section::PeakResolution });
        assert_eq!(with(Some(0.75), &own[..4]), mismatch);
        assert_eq!(with(None, &own), mismatch);
        // So does the parser, with a good CRC: a bad value, the section's
        // flag without the header's.
        let at_p = |p: usize| res.len() - 4 - 4 * (5 - p);
        assert_eq!(resealed(res.clone(), &|b| put_f32(b, at_p(4), 0.9)), Err(oor(4)));
        assert_eq!(resealed(res.clone(), &|b| put_f32(b, at_p(0), -0.1)), Err(oor(0)));
        let flags = get_u16(&res, 22) & !FLAG_PEAK_RESOLUTION;
        assert_eq!(
            resealed(res.clone(), &|b| {
                put_u16(b, 22, flags);
                put_f32(b, 60, 0.0)
            }),
            Err(BlobError::ReservedNotZero)
        );
    }

    #[test]
    fn the_second_uncertainty_table_is_flag_bit_8_before_the_crc_and_is_checked() {
        use crate::band::BandTable;
        let o = sample(6, 4, 2, 5);
        let broad: Vec<f32> = (0..12).map(|i| 0.01 * i as f32).collect();
        let with = |table: &[f32]| {
            let ex = BlobExtras { broad_uncertainty: table, ..BlobExtras::NONE };
            let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
            write_blob_with(&contents(&o), &ex, &mut buf).map(|n| {
                buf.truncate(n);
                buf
            })
        };
        let (bare, two) = (with(&[]).unwrap(), with(&broad).unwrap());
        // Version 2, the flag, Z x K x n values just before the CRC; nothing
        // before them moves.
        assert_eq!((get_u16(&bare, 4), get_u16(&two, 4)), (FORMAT_VERSION_1, FORMAT_VERSION_2));
        assert_eq!(get_u16(&two, 22) & FLAG_BROAD_BAND, FLAG_BROAD_BAND);
        assert_eq!(two.len(), bare.len() + 4 * 12);
        assert_eq!(two[64..bare.len() - 4], bare[64..bare.len() - 4]);
        let (v, b) = (BlobView::parse(&two).unwrap(), BlobView::parse(&bare).unwrap());
        assert!(v.has_broad_band() && !b.has_broad_band());
        // A broad point takes the second table, a sharp one the first; a
        // blob without the second gives every point the first.
        assert_eq!(v.uncertainty_in(BandTable::Broad, 1, 0, 2), broad[6 + 2]);
        assert_eq!(v.uncertainty_in(BandTable::Sharp, 1, 0, 2), v.uncertainty_of(1, 0, 2));
        assert_eq!(b.uncertainty_in(BandTable::Broad, 1, 0, 2), b.uncertainty_of(1, 0, 2));
        assert_eq!(v.point_uncertainty(BandTable::Broad, (1, 0), 2, 0.5, -3.0), 3.0 * broad[8]);
        // Bins 1 deg apart: a flat estimate is broad, a one-bin spike sharp.
        let grid: Vec<f32> = (0..6).map(|i| 40.0 + i as f32).collect();
        let flat = [1.0f32; 6];
        let spike = [0.0f32, 0.0, 1.0, 0.0, 0.0, 0.0];
        assert_eq!(v.band_table(&grid, &flat), BandTable::Broad);
        assert_eq!(v.band_table(&grid, &spike), BandTable::Sharp);
        assert_eq!(b.band_table(&grid, &flat), BandTable::Sharp);
        // The writer refuses the wrong count; the parser, with a good CRC,
        // a negative or non-finite value, indexed on from the first table.
        assert_eq!(with(&broad[..11]), Err(BlobError::ContentMismatch { section: Section::Uncertainty }));
        let at = |i: usize| two.len() - 4 - 4 * (12 - i);
        assert_eq!(
            resealed(two.clone(), &|b| put_f32(b, at(3), -0.5)),
            Err(BlobError::OutOfRange { section: Section::Uncertainty, index: 12 + 3 })
        );
        assert_eq!(
            resealed(two.clone(), &|b| put_f32(b, at(0), f32::NAN)),
            Err(BlobError::NonFinite { section: Section::Uncertainty, index: 12 })
        );
        // The flag without its table is a length mismatch; in a version 1
        // blob, a reserved flag.
        let flags = get_u16(&two, 22) & !FLAG_BROAD_BAND;
        assert!(matches!(resealed(two.clone(), &|b| put_u16(b, 22, flags)), Err(BlobError::LengthMismatch { .. })));
        let v1_flags = get_u16(&bare, 22) | FLAG_BROAD_BAND;
        assert_eq!(resealed(bare, &|b| put_u16(b, 22, v1_flags)), Err(BlobError::ReservedNotZero));
    }

    #[test]
    fn version_1_is_still_written_and_read_as_before_and_v2_rules_hold() {
        let o = sample(6, 4, 2, 5);
        let buf = encode(&o);
        assert_eq!(get_u16(&buf, 4), FORMAT_VERSION_1);
        assert_eq!(BlobView::parse(&buf).unwrap().version(), 1);
        // A version 1 blob cannot carry a scale-free kind.
        let mut bad = buf.clone();
        put_u16(&mut bad, 20, EstimatorKind::ScaleFree as u16);
        let crc_at = bad.len() - 4;
        let crc = CRC32.checksum(&bad[..crc_at]);
        put_u32(&mut bad, crc_at, crc);
        assert_eq!(BlobView::parse(&bad).unwrap_err(), BlobError::UnknownEstimator(6));
        // Piecewise needs K >= 2; other kinds K = 1.
        let (unc, mats, cents, _) = v2_extras(&o, 1);
        let mut c = contents(&o);
        c.estimator = EstimatorKind::ScaleFreePiecewise;
        c.uncertainty = &unc;
        c.matrices = &mats;
        let ex = BlobExtras { clusters: 1, centroids: &cents, out_of_prior: None, ..BlobExtras::NONE };
        let mut out = vec![0u8; 4096];
        assert!(matches!(write_blob_with(&c, &ex, &mut out), Err(BlobError::BadDimension { field: "clusters", .. })));
        // The threshold must be positive.
        let oop = vec![0.5; 2 * out_of_prior_len(4)];
        let c = contents(&o);
        let ex = BlobExtras {
            clusters: 1,
            centroids: &[],
            out_of_prior: Some(OutOfPriorData {
                threshold: 0.0,
                form: OutOfPriorForm::Linear,
                data: &oop,
                band_factor: 1.0,
            }),
            ..BlobExtras::NONE
        };
        assert_eq!(
            write_blob_with(&c, &ex, &mut out),
            Err(BlobError::OutOfRange { section: Section::OutOfPrior, index: 0 })
        );
        let ex = BlobExtras {
            clusters: 1,
            centroids: &[],
            out_of_prior: Some(OutOfPriorData {
                threshold: 3.0,
                form: OutOfPriorForm::Linear,
                data: &oop[1..],
                band_factor: 1.0,
            }),
            ..BlobExtras::NONE
        };
        assert_eq!(
            write_blob_with(&c, &ex, &mut out),
            Err(BlobError::ContentMismatch { section: Section::OutOfPrior })
        );
    }

    #[test]
    fn a_zone_without_a_gloss_reading_is_all_nan_and_nothing_else_is() {
        let o = sample(6, 4, 3, 5);
        let (unc, mats, cents, oop) = v2_extras(&o, 2);
        let (mut reference, mut blocks) = gloss_parts(&o, 2);
        let bl = crate::gloss::block_len(4);
        // Zone 1 cannot see the standard.
        reference[1] = f32::NAN;
        blocks[2 * bl..4 * bl].fill(f32::NAN);
        let mut c = contents(&o);
        c.estimator = EstimatorKind::ScaleFreePiecewise;
        c.uncertainty = &unc;
        c.matrices = &mats;
        let g = gloss_data(&reference, &blocks, &[]);
        let ex = BlobExtras {
            clusters: 2,
            centroids: &cents,
            out_of_prior: Some(OutOfPriorData {
                threshold: 2.0,
                form: OutOfPriorForm::Linear,
                data: &oop,
                band_factor: 1.0,
            }),
            gloss: Some(g),
            ..BlobExtras::NONE
        };
        let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
        write_blob_with(&c, &ex, &mut buf).unwrap();
        let v = BlobView::parse(&buf).unwrap();
        let mut block = vec![0.0; bl];
        let (_, _, s) = v.copy_gloss(1, 1, &mut block).unwrap();
        assert!(s.is_nan() && block.iter().all(|x| x.is_nan()));
        assert_eq!(v.copy_gloss(2, 0, &mut block), Some((100.0, 1.567, 82.0)));
        assert!(block.iter().all(|x| x.is_finite()));
        let lay = o.dims.layout_with(&Extras::of(&ex, EstimatorKind::ScaleFreePiecewise, &o.dims));
        let resealed = |f: &dyn Fn(&mut Vec<u8>)| {
            let mut b = buf.clone();
            f(&mut b);
            let at = b.len() - 4;
            let crc = CRC32.checksum(&b[..at]);
            put_u32(&mut b, at, crc);
            BlobView::parse(&b).map(|_| ())
        };
        let head = 2 + 3;
        // A finite value in the marked zone's blocks, a NaN in another zone's,
        // a NaN reference over finite blocks: all refused.
        let in_zone1 = head + 2 * bl + 7;
        assert_eq!(
            resealed(&|b| put_f32(b, lay.gloss + 4 * in_zone1, 0.5)),
            Err(BlobError::OutOfRange { section: Section::Gloss, index: in_zone1 })
        );
        let in_zone2 = head + 4 * bl + 3;
        assert_eq!(
            resealed(&|b| put_f32(b, lay.gloss + 4 * in_zone2, f32::NAN)),
            Err(BlobError::NonFinite { section: Section::Gloss, index: in_zone2 })
        );
        assert_eq!(
            resealed(&|b| put_f32(b, lay.gloss + 4 * 2, f32::NAN)),
            Err(BlobError::NonFinite { section: Section::Gloss, index: 2 })
        );
        // The assigned value is never NaN.
        assert_eq!(
            resealed(&|b| put_f32(b, lay.gloss, f32::NAN)),
            Err(BlobError::NonFinite { section: Section::Gloss, index: 0 })
        );
    }

    /// A gloss section on the black glass (100 GU, n = 1.567).
    fn gloss_data<'a>(reference: &'a [f32], blocks: &'a [f32], centroids: &'a [f32]) -> GlossData<'a> {
        GlossData {
            assigned_gu: 100.0,
            refractive_index: 1.567,
            reference,
            blocks,
            centroids,
            root_readings: crate::gloss::RootReadings::Shoulders,
        }
    }

    /// A version 3 blob's gloss section for `o` with K clusters.
    fn gloss_parts(o: &Owned, k: usize) -> (Vec<f32>, Vec<f32>) {
        let d = o.dims;
        let reference = (0..d.zones).map(|z| 80.0 + z as f32).collect();
        let bl = crate::gloss::block_len(d.m);
        let blocks = (0..d.zones * k * bl)
            .map(|i| if (i % bl) >= crate::gloss::LINEAR * d.m { 0.25 } else { (i as f32 * 0.3).sin() })
            .collect();
        (reference, blocks)
    }

    /// A piecewise blob (K = 3) with a version 4 gloss section whose rows
    /// have `kg` clusters of their own (`kg = 0`: the maps').
    fn gloss_clusters_blob(kg: usize, centroids: &[f32]) -> Result<Vec<u8>, BlobError> {
        gloss_clusters_blob_of(EstimatorKind::ScaleFreePiecewise, kg, centroids)
    }

    /// [`gloss_clusters_blob`] labelled as estimator `kind`.
    fn gloss_clusters_blob_of(kind: EstimatorKind, kg: usize, centroids: &[f32]) -> Result<Vec<u8>, BlobError> {
        gloss_blob(kind, kg, centroids, false, crate::gloss::RootReadings::Shoulders)
    }

    /// A K = 3 blob of estimator `kind` with a version 4 gloss section whose
    /// rows have `kg` clusters of their own (`kg = 0`: the maps'), in the
    /// root form or not, its rows read in `form`.
    fn gloss_blob(
        kind: EstimatorKind,
        kg: usize,
        centroids: &[f32],
        root_form: bool,
        form: crate::gloss::RootReadings,
    ) -> Result<Vec<u8>, BlobError> {
        let o = sample(6, 4, 2, 5);
        let (unc, mats, cents, _) = v2_extras(&o, 3);
        let (_, blocks) = gloss_parts(&o, if kg == 0 { 3 } else { kg });
        let reference: Vec<f32> = (0..o.dims.pixels).map(|p| 90.0 + p as f32).collect();
        let mut c = contents(&o);
        c.estimator = kind;
        c.uncertainty = &unc;
        c.matrices = &mats;
        let g = GlossData { root_readings: form, ..gloss_data(&reference, &blocks, centroids) };
        let ex = BlobExtras { clusters: 3, centroids: &cents, gloss: Some(g), root_form, ..BlobExtras::NONE };
        let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
        write_blob_with(&c, &ex, &mut buf).map(|n| {
            buf.truncate(n);
            buf
        })
    }

    #[test]
    fn the_gloss_rows_own_clusters_are_flag_bit_9_with_k_g_at_offset_50_and_are_checked() {
        let (z, m, kg) = (2, 4, 5);
        // Each centroid a distinct point of the shares' simplex.
        let cents: Vec<f32> = (0..z * kg)
            .flat_map(|c| {
                let v: Vec<f32> = (0..m).map(|i| 1.0 + ((7 * c + 3 * i) % 11) as f32).collect();
                let s: f32 = v.iter().sum();
                v.into_iter().map(move |x| x / s)
            })
            .collect();
        let (maps, own) = (gloss_clusters_blob(0, &[]).unwrap(), gloss_clusters_blob(kg, &cents).unwrap());
        // Without the bit: K blocks per zone, offset 50 zero, a point's
        // block its BRDF cluster's.
        let v0 = BlobView::parse(&maps).unwrap();
        assert_eq!((v0.gloss_clusters(), v0.has_gloss_centroids(), get_u16(&maps, 50)), (3, false, 0));
        assert!(!v0.copy_gloss_centroids(1, &mut [0.0; 12]));
        // With it: K_g in the header, K_g blocks per zone, then the centroids.
        let v = BlobView::parse(&own).unwrap();
        assert_eq!(get_u16(&own, 22) & FLAG_GLOSS_CLUSTERS, FLAG_GLOSS_CLUSTERS);
        assert_eq!((v.gloss_clusters(), v.clusters(), get_u16(&own, 50)), (kg, 3, kg as u16));
        let bl = crate::gloss::block_len(m);
        assert_eq!(own.len(), maps.len() + 4 * (z * (kg - 3) * bl + z * kg * m));
        let mut got = vec![0.0; kg * m];
        assert!(v.copy_gloss_centroids(1, &mut got));
        assert_eq!(got, cents[kg * m..]);
        let (_, blocks) = gloss_parts(&sample(6, 4, 2, 5), kg);
        let mut block = vec![0.0; bl];
        v.copy_gloss(1, 4, &mut block).unwrap();
        assert_eq!(block, blocks[(kg + 4) * bl..(kg + 5) * bl]);
        // In place, a point's block is the one its readings select among its
        // zone's gloss centroids, whatever its BRDF cluster.
        let aligned: Vec<u32> = own.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect();
        let bytes: &[u8] = bytemuck::cast_slice(&aligned);
        let g = BlobView::parse(bytes).unwrap().gloss_in_place().unwrap();
        assert_eq!(g.centroids, &cents[..]);
        let near_3 = &cents[(kg + 3) * m..(kg + 4) * m];
        let pick = crate::kernel::select_cluster(&cents[kg * m..], near_3);
        assert_eq!(pick, 3);
        assert_eq!(g.block(1, 0, kg, near_3), &blocks[(kg + 3) * bl..(kg + 4) * bl]);
        // The writer refuses centroids that are not Z x K_g x m (one too
        // many: K_g still matches the blocks; one too few: it does not); a
        // count of 1 or over the limit; the rows' clusters without the
        // piecewise kind.
        let mismatch = Err(BlobError::ContentMismatch { section: Section::Gloss });
        let one_more: Vec<f32> = cents.iter().copied().chain([0.25]).collect();
        assert_eq!(gloss_clusters_blob(kg, &one_more), mismatch);
        assert_eq!(gloss_clusters_blob(kg, &cents[1..]), mismatch);
        assert!(matches!(
            gloss_clusters_blob(1, &cents[..z * m]),
            Err(BlobError::BadDimension { field: "gloss clusters", value: 1 })
        ));
        let over = MAX_CLUSTERS + 1;
        let many: Vec<f32> = (0..z * over * m).map(|i| 0.25 + (i % 7) as f32 * 0.01).collect();
        assert!(matches!(
            gloss_clusters_blob(over, &many),
            Err(BlobError::BadDimension { field: "gloss clusters", value }) if usize::from(value) == over
        ));
        assert!(matches!(
            gloss_clusters_blob_of(EstimatorKind::ScaleFree, kg, &cents),
            Err(BlobError::BadDimension { field: "gloss clusters", .. })
        ));
        // The parser: a non-finite centroid, K_g 0 or over the limit, the
        // bit on another kind, the bit without the gloss section, offset
        // 50 set without the bit.
        let first_centroid = own.len() - 4 - 4 * z * kg * m;
        assert_eq!(
            resealed(own.clone(), &|b| put_f32(b, first_centroid + 4, f32::INFINITY)),
            Err(BlobError::NonFinite { section: Section::Gloss, index: gloss_len(5, z, kg, m) + 1 })
        );
        assert_eq!(
            resealed(own.clone(), &|b| put_u16(b, 50, 0)),
            Err(BlobError::BadDimension { field: "gloss clusters", value: 0 })
        );
        assert_eq!(
            resealed(own.clone(), &|b| put_u16(b, 50, over as u16)),
            Err(BlobError::BadDimension { field: "gloss clusters", value: over as u16 })
        );
        let scale_free = EstimatorKind::ScaleFree as u16;
        assert_eq!(
            resealed(own.clone(), &|b| put_u16(b, 20, scale_free)),
            Err(BlobError::BadDimension { field: "gloss clusters", value: kg as u16 })
        );
        let bare = out_of_prior_blob(OutOfPriorForm::Linear, 1.0);
        let flags = get_u16(&bare, 22) | FLAG_GLOSS_CLUSTERS;
        assert!(matches!(
            resealed(bare.clone(), &|b| {
                put_u16(b, 22, flags);
                put_u16(b, 50, 4);
            }),
            Err(BlobError::BadDimension { field: "gloss clusters", .. })
        ));
        assert_eq!(resealed(maps, &|b| put_u16(b, 50, 4)), Err(BlobError::ReservedNotZero));
    }

    /// A piecewise blob with a version 4 gloss section (the maps'
    /// clusters), in the root form or not, its rows read in `form`.
    fn deficit_readings_blob(root_form: bool, form: crate::gloss::RootReadings) -> Result<Vec<u8>, BlobError> {
        gloss_blob(EstimatorKind::ScaleFreePiecewise, 0, &[], root_form, form)
    }

    #[test]
    fn the_deficit_readings_are_flag_bit_10_of_the_root_forms_gloss_rows() {
        use crate::gloss::RootReadings::{Deficit, Shoulders};
        let shoulders = deficit_readings_blob(true, Shoulders).unwrap();
        let deficit = deficit_readings_blob(true, Deficit).unwrap();
        // Same layout and values; only the flag differs (and the CRC).
        assert_eq!(shoulders.len(), deficit.len());
        assert_eq!(get_u16(&deficit, 22), get_u16(&shoulders, 22) | FLAG_DEFICIT_READINGS);
        assert_eq!(shoulders[24..shoulders.len() - 4], deficit[24..deficit.len() - 4]);
        // The view and the in-place section say which row the device reads.
        assert_eq!(BlobView::parse(&shoulders).unwrap().root_readings(), Shoulders);
        let v = BlobView::parse(&deficit).unwrap();
        assert_eq!(v.root_readings(), Deficit);
        let aligned: Vec<u32> = deficit.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect();
        let bytes: &[u8] = bytemuck::cast_slice(&aligned);
        assert_eq!(BlobView::parse(bytes).unwrap().gloss_in_place().unwrap().root_readings, Deficit);
        // The deficit is a root: the writer refuses it outside the root
        // form, and the parser refuses the bit there or without the gloss
        // section.
        assert_eq!(deficit_readings_blob(false, Deficit), Err(BlobError::ReservedNotZero));
        let linear = deficit_readings_blob(false, Shoulders).unwrap();
        let flags = get_u16(&linear, 22) | FLAG_DEFICIT_READINGS;
        assert_eq!(resealed(linear, &|b| put_u16(b, 22, flags)), Err(BlobError::ReservedNotZero));
        let bare = out_of_prior_blob(OutOfPriorForm::Linear, 1.0);
        let flags = get_u16(&bare, 22) | FLAG_ROOT | FLAG_DEFICIT_READINGS;
        assert_eq!(resealed(bare, &|b| put_u16(b, 22, flags)), Err(BlobError::ReservedNotZero));
    }

    #[test]
    fn the_sensors_linearity_is_flag_bit_11_and_its_factors_before_the_crc() {
        let o = sample(6, 4, 2, 5);
        let c = contents(&o);
        let factors: [f32; LINEARITY_KNOTS] = core::array::from_fn(|k| 1.04 - 0.0025 * k as f32);
        let lin = Linearity::new(factors).unwrap();
        let ex = BlobExtras { linearity: Some(lin), ..BlobExtras::NONE };
        let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
        assert_eq!(write_blob_with(&c, &ex, &mut buf), Ok(buf.len()));
        assert_eq!(buf.len(), o.dims.blob_len() + 4 * LINEARITY_KNOTS);
        let v = BlobView::parse(&buf).unwrap();
        // A version 1 blob's kind, but the flag needs version 2's header.
        assert_eq!((v.version(), get_u16(&buf, 22)), (FORMAT_VERSION_2, FLAG_LINEARITY));
        assert_eq!(v.linearity(), Some(lin));
        // Everything else reads as the blob without it (no second table).
        assert!(!v.has_broad_band());
        let plain = encode(&o);
        assert_eq!(BlobView::parse(&plain).unwrap().linearity(), None);
        assert_eq!(buf[64..plain.len() - 4], plain[64..plain.len() - 4]);
        // A factor out of range, not finite, or a falling response: refused,
        // naming the knot.
        let at = buf.len() - 4 - 4 * LINEARITY_KNOTS;
        let edit = |k: usize, x: f32| resealed(buf.clone(), &move |b| put_f32(b, at + 4 * k, x));
        let section = Section::Linearity;
        assert_eq!(edit(5, 9.0), Err(BlobError::OutOfRange { section, index: 5 }));
        assert_eq!(edit(16, f32::NAN), Err(BlobError::NonFinite { section, index: 16 }));
        assert_eq!(edit(9, 0.6), Err(BlobError::OutOfRange { section, index: 8 }));
        // The bit in a version 1 header is reserved.
        let flagged = resealed(plain, &|b| put_u16(b, 22, FLAG_LINEARITY));
        assert_eq!(flagged, Err(BlobError::ReservedNotZero));
    }

    #[test]
    fn the_peaks_uncertainty_factors_are_flag_bit_12_after_the_linearity() {
        let o = sample(6, 4, 2, 5);
        let c = contents(&o);
        let lin = Linearity::new([1.0; LINEARITY_KNOTS]).unwrap();
        let factors = PeakFactors { height: 1.25, width: 0.8 };
        let ex = BlobExtras {
            peak_resolution_deg: Some(0.9),
            linearity: Some(lin),
            peak_factors: Some(factors),
            ..BlobExtras::NONE
        };
        let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
        assert_eq!(write_blob_with(&c, &ex, &mut buf), Ok(buf.len()));
        assert_eq!(buf.len(), o.dims.blob_len() + 4 * LINEARITY_KNOTS + 8);
        let v = BlobView::parse(&buf).unwrap();
        assert_eq!(get_u16(&buf, 22), FLAG_PEAK_RESOLUTION | FLAG_LINEARITY | FLAG_PEAK_FACTORS);
        assert_eq!((v.peak_factors(), v.linearity()), (Some(factors), Some(lin)));
        assert_eq!(get_f32(&buf, buf.len() - 12), 1.25, "height, then width, just before the CRC");
        // Without them the blob reads as before.
        let without = BlobExtras { peak_factors: None, ..ex };
        let mut plain = vec![0u8; o.dims.blob_len_with(&without)];
        write_blob_with(&c, &without, &mut plain).unwrap();
        assert_eq!(BlobView::parse(&plain).unwrap().peak_factors(), None);
        assert_eq!(buf[64..plain.len() - 4], plain[64..plain.len() - 4]);
        // A factor not finite or not above zero: refused, naming it.
        let section = Section::PeakFactors;
        let at = buf.len() - 12;
        let edit = |k: usize, x: f32| resealed(buf.clone(), &move |b| put_f32(b, at + 4 * k, x));
        assert_eq!(edit(1, f32::INFINITY), Err(BlobError::NonFinite { section, index: 1 }));
        assert_eq!(edit(0, 0.0), Err(BlobError::OutOfRange { section, index: 0 }));
        // Only with the peak resolution they scale the peaks of: the writer
        // refuses them without it, and so does the parser.
        let alone = BlobExtras { peak_resolution_deg: None, ..ex };
        let mut out = vec![0u8; o.dims.blob_len_with(&alone)];
        assert_eq!(write_blob_with(&c, &alone, &mut out), Err(BlobError::ContentMismatch { section }));
        let flags = FLAG_LINEARITY | FLAG_PEAK_FACTORS;
        assert_eq!(
            resealed(buf.clone(), &move |b| {
                put_u16(b, 22, flags);
                put_u32(b, 60, 0);
            }),
            Err(BlobError::ReservedNotZero)
        );
    }

    #[test]
    fn version_4_carries_one_gloss_reference_per_pixel() {
        let o = sample(6, 4, 2, 5);
        let (_, blocks) = gloss_parts(&o, 1);
        let d = o.dims;
        let reference: Vec<f32> = (0..d.pixels).map(|p| 90.0 + p as f32).collect();
        let c = contents(&o);
        let g = gloss_data(&reference, &blocks, &[]);
        let ex = BlobExtras { gloss: Some(g), ..BlobExtras::NONE };
        let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
        assert_eq!(write_blob_with(&c, &ex, &mut buf), Ok(buf.len()));
        assert_eq!(buf.len(), o.dims.blob_len() + 4 * gloss_len(d.pixels, d.zones, 1, 4));
        let v = BlobView::parse(&buf).unwrap();
        assert_eq!(v.version(), 4);
        for p in 0..d.pixels {
            assert_eq!(v.gloss_reference(p), Some(90.0 + p as f32));
            assert_eq!(g.reference_for(p, v.zone_of_pixel(p), d.pixels), 90.0 + p as f32);
        }
        // copy_gloss gives the zone's first pixel's reference.
        let mut block = vec![0.0; crate::gloss::block_len(4)];
        assert_eq!(v.copy_gloss(1, 0, &mut block).unwrap().2, 90.0 + v.zone_start(1) as f32);
        // A zone without a reading: NaN at each of its pixels and in its blocks, or refused.
        let z1 = v.zone_start(1) as usize;
        let mut r2 = reference.clone();
        let mut b2 = blocks.clone();
        let bl = crate::gloss::block_len(4);
        r2[z1..].fill(f32::NAN);
        b2[bl..].fill(f32::NAN);
        let g2 = GlossData { reference: &r2, blocks: &b2, ..g };
        let ex2 = BlobExtras { gloss: Some(g2), ..BlobExtras::NONE };
        assert_eq!(write_blob_with(&c, &ex2, &mut buf), Ok(buf.len()));
        r2[z1] = 95.0;
        let g3 = GlossData { reference: &r2, blocks: &b2, ..g };
        let ex3 = BlobExtras { gloss: Some(g3), ..BlobExtras::NONE };
        assert!(write_blob_with(&c, &ex3, &mut buf).is_err(), "a reading pixel in a zone without a reading");
    }

    #[test]
    fn version_3_carries_the_gloss_section_and_its_rules_hold() {
        let o = sample(6, 4, 2, 5);
        let (reference, blocks) = gloss_parts(&o, 1);
        let c = contents(&o);
        let g = gloss_data(&reference, &blocks, &[]);
        let ex = BlobExtras { gloss: Some(g), ..BlobExtras::NONE };
        let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
        assert_eq!(write_blob_with(&c, &ex, &mut buf), Ok(buf.len()));
        assert_eq!(buf.len(), o.dims.blob_len() + 4 * gloss_len(2, 2, 1, 4));
        let v = BlobView::parse(&buf).unwrap();
        assert_eq!((v.version(), v.clusters(), v.estimator(), v.has_gloss()), (3, 1, EstimatorKind::Wiener, true));
        let mut block = vec![0.0; crate::gloss::block_len(4)];
        assert_eq!(v.copy_gloss(1, 0, &mut block), Some((100.0, 1.567, 81.0)));
        assert_eq!(block, blocks[block.len()..]);
        let mut aligned = vec![0u32; buf.len() / 4];
        bytemuck::cast_slice_mut::<u32, u8>(&mut aligned).copy_from_slice(&buf);
        let va = BlobView::parse(bytemuck::cast_slice(&aligned)).unwrap();
        assert_eq!(va.gloss_in_place(), Some(g));
        for pos in 0..buf.len() {
            let mut bad = buf.clone();
            bad[pos] ^= 0x5A;
            assert!(BlobView::parse(&bad).is_err(), "corruption at byte {pos} accepted");
        }
        // A blob without the section: as before, and no readings.
        let old = encode(&o);
        let vo = BlobView::parse(&old).unwrap();
        assert_eq!((vo.version(), vo.has_gloss(), vo.copy_gloss(0, 0, &mut block)), (1, false, None));
        // The flag bit and the version go together, with a good CRC.
        assert_eq!(resealed(buf.clone(), &|b| put_u16(b, 4, 2)), Err(BlobError::ReservedNotZero));
        assert_eq!(resealed(old.clone(), &|b| put_u16(b, 22, 4)), Err(BlobError::ReservedNotZero));
        assert_eq!(resealed(buf.clone(), &|b| put_u16(b, 4, 5)), Err(BlobError::UnsupportedVersion(5)));
        // Relabelled version 4, it would need one reference per pixel.
        assert!(matches!(resealed(buf.clone(), &|b| put_u16(b, 4, 4)), Err(BlobError::LengthMismatch { .. })));
        // Every malformed value is named by its index in the section.
        let lay = o.dims.layout_with(&Extras::of(&ex, EstimatorKind::Wiener, &o.dims));
        let bl = crate::gloss::block_len(4);
        let cov00 = 2 + 2 + 4 * 4;
        for (i, x, want) in [
            (0, 0.0, BlobError::OutOfRange { section: Section::Gloss, index: 0 }),
            (1, 1.0, BlobError::OutOfRange { section: Section::Gloss, index: 1 }),
            (3, -1.0, BlobError::OutOfRange { section: Section::Gloss, index: 3 }),
            (5, f32::NAN, BlobError::NonFinite { section: Section::Gloss, index: 5 }),
            (cov00 + bl, -0.5, BlobError::OutOfRange { section: Section::Gloss, index: cov00 + bl }),
        ] {
            assert_eq!(resealed(buf.clone(), &|b| put_f32(b, lay.gloss + 4 * i, x)), Err(want), "index {i}");
        }
        // An off-diagonal covariance and a row may be negative.
        assert_eq!(resealed(buf.clone(), &|b| put_f32(b, lay.gloss + 4 * (cov00 + 1), -0.5)), Ok(()));
        assert_eq!(resealed(buf.clone(), &|b| put_f32(b, lay.gloss + 4 * 4, -7.0)), Ok(()));
        // The writer checks the section's size.
        let short = GlossData { blocks: &blocks[1..], ..g };
        let ex = BlobExtras { gloss: Some(short), ..BlobExtras::NONE };
        assert_eq!(write_blob_with(&c, &ex, &mut buf), Err(BlobError::ContentMismatch { section: Section::Gloss }));
        // With K clusters (piecewise scale-free), blocks per zone and cluster.
        let (unc, mats, cents, oop) = v2_extras(&o, 3);
        let (reference, blocks) = gloss_parts(&o, 3);
        let mut c = contents(&o);
        c.estimator = EstimatorKind::ScaleFreePiecewise;
        c.uncertainty = &unc;
        c.matrices = &mats;
        let ex = BlobExtras {
            clusters: 3,
            centroids: &cents,
            out_of_prior: Some(OutOfPriorData {
                threshold: 2.0,
                form: OutOfPriorForm::Linear,
                data: &oop,
                band_factor: 1.0,
            }),
            gloss: Some(GlossData { reference: &reference, blocks: &blocks, ..g }),
            ..BlobExtras::NONE
        };
        let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
        write_blob_with(&c, &ex, &mut buf).unwrap();
        let v = BlobView::parse(&buf).unwrap();
        assert_eq!(v.copy_gloss(1, 2, &mut block), Some((100.0, 1.567, 81.0)));
        assert_eq!(block, blocks[5 * bl..6 * bl]);
        let (mut mean, mut gg) = (vec![0.0; 3], vec![0.0; 6]);
        assert!(v.copy_out_of_prior(1, &mut mean, &mut gg));
        assert_eq!(mean, oop[9..12]);
    }
}
