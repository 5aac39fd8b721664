//! The errors that travel: why a frame could not be read ([`FrameError`])
//! and the typed error replies ([`DeviceError`], [`BlobFault`]).
use super::BlobSection;
use crate::blob::BlobError;
use crate::firmware::image::ImageFault;
use crate::hw::SensorError;
use crate::signed::SignatureFault;
use serde::{Deserialize, Serialize};

/// Why a frame could not be read.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// The COBS encoding is invalid.
    Cobs,
    /// More bytes than [`MAX_FRAME`](super::MAX_FRAME) before a delimiter.
    Oversized,
    /// Fewer bytes than the header declares (or than a header).
    Truncated {
        /// Payload length declared (0 if no header).
        declared: u16,
        /// Payload length received.
        got: u16,
    },
    /// The CRC does not match.
    BadCrc,
    /// A protocol version this side does not speak.
    UnsupportedVersion {
        /// Version found.
        got: u16,
    },
    /// The body is not a valid message (unknown variant, bad field, trailing bytes).
    Malformed,
    /// The message does not fit [`MAX_PAYLOAD`](super::MAX_PAYLOAD) (sender side).
    TooLarge,
}

/// Which build-time size a blob disagreed with.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SizeField {
    /// Angle bins n.
    Bins,
    /// LEDs m.
    Leds,
    /// Pixels P.
    Pixels,
}

/// A blob rejection, as it travels (mirrors [`BlobError`]).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BlobFault {
    /// Truncated.
    TooShort,
    /// Bad magic.
    BadMagic,
    /// Unsupported blob format version.
    UnsupportedVersion,
    /// Bad header length.
    BadHeaderLen,
    /// Bad dimension.
    BadDimension,
    /// Length mismatch.
    LengthMismatch,
    /// Internal CRC mismatch.
    CrcMismatch,
    /// Reserved bits set.
    ReservedNotZero,
    /// Unknown estimator.
    UnknownEstimator,
    /// NaN or infinity.
    NonFinite,
    /// Out of range value.
    OutOfRange,
    /// Grid not ascending.
    GridNotAscending,
    /// LED order not a permutation.
    BadLedOrder,
    /// Zone map invalid.
    BadZoneMap,
    /// Other.
    Other,
}

/// A typed error reply.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DeviceError {
    /// The request frame could not be read; the device discarded it.
    Frame(FrameError),
    /// A measurement needs a calibration and none is provisioned.
    NoCalibration,
    /// Refused while a measurement runs (stop it first).
    Busy,
    /// A provisioning request arrived with no provisioning in progress.
    NotProvisioning,
    /// A chunk arrived at the wrong offset; resend from `expected`.
    OutOfOrder {
        /// Offset the device expects.
        expected: u32,
        /// Offset received.
        got: u32,
    },
    /// A chunk is larger than [`MAX_CHUNK`](super::MAX_CHUNK) or runs past the declared length.
    ChunkTooLarge {
        /// Largest acceptable.
        max: u32,
    },
    /// The blob does not fit a calibration slot.
    BlobTooLarge {
        /// Declared length.
        len: u32,
        /// Largest a slot holds.
        max: u32,
    },
    /// Commit before all bytes arrived.
    Incomplete {
        /// Bytes received.
        received: u32,
        /// Bytes declared.
        len: u32,
    },
    /// The received blob's CRC differs from the one declared at begin.
    CrcMismatch {
        /// Declared at [`Request::ProvisionBegin`](super::Request::ProvisionBegin).
        declared: u32,
        /// Computed over the bytes stored in flash.
        computed: u32,
    },
    /// The blob is malformed.
    BlobRejected {
        /// Why.
        fault: BlobFault,
        /// Section concerned, when known.
        section: Option<BlobSection>,
        /// Index or value detail.
        detail: u32,
    },
    /// The blob is valid but made for another instrument build.
    Mismatch {
        /// Which size.
        field: SizeField,
        /// The device's.
        device: u16,
        /// The blob's.
        blob: u16,
    },
    /// The flash reported an error (the previous calibration is kept).
    Storage,
    /// The sensor failed.
    Sensor(SensorError),
    /// Simulation request on a device without a simulated sensor, or out of range.
    Simulation,
    /// The signature of a calibration, or of an inspection recipe (the two
    /// stores share the check), was refused (unsigned, malformed trailer,
    /// untrusted key, or a signature that does not verify); the previous
    /// one is kept. Its message names the calibration; the host, which
    /// knows it sent a recipe, says so (`inspect provision`).
    SignatureRejected(SignatureFault),
    /// A measurement's bin range is empty or beyond the device's n bins.
    BadBins {
        /// The device's bins n.
        bins: u16,
    },
    /// The firmware image was refused (unsigned, malformed, for another
    /// machine, not bootable, or its signature); the running firmware keeps
    /// running and nothing was marked for the bootloader.
    FirmwareRejected(ImageFault),
    /// An update request that cannot be served now (see [`UpdateFault`]).
    Update(UpdateFault),
    /// The calibration in flash is a blob format this firmware cannot read:
    /// it is kept, and nothing is measured with it.
    CalibrationUnsupported {
        /// The blob's format version.
        format: u16,
        /// The oldest format this firmware reads.
        oldest: u16,
        /// The newest format this firmware reads.
        newest: u16,
    },
    /// The inspection recipe was refused (malformed, another format, another
    /// device's shape); the previous recipe is kept.
    RecipeRejected(crate::inspect::RecipeFault),
    /// The recipe was taught with another calibration than the active one
    /// (`active` 0: none is active); the previous recipe is kept.
    RecipeForOtherCalibration {
        /// CRC of the calibration the recipe was taught with.
        recipe: u32,
        /// CRC of the active calibration.
        active: u32,
    },
    /// An inspection needs a recipe (for the active calibration) and none is.
    NoRecipe,
}

/// Why an update request cannot be served.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum UpdateFault {
    /// This build takes no updates over the link (no update partition).
    Unsupported,
    /// A chunk or commit with no update in progress (begin first).
    NotUpdating,
    /// The image does not fit the active image region.
    TooLarge {
        /// Declared length.
        len: u32,
        /// Largest image.
        max: u32,
    },
    /// The running image is itself on trial: it must pass its self-test and
    /// confirm before it takes another update.
    TrialNotConfirmed,
    /// An update is already committed: reset the device to start it.
    Pending,
}

impl From<SignatureFault> for DeviceError {
    fn from(e: SignatureFault) -> Self {
        DeviceError::SignatureRejected(e)
    }
}

impl From<BlobError> for DeviceError {
    fn from(e: BlobError) -> Self {
        let (fault, section, detail) = match e {
            BlobError::TooShort { got, .. } => (BlobFault::TooShort, None, got),
            BlobError::BadMagic => (BlobFault::BadMagic, None, 0),
            BlobError::UnsupportedVersion(v) => (BlobFault::UnsupportedVersion, None, v as usize),
            BlobError::BadHeaderLen(l) => (BlobFault::BadHeaderLen, None, l as usize),
            BlobError::BadDimension { value, .. } => (BlobFault::BadDimension, None, value as usize),
            BlobError::LengthMismatch { got, .. } => (BlobFault::LengthMismatch, None, got),
            BlobError::CrcMismatch { .. } => (BlobFault::CrcMismatch, None, 0),
            BlobError::ReservedNotZero => (BlobFault::ReservedNotZero, None, 0),
            BlobError::UnknownEstimator(c) => (BlobFault::UnknownEstimator, None, c as usize),
            BlobError::NonFinite { section, index } => (BlobFault::NonFinite, Some(section), index),
            BlobError::OutOfRange { section, index } => (BlobFault::OutOfRange, Some(section), index),
            BlobError::GridNotAscending { index } => (BlobFault::GridNotAscending, Some(BlobSection::Grid), index),
            BlobError::BadLedOrder { index } => (BlobFault::BadLedOrder, Some(BlobSection::LedOrder), index),
            BlobError::BadZoneMap { index } => (BlobFault::BadZoneMap, Some(BlobSection::Zones), index),
            BlobError::BufferTooSmall { .. } | BlobError::ContentMismatch { .. } => (BlobFault::Other, None, 0),
        };
        DeviceError::BlobRejected { fault, section, detail: detail as u32 }
    }
}

impl core::fmt::Display for DeviceError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Frame(e) => write!(f, "the device could not read the request frame: {e:?}"),
            Self::NoCalibration => write!(f, "no calibration is provisioned: run `host-tools provision` first"),
            Self::Busy => write!(f, "a measurement is running: stop it first"),
            Self::NotProvisioning => write!(f, "no provisioning in progress (begin first)"),
            Self::OutOfOrder { expected, got } => {
                write!(f, "chunk at offset {got} out of order: the device expects offset {expected}")
            }
            Self::ChunkTooLarge { max } => write!(f, "chunk too large or past the declared end (max {max} bytes)"),
            Self::BlobTooLarge { len, max } => write!(f, "blob of {len} bytes does not fit a slot ({max} bytes)"),
            Self::Incomplete { received, len } => write!(f, "commit after {received} of {len} bytes"),
            Self::CrcMismatch { declared, computed } => write!(
                f,
                "blob CRC mismatch: declared {declared:#010x}, device computed {computed:#010x} (transfer corrupted); the previous calibration is kept"
            ),
            Self::BlobRejected { fault, section, detail } => write!(
                f,
                "the device rejected the blob: {fault:?} in {section:?} (detail {detail}); the previous calibration is kept"
            ),
            Self::Mismatch { field, device, blob } => write!(
                f,
                "blob made for another instrument: {field:?} is {blob} in the blob but {device} on the device; the previous calibration is kept"
            ),
            Self::Storage => write!(f, "flash error; the previous calibration is kept"),
            Self::Sensor(SensorError::NoData) => write!(
                f,
                "the sensor has no frame to give (a simulated sensor with no scene loaded: load one, `measure --scene`)"
            ),
            Self::Sensor(e) => write!(f, "sensor error: {e:?}"),
            Self::Simulation => write!(f, "simulation request refused (not a simulated device, or out of range)"),
            Self::SignatureRejected(e) => {
                let hint = match e {
                    SignatureFault::Unsigned => crate::signed::SIGN_CALIBRATION_HINT,
                    _ => "",
                };
                write!(f, "the device refused the calibration: {e}{hint}; the previous calibration is kept")
            }
            Self::BadBins { bins } => {
                write!(f, "the bin range is empty or beyond the device's {bins} bins: nothing was measured")
            }
            Self::FirmwareRejected(e) => {
                write!(f, "the device refused the firmware image: {e}; the running firmware keeps running")
            }
            Self::Update(UpdateFault::Unsupported) => {
                write!(f, "this device takes no firmware updates over the link (no update partition)")
            }
            Self::Update(UpdateFault::NotUpdating) => write!(f, "no firmware update in progress (begin first)"),
            Self::Update(UpdateFault::TooLarge { len, max }) => write!(
                f,
                "a firmware image of {len} bytes does not fit the device's update partition ({max} bytes); the running firmware keeps running"
            ),
            Self::Update(UpdateFault::TrialNotConfirmed) => write!(
                f,
                "the running firmware is on trial and has not passed its self-test yet: it takes no update until it confirms"
            ),
            Self::Update(UpdateFault::Pending) => {
                write!(
                    f,
                    "an update is already committed: reset the device to start it (host-tools update-firmware --reboot-only)"
                )
            }
            Self::CalibrationUnsupported { format, oldest, newest } => write!(
                f,
                "the calibration in flash is blob format {format}, which this firmware cannot read (it reads formats {oldest} to {newest}): provision a calibration trained for this firmware, or go back to the firmware that wrote it; nothing is measured with it"
            ),
            Self::RecipeRejected(fault) => write!(
                f,
                "the device refused the inspection recipe: {fault:?}; teach it again for this device (host-tools inspect teach); the previous recipe is kept"
            ),
            Self::RecipeForOtherCalibration { recipe, active } => write!(
                f,
                "the recipe was taught with calibration {recipe:#010x}, but the device's active calibration is {active:#010x}: teach the recipe again with the active calibration; the previous recipe is kept"
            ),
            Self::NoRecipe => write!(
                f,
                "no inspection recipe for the active calibration: teach one (host-tools inspect teach) and provision it (inspect provision)"
            ),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for DeviceError {}
