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
//! | 22 | 2 | flags: bit 0 far-field, bit 1 out-of-prior section present, bit 3 the root form (below), bit 4 the out-of-prior section is for the log-ratio statistic (with bit 1 only), bit 5 the header holds the out-of-prior band factor (with bit 1 only; below), bit 6 the header holds the peak resolution (below), bit 7 the per-pixel peak resolutions follow (with bit 6 only; below), bit 8 the second per-bin uncertainty table follows (below), bit 9 the gloss rows have clusters of their own (format version 3 and up, the piecewise kind only; below), bit 11 the sensor's linearity correction follows (below), bit 12 the specular peak's uncertainty factors follow (with bit 6 only; below), bit 13 the white reference's uncertainty follows (below), bit 14 the gloss scale's uncertainty follows (with the gloss section only; below) |
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
//! | 4 (bit 13 only) | the white reference's relative standard uncertainty (below) |
//! | 4 (bit 14 only) | the gloss scale's relative standard uncertainty (below) |
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
//! ## The white reference's uncertainty (flag bit 13)
//! A calibration standardised on a white tile (host-tools `standardise`,
//! [`with_white_uncertainty`]) carries its white reference's relative
//! standard uncertainty (k = 1): the tile certificate's and the scatter of
//! the tile's readings, in quadrature (finite, 0 to
//! [`MAX_WHITE_UNCERTAINTY`]). Every reading is divided by the white, so
//! every value the host states carries it as a relative term; the device
//! does not use it. A blob without the flag states none (its white is the
//! training's, exact in the model); firmware from before it rejects such a
//! blob as having a reserved flag set, and keeps its last good calibration.
//!
//! ## The gloss scale's uncertainty (flag bit 14)
//! A calibration standardised on a certified black-glass standard
//! (host-tools `standardise --black-glass-gu`: its gloss references
//! rescaled, [`rewrite_gloss_references`], within [`GLOSS_RATIO_RANGE`])
//! carries the gloss scale's relative standard uncertainty (k = 1): the
//! standard's certificate and the scatter of its readings, in quadrature
//! (finite, 0 to [`MAX_GLOSS_UNCERTAINTY`]; [`with_gloss_uncertainty`]).
//! The host adds it to the gloss and haze readings' uncertainties; the
//! device does not use it. Only a blob with the gloss section may carry
//! it; firmware from before it rejects such a blob as having a reserved
//! flag set, and keeps its last good calibration.
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
//!
//! # Where it lives
//! - this file: the format's constants, flags and the header's small types;
//! - `error`: [`BlobError`] and [`Section`], what a refused blob says;
//! - `layout`: [`Dims`] and the byte offsets they and the extras imply;
//! - `contents`: what a blob holds, borrowed, for the writer
//!   ([`BlobContents`], [`BlobExtras`]);
//! - `write`: [`write_blob`] and [`write_blob_with`];
//! - `white`: [`rewrite_white`] and [`with_white_uncertainty`], the white
//!   reference rewritten and its uncertainty stated (a standardisation);
//! - `gloss_scale`: [`rewrite_gloss_references`] and
//!   [`with_gloss_uncertainty`], the same for the gloss scale on the black
//!   glass;
//! - `stated`: what both write: values rewritten in place and the blob
//!   sealed again, and the trailing one-value sections, added or
//!   replaced;
//! - `parse`: [`BlobView::parse`], every check a blob must pass;
//! - `view`: [`BlobView`] and what the device and host read from it;
//! - `bytes`: little-endian field access.

mod bytes;
mod contents;
mod error;
mod gloss_scale;
mod layout;
mod parse;
mod stated;
#[cfg(test)]
mod tests;
mod view;
mod white;
mod write;

pub use contents::{BlobContents, BlobExtras, GlossData, OutOfPriorData};
pub use error::{BlobError, Section};
pub use gloss_scale::{GLOSS_RATIO_RANGE, MAX_GLOSS_UNCERTAINTY, rewrite_gloss_references, with_gloss_uncertainty};
pub use layout::{Dims, MAX_CLUSTERS, gloss_len, out_of_prior_len};
pub use view::BlobView;
pub use white::{MAX_WHITE_UNCERTAINTY, WHITE_RATIO_RANGE, rewrite_white, with_white_uncertainty};
pub use write::{write_blob, write_blob_with};

use bytes::{get_f32, get_u16, get_u32, put_f32, put_u16, put_u32};
use error::{check_gloss_uncertainty, check_peak_resolution, check_pixel_resolution, check_white_uncertainty};
use layout::{Extras, Layout};

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
/// Header flag bit 13: the white reference's relative standard uncertainty
/// follows (a standardisation's, host-tools `standardise`).
const FLAG_WHITE_UNCERTAINTY: u16 = 8192;
/// Header flag bit 14: the gloss scale's relative standard uncertainty
/// follows (a standardisation on the black glass; with `FLAG_GLOSS` only).
const FLAG_GLOSS_UNCERTAINTY: u16 = 16384;

/// What the host multiplies a resolved specular peak's first-order
/// standard uncertainties by (the module docs, flag bit 12): finite, > 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeakFactors {
    /// On the peak's height.
    pub height: f32,
    /// On its full width at half maximum.
    pub width: f32,
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
