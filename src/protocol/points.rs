//! Line frames: several points of one line in one frame ([`PointsFrame`]),
//! their per-point records and the value encodings, written down once for
//! the device (which builds them with [`PointsBlock`]) and the host (which
//! reads them with [`PointsFrame::records`]).
//!
//! # A frame's points
//! `meta` holds one [`POINT_META_LEN`]-byte record per point, little-endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 2 | zone |
//! | 2 | 1 | cluster |
//! | 3 | 1 | [`super::flags`] |
//! | 4 | 4 | `sigma_scale`, f32 |
//! | 8 | 4 x R | the gloss readings, f32 ([`crate::gloss`], R = [`READINGS`]) |
//! | 8 + 4 R | 4 x R | their standard uncertainties, f32 |
//!
//! `data` holds, point after point, what the frame's [`Encoding`] says:
//! - [`Encoding::F32`]: the selected bins' values, f32 (bit for bit);
//! - [`Encoding::Sigma16`]: the selected bins' values as i16 multiples of
//!   [`sigma16_step`] of the bin's standard uncertainty (the blob's per-bin
//!   uncertainty of the point's zone and cluster times `|sigma_scale|`);
//! - [`Encoding::Corrected`]: the point's m white-corrected readings, f32, from
//!   which the host computes the estimate with the same kernel and blob.
//!
//! # Sigma16's error bound
//! The step is the largest power of two at most `u / 128` (u the bin's
//! standard uncertainty), so it is more than `u / 256`, and a value is sent
//! as `round(v / step)`: the decoded `q * step` (exact in f32) is within
//! `step / 2 <= u / 256` of the device's f32 value, 0.39 % of the bin's
//! uncertainty at most (0.23 % RMS for a uniform rounding error; below
//! 1 %, the default's rule). Values beyond 32767 steps (128 to 256
//! uncertainties) or bins whose uncertainty is not a normal positive f32
//! cannot be sent so: the device then sends that point alone in an
//! [`Encoding::F32`] frame, so the bound always holds.
use super::{LeBytes, MAX_PAYLOAD};
use crate::shape::READINGS;
use serde::{Deserialize, Serialize};

/// Bytes of one point's record in [`PointsFrame::meta`].
pub const POINT_META_LEN: usize = 8 + 8 * READINGS;

/// How a measurement's values travel.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Encoding {
    /// f32 values, bit for bit (lossless).
    F32,
    /// i16 multiples of a power-of-two step at most 1/128 of each bin's
    /// standard uncertainty (error at most 1/256 of it): the default.
    #[default]
    Sigma16,
    /// The m corrected readings; the host, which holds the same blob
    /// (checked by its CRC), computes `W v` with the same kernel (lossless).
    Corrected,
}

impl Encoding {
    /// Bytes one point's data takes: `bins` values, or `m` readings.
    pub const fn point_bytes(self, bins: usize, m: usize) -> usize {
        match self {
            Self::F32 => 4 * bins,
            Self::Sigma16 => 2 * bins,
            Self::Corrected => 4 * m,
        }
    }
}

/// The bins a measurement streams: `first`, `first + step`, ... (`count`
/// of them).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BinRange {
    /// First bin.
    pub first: u16,
    /// Distance between bins (>= 1).
    pub step: u16,
    /// Number of bins (>= 1).
    pub count: u16,
}

impl BinRange {
    /// Every one of `n` bins.
    pub const fn all(n: usize) -> Self {
        Self { first: 0, step: 1, count: n as u16 }
    }
    /// Whether the range is non-empty and within `n` bins.
    pub fn fits(&self, n: usize) -> bool {
        self.count >= 1 && self.step >= 1 && (self.first as usize + (self.count as usize - 1) * self.step as usize) < n
    }
    /// The bin indices.
    pub fn bins(&self) -> impl Iterator<Item = usize> + use<> {
        let (f, s) = (self.first as usize, self.step as usize);
        (0..self.count as usize).map(move |k| f + k * s)
    }
}

/// What a measurement request asks the stream to carry.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StreamFormat {
    /// Value encoding.
    pub encoding: Encoding,
    /// Bins to send; `None` for all n.
    pub bins: Option<BinRange>,
}

impl StreamFormat {
    /// f32 values of every bin: bit for bit.
    pub const LOSSLESS: Self = Self { encoding: Encoding::F32, bins: None };
    /// The bins this format sends on a device of `n` bins.
    pub fn bin_range(&self, n: usize) -> BinRange {
        self.bins.unwrap_or(BinRange::all(n))
    }
}

/// Consecutive points of one line, streamed during a measurement.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct PointsFrame<'a> {
    /// Line number within the measurement (0-based).
    pub line: u32,
    /// Stream sequence number of the first point (points count up from it),
    /// so a host sees any lost point.
    pub seq: u32,
    /// Pixel index of the first point; the others follow it.
    pub first_point: u16,
    /// CRC of the calibration blob that made the estimates: the host needs
    /// the same blob to decode [`Encoding::Sigma16`] and
    /// [`Encoding::Corrected`], and refuses a frame of another.
    pub blob_crc: u32,
    /// How `data` is encoded (the requested encoding, or [`Encoding::F32`]
    /// for a point Sigma16 cannot carry within its bound).
    pub encoding: Encoding,
    /// The bins the values are (for [`Encoding::Corrected`], the bins the host
    /// is to compute).
    pub bins: BinRange,
    /// Per-point records, [`POINT_META_LEN`] bytes each (module docs).
    #[serde(borrow)]
    pub meta: LeBytes<'a>,
    /// Per-point data, as `encoding` says.
    #[serde(borrow)]
    pub data: LeBytes<'a>,
}

/// One point's record in a [`PointsFrame`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointMetaWire {
    /// The pixel's zone.
    pub zone: u16,
    /// Cluster whose matrix made the estimate.
    pub cluster: u8,
    /// [`super::flags`] bits.
    pub flags: u8,
    /// Multiplies the calibration's per-bin uncertainty for this point.
    pub sigma_scale: f32,
    /// The gloss readings ([`crate::gloss`]; NaN: none).
    pub readings: [f32; READINGS],
    /// Their standard uncertainties.
    pub reading_sigma: [f32; READINGS],
}

impl PointMetaWire {
    fn write(&self, out: &mut [u8]) {
        out[0..2].copy_from_slice(&self.zone.to_le_bytes());
        out[2] = self.cluster;
        out[3] = self.flags;
        out[4..8].copy_from_slice(&self.sigma_scale.to_le_bytes());
        for (k, x) in self.readings.iter().chain(&self.reading_sigma).enumerate() {
            out[8 + 4 * k..12 + 4 * k].copy_from_slice(&x.to_le_bytes());
        }
    }
    fn read(b: &[u8]) -> Self {
        Self {
            zone: u16::from_le_bytes([b[0], b[1]]),
            cluster: b[2],
            flags: b[3],
            sigma_scale: f32::from_le_bytes([b[4], b[5], b[6], b[7]]),
            readings: core::array::from_fn(|k| f32_at(b, 8 + 4 * k)),
            reading_sigma: core::array::from_fn(|k| f32_at(b, 8 + 4 * (READINGS + k))),
        }
    }
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Why a [`PointsFrame`]'s contents cannot be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointsError {
    /// `meta` is not a whole number of records, or empty.
    BadMeta,
    /// `data` does not hold exactly what the records and encoding say.
    BadData,
    /// The bin range is empty or beyond the device's bins.
    BadBins,
}

impl<'a> PointsFrame<'a> {
    /// Points in the frame.
    pub fn count(&self) -> usize {
        self.meta.0.len() / POINT_META_LEN
    }

    /// Checks the frame's shape for `n` bins and `m` readings and returns
    /// each point's record and data bytes.
    pub fn records(
        &self,
        n: usize,
        m: usize,
    ) -> Result<impl Iterator<Item = (PointMetaWire, &'a [u8])> + 'a, PointsError> {
        if self.meta.0.is_empty() || !self.meta.0.len().is_multiple_of(POINT_META_LEN) {
            return Err(PointsError::BadMeta);
        }
        if !self.bins.fits(n) {
            return Err(PointsError::BadBins);
        }
        let per = self.encoding.point_bytes(self.bins.count as usize, m);
        if self.data.0.len() != per * self.count() {
            return Err(PointsError::BadData);
        }
        Ok(self.meta.0.chunks_exact(POINT_META_LEN).map(PointMetaWire::read).zip(self.data.0.chunks_exact(per)))
    }
}

/// The Sigma16 step of a bin whose standard uncertainty is `u` (the blob's
/// value times `|sigma_scale|`, multiplied in f32): the largest power of two
/// at most `u / 128`; `None` when `u` is not a normal positive f32 or the
/// step would not be one.
#[inline]
pub fn sigma16_step(u: f32) -> Option<f32> {
    if !(u.is_finite() && u >= f32::MIN_POSITIVE) {
        return None;
    }
    let biased = (u.to_bits() >> 23) & 0xff;
    // u in [2^(b-127), 2^(b-126)): step 2^(b-127-7), biased exponent b - 7.
    (biased > 7).then(|| f32::from_bits((biased - 7) << 23))
}

/// One bin's uncertainty for a point: the blob's value times the point's
/// `|sigma_scale|` (the one product device and host both form).
#[inline]
pub fn point_uncertainty(blob_sigma: f32, sigma_scale: f32) -> f32 {
    blob_sigma * sigma_scale.abs()
}

/// Encodes `v` with step `step` (from [`sigma16_step`]): `round(v / step)`
/// (half away from zero), or `None` beyond the i16 range or not finite.
#[inline]
pub fn sigma16_quantise(v: f32, step: f32) -> Option<i16> {
    // Division by a power of two is exact (barring underflow, which only
    // rounds a value far below the step to 0 or +-1 steps' worth).
    let t = v / step;
    // NaN fails the comparison too.
    if t.abs().partial_cmp(&32767.5) != Some(core::cmp::Ordering::Less) {
        return None;
    }
    // |t| < 2^15, so t +- 0.5 is exact and truncation rounds half away from 0.
    let r = if t >= 0.0 { t + 0.5 } else { t - 0.5 };
    Some(r as i32 as i16)
}

/// [`sigma16_quantise`] of `v` with [`sigma16_step`] of `u`, in one step
/// (the device's per-bin path): the step's reciprocal is built from `u`'s
/// exponent, and multiplying by a power of two is as exact as dividing.
#[inline]
fn sigma16_encode(v: f32, u: f32) -> Option<i16> {
    let bits = u.to_bits();
    // One compare for every u with no step: negative, zero, subnormal,
    // biased exponent <= 7, infinite or NaN (biased exponent 8..=254 pass).
    if bits.wrapping_sub(8 << 23) >= 247 << 23 {
        return None;
    }
    // step = 2^(b - 7 - 127) for u's biased exponent b, so 1 / step =
    // 2^(127 - (b - 7)): biased exponent 261 - b.
    let t = v * f32::from_bits((261 << 23) - (bits & 0x7f80_0000));
    // NaN fails the comparison too.
    if t.abs().partial_cmp(&32767.5) != Some(core::cmp::Ordering::Less) {
        return None;
    }
    Some((t + 0.5f32.copysign(t)) as i32 as i16)
}

/// Why [`PointsBlock::push`] did not take a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PushError {
    /// The frame is full: send it, start the next and push again.
    Full,
    /// A value or uncertainty Sigma16 cannot carry within its bound: send
    /// the point alone with [`Encoding::F32`].
    NotRepresentable,
}

/// One point as the device pushes it into a [`PointsBlock`].
pub struct PointIn<'p> {
    /// Its record.
    pub meta: PointMetaWire,
    /// The n estimated values.
    pub values: &'p [f32],
    /// The m corrected readings.
    pub readings: &'p [f32],
    /// The blob's per-bin uncertainty for the point's zone and cluster (n
    /// values), for Sigma16; may be empty for the other encodings.
    pub sigma: &'p [f32],
}

/// The device's builder of [`PointsFrame`]s: points are pushed one by one
/// into a frame-sized buffer until it is full.
pub struct PointsBlock {
    meta: [u8; MAX_BLOCK_META],
    data: [u8; MAX_BLOCK_DATA],
    /// Points held.
    count: usize,
    meta_len: usize,
    data_len: usize,
    capacity: usize,
    /// The frame's fixed fields.
    pub line: u32,
    /// Stream sequence number of the first point held.
    pub seq: u32,
    /// Pixel of the first point held.
    pub first_point: u16,
    /// The calibration's CRC.
    pub blob_crc: u32,
    /// Encoding of this block.
    pub encoding: Encoding,
    /// Bins.
    pub bins: BinRange,
}

/// Room a frame leaves for `meta` and `data` after the header, the CRC and
/// the postcard fields (at most 5 + 5 + 3 + 5 + 1 + 3 x 3 + 2 + 3 bytes).
pub const POINTS_OVERHEAD: usize = 8 + 4 + 33;
/// Largest `meta` a frame carries (at least one point fits).
const MAX_BLOCK_META: usize = MAX_POINTS_PER_FRAME * POINT_META_LEN;
/// Largest `data` a frame carries.
const MAX_BLOCK_DATA: usize = MAX_PAYLOAD - POINTS_OVERHEAD - POINT_META_LEN;

/// Most points one frame carries.
pub const MAX_POINTS_PER_FRAME: usize = 32;

/// Points of `per_point` data bytes one frame carries (at most
/// [`MAX_POINTS_PER_FRAME`], at least 1).
pub const fn points_per_frame(per_point: usize) -> usize {
    let k = (MAX_PAYLOAD - POINTS_OVERHEAD) / (POINT_META_LEN + per_point);
    if k > MAX_POINTS_PER_FRAME {
        MAX_POINTS_PER_FRAME
    } else if k < 1 {
        1
    } else {
        k
    }
}

impl PointsBlock {
    /// An empty block.
    pub const fn new() -> Self {
        Self {
            meta: [0; MAX_BLOCK_META],
            data: [0; MAX_BLOCK_DATA],
            count: 0,
            meta_len: 0,
            data_len: 0,
            capacity: 1,
            line: 0,
            seq: 0,
            first_point: 0,
            blob_crc: 0,
            encoding: Encoding::F32,
            bins: BinRange { first: 0, step: 1, count: 1 },
        }
    }

    /// Starts a new frame at point `first_point` of `line` (stream sequence
    /// `seq`), with `encoding` and `bins` (already checked against n) and
    /// `m` readings per point.
    #[allow(clippy::too_many_arguments)]
    pub fn start(
        &mut self,
        line: u32,
        seq: u32,
        first_point: u16,
        blob_crc: u32,
        encoding: Encoding,
        bins: BinRange,
        m: usize,
    ) {
        self.line = line;
        self.seq = seq;
        self.first_point = first_point;
        self.blob_crc = blob_crc;
        self.encoding = encoding;
        self.bins = bins;
        self.capacity = points_per_frame(encoding.point_bytes(bins.count as usize, m));
        self.count = 0;
        self.meta_len = 0;
        self.data_len = 0;
    }

    /// Points held.
    pub fn len(&self) -> usize {
        self.count
    }

    /// Whether it holds no point.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Appends one point, encoded as the block's encoding says.
    pub fn push(&mut self, p: &PointIn<'_>) -> Result<(), PushError> {
        if self.count >= self.capacity {
            return Err(PushError::Full);
        }
        let d = &mut self.data[self.data_len..];
        let (first, step, count) = (self.bins.first as usize, self.bins.step as usize, self.bins.count as usize);
        let written = match self.encoding {
            Encoding::F32 => {
                if step == 1 {
                    // Contiguous bins: one copy (both targets are little-endian).
                    let src: &[u8] = bytemuck::cast_slice(&p.values[first..first + count]);
                    d[..4 * count].copy_from_slice(src);
                } else {
                    for (o, j) in d[..4 * count].chunks_exact_mut(4).zip(self.bins.bins()) {
                        o.copy_from_slice(&p.values[j].to_le_bytes());
                    }
                }
                4 * count
            }
            Encoding::Sigma16 => {
                let last = first + (count - 1) * step;
                if p.sigma.len() <= last || p.values.len() <= last {
                    return Err(PushError::NotRepresentable);
                }
                let scale = p.meta.sigma_scale.abs();
                let out = &mut d[..2 * count];
                if step == 1 {
                    let (v, s) = (&p.values[first..first + count], &p.sigma[first..first + count]);
                    for ((o, v), s) in out.chunks_exact_mut(2).zip(v).zip(s) {
                        let q = sigma16_encode(*v, *s * scale).ok_or(PushError::NotRepresentable)?;
                        o.copy_from_slice(&q.to_le_bytes());
                    }
                } else {
                    for (o, j) in out.chunks_exact_mut(2).zip(self.bins.bins()) {
                        let q = sigma16_encode(p.values[j], p.sigma[j] * scale).ok_or(PushError::NotRepresentable)?;
                        o.copy_from_slice(&q.to_le_bytes());
                    }
                }
                2 * count
            }
            Encoding::Corrected => {
                for (k, x) in p.readings.iter().enumerate() {
                    d[4 * k..4 * k + 4].copy_from_slice(&x.to_le_bytes());
                }
                4 * p.readings.len()
            }
        };
        p.meta.write(&mut self.meta[self.meta_len..self.meta_len + POINT_META_LEN]);
        self.meta_len += POINT_META_LEN;
        self.data_len += written;
        self.count += 1;
        Ok(())
    }

    /// The frame of the points held.
    pub fn frame(&self) -> PointsFrame<'_> {
        PointsFrame {
            line: self.line,
            seq: self.seq,
            first_point: self.first_point,
            blob_crc: self.blob_crc,
            encoding: self.encoding,
            bins: self.bins,
            meta: LeBytes(&self.meta[..self.meta_len]),
            data: LeBytes(&self.data[..self.data_len]),
        }
    }
}

impl Default for PointsBlock {
    fn default() -> Self {
        Self::new()
    }
}
