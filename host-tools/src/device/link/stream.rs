//! Decoding the device's line frames ([`PointsFrame`]) into one
//! [`PointRecord`] per point, whatever their encoding: f32 as sent,
//! Sigma16 scaled back by the blob's per-bin uncertainty, readings through
//! the device's own rule ([`PointEstimator`], the same no_std kernel). The
//! last two need the calibration the device ran, identified by its CRC.
use super::PointRecord;
use crate::device::reference::PointEstimator;
use brdf_meter::blob::BlobView;
use brdf_meter::protocol::{
    BinRange, Encoding, PointFrame, PointsError, PointsFrame, flags, point_uncertainty, sigma16_step,
};

/// Why a line frame could not be decoded.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DecodeError {
    /// Sigma16 or corrected readings without the calibration blob.
    #[error("a {0:?} frame needs the calibration blob the device runs (give it with --blob)")]
    NeedsBlob(Encoding),
    /// The frame was made with another calibration.
    #[error("the device measured with calibration {device:#010x} but the host holds {host:#010x}: refused")]
    OtherBlob {
        /// The frame's blob CRC.
        device: u32,
        /// The host's.
        host: u32,
    },
    /// The frame's shape is inconsistent.
    #[error("malformed line frame: {0:?}")]
    Shape(PointsError),
    /// A point's zone is not one of the calibration's.
    #[error("point {point}: zone {zone} is not in the calibration")]
    BadZone {
        /// Pixel.
        point: u32,
        /// Zone.
        zone: u16,
    },
    /// A Sigma16 value whose step cannot exist (the device never sends one).
    #[error("point {point}: a Sigma16 value with no valid step")]
    BadStep {
        /// Pixel.
        point: u32,
    },
    /// The host's computation from the readings disagrees with the device's
    /// record of the point (zone, cluster, scale or out-of-prior flag).
    #[error("point {point}: the readings give {host:?}, the device sent {device:?}")]
    Disagrees {
        /// Pixel.
        point: u32,
        /// (zone, cluster, sigma_scale bits, out-of-prior) from the readings.
        host: (u16, u8, u32, bool),
        /// The device's.
        device: (u16, u8, u32, bool),
    },
}

/// The calibration the host decodes with: the blob the device runs.
pub struct StreamDecoder {
    bytes: Vec<u8>,
}

impl StreamDecoder {
    /// Holds `blob` (a calibration blob, signed or not).
    pub fn new(blob: &[u8]) -> anyhow::Result<Self> {
        BlobView::parse(blob).map_err(|e| anyhow::anyhow!("not a calibration blob: {e:?}"))?;
        Ok(Self { bytes: blob.to_vec() })
    }

    /// The blob.
    pub fn view(&self) -> BlobView<'_> {
        BlobView::parse(&self.bytes).expect("checked by new")
    }

    /// The blob's CRC (what the device reports as its calibration).
    pub fn crc(&self) -> u32 {
        self.view().crc()
    }
}

/// A protocol 2 point frame as a record.
impl From<PointFrame<'_>> for PointRecord {
    fn from(p: PointFrame<'_>) -> Self {
        let values: Vec<f32> = p.values.f32s().collect();
        Self {
            line: p.line,
            seq: p.seq,
            point: p.point,
            zone: p.zone,
            cluster: p.cluster,
            flags: p.flags,
            sigma_scale: p.sigma_scale,
            readings: p.readings,
            reading_sigma: p.reading_sigma,
            bins: BinRange::all(values.len()),
            encoding: Encoding::F32,
            values,
            corrected: Vec::new(),
        }
    }
}

/// Decodes every point of `f`: with `decoder` for Sigma16 and corrected
/// readings (refused when its blob is not the frame's); f32 values need no
/// blob (any n up to the frame's bins).
pub fn decode_points(f: &PointsFrame<'_>, decoder: Option<&StreamDecoder>) -> Result<Vec<PointRecord>, DecodeError> {
    let view = match (f.encoding, decoder) {
        (Encoding::F32, _) => None,
        (e, None) => return Err(DecodeError::NeedsBlob(e)),
        (_, Some(d)) => {
            if d.crc() != f.blob_crc {
                return Err(DecodeError::OtherBlob { device: f.blob_crc, host: d.crc() });
            }
            Some(d.view())
        }
    };
    decode_with(f, view.as_ref())
}

/// [`decode_points`] after the CRC check: `view` is the frame's blob (or
/// `None` for an f32 frame). Public so the fuzz target reaches the decoding
/// behind the CRC check.
pub fn decode_with(f: &PointsFrame<'_>, view: Option<&BlobView<'_>>) -> Result<Vec<PointRecord>, DecodeError> {
    let (n, m) = match view {
        None if f.encoding != Encoding::F32 => return Err(DecodeError::NeedsBlob(f.encoding)),
        Some(v) => (v.dims().n, v.dims().m),
        // An f32 frame read without a blob: its bins define the shape.
        None => (f.bins.first as usize + (f.bins.count.max(1) as usize - 1) * f.bins.step as usize + 1, 0),
    };
    let recs = f.records(n, m).map_err(DecodeError::Shape)?;
    let mut estimators: Vec<Option<PointEstimator<'_>>> = Vec::new();
    let mut out = Vec::with_capacity(f.count());
    for (k, (meta, data)) in recs.enumerate() {
        let point = f.first_point as u32 + k as u32;
        let zone_ok = |v: &BlobView<'_>| (meta.zone as usize) < v.dims().zones;
        let mut corrected = Vec::new();
        let values: Vec<f32> = match f.encoding {
            Encoding::F32 => data.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect(),
            Encoding::Sigma16 => {
                let v = view.expect("checked above: not f32");
                if !zone_ok(v) || meta.cluster as usize >= v.clusters() {
                    return Err(DecodeError::BadZone { point, zone: meta.zone });
                }
                f.bins
                    .bins()
                    .zip(data.chunks_exact(2))
                    .map(|(j, c)| {
                        let u = point_uncertainty(
                            v.uncertainty_of(meta.zone as usize, meta.cluster as usize, j),
                            meta.sigma_scale,
                        );
                        let step = sigma16_step(u).ok_or(DecodeError::BadStep { point })?;
                        Ok(i16::from_le_bytes([c[0], c[1]]) as f32 * step)
                    })
                    .collect::<Result<_, _>>()?
            }
            Encoding::Corrected => {
                let v = view.expect("checked above: not f32");
                if !zone_ok(v) {
                    return Err(DecodeError::BadZone { point, zone: meta.zone });
                }
                let z = meta.zone as usize;
                if estimators.len() <= z {
                    estimators.resize_with(z + 1, || None);
                }
                let est = match &mut estimators[z] {
                    Some(e) => e,
                    slot => slot.insert(
                        PointEstimator::new(*v, z).map_err(|_| DecodeError::BadZone { point, zone: meta.zone })?,
                    ),
                };
                let readings: Vec<f32> =
                    data.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
                let e = est.apply(&readings);
                let oop = |b: u8| b & flags::OUT_OF_PRIOR != 0;
                // NaN scales (non-finite readings) compare equal: their bits
                // differ between the M4 and x86 (default NaN sign).
                let bits = |x: f32| if x.is_nan() { f32::NAN.to_bits() } else { x.to_bits() };
                let host = (meta.zone, e.cluster, bits(e.sigma_scale), oop(e.flag_bits));
                let device = (meta.zone, meta.cluster, bits(meta.sigma_scale), oop(meta.flags));
                // The device's rule for the zone, checked: the pixel's zone.
                let pz = (point as usize) < v.dims().pixels && v.zone_of_pixel(point as usize) == z;
                if host != device || !pz {
                    return Err(DecodeError::Disagrees { point, host, device });
                }
                let rho = if meta.flags & flags::NON_FINITE != 0 { vec![0.0; v.dims().n] } else { e.rho };
                corrected = readings;
                f.bins.bins().map(|j| rho[j]).collect()
            }
        };
        out.push(PointRecord {
            line: f.line,
            seq: f.seq.wrapping_add(k as u32),
            point: point as u16,
            zone: meta.zone,
            cluster: meta.cluster,
            flags: meta.flags,
            sigma_scale: meta.sigma_scale,
            readings: meta.readings,
            reading_sigma: meta.reading_sigma,
            bins: f.bins,
            encoding: f.encoding,
            values,
            corrected,
        });
    }
    Ok(out)
}
