//! A reference's lines measured by the instrument itself, for teaching a
//! recipe on the device that will inspect: each point's corrected readings
//! and flags as the device sends them in the corrected encoding, bit for
//! bit what its decision sees (the same numbers `lines` computes from a
//! simulated scene's raw frames).
//!
//! A real instrument measures the sample under it. A simulated one (QEMU,
//! the host simulation) holds only a few scene lines, so the reference is
//! fed to it in batches of that many, each measured once: every line
//! taught from is a line of its own, with its own noise.
use super::lines::Line;
use crate::device::link::{Client, PointRecord, Transport};
use crate::forward::scene::defects::DefectScene;
use brdf_meter::protocol::{Encoding, StreamFormat, flags};
use brdf_meter::shape::LEDS as M;
use nalgebra::SVector;

/// The correction's flags (a point's others are the estimate's).
const CORRECTION_FLAGS: u8 = flags::SATURATED | flags::UNDER_EXPOSED | flags::NON_FINITE;

/// The lines of a measurement in the corrected encoding, `pixels` points
/// each, in the order measured.
pub fn lines_from_points(points: &[PointRecord], pixels: usize) -> anyhow::Result<Vec<Line>> {
    anyhow::ensure!(
        pixels > 0 && points.len().is_multiple_of(pixels),
        "{} points do not make whole lines of {pixels} pixels",
        points.len()
    );
    points
        .chunks(pixels)
        .map(|line| {
            let mut out = Line { v: Vec::with_capacity(pixels), flags: Vec::with_capacity(pixels) };
            for (px, p) in line.iter().enumerate() {
                anyhow::ensure!(
                    p.encoding == Encoding::Corrected && p.corrected.len() == M,
                    "line {} point {}: {} corrected readings in the {:?} encoding; a recipe is taught from the \
                     corrected encoding's {M}",
                    p.line,
                    p.point,
                    p.corrected.len(),
                    p.encoding
                );
                anyhow::ensure!(
                    usize::from(p.point) == px && p.line == line[0].line,
                    "line {} point {}: expected line {} point {px} (the device sends a line's points in order)",
                    p.line,
                    p.point,
                    line[0].line
                );
                out.v.push(SVector::from_column_slice(&p.corrected));
                out.flags.push(p.flags & CORRECTION_FLAGS);
            }
            Ok(out)
        })
        .collect()
}

/// Measures `lines` lines of the reference under the device on `c` (whose
/// calibration the client decodes with, [`Client::set_calibration`]), in
/// the corrected encoding. `scene`: a simulated device is fed the scene's
/// lines from the given one on, in batches it holds. `on_line` is told how
/// many lines are done.
pub fn measure_reference<T: Transport>(
    c: &mut Client<T>,
    pixels: usize,
    lines: usize,
    scene: Option<(&DefectScene, u64)>,
    on_line: &mut dyn FnMut(usize),
) -> anyhow::Result<Vec<Line>> {
    use anyhow::Context;
    anyhow::ensure!(lines >= 1, "no lines to measure");
    let format = std::mem::replace(&mut c.format, StreamFormat { encoding: Encoding::Corrected, bins: None });
    let result = (|| {
        let mut out = Vec::with_capacity(lines);
        match scene {
            Some((ds, first)) => {
                let held = brdf_meter::shape::qemu::FRAME_LINES;
                for start in (0..lines).step_by(held) {
                    let n = held.min(lines - start);
                    let from = first + start as u64;
                    let frames =
                        (from..from + n as u64).map(|l| ds.raw_frames_at(l)).collect::<anyhow::Result<Vec<_>>>()?;
                    c.load_scene(&frames)
                        .with_context(|| format!("loading reference lines {from}.. into the simulated sensor"))?;
                    let points = c.measure(n as u32).with_context(|| format!("measuring reference lines {from}.."))?;
                    out.extend(lines_from_points(&points, pixels)?);
                    on_line(out.len());
                }
            }
            None => {
                let mut points_done = 0usize;
                let points = c
                    .measure_observed(lines as u32, &mut |_| {
                        points_done += 1;
                        if points_done.is_multiple_of(pixels) {
                            on_line(points_done / pixels);
                        }
                    })
                    .context("measuring the reference")?;
                out = lines_from_points(&points, pixels)?;
            }
        }
        Ok(out)
    })();
    c.format = format;
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf_meter::protocol::BinRange;

    fn point(line: u32, point: u16, corrected: Vec<f32>, flags: u8) -> PointRecord {
        PointRecord {
            line,
            seq: line * 2 + u32::from(point),
            point,
            zone: 0,
            flags,
            cluster: 0,
            sigma_scale: 1.0,
            readings: [f32::NAN; 3],
            reading_sigma: [f32::NAN; 3],
            bins: BinRange::all(3),
            encoding: Encoding::Corrected,
            values: vec![0.0; 3],
            corrected,
        }
    }

    #[test]
    fn points_become_lines_of_corrected_readings_with_the_corrections_flags() {
        let r = |x: f32| (0..M).map(|i| x + i as f32).collect::<Vec<_>>();
        let pts = [
            point(0, 0, r(1.0), 0),
            point(0, 1, r(2.0), flags::SATURATED | flags::OUT_OF_PRIOR),
            point(1, 0, r(3.0), flags::OUT_OF_PRIOR),
            point(1, 1, r(4.0), 0),
        ];
        let lines = lines_from_points(&pts, 2).unwrap();
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[1].v[0].as_slice(), r(3.0).as_slice());
        assert_eq!(lines[0].flags, [0, flags::SATURATED]);
        assert_eq!(lines[1].flags, [0, 0]);
        // Refused, saying what: another encoding, a broken line, a missing point.
        let mut f32s = pts.to_vec();
        f32s[2].encoding = Encoding::F32;
        f32s[2].corrected.clear();
        let e = lines_from_points(&f32s, 2).unwrap_err().to_string();
        assert!(e.contains("line 1 point 0") && e.contains("corrected encoding"), "{e}");
        let e = lines_from_points(&pts[..3], 2).unwrap_err().to_string();
        assert!(e.contains("3 points") && e.contains("2 pixels"), "{e}");
        let e = lines_from_points(&[pts[0].clone(), pts[2].clone()], 2).unwrap_err().to_string();
        assert!(e.contains("expected line 0 point 1"), "{e}");
    }
}
