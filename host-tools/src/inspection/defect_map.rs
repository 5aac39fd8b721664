//! The defect map: a pixel x line image (one column per pixel, one row per
//! line, oldest at the top) with each defect run coloured by its kind, a
//! drift alarm marked in the first column; written as PNG.
use brdf_meter::inspect::{DefectKind, Verdict};
use std::path::Path;

/// The colour of each kind (RGB), in `DefectKind::ALL`'s order.
pub const COLOURS: [[u8; 3]; 7] = [
    [30, 90, 230],  // gloss low: blue
    [230, 60, 30],  // gloss high: red
    [240, 170, 0],  // haze: amber
    [160, 60, 200], // distinctness: violet
    [230, 0, 140],  // out of distribution: magenta
    [0, 170, 90],   // out of prior: green
    [20, 20, 20],   // unreadable: black
];

/// Defect-free pixels.
const GOOD: [u8; 3] = [225, 225, 225];
/// A drift alarm (first column).
const ALARM: [u8; 3] = [255, 120, 0];

/// Colour of `kind`.
pub fn colour(kind: DefectKind) -> [u8; 3] {
    COLOURS[DefectKind::ALL.iter().position(|k| *k == kind).expect("every kind is listed")]
}

/// RGB rows of the map of `verdicts` over `pixels` pixels.
pub fn render(verdicts: &[Verdict], pixels: usize) -> Vec<u8> {
    let mut img = vec![0u8; 3 * pixels * verdicts.len()];
    for (row, v) in verdicts.iter().enumerate() {
        let line = &mut img[3 * pixels * row..3 * pixels * (row + 1)];
        for px in line.chunks_mut(3) {
            px.copy_from_slice(&GOOD);
        }
        for r in v.runs.as_slice() {
            for p in r.first as usize..(r.first as usize + r.len as usize).min(pixels) {
                line[3 * p..3 * p + 3].copy_from_slice(&colour(r.kind));
            }
        }
        if v.drift_alarm() {
            line[..3].copy_from_slice(&ALARM);
        }
    }
    img
}

/// Writes the map as a PNG (atomically), each cell `scale` x `scale` pixels.
pub fn write_png(path: &Path, verdicts: &[Verdict], pixels: usize, scale: usize) -> anyhow::Result<()> {
    anyhow::ensure!(!verdicts.is_empty(), "no verdicts to map");
    let img = render(verdicts, pixels);
    let (w, h) = (pixels * scale, verdicts.len() * scale);
    let mut big = Vec::with_capacity(3 * w * h);
    for row in img.chunks(3 * pixels) {
        let mut wide = Vec::with_capacity(3 * w);
        for px in row.chunks(3) {
            for _ in 0..scale {
                wide.extend_from_slice(px);
            }
        }
        for _ in 0..scale {
            big.extend_from_slice(&wide);
        }
    }
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, w as u32, h as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.write_header()?.write_image_data(&big)?;
    }
    crate::output::io::write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf_meter::inspect::DefectRun;
    use brdf_meter::inspect::decide::{Runs, verdict};

    #[test]
    fn runs_are_painted_in_their_kind_and_alarms_marked() {
        let mut runs = Runs::new();
        runs.push(DefectRun { first: 2, len: 2, kind: DefectKind::GlossHigh, peak_d2: 1.0 }).unwrap();
        let v = Verdict {
            line: 0,
            flags: verdict::REJECT | verdict::DRIFT_ALARM,
            mean_gloss: 0.0,
            ewma: 0.0,
            max_d2: 1.0,
            runs,
        };
        let img = render(&[v], 5);
        assert_eq!(&img[0..3], &ALARM);
        assert_eq!(&img[3..6], &GOOD);
        assert_eq!(&img[6..9], &colour(DefectKind::GlossHigh));
        assert_eq!(&img[9..12], &colour(DefectKind::GlossHigh));
        assert_eq!(&img[12..15], &GOOD);
    }
}
