//! The messages: what the host asks ([`Request`]), what the device answers
//! or streams ([`Response`], [`PointFrame`]) and the records they carry.
use super::DeviceError;
use serde::{Deserialize, Serialize};

/// Raw little-endian bytes of a numeric array, borrowed from the frame.
///
/// On the wire: a varint length and the bytes (postcard's encoding of a
/// byte sequence), written as bytes in one copy rather than element by
/// element (what serde's derive of a `&[u8]` field would do; same bytes).
#[derive(Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub struct LeBytes<'a>(#[serde(borrow)] pub &'a [u8]);

impl Serialize for LeBytes<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_newtype_struct("LeBytes", &Bytes(self.0))
    }
}

/// A byte slice serialised as bytes.
struct Bytes<'a>(&'a [u8]);

impl Serialize for Bytes<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(self.0)
    }
}

impl<'a> LeBytes<'a> {
    /// Wraps f32 values without copying (both our targets are little-endian).
    #[cfg(target_endian = "little")]
    pub fn from_f32(values: &'a [f32]) -> Self {
        Self(bytemuck::cast_slice(values))
    }
    /// Wraps u16 values without copying.
    #[cfg(target_endian = "little")]
    pub fn from_u16(values: &'a [u16]) -> Self {
        Self(bytemuck::cast_slice(values))
    }
    /// The values as f32 (ignores a trailing partial value, which a well-formed
    /// frame never has: see [`Self::is_whole`]).
    pub fn f32s(&self) -> impl Iterator<Item = f32> + 'a {
        self.0.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
    }
    /// The values as u16.
    pub fn u16s(&self) -> impl Iterator<Item = u16> + 'a {
        self.0.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]]))
    }
    /// Whether the length is a whole number of `size`-byte values.
    pub fn is_whole(&self, size: usize) -> bool {
        self.0.len().is_multiple_of(size)
    }
}

/// What the host asks.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum Request<'a> {
    /// Device identity, build-time sizes and active calibration.
    Info,
    /// Measurement and provisioning state, counters.
    Status,
    /// Starts provisioning a blob of `len` bytes whose CRC-32 over all its
    /// bytes is `crc`. Erases nothing the active calibration uses.
    ProvisionBegin {
        /// Blob length in bytes.
        len: u32,
        /// CRC-32 (ISO-HDLC) of the whole blob.
        crc: u32,
    },
    /// The blob bytes at `offset`; chunks must arrive in order.
    ProvisionChunk {
        /// Byte offset of `data` in the blob.
        offset: u32,
        /// At most [`MAX_CHUNK`](super::MAX_CHUNK) bytes.
        #[serde(borrow)]
        data: &'a [u8],
    },
    /// Verifies the whole blob and makes it the active calibration.
    ProvisionCommit,
    /// Abandons a provisioning; the active calibration is untouched.
    ProvisionAbort,
    /// Measures `lines` lines; 0 measures continuously until [`Request::Stop`].
    Measure {
        /// Number of lines, 0 for continuous.
        lines: u32,
        /// What the stream carries: value encoding and bins.
        format: super::StreamFormat,
    },
    /// Stops a measurement after the line in progress.
    Stop,
    /// Simulation only: loads part of one raw frame of the simulated scene.
    /// `frame` 0 is the dark frame, `1 + k` the frame under LED k (physical
    /// index, not reading order); `line` selects one of the scene's lines.
    SimFrame {
        /// Scene line slot.
        line: u8,
        /// 0 = dark, 1 + LED index.
        frame: u8,
        /// First pixel that `pixels` covers.
        first_pixel: u16,
        /// Pixel values, u16 little-endian.
        #[serde(borrow)]
        pixels: LeBytes<'a>,
    },
    /// Simulation only: sets how many scene lines the sensor cycles through.
    SimLines {
        /// Number of loaded lines (1..=capacity).
        lines: u8,
    },
    /// The running firmware's version, boot state, self-test and trusted
    /// keys (protocol 4).
    FirmwareInfo,
    /// Starts, or resumes, a firmware update: a signed image of `len` bytes
    /// whose CRC-32 over all its bytes is `crc` (`host-tools sign-firmware`).
    /// A `begin` with the length and CRC of the update in progress resumes
    /// it. Touches nothing the running firmware uses.
    UpdateBegin {
        /// Signed image length in bytes.
        len: u32,
        /// CRC-32 (ISO-HDLC) of the whole signed image.
        crc: u32,
    },
    /// The image bytes at `offset`, in order, a multiple of 8 bytes.
    UpdateChunk {
        /// Byte offset of `data` in the image.
        offset: u32,
        /// At most [`MAX_CHUNK`](super::MAX_CHUNK) bytes.
        #[serde(borrow)]
        data: &'a [u8],
    },
    /// Checks the whole image (CRC, trailer, target, signature) and marks it
    /// for the bootloader: the next reset swaps it in, on trial.
    UpdateCommit,
    /// Abandons an update; nothing the running firmware uses was touched.
    UpdateAbort,
    /// Resets the device (after [`Request::UpdateCommit`]: into the new
    /// firmware), once the reply is sent.
    Reboot,
    /// Starts provisioning an inspection recipe (signed, `host-tools inspect
    /// teach`) of `len` bytes with CRC-32 `crc` into the inactive recipe
    /// slot; chunks and commit as for a calibration.
    RecipeBegin {
        /// Signed recipe length in bytes.
        len: u32,
        /// CRC-32 (ISO-HDLC) of all its bytes.
        crc: u32,
    },
    /// The recipe bytes at `offset`, in order.
    RecipeChunk {
        /// Byte offset of `data`.
        offset: u32,
        /// At most [`MAX_CHUNK`](crate::protocol::MAX_CHUNK) bytes.
        #[serde(borrow)]
        data: &'a [u8],
    },
    /// Verifies the recipe (CRC, signature, format, shape, the calibration
    /// it was taught with) and makes it the active one.
    RecipeCommit,
    /// Abandons a recipe provisioning; the active recipe is untouched.
    RecipeAbort,
    /// Inspects `lines` lines (0: until [`Request::Stop`]) with the active
    /// recipe: one [`Response::Verdict`] per line, reject pulses as
    /// [`Response::RejectPulse`] events, and with `defect_points` the
    /// points of each rejected line in `format` after its verdict;
    /// [`Response::MeasureDone`] once the pulses are over.
    Inspect {
        /// Number of lines, 0 for continuous.
        lines: u32,
        /// Whether a rejected line's points follow its verdict.
        defect_points: bool,
        /// How those points travel.
        format: super::StreamFormat,
    },
    /// The active recipe and the inspection's counters.
    InspectStatus,
}

/// What the device answers or streams.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum Response<'a> {
    /// Reply to [`Request::Info`].
    Info(DeviceInfo),
    /// Reply to [`Request::Status`].
    Status(DeviceStatus),
    /// Provisioning accepted; send chunks from offset 0.
    ProvisionReady {
        /// Slot being written (0 = A, 1 = B).
        slot: u8,
        /// Largest chunk the device accepts.
        max_chunk: u16,
    },
    /// A chunk was written; the next must start at `next_offset`.
    ChunkAck {
        /// Offset expected next.
        next_offset: u32,
    },
    /// The blob was verified, committed and is now the active calibration.
    Committed(CalInfo),
    /// Provisioning abandoned; the previous calibration is still active.
    Aborted,
    /// Measurement started.
    MeasureStarted {
        /// Lines requested (0 = continuous).
        lines: u32,
    },
    /// Reply to [`Request::Stop`]: a running measurement stops after the line
    /// in progress and its `MeasureDone` follows; with none running, nothing
    /// follows.
    StopRequested,
    /// The measurement is over (all requested lines sent, stopped, or ended by
    /// an error sent just before). An inspection's comes after the last of
    /// its [`Response::RejectPulse`] events: every pulse its rejected lines
    /// set off has been driven and reported, those a delay in lines still
    /// held at its end driven at once.
    MeasureDone {
        /// Lines measured.
        lines_done: u32,
    },
    /// A simulated frame part was stored.
    SimLoaded,
    /// One point's BRDF estimate.
    Point(#[serde(borrow)] PointFrame<'a>),
    /// The request (or the measurement) failed; nothing was changed unless the
    /// error says so.
    Error(DeviceError),
    /// Consecutive points of one line (protocol 3's stream).
    Points(#[serde(borrow)] super::PointsFrame<'a>),
    /// Reply to [`Request::FirmwareInfo`].
    Firmware(FirmwareInfo),
    /// An update is under way; send the chunk at `next_offset` (0 for a new
    /// update, further on for one resumed).
    UpdateReady {
        /// Offset of the next chunk.
        next_offset: u32,
        /// Largest chunk the device accepts.
        max_chunk: u16,
    },
    /// The image was verified and marked: the next reset starts it, on trial.
    UpdateCommitted {
        /// Its version.
        version: [u8; 3],
    },
    /// The device resets once this reply is sent.
    Rebooting,
    /// The recipe was verified, committed and is now the active one.
    RecipeCommitted(RecipeInfo),
    /// One inspected line's verdict.
    Verdict(crate::inspect::Verdict),
    /// The reject output was driven: a pulse for `line` from `start_us` (the
    /// device's clock) for `len_us`. The event that makes the output
    /// observable where no pin can be seen (QEMU, the host simulation).
    RejectPulse {
        /// The rejected line.
        line: u32,
        /// Start, us since boot.
        start_us: u64,
        /// Length, us.
        len_us: u32,
    },
    /// Reply to [`Request::InspectStatus`].
    Inspection(InspectStatus),
}

impl<'a> Response<'a> {
    /// Every reply but a point or line frame owns its data: returns it with
    /// a `'static` life, or the frame (which borrows the frame buffer).
    pub fn detach(self) -> Result<Response<'static>, Streamed<'a>> {
        Ok(match self {
            Self::Point(p) => return Err(Streamed::Point(p)),
            Self::Points(p) => return Err(Streamed::Points(p)),
            Self::Info(x) => Response::Info(x),
            Self::Status(x) => Response::Status(x),
            Self::ProvisionReady { slot, max_chunk } => Response::ProvisionReady { slot, max_chunk },
            Self::ChunkAck { next_offset } => Response::ChunkAck { next_offset },
            Self::Committed(x) => Response::Committed(x),
            Self::Aborted => Response::Aborted,
            Self::MeasureStarted { lines } => Response::MeasureStarted { lines },
            Self::StopRequested => Response::StopRequested,
            Self::MeasureDone { lines_done } => Response::MeasureDone { lines_done },
            Self::SimLoaded => Response::SimLoaded,
            Self::Error(e) => Response::Error(e),
            Self::Firmware(x) => Response::Firmware(x),
            Self::UpdateReady { next_offset, max_chunk } => Response::UpdateReady { next_offset, max_chunk },
            Self::UpdateCommitted { version } => Response::UpdateCommitted { version },
            Self::Rebooting => Response::Rebooting,
            Self::RecipeCommitted(x) => Response::RecipeCommitted(x),
            Self::Verdict(x) => Response::Verdict(x),
            Self::RejectPulse { line, start_us, len_us } => Response::RejectPulse { line, start_us, len_us },
            Self::Inspection(x) => Response::Inspection(x),
        })
    }
}

/// A streamed frame, borrowing the frame buffer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Streamed<'a> {
    /// One point (protocol 2's stream).
    Point(PointFrame<'a>),
    /// Points of a line.
    Points(super::PointsFrame<'a>),
}

/// Build-time sizes and identity of the device.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceInfo {
    /// Protocol version the device speaks.
    pub protocol: u16,
    /// Firmware version, major/minor/patch.
    pub firmware: [u8; 3],
    /// Angle bins n this build estimates.
    pub bins: u16,
    /// LEDs m.
    pub leds: u16,
    /// Pixels P of the line sensor.
    pub pixels: u16,
    /// Sensor full scale: raw readings at or above it are saturated.
    pub full_scale: u16,
    /// Largest blob a slot holds, bytes.
    pub max_blob: u32,
    /// Matrices up to this many f32 words are copied to RAM; above, read in place.
    pub ram_matrix_words: u32,
    /// Whether the sensor is simulated (accepts [`Request::SimFrame`]).
    pub simulated: bool,
    /// Active calibration, if any.
    pub calibration: Option<CalInfo>,
}

/// The active calibration.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CalInfo {
    /// Slot it lives in (0 = A, 1 = B).
    pub slot: u8,
    /// Slot sequence number (higher is newer).
    pub sequence: u32,
    /// The blob's own CRC (identifies it).
    pub blob_crc: u32,
    /// Blob length.
    pub blob_len: u32,
    /// Zones.
    pub zones: u16,
    /// Whether the matrices were copied to RAM (else read in place from flash).
    pub in_ram: bool,
}

/// Device state.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceStatus {
    /// A measurement is running.
    pub measuring: bool,
    /// Lines measured since boot.
    pub lines_total: u32,
    /// Provisioning in progress: bytes received so far.
    pub provisioning: Option<u32>,
    /// Frames rejected since boot (bad CRC, truncated, ...).
    pub bad_frames: u32,
    /// Requests refused since boot.
    pub refused: u32,
    /// Active calibration.
    pub calibration: Option<CalInfo>,
}

/// Where the running firmware stands with the bootloader.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BootState {
    /// Confirmed: the bootloader starts this image on every reset.
    Confirmed,
    /// A new image on trial: the next reset swaps the previous one back
    /// unless this one passes its self-test first and confirms itself.
    Trial,
    /// The last update failed its trial and was swapped back out: this is
    /// the previous image.
    Reverted,
    /// The bootloader was asked to wait for a USB DFU download.
    DfuRequested,
    /// No bootloader state to read (a build without an updater).
    Unknown,
}

/// The running firmware's self-test: it confirms a trial image only when all
/// three pass.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SelfTest {
    /// The calibration store was read at boot (both slots' headers).
    pub store: bool,
    /// The sensor delivered a frame.
    pub sensor: bool,
    /// A valid request arrived over the link.
    pub link: bool,
}

impl SelfTest {
    /// Whether every part passed.
    pub fn passed(&self) -> bool {
        self.store && self.sensor && self.link
    }
}

/// Reply to [`Request::FirmwareInfo`].
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FirmwareInfo {
    /// Firmware version, major/minor/patch.
    pub version: [u8; 3],
    /// The machine this build is for.
    pub target: crate::firmware::image::Target,
    /// Boot state.
    pub boot: BootState,
    /// Self-test so far.
    pub self_test: SelfTest,
    /// Whether this build takes updates over the link.
    pub updates: bool,
    /// Largest signed image an update may be.
    pub max_image: u32,
    /// An update in progress: bytes received.
    pub receiving: Option<u32>,
    /// An update committed, waiting for a reset: its version.
    pub pending: Option<[u8; 3]>,
    /// The calibration blob format versions this firmware reads (oldest, newest).
    pub blob_formats: [u16; 2],
    /// Number of trusted keys (the first [`MAX_KEY_IDS`] are listed).
    pub trusted_count: u8,
    /// Ids of the trusted keys (first 8 bytes of each public key); only the
    /// first `trusted_count` are meaningful.
    pub trusted: [crate::signed::KeyId; MAX_KEY_IDS],
    /// Whether this build trusts the DEVELOPMENT key (NOT FOR PRODUCTION).
    pub trusts_development_key: bool,
    /// Why the last update request (over the link or USB DFU) was refused,
    /// until an update is committed; USB DFU's own status can only say
    /// that the file failed verification.
    pub refused: Option<DeviceError>,
}

/// The active inspection recipe.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RecipeInfo {
    /// Recipe slot (0 = A, 1 = B).
    pub slot: u8,
    /// Slot sequence number.
    pub sequence: u32,
    /// The recipe's own CRC (identifies it).
    pub crc: u32,
    /// The user's version number.
    pub version: u32,
    /// CRC of the calibration it was taught with.
    pub calibration_crc: u32,
}

/// Reply to [`Request::InspectStatus`].
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InspectStatus {
    /// The active recipe, if any.
    pub recipe: Option<RecipeInfo>,
    /// Why the newest recipe in flash is not used, if one is not.
    pub refused: Option<DeviceError>,
    /// Whether an inspection is running.
    pub inspecting: bool,
    /// Counters of the current (or last) inspection.
    pub counters: crate::inspect::InspectCounters,
}

/// Most trusted key ids a [`FirmwareInfo`] lists.
pub const MAX_KEY_IDS: usize = 4;

/// Per-point quality flags.
pub mod flags {
    /// A raw reading (dark or lit) reached the sensor's full scale.
    pub const SATURATED: u8 = 1 << 0;
    /// A dark-corrected reading is below the minimum usable signal.
    pub const UNDER_EXPOSED: u8 = 1 << 1;
    /// A corrected reading or an estimated value is NaN or infinite.
    pub const NON_FINITE: u8 = 1 << 2;
    /// The readings are unlike the calibration's prior (out-of-prior
    /// statistic above the blob's threshold): the estimate is not to be trusted.
    pub const OUT_OF_PRIOR: u8 = 1 << 3;
    /// The flags of the readings themselves, raised in acquisition (the
    /// others judge the estimate).
    pub const OF_READINGS: u8 = SATURATED | UNDER_EXPOSED | NON_FINITE;
    /// Each flag and its name, in bit order: the names every output writes.
    pub const NAMES: [(u8, &str); 4] = [
        (SATURATED, "saturated"),
        (UNDER_EXPOSED, "under-exposed"),
        (NON_FINITE, "non-finite"),
        (OUT_OF_PRIOR, "out-of-prior"),
    ];
}

/// One point's estimate in a frame of its own, f32 (protocol 2's stream; a
/// protocol 3 device streams [`super::PointsFrame`]s, which the rate report
/// compares with this).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct PointFrame<'a> {
    /// Line number within the measurement (0-based).
    pub line: u32,
    /// Stream sequence number: counts point frames of this measurement, so a
    /// host sees any lost frame.
    pub seq: u32,
    /// Pixel index along the line.
    pub point: u16,
    /// Zone of the pixel (selects the matrix).
    pub zone: u16,
    /// Cluster within the zone whose matrix made the estimate (piecewise
    /// calibrations; 0 otherwise): selects the per-bin uncertainty.
    pub cluster: u8,
    /// [`flags`] bits.
    pub flags: u8,
    /// What the calibration's per-bin standard uncertainty is multiplied by
    /// for this point: the readings' scale for the scale-free estimators (the
    /// estimate scales with the point, and so does its uncertainty), 1 for
    /// the linear ones; for a point flagged out of prior, widened by the
    /// calibration's band factor
    /// ([`crate::kernel::scale_free::flagged_sigma_scale`]).
    pub sigma_scale: f32,
    /// The point's gloss readings, in the order of `crate::gloss`
    /// (specular gloss in GU, haze in HU, distinctness in %). NaN means "no
    /// reading": the calibration carries no gloss section, or the point's
    /// estimate was not finite (then [`flags::NON_FINITE`] is set too).
    pub readings: [f32; crate::shape::READINGS],
    /// The standard uncertainty (k = 1) of each reading, from the
    /// calibration's error covariance, already multiplied by the readings'
    /// scale where it applies (never widened by the band factor: the
    /// readings' uncertainties are calibrated on their own); NaN with the
    /// reading.
    pub reading_sigma: [f32; crate::shape::READINGS],
    /// The n estimated values, f32 little-endian.
    #[serde(borrow)]
    pub values: LeBytes<'a>,
}

/// A blob section, as it travels: the blob's own [`crate::blob::Section`].
pub use crate::blob::Section as BlobSection;
