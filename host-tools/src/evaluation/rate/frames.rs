//! The frames the device sends for one line, rebuilt on the host: the
//! device's points from the host's bit-identical reference of the device
//! (`device::reference`), framed with the library's own `PointsBlock` and
//! `protocol::encode` in the estimation task's order (a full block is sent
//! and a new one started; a point Sigma16 cannot carry goes alone as f32).
//! `host-tools rate` checks that the frame count equals the one the line
//! bench framed on the Cortex-M4, and measures Sigma16's error against each
//! bin's uncertainty by decoding these frames as the host does.
use super::link::LineTraffic;
use crate::device::link::{StreamDecoder, decode_points};
use crate::device::reference::expected_line;
use brdf_meter::acquire::AcqConfig;
use brdf_meter::blob::BlobView;
use brdf_meter::protocol::{
    self, BinRange, Encoding, LeBytes, MAX_FRAME, PointFrame, PointIn, PointMetaWire, PointsBlock, PushError, Response,
    point_uncertainty,
};
use serde::Serialize;

/// One point as the device has it before framing.
struct DevicePoint {
    meta: PointMetaWire,
    values: Vec<f32>,
    readings: Vec<f32>,
    sigma: Vec<f32>,
}

/// The line's points, its readings corrected with the shorter exposures
/// `frames` holds, as the device and the line bench correct them.
fn device_points(view: &BlobView<'_>, frames: &[Vec<u16>], full_scale: u16, acq: &AcqConfig) -> Vec<DevicePoint> {
    let n = view.dims().n;
    expected_line(view, frames, full_scale, acq)
        .into_iter()
        .map(|e| DevicePoint {
            meta: PointMetaWire {
                zone: e.zone,
                cluster: e.cluster,
                flags: e.flags,
                sigma_scale: e.sigma_scale,
                readings: e.readings,
                reading_sigma: e.reading_sigma,
            },
            sigma: (0..n).map(|j| view.uncertainty_of(e.zone as usize, e.cluster as usize, j)).collect(),
            values: e.values,
            readings: e.corrected,
        })
        .collect()
}

fn encode(r: &Response<'_>) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME];
    let n = protocol::encode(1, r, &mut out).expect("every frame fits");
    out[..n].to_vec()
}

/// The frames of one line in `encoding` (`None`: protocol 2's one f32 frame
/// per point), as the device sends them.
pub fn line_frames(
    view: &BlobView<'_>,
    frames: &[Vec<u16>],
    full_scale: u16,
    acq: &AcqConfig,
    encoding: Option<Encoding>,
) -> Vec<Vec<u8>> {
    let pts = device_points(view, frames, full_scale, acq);
    let m = view.dims().m;
    let bins = BinRange::all(view.dims().n);
    let crc = view.crc();
    let Some(encoding) = encoding else {
        return pts
            .iter()
            .enumerate()
            .map(|(p, d)| {
                encode(&Response::Point(PointFrame {
                    line: 0,
                    seq: p as u32,
                    point: p as u16,
                    zone: d.meta.zone,
                    cluster: d.meta.cluster,
                    flags: d.meta.flags,
                    sigma_scale: d.meta.sigma_scale,
                    readings: d.meta.readings,
                    reading_sigma: d.meta.reading_sigma,
                    values: LeBytes::from_f32(&d.values),
                }))
            })
            .collect();
    };
    let mut out = Vec::new();
    let mut block = PointsBlock::new();
    block.start(0, 0, 0, crc, encoding, bins, m);
    let send = |block: &PointsBlock, out: &mut Vec<Vec<u8>>| out.push(encode(&Response::Points(block.frame())));
    for (p, d) in pts.iter().enumerate() {
        let pin = PointIn { meta: d.meta, values: &d.values, readings: &d.readings, sigma: &d.sigma };
        let alone = |block: &mut PointsBlock, out: &mut Vec<Vec<u8>>| {
            block.start(0, p as u32, p as u16, crc, Encoding::F32, bins, m);
            block.push(&pin).expect("an f32 point fits an empty block");
            send(block, out);
            block.start(0, p as u32 + 1, p as u16 + 1, crc, encoding, bins, m);
        };
        match block.push(&pin) {
            Ok(()) => {}
            Err(PushError::Full) => {
                send(&block, &mut out);
                block.start(0, p as u32, p as u16, crc, encoding, bins, m);
                if block.push(&pin).is_err() {
                    alone(&mut block, &mut out);
                }
            }
            Err(PushError::NotRepresentable) => {
                if !block.is_empty() {
                    send(&block, &mut out);
                }
                alone(&mut block, &mut out);
            }
        }
    }
    if !block.is_empty() {
        send(&block, &mut out);
    }
    out
}

/// A line's traffic.
pub fn traffic(frames: &[Vec<u8>]) -> LineTraffic {
    let mut t = LineTraffic::default();
    for f in frames {
        t.add(f.len());
    }
    t
}

/// Sigma16's error against each bin's standard uncertainty, on one line.
#[derive(Clone, Debug, Serialize)]
pub struct QuantisationError {
    /// Largest |decoded - f32| / uncertainty over every bin of every point
    /// that travelled as Sigma16.
    pub max_ratio: f64,
    /// Root mean square of the same ratio.
    pub rms_ratio: f64,
    /// Points sent as Sigma16.
    pub sigma16_points: usize,
    /// Points the device sent alone as f32 (beyond Sigma16's range).
    pub f32_fallback_points: usize,
}

/// Decodes the line's Sigma16 frames as the host does and compares them
/// with the device's f32 values.
pub fn sigma16_error(
    view: &BlobView<'_>,
    blob: &[u8],
    frames: &[Vec<u16>],
    full_scale: u16,
    acq: &AcqConfig,
) -> anyhow::Result<QuantisationError> {
    let pts = device_points(view, frames, full_scale, acq);
    let decoder = StreamDecoder::new(blob)?;
    let (mut max, mut sum, mut count, mut q_points, mut fallback) = (0.0f64, 0.0f64, 0usize, 0, 0);
    for mut f in line_frames(view, frames, full_scale, acq, Some(Encoding::Sigma16)) {
        f.pop();
        let (_, r): (u32, Response<'_>) = protocol::decode(&mut f).map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let Response::Points(pf) = r else { anyhow::bail!("not a line frame") };
        for rec in decode_points(&pf, Some(&decoder))? {
            if rec.encoding != Encoding::Sigma16 {
                fallback += 1;
                continue;
            }
            q_points += 1;
            let d = &pts[rec.point as usize];
            for (j, v) in rec.values.iter().enumerate() {
                let u = point_uncertainty(d.sigma[j], d.meta.sigma_scale) as f64;
                let ratio = (*v as f64 - d.values[j] as f64).abs() / u;
                max = max.max(ratio);
                sum += ratio * ratio;
                count += 1;
            }
        }
    }
    Ok(QuantisationError {
        max_ratio: max,
        rms_ratio: (sum / count.max(1) as f64).sqrt(),
        sigma16_points: q_points,
        f32_fallback_points: fallback,
    })
}
