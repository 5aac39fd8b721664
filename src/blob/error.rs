//! What a refused blob says: where ([`Section`]) and what ([`BlobError`]), and
//! the checks on values that both the writer and the parser apply.

use super::*;
use core::fmt;

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
    /// The white reference's uncertainty (header flag bit 13).
    WhiteUncertainty,
    /// The gloss scale's uncertainty (header flag bit 14).
    GlossUncertainty,
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

/// A peak resolution must be a finite width above zero.
pub(super) fn check_peak_resolution(r: f32) -> Result<(), BlobError> {
    if !r.is_finite() {
        Err(BlobError::NonFinite { section: Section::Header, index: 60 })
    } else if r <= 0.0 {
        Err(BlobError::OutOfRange { section: Section::Header, index: 60 })
    } else {
        Ok(())
    }
}

/// The white reference's relative uncertainty: finite, 0 to
/// [`super::MAX_WHITE_UNCERTAINTY`].
pub(super) fn check_white_uncertainty(u: f32) -> Result<(), BlobError> {
    if !u.is_finite() {
        Err(BlobError::NonFinite { section: Section::WhiteUncertainty, index: 0 })
    } else if !(0.0..=super::MAX_WHITE_UNCERTAINTY).contains(&u) {
        Err(BlobError::OutOfRange { section: Section::WhiteUncertainty, index: 0 })
    } else {
        Ok(())
    }
}

/// The gloss scale's relative uncertainty: finite, 0 to
/// [`super::MAX_GLOSS_UNCERTAINTY`].
pub(super) fn check_gloss_uncertainty(u: f32) -> Result<(), BlobError> {
    if !u.is_finite() {
        Err(BlobError::NonFinite { section: Section::GlossUncertainty, index: 0 })
    } else if !(0.0..=super::MAX_GLOSS_UNCERTAINTY).contains(&u) {
        Err(BlobError::OutOfRange { section: Section::GlossUncertainty, index: 0 })
    } else {
        Ok(())
    }
}

/// A pixel's peak resolution: NaN (none of its own), or a finite width
/// above zero and at most the calibration's `widest`.
pub(super) fn check_pixel_resolution(r: f32, widest: f32, p: usize) -> Result<(), BlobError> {
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
