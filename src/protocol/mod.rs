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
//! - So does any change to what a message promises or when it comes, with
//!   the encoding unchanged: a host that relies on the new meaning would
//!   misread a device of the old one without a word. (Protocol 5: an
//!   inspection's `MeasureDone` comes after its last reject pulse. A host
//!   that stops at it would lose the late pulses of a protocol-4 device.)
//! - Variants are only appended, never reordered, within one version's life.
//! - A host and a device of different versions refuse each other's frames;
//!   the device answers with the version it got, and the host names both
//!   (`host_tools::device::link::LinkError::ProtocolMismatch`). Firmware of
//!   another version still goes onto the board over USB DFU, which does not
//!   speak this protocol.
//!
//! # Numbers on the wire
//! f32 values (BRDF vectors) and u16 pixel values (simulated frames) travel as
//! raw little-endian bytes ([`LeBytes`]) so they arrive bit for bit and cost no
//! encoding time on the device.
//!
//! # Where
//! - `messages`: the requests, replies and streamed points, and what they carry.
//! - `errors`: the typed errors that travel (frame, blob, device).
//! - `framing`: header + CRC + COBS around a message, and the frame reader.
//! - `points`: line frames (several points per frame), their per-point
//!   records and value encodings (f32, Sigma16, readings).
mod errors;
mod framing;
mod messages;
mod points;

pub use errors::*;
pub use framing::*;
pub use messages::*;
pub use points::*;

/// The protocol version this library speaks.
pub const PROTOCOL_VERSION: u16 = 5;
/// Largest decoded payload (header + body + CRC) either side sends or accepts.
/// (1024: a line frame carries 5 points of 81 Sigma16 values, or 27 points'
/// readings; the device holds 4 outgoing frames and one incoming.)
pub const MAX_PAYLOAD: usize = 1024;
/// Largest frame on the wire: COBS overhead plus the `0x00` delimiter.
pub const MAX_FRAME: usize = MAX_PAYLOAD + MAX_PAYLOAD / 254 + 2;
/// Largest data a [`Request::ProvisionChunk`] may carry.
pub const MAX_CHUNK: usize = 512;
/// Largest data a [`Request::SimFrame`] may carry.
pub const MAX_SIM_BYTES: usize = 512;
/// Largest number of bins a [`PointFrame`] can carry within [`MAX_PAYLOAD`].
pub const MAX_WIRE_BINS: usize = 128;

#[cfg(test)]
mod tests;
