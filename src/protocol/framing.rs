//! Framing: `COBS(version | length | sequence | postcard body | CRC-32) 0x00`
//! (layout in the module docs of [`super`]), and the reader that cuts a byte
//! stream into frames.
use super::{FrameError, MAX_FRAME, MAX_PAYLOAD, PROTOCOL_VERSION};
use serde::{Deserialize, Serialize};

/// The frames' CRC-32: the blob's (ISO-HDLC, one 1 KiB table). Measured on
/// the line bench, the crate's slice-by-16 tables (16 KiB of flash) cost as
/// many instructions per byte on the Cortex-M4 (6.7 against 6.5).
const FRAME_CRC: crc::Crc<u32> = crate::blob::CRC32;

/// Header bytes before the body: version, length, sequence.
pub(crate) const HEADER: usize = 8;
/// CRC bytes after the body.
pub(crate) const CRC_LEN: usize = 4;

/// Encodes `msg` with sequence number `seq` into `out` as one complete frame
/// (COBS + delimiter); returns the frame length. The three steps
/// ([`serialise`], [`seal`], [`stuff`]) are public so the line bench can
/// count each.
pub fn encode<T: Serialize>(seq: u32, msg: &T, out: &mut [u8]) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_PAYLOAD];
    let len = serialise(seq, msg, &mut raw)?;
    seal(&mut raw[..len]);
    stuff(&raw[..len], out)
}

/// Header and postcard body of `msg` into `raw`; returns the payload length,
/// the 4 CRC bytes at its end included (not yet written).
pub fn serialise<T: Serialize>(seq: u32, msg: &T, raw: &mut [u8; MAX_PAYLOAD]) -> Result<usize, FrameError> {
    let body_len =
        postcard::to_slice(msg, &mut raw[HEADER..MAX_PAYLOAD - CRC_LEN]).map_err(|_| FrameError::TooLarge)?.len();
    let len = HEADER + body_len + CRC_LEN;
    raw[0..2].copy_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    raw[2..4].copy_from_slice(&(len as u16).to_le_bytes());
    raw[4..8].copy_from_slice(&seq.to_le_bytes());
    Ok(len)
}

/// Writes the CRC-32 of everything before the payload's last 4 bytes into them.
pub fn seal(payload: &mut [u8]) {
    let n = payload.len() - CRC_LEN;
    let crc = FRAME_CRC.checksum(&payload[..n]);
    payload[n..].copy_from_slice(&crc.to_le_bytes());
}

/// COBS-encodes `payload` into `out` and appends the delimiter; returns the
/// frame length.
pub fn stuff(payload: &[u8], out: &mut [u8]) -> Result<usize, FrameError> {
    let n = cobs_encode(payload, out).ok_or(FrameError::TooLarge)?;
    if n >= out.len() {
        return Err(FrameError::TooLarge);
    }
    out[n] = 0;
    Ok(n + 1)
}

/// COBS encoding (the `cobs` crate's output, byte for byte: the tests
/// compare them), a run of non-zero bytes at a time: zeros are found a
/// word at a time and each run is copied whole, where a byte-wise encoder
/// spends about 15 instructions per byte on the Cortex-M4.
pub(crate) fn cobs_encode(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    if src.is_empty() {
        return Some(0); // as the crate does (a frame is never empty)
    }
    let mut out = 0usize;
    let mut start = 0usize;
    loop {
        let rest = &src[start..];
        let max = rest.len().min(254);
        let run = first_zero(&rest[..max]);
        let end = out + 1 + run;
        if end > dst.len() {
            return None;
        }
        dst[out] = (run + 1) as u8;
        if run <= 8 && rest.len() >= 8 && dst.len() >= out + 9 {
            // A short run (zeros are common in f32 and i16 data): a fixed
            // 8-byte copy, two word moves, beats a memcpy call; the bytes
            // past the run are overwritten by what follows, or past the end.
            dst[out + 1..out + 9].copy_from_slice(&rest[..8]);
        } else {
            dst[out + 1..end].copy_from_slice(&rest[..run]);
        }
        out = end;
        start += run;
        if run < max {
            // A zero ends the block (a zero as the last byte is followed by
            // an empty block, as the loop's next turn writes).
            start += 1;
        } else if start == src.len() {
            return Some(out);
        }
    }
}

/// Index of the first zero byte of `s` (or its length).
#[inline]
fn first_zero(s: &[u8]) -> usize {
    let mut i = 0;
    for w in s.chunks_exact(4) {
        // One (unaligned) word load; a zero byte sets its 0x80 bit here.
        let w = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
        if w.wrapping_sub(0x0101_0101) & !w & 0x8080_8080 != 0 {
            break;
        }
        i += 4;
    }
    while i < s.len() && s[i] != 0 {
        i += 1;
    }
    i
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
    if FRAME_CRC.checksum(&raw[..n - CRC_LEN]) != stored {
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
