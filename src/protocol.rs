//! The wire protocol between the instrument and the host, defined once here and
//! used by the firmware, the host simulation and host-tools.
//!
//! # Framing
//! Every message travels as one frame: `COBS(payload) 0x00`. The decoded payload
//! is
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 2 | protocol version ([`PROTOCOL_VERSION`]), little-endian |
//! | 2 | 2 | payload length in bytes, CRC included |
//! | 4 | 4 | sequence number (requests: the host's; replies echo it) |
//! | 8 | .. | the postcard-encoded [`Request`] or [`Response`] |
//! | end-4 | 4 | CRC-32 (ISO-HDLC) of everything before it |
//!
//! COBS gives resynchronisation (a receiver that lost bytes recovers at the next
//! `0x00`); the length field tells a truncated frame from a corrupted one; the
//! CRC catches corruption that still decodes; the version is checked before the
//! body, so a host and a device of different protocol versions get
//! [`FrameError::UnsupportedVersion`] rather than a misread message.
//!
//! # Compatibility rules
//! - Any change to a message's encoding bumps [`PROTOCOL_VERSION`]; postcard
//!   is not self-describing, so there is no "compatible addition".
//! - Variants are only appended, never reordered, within one version's life.
//!
//! # Numbers on the wire
//! f32 values (BRDF vectors) and u16 pixel values (simulated frames) travel as
//! raw little-endian bytes ([`LeBytes`]) so they arrive bit for bit and cost no
//! encoding time on the device.
use crate::blob::BlobError;
use crate::hw::SensorError;
use serde::{Deserialize, Serialize};

/// The protocol version this library speaks.
pub const PROTOCOL_VERSION: u16 = 1;
/// Largest decoded payload (header + body + CRC) either side sends or accepts.
pub const MAX_PAYLOAD: usize = 640;
/// Largest frame on the wire: COBS overhead plus the `0x00` delimiter.
pub const MAX_FRAME: usize = MAX_PAYLOAD + MAX_PAYLOAD / 254 + 2;
/// Largest data a [`Request::ProvisionChunk`] may carry.
pub const MAX_CHUNK: usize = 512;
/// Largest data a [`Request::SimFrame`] may carry.
pub const MAX_SIM_BYTES: usize = 512;
/// Largest number of bins a [`PointFrame`] can carry within [`MAX_PAYLOAD`].
pub const MAX_WIRE_BINS: usize = 128;
const HEADER: usize = 8;
const CRC_LEN: usize = 4;

/// Raw little-endian bytes of a numeric array, borrowed from the frame.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub struct LeBytes<'a>(#[serde(borrow)] pub &'a [u8]);

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
        /// At most [`MAX_CHUNK`] bytes.
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
    /// an error sent just before).
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
}

impl<'a> Response<'a> {
    /// Every reply but a point frame owns its data: returns it with a
    /// `'static` life, or the point frame (which borrows the frame buffer).
    pub fn detach(self) -> Result<Response<'static>, PointFrame<'a>> {
        Ok(match self {
            Self::Point(p) => return Err(p),
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
        })
    }
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
}

/// One point's estimate, streamed during a measurement.
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
    /// [`flags`] bits.
    pub flags: u8,
    /// The n estimated values, f32 little-endian.
    #[serde(borrow)]
    pub values: LeBytes<'a>,
}

/// Why a frame could not be read.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// The COBS encoding is invalid.
    Cobs,
    /// More bytes than [`MAX_FRAME`] before a delimiter.
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
    /// The message does not fit [`MAX_PAYLOAD`] (sender side).
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
    /// A chunk is larger than [`MAX_CHUNK`] or runs past the declared length.
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
        /// Declared at [`Request::ProvisionBegin`].
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
}

/// A blob section, as it travels: the blob's own [`crate::blob::Section`].
pub use crate::blob::Section as BlobSection;

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
            Self::Sensor(e) => write!(f, "sensor error: {e:?}"),
            Self::Simulation => write!(f, "simulation request refused (not a simulated device, or out of range)"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for DeviceError {}

/// Encodes `msg` with sequence number `seq` into `out` as one complete frame
/// (COBS + delimiter); returns the frame length.
pub fn encode<T: Serialize>(seq: u32, msg: &T, out: &mut [u8]) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_PAYLOAD];
    let body_len = postcard::to_slice(msg, &mut raw[HEADER..MAX_PAYLOAD - CRC_LEN])
        .map_err(|_| FrameError::TooLarge)?
        .len();
    let len = HEADER + body_len + CRC_LEN;
    raw[0..2].copy_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    raw[2..4].copy_from_slice(&(len as u16).to_le_bytes());
    raw[4..8].copy_from_slice(&seq.to_le_bytes());
    let crc = crate::blob::CRC32.checksum(&raw[..len - CRC_LEN]);
    raw[len - CRC_LEN..len].copy_from_slice(&crc.to_le_bytes());
    let n = cobs::try_encode(&raw[..len], out).map_err(|_| FrameError::TooLarge)?;
    if n >= out.len() {
        return Err(FrameError::TooLarge);
    }
    out[n] = 0;
    Ok(n + 1)
}

/// Decodes one frame's bytes (without the `0x00` delimiter), in place.
pub fn decode<'a, T: Deserialize<'a>>(frame: &'a mut [u8]) -> Result<(u32, T), FrameError> {
    if frame.len() > MAX_FRAME {
        return Err(FrameError::Oversized);
    }
    let n = cobs::decode_in_place(frame).map_err(|_| FrameError::Cobs)?;
    let raw = &frame[..n];
    if n < HEADER + CRC_LEN {
        let declared = if n >= 4 { u16::from_le_bytes([raw[2], raw[3]]) } else { 0 };
        return Err(FrameError::Truncated { declared, got: n as u16 });
    }
    let declared = u16::from_le_bytes([raw[2], raw[3]]) as usize;
    if n < declared {
        return Err(FrameError::Truncated { declared: declared as u16, got: n as u16 });
    }
    // Longer than declared, or shorter than a header: a corrupted length (the
    // CRC check below would also fail, but this says more).
    if n != declared {
        return Err(FrameError::BadCrc);
    }
    let stored = u32::from_le_bytes([raw[n - 4], raw[n - 3], raw[n - 2], raw[n - 1]]);
    if crate::blob::CRC32.checksum(&raw[..n - CRC_LEN]) != stored {
        return Err(FrameError::BadCrc);
    }
    let version = u16::from_le_bytes([raw[0], raw[1]]);
    if version != PROTOCOL_VERSION {
        return Err(FrameError::UnsupportedVersion { got: version });
    }
    let seq = u32::from_le_bytes([raw[4], raw[5], raw[6], raw[7]]);
    let (msg, rest) = postcard::take_from_bytes(&frame[HEADER..n - CRC_LEN]).map_err(|_| FrameError::Malformed)?;
    if !rest.is_empty() {
        return Err(FrameError::Malformed);
    }
    Ok((seq, msg))
}

/// Collects bytes from a stream into frames, delimited by `0x00`.
///
/// Bytes beyond [`MAX_FRAME`] are dropped until the next delimiter, which then
/// yields [`FrameError::Oversized`]: a flood of garbage costs a bounded buffer
/// and one error reply, and the next frame is read normally.
pub struct FrameReader {
    buf: [u8; MAX_FRAME],
    len: usize,
    overflow: bool,
}

impl Default for FrameReader {
    fn default() -> Self {
        Self::new()
    }
}

/// What [`FrameReader::push`] found.
pub enum Pushed<'a> {
    /// Need more bytes.
    More,
    /// A complete frame (COBS-encoded, delimiter stripped), to [`decode`].
    Frame(&'a mut [u8]),
    /// A frame that was too long was dropped.
    Oversized,
}

impl FrameReader {
    /// An empty reader.
    pub const fn new() -> Self {
        Self { buf: [0; MAX_FRAME], len: 0, overflow: false }
    }

    /// Feeds one byte.
    pub fn push(&mut self, byte: u8) -> Pushed<'_> {
        if byte != 0 {
            if self.len < self.buf.len() {
                self.buf[self.len] = byte;
                self.len += 1;
            } else {
                self.overflow = true;
            }
            return Pushed::More;
        }
        let len = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.overflow) {
            return Pushed::Oversized;
        }
        if len == 0 {
            // Empty frames are padding (a host may send 0x00 to resynchronise).
            return Pushed::More;
        }
        Pushed::Frame(&mut self.buf[..len])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame_of<T: Serialize>(seq: u32, msg: &T) -> Vec<u8> {
        let mut out = [0u8; MAX_FRAME];
        let n = encode(seq, msg, &mut out).unwrap();
        assert_eq!(out[n - 1], 0);
        assert!(out[..n - 1].iter().all(|b| *b != 0), "COBS leaves no zero inside a frame");
        out[..n].to_vec()
    }

    fn round_trip_req(req: Request<'_>) {
        let mut f = frame_of(42, &req);
        f.pop();
        let (seq, back): (u32, Request<'_>) = decode(&mut f).unwrap();
        assert_eq!(seq, 42);
        assert_eq!(back, req);
    }

    fn round_trip_resp(resp: Response<'_>) {
        let mut f = frame_of(7, &resp);
        f.pop();
        let (seq, back): (u32, Response<'_>) = decode(&mut f).unwrap();
        assert_eq!(seq, 7);
        assert_eq!(back, resp);
    }

    fn cal() -> CalInfo {
        CalInfo { slot: 1, sequence: 9, blob_crc: 0xDEAD_BEEF, blob_len: 11_000, zones: 4, in_ram: true }
    }

    #[test]
    fn every_request_round_trips() {
        let chunk = [0u8, 1, 2, 255, 0, 0];
        let px = [1u16, 0, 65535, 300];
        for req in [
            Request::Info,
            Request::Status,
            Request::ProvisionBegin { len: 123_456, crc: 0x1234_5678 },
            Request::ProvisionChunk { offset: 512, data: &chunk },
            Request::ProvisionChunk { offset: 0, data: &[0xAB; MAX_CHUNK] },
            Request::ProvisionCommit,
            Request::ProvisionAbort,
            Request::Measure { lines: 0 },
            Request::Measure { lines: u32::MAX },
            Request::Stop,
            Request::SimFrame { line: 3, frame: 7, first_pixel: 96, pixels: LeBytes::from_u16(&px) },
            Request::SimLines { lines: 2 },
        ] {
            round_trip_req(req);
        }
    }

    #[test]
    fn every_response_round_trips() {
        let vals = [0.5f32, -0.0, f32::MAX, f32::MIN_POSITIVE, 1.0e-40, f32::NAN];
        let status = DeviceStatus {
            measuring: true,
            lines_total: 5,
            provisioning: Some(77),
            bad_frames: 2,
            refused: 1,
            calibration: Some(cal()),
        };
        let errors = [
            DeviceError::Frame(FrameError::Truncated { declared: 30, got: 12 }),
            DeviceError::Frame(FrameError::UnsupportedVersion { got: 9 }),
            DeviceError::NoCalibration,
            DeviceError::Busy,
            DeviceError::NotProvisioning,
            DeviceError::OutOfOrder { expected: 512, got: 1024 },
            DeviceError::ChunkTooLarge { max: 512 },
            DeviceError::BlobTooLarge { len: 1 << 20, max: 12_000 },
            DeviceError::Incomplete { received: 5, len: 10 },
            DeviceError::CrcMismatch { declared: 1, computed: 2 },
            DeviceError::BlobRejected { fault: BlobFault::NonFinite, section: Some(BlobSection::Matrices), detail: 3 },
            DeviceError::Mismatch { field: SizeField::Pixels, device: 32, blob: 16 },
            DeviceError::Storage,
            DeviceError::Sensor(SensorError::NoData),
            DeviceError::Simulation,
        ];
        let mut all = vec![
            Response::Info(DeviceInfo {
                protocol: PROTOCOL_VERSION,
                firmware: [0, 1, 0],
                bins: 81,
                leds: 7,
                pixels: 32,
                full_scale: 4095,
                max_blob: 12_000,
                ram_matrix_words: 9072,
                simulated: true,
                calibration: None,
            }),
            Response::Status(status),
            Response::Status(DeviceStatus::default()),
            Response::ProvisionReady { slot: 1, max_chunk: MAX_CHUNK as u16 },
            Response::ChunkAck { next_offset: 1024 },
            Response::Committed(cal()),
            Response::Aborted,
            Response::MeasureStarted { lines: 3 },
            Response::MeasureDone { lines_done: 3 },
            Response::StopRequested,
            Response::SimLoaded,
        ];
        all.extend(errors.map(Response::Error));
        for r in all {
            round_trip_resp(r);
        }
        // Point frames carry their values bit for bit, NaN and -0.0 included.
        let p = Response::Point(PointFrame {
            line: 4,
            seq: 99,
            point: 31,
            zone: 3,
            flags: flags::SATURATED | flags::NON_FINITE,
            values: LeBytes::from_f32(&vals),
        });
        let mut f = frame_of(1, &p);
        f.pop();
        let (_, back): (u32, Response<'_>) = decode(&mut f).unwrap();
        let Response::Point(pf) = back else { panic!("not a point") };
        let bits: Vec<u32> = pf.values.f32s().map(f32::to_bits).collect();
        assert_eq!(bits, vals.map(f32::to_bits));
        assert_eq!((pf.line, pf.seq, pf.point, pf.zone), (4, 99, 31, 3));
    }

    #[test]
    fn largest_point_frame_fits() {
        let vals = [1.0f32; MAX_WIRE_BINS];
        let p = Response::Point(PointFrame {
            line: u32::MAX,
            seq: u32::MAX,
            point: u16::MAX,
            zone: u16::MAX,
            flags: 0xFF,
            values: LeBytes::from_f32(&vals),
        });
        let mut out = [0u8; MAX_FRAME];
        encode(u32::MAX, &p, &mut out).unwrap();
        let big = Request::ProvisionChunk { offset: u32::MAX, data: &[0xFF; MAX_CHUNK] };
        encode(u32::MAX, &big, &mut out).unwrap();
        let sim = Request::SimFrame { line: 255, frame: 255, first_pixel: 65535, pixels: LeBytes(&[0xFF; MAX_SIM_BYTES]) };
        encode(u32::MAX, &sim, &mut out).unwrap();
    }

    #[test]
    fn every_truncation_is_a_typed_error() {
        let chunk = [7u8; 40];
        let f = frame_of(3, &Request::ProvisionChunk { offset: 8, data: &chunk });
        for cut in 1..f.len() - 1 {
            let mut t = f[..cut].to_vec();
            let r: Result<(u32, Request<'_>), _> = decode(&mut t);
            assert!(
                matches!(r, Err(FrameError::Truncated { .. } | FrameError::Cobs | FrameError::BadCrc)),
                "cut at {cut}: {r:?}"
            );
        }
        // A cut that keeps the COBS structure valid is reported as truncated.
        let mut raw = [0u8; MAX_PAYLOAD];
        let mut enc = [0u8; MAX_FRAME];
        let n = encode(3, &Request::Measure { lines: 2 }, &mut enc).unwrap();
        let m = cobs::decode(&enc[..n - 1], &mut raw).unwrap();
        let mut re = [0u8; MAX_FRAME];
        let k = cobs::encode(&raw[..m - 2], &mut re);
        let r: Result<(u32, Request<'_>), _> = decode(&mut re[..k]);
        assert_eq!(r, Err(FrameError::Truncated { declared: m as u16, got: (m - 2) as u16 }));
    }

    #[test]
    fn every_single_byte_corruption_is_a_typed_error() {
        let f = frame_of(3, &Request::ProvisionBegin { len: 1000, crc: 5 });
        for pos in 0..f.len() - 1 {
            for x in [0x01u8, 0x80, 0xFF] {
                let mut t = f[..f.len() - 1].to_vec();
                t[pos] ^= x;
                if t[pos] == 0 {
                    continue; // a zero byte is a delimiter: it splits the frame, tested elsewhere
                }
                let r: Result<(u32, Request<'_>), _> = decode(&mut t);
                assert!(r.is_err(), "corruption at {pos} accepted: {r:?}");
            }
        }
    }

    #[test]
    fn wrong_version_is_reported_before_the_body() {
        let mut raw = [0u8; 32];
        raw[0..2].copy_from_slice(&2u16.to_le_bytes());
        raw[2..4].copy_from_slice(&13u16.to_le_bytes());
        raw[8] = 0xEE; // not a variant of version 1
        let crc = crate::blob::CRC32.checksum(&raw[..9]);
        raw[9..13].copy_from_slice(&crc.to_le_bytes());
        let mut enc = [0u8; 64];
        let k = cobs::encode(&raw[..13], &mut enc);
        let r: Result<(u32, Request<'_>), _> = decode(&mut enc[..k]);
        assert_eq!(r, Err(FrameError::UnsupportedVersion { got: 2 }));
    }

    #[test]
    fn unknown_variant_and_trailing_bytes_are_malformed() {
        for body in [&[0xEEu8][..], &[0u8, 0][..]] {
            let mut raw = [0u8; 32];
            let len = 8 + body.len() + 4;
            raw[0..2].copy_from_slice(&PROTOCOL_VERSION.to_le_bytes());
            raw[2..4].copy_from_slice(&(len as u16).to_le_bytes());
            raw[8..8 + body.len()].copy_from_slice(body);
            let crc = crate::blob::CRC32.checksum(&raw[..len - 4]);
            raw[len - 4..len].copy_from_slice(&crc.to_le_bytes());
            let mut enc = [0u8; 64];
            let k = cobs::encode(&raw[..len], &mut enc);
            let r: Result<(u32, Request<'_>), _> = decode(&mut enc[..k]);
            assert_eq!(r, Err(FrameError::Malformed), "body {body:?}");
        }
    }

    #[test]
    fn reader_splits_frames_and_survives_oversized_garbage() {
        let a = frame_of(1, &Request::Info);
        let b = frame_of(2, &Request::Status);
        let mut stream = vec![0u8, 0];
        stream.extend_from_slice(&a);
        stream.extend(core::iter::repeat_n(0x55, MAX_FRAME * 3));
        stream.push(0);
        stream.extend_from_slice(&b);
        let mut rd = FrameReader::new();
        let mut got = Vec::new();
        for byte in stream {
            match rd.push(byte) {
                Pushed::More => {}
                Pushed::Oversized => got.push(Err(FrameError::Oversized)),
                Pushed::Frame(f) => {
                    let r: Result<(u32, Request<'_>), _> = decode(f);
                    got.push(r.map(|(s, _)| s));
                }
            }
        }
        assert_eq!(got, vec![Ok(1), Err(FrameError::Oversized), Ok(2)]);
    }

    #[test]
    fn too_large_a_message_is_refused_by_the_sender() {
        let big = [0u8; MAX_PAYLOAD];
        let mut out = [0u8; MAX_FRAME];
        assert_eq!(encode(0, &Request::ProvisionChunk { offset: 0, data: &big }, &mut out), Err(FrameError::TooLarge));
    }

    #[test]
    fn blob_errors_map_to_typed_faults() {
        let e: DeviceError = BlobError::NonFinite { section: BlobSection::White, index: 12 }.into();
        assert_eq!(
            e,
            DeviceError::BlobRejected { fault: BlobFault::NonFinite, section: Some(BlobSection::White), detail: 12 }
        );
    }
}
