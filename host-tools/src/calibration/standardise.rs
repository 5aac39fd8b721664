//! Standardisation on a white tile: the calibration's white reference made
//! true again for the LEDs and sensor as they are today.
//!
//! Every reading the device corrects is divided by the calibration's white
//! reference, one value per pixel and reading: what a perfect diffuser read
//! when the calibration was made. LEDs age and drift with temperature, so a
//! real instrument, like every gloss meter, is standardised on a reference
//! tile from time to time. Here the tile is a white diffuser whose
//! reflectance factor at the instrument's geometry is certified (`rf`, with
//! its standard uncertainty). Its corrected readings are `rf` times each
//! LED's and pixel's drift since calibration, so each white value is
//! multiplied by the mean reading over `rf`, and the tile then reads `rf`
//! again. The matrices, uncertainties and gloss rows stay as trained
//! ([`brdf_meter::blob::rewrite_white`]).
//!
//! A standardisation is refused, with the pixel and reading named, when the
//! readings cannot be the tile's: a flagged reading, a reading that is not a
//! positive number, a ratio outside [`RATIO_RANGE`] (not the tile certified
//! at `rf`, the tile not in place, or a failing LED), or readings that
//! scatter so much that their mean is not known to [`MAX_SCATTER`] (the
//! tile moved, or light leaks in).
use anyhow::{Context, bail, ensure};
use brdf_meter::blob::BlobView;
use brdf_meter::protocol::flags;
use serde::Serialize;

/// The ratio of a reading of the tile to its certified reflectance factor
/// that a standardisation accepts: LEDs that drifted by half or doubled are
/// not drift but a fault, or another tile (the blob's own rule,
/// [`brdf_meter::blob::WHITE_RATIO_RANGE`]).
pub const RATIO_RANGE: (f64, f64) =
    (brdf_meter::blob::WHITE_RATIO_RANGE.0 as f64, brdf_meter::blob::WHITE_RATIO_RANGE.1 as f64);

/// The largest relative standard error of a reading's mean over the lines
/// (its standard deviation over the square root of their count) that a
/// standardisation accepts.
pub const MAX_SCATTER: f64 = 0.01;

/// The white tile: its certified reflectance factor at the instrument's
/// geometry and that value's standard uncertainty (k = 1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Tile {
    /// Reflectance factor (a perfect diffuser is 1).
    pub rf: f64,
    /// Its standard uncertainty (k = 1), from the tile's certificate.
    pub u_rf: f64,
}

impl Tile {
    /// A tile, checked: `rf` in (0, 1.5], `u_rf` in [0, rf / 20].
    pub fn new(rf: f64, u_rf: f64) -> anyhow::Result<Self> {
        ensure!(
            rf.is_finite() && rf > 0.0 && rf <= 1.5,
            "--tile-rf {rf}: a white tile's reflectance factor is above 0 and at most 1.5 (a perfect diffuser is 1; \
             take the value from its certificate)"
        );
        ensure!(
            u_rf.is_finite() && u_rf >= 0.0 && u_rf <= rf / 20.0,
            "--tile-u: the certificate's standard uncertainty {u_rf} (k = 1) is not at least 0 and at most 5 % of \
             --tile-rf (a certificate at k = 2 states twice it: give that with --tile-k 2)"
        );
        Ok(Self { rf, u_rf })
    }
}

/// One reading of the tile: its pixel, the m corrected readings in the
/// blob's reading order, and the device's flags.
#[derive(Clone, Copy, Debug)]
pub struct TileReading<'a> {
    /// The pixel.
    pub pixel: usize,
    /// The m corrected readings.
    pub v: &'a [f32],
    /// The point's flags (`brdf_meter::protocol::flags`).
    pub flags: u8,
}

/// What the standardisation found for one reading (one LED) over the line.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReadingSummary {
    /// The reading's index (the blob's reading order).
    pub reading: usize,
    /// The LED fired for it (physical index, 0-based).
    pub led: usize,
    /// The tile's mean reading over its certified value, the median over
    /// the pixels: the LED's drift since calibration (1: none).
    pub ratio_median: f64,
    /// The least and greatest over the pixels.
    pub ratio_min: f64,
    /// The greatest over the pixels.
    pub ratio_max: f64,
    /// The largest relative standard error of a pixel's mean.
    pub scatter_max: f64,
}

/// A standardisation: the new white reference and what it rests on.
#[derive(Clone, Debug, Serialize)]
pub struct Standardisation {
    /// The tile.
    pub tile: Tile,
    /// The fewest readings of a pixel (lines measured).
    pub lines: usize,
    /// Per reading, over the pixels.
    pub readings: Vec<ReadingSummary>,
    /// The relative standard uncertainty (k = 1) the new white reference
    /// gives every reading: the certificate's and the worst mean's
    /// scatter, combined in quadrature. The standardised blob states it
    /// (`brdf_meter::blob::with_white_uncertainty`), and the host adds it
    /// to every value it states from that calibration.
    pub u_rel: f64,
    /// The CRC of the calibration standardised.
    pub crc_before: u32,
    /// The new white reference, pixel-major `P x m`.
    #[serde(skip)]
    pub white: Vec<f32>,
}

/// Standardises the calibration `view` on `tile` from its corrected
/// readings (the device's, corrected with this calibration's white).
/// Every pixel needs at least two readings.
pub fn standardise<'a>(
    view: &BlobView<'_>,
    readings: impl IntoIterator<Item = TileReading<'a>>,
    tile: Tile,
) -> anyhow::Result<Standardisation> {
    let d = view.dims();
    let (pixels, m) = (d.pixels, d.m);
    // Per pixel and reading: count, sum, sum of squares (f64).
    let mut acc = vec![(0usize, 0.0f64, 0.0f64); pixels * m];
    for r in readings {
        ensure!(r.v.len() == m, "pixel {}: {} readings, but the calibration has m = {m}", r.pixel, r.v.len());
        // The out-of-prior flag judges an estimate, not the readings: a
        // diffuser may lie outside a glossy prior and still be read true.
        check_standard_reading(
            r.pixel,
            pixels,
            r.flags & flags::OF_READINGS,
            "the tile's reading",
            "the tile is not under the instrument, or not lit as a white tile is; nothing was standardised",
        )?;
        for (i, x) in r.v.iter().enumerate() {
            ensure!(
                x.is_finite() && *x > 0.0,
                "pixel {}, reading {i}: {x} is not a positive reading of a white tile; nothing was standardised",
                r.pixel
            );
            let a = &mut acc[r.pixel * m + i];
            let x = f64::from(*x);
            *a = (a.0 + 1, a.1 + x, a.2 + x * x);
        }
    }
    let lines = acc.iter().map(|a| a.0).min().unwrap_or(0);
    if lines < 2 {
        let p = acc.iter().position(|a| a.0 < 2).unwrap_or(0) / m.max(1);
        bail!(
            "pixel {p}: {} reading(s) of the tile; a standardisation needs at least 2 of every pixel (measure more \
             lines)",
            acc[p * m].0
        );
    }
    let led_of = |i: usize| usize::from(view.led_order()[i]);
    let mut white = Vec::with_capacity(pixels * m);
    let (mut ratio, mut scatter) = (vec![0.0; pixels * m], vec![0.0; pixels * m]);
    for p in 0..pixels {
        for i in 0..m {
            let (n, s, ss) = acc[p * m + i];
            let mean = s / n as f64;
            let var = ((ss - s * mean) / (n - 1) as f64).max(0.0);
            let sem = (var / n as f64).sqrt() / mean;
            let r = mean / tile.rf;
            ensure!(
                (RATIO_RANGE.0..=RATIO_RANGE.1).contains(&r),
                "pixel {p}, reading {i} (LED {}): the tile reads {mean:.4}, {r:.3} times its certified {}: outside \
                 {}..{} times. Is this the tile certified at {}, seated under the instrument? Or the LED is failing. \
                 Nothing was standardised",
                led_of(i) + 1,
                tile.rf,
                RATIO_RANGE.0,
                RATIO_RANGE.1,
                tile.rf
            );
            ensure!(
                sem <= MAX_SCATTER,
                "pixel {p}, reading {i} (LED {}): the tile's readings scatter by {:.2} % (the standard error of their \
                 mean over {n} lines), above {} %: the tile moved or light leaks in. Reseat it, or measure more lines. \
                 Nothing was standardised",
                led_of(i) + 1,
                100.0 * sem,
                100.0 * MAX_SCATTER
            );
            white.push((f64::from(view.white(p, i)) * r) as f32);
            ratio[p * m + i] = r;
            scatter[p * m + i] = sem;
        }
    }
    let readings = (0..m)
        .map(|i| {
            let mut rs: Vec<f64> = (0..pixels).map(|p| ratio[p * m + i]).collect();
            rs.sort_by(f64::total_cmp);
            ReadingSummary {
                reading: i,
                led: led_of(i),
                ratio_median: rs[rs.len() / 2],
                ratio_min: rs[0],
                ratio_max: rs[rs.len() - 1],
                scatter_max: (0..pixels).map(|p| scatter[p * m + i]).fold(0.0, f64::max),
            }
        })
        .collect();
    let worst = scatter.iter().copied().fold(0.0, f64::max);
    let u_rel = ((tile.u_rf / tile.rf).powi(2) + worst * worst).sqrt();
    Ok(Standardisation { tile, lines, readings, u_rel, crc_before: view.crc(), white })
}

impl Standardisation {
    /// The calibration `blob` (the one standardised, unsigned) with the new
    /// white reference: a new calibration with a new CRC.
    pub fn blob(&self, blob: &[u8]) -> anyhow::Result<Vec<u8>> {
        standardised_blob(
            blob,
            self.crc_before,
            (brdf_meter::blob::with_white_uncertainty, self.u_rel, "the white reference's uncertainty"),
            (|b: &mut [u8]| brdf_meter::blob::rewrite_white(b, &self.white), "the new white reference"),
        )
    }

    /// The report's lines: per reading, the drift and scatter found.
    pub fn table(&self) -> String {
        let mut s = format!(
            "tile: reflectance factor {} (u = {}), {} lines\nreading  LED  drift (median; least..greatest over \
             the pixels)  scatter of the mean (worst pixel)\n",
            self.tile.rf, self.tile.u_rf, self.lines
        );
        for r in &self.readings {
            s += &format!(
                "{:>7}  {:>3}  {:+.2} % ({:+.2} .. {:+.2} %)  {:.3} %\n",
                r.reading,
                r.led + 1,
                100.0 * (r.ratio_median - 1.0),
                100.0 * (r.ratio_min - 1.0),
                100.0 * (r.ratio_max - 1.0),
                100.0 * r.scatter_max
            );
        }
        s += &format!(
            "the new white reference's relative standard uncertainty: {:.3} % (certificate {:.3} %, scatter {:.3} %), \
             stated in the calibration: every value measured with it carries it\n",
            100.0 * self.u_rel,
            100.0 * self.tile.u_rf / self.tile.rf,
            100.0 * self.readings.iter().map(|r| r.scatter_max).fold(0.0, f64::max)
        );
        s
    }
}

/// Refuses a reading of a standard at `pixel` that is not one of the
/// calibration's `pixels`, or that the device flagged with any of `bits`
/// (the flags the caller refuses), naming the flags: "the device flagged
/// `what` (saturated): `then`".
pub(crate) fn check_standard_reading(
    pixel: usize,
    pixels: usize,
    bits: u8,
    what: &str,
    then: &str,
) -> anyhow::Result<()> {
    ensure!(pixel < pixels, "pixel {pixel}: the calibration has pixels 0..={}", pixels - 1);
    if bits == 0 {
        return Ok(());
    }
    let names: Vec<&str> = flags::NAMES.iter().filter(|(b, _)| bits & b != 0).map(|(_, n)| *n).collect();
    bail!("pixel {pixel}: the device flagged {what} ({}): {then}", names.join(", "))
}

/// States an uncertainty in a blob: `brdf_meter::blob::with_white_uncertainty`
/// or `with_gloss_uncertainty`.
pub(crate) type State = fn(&[u8], f32, &mut [u8]) -> Result<usize, brdf_meter::blob::BlobError>;

/// The calibration `blob` (the one standardised, unsigned, whose CRC was
/// `crc_before`) with an uncertainty stated (`state`, the relative
/// uncertainty, what it is) and then values rewritten (`rewrite`, what
/// they are): the standardised calibration, with a new CRC.
pub(crate) fn standardised_blob(
    blob: &[u8],
    crc_before: u32,
    (state, u_rel, stated): (State, f64, &str),
    (rewrite, written): (impl FnOnce(&mut [u8]) -> Result<(), brdf_meter::blob::BlobError>, &str),
) -> anyhow::Result<Vec<u8>> {
    let view = BlobView::parse(blob).map_err(|e| anyhow::anyhow!("not a valid calibration blob: {e}"))?;
    ensure!(
        view.crc() == crc_before,
        "the blob's CRC is {:#010x}, but the standardisation was made for {crc_before:#010x}",
        view.crc()
    );
    let mut out = vec![0u8; view.as_bytes().len() + 4];
    let n = state(view.as_bytes(), u_rel as f32, &mut out).map_err(|e| anyhow::anyhow!("stating {stated}: {e}"))?;
    out.truncate(n);
    rewrite(&mut out).map_err(|e| anyhow::anyhow!("writing {written}: {e}")).context("standardising")?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf_meter::test_blobs::test_blob;

    const P: usize = 16;
    const M: usize = 7;

    /// `lines` readings of every pixel of a tile of `rf` whose reading `i`
    /// drifted by `gain(i)`, with a relative wobble `wobble` alternating
    /// in sign from line to line.
    fn tile_lines(rf: f64, gain: impl Fn(usize) -> f64, wobble: f64, lines: usize) -> Vec<(usize, Vec<f32>)> {
        (0..lines)
            .flat_map(|l| {
                let w = if l % 2 == 0 { 1.0 + wobble } else { 1.0 - wobble };
                let gain = &gain;
                (0..P).map(move |p| (p, (0..M).map(|i| (rf * gain(i) * w) as f32).collect()))
            })
            .collect()
    }

    fn run(blob: &[u8], lines: &[(usize, Vec<f32>)], tile: Tile) -> anyhow::Result<Standardisation> {
        let view = BlobView::parse(blob).unwrap();
        standardise(&view, lines.iter().map(|(p, v)| TileReading { pixel: *p, v, flags: 0 }), tile)
    }

    #[test]
    fn the_drift_goes_into_the_white_and_the_tile_then_reads_its_value() {
        let blob = test_blob(9, M, 2, P, 0.5);
        let view = BlobView::parse(&blob).unwrap();
        let gain = |i: usize| 1.0 + 0.03 * i as f64 - 0.05;
        let tile = Tile::new(0.95, 0.004).unwrap();
        let s = run(&blob, &tile_lines(0.95, gain, 0.002, 8), tile).unwrap();
        assert_eq!(s.lines, 8);
        let new = s.blob(&blob).unwrap();
        let nv = BlobView::parse(&new).unwrap();
        assert_ne!(nv.crc(), view.crc());
        // The blob states the new white's uncertainty.
        assert_eq!(nv.white_uncertainty(), s.u_rel as f32);
        for p in 0..P {
            for i in 0..M {
                let want = f64::from(view.white(p, i)) * gain(i);
                assert!((f64::from(nv.white(p, i)) / want - 1.0).abs() < 1e-6, "pixel {p} reading {i}");
                // Corrected with the new white, the tile reads its certified value.
                let raw = 0.95 * gain(i) * f64::from(view.white(p, i));
                assert!((raw / f64::from(nv.white(p, i)) - 0.95).abs() < 1e-6);
            }
        }
        for r in &s.readings {
            assert!((r.ratio_median - gain(r.reading)).abs() < 1e-6, "{r:?}");
            assert!(r.scatter_max > 0.0005 && r.scatter_max < 0.001, "{r:?}");
        }
        // The certificate (0.42 %) and the scatter (0.07 %) in quadrature.
        assert!((s.u_rel - ((0.004f64 / 0.95).powi(2) + 0.002f64.powi(2) / 8.0 * 8.0 / 7.0).sqrt()).abs() < 2e-4);
        assert!(s.table().contains("tile: reflectance factor 0.95"), "{}", s.table());
        // Another blob is not the one standardised.
        let other = test_blob(9, M, 2, P, 0.7);
        assert!(s.blob(&other).unwrap_err().to_string().contains("was made for"));
    }

    #[test]
    fn readings_that_cannot_be_the_tiles_are_refused_naming_pixel_and_reading() {
        let blob = test_blob(9, M, 2, P, 0.5);
        let tile = Tile::new(0.95, 0.0).unwrap();
        let ok = tile_lines(0.95, |_| 1.0, 0.0, 4);
        let refused = |lines: &[(usize, Vec<f32>)], why: &str| {
            let e = format!("{:#}", run(&blob, lines, tile).unwrap_err());
            assert!(e.contains(why), "{why}: {e}");
        };
        // One line: no scatter to judge the mean by.
        refused(&ok[..P], "at least 2 of every pixel");
        // A pixel never read.
        refused(&ok.iter().filter(|(p, _)| *p != 5).cloned().collect::<Vec<_>>(), "pixel 5: 0 reading(s)");
        // Another tile (a grey one), or no tile at all.
        refused(&tile_lines(0.95, |_| 0.4, 0.0, 4), "pixel 0, reading 0 (LED");
        // One LED failing.
        refused(&tile_lines(0.95, |i| if i == 3 { 0.3 } else { 1.0 }, 0.0, 4), "reading 3");
        // The tile moving: +-5 % over 4 lines, a standard error of 5 % x sqrt(4/3) / 2.
        refused(&tile_lines(0.95, |_| 1.0, 0.05, 4), "scatter by 2.89 %");
        // Not a reading.
        let mut bad = ok.clone();
        bad[17].1[2] = f32::NAN;
        refused(&bad, "pixel 1, reading 2: NaN");
        bad[17].1[2] = -0.1;
        refused(&bad, "is not a positive reading");
        let mut wrong = ok.clone();
        wrong[0].0 = P;
        refused(&wrong, "pixel 16: the calibration has pixels 0..=15");
        wrong[0] = (0, vec![0.95; M - 1]);
        refused(&wrong, "but the calibration has m = 7");
        // A flagged reading.
        let view = BlobView::parse(&blob).unwrap();
        let e = standardise(
            &view,
            ok.iter().map(|(p, v)| TileReading { pixel: *p, v, flags: brdf_meter::protocol::flags::UNDER_EXPOSED }),
            tile,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("flagged the tile's reading (under-exposed)"), "{e}");
        // The out-of-prior flag judges the estimate, not the readings.
        let s = standardise(
            &view,
            ok.iter().map(|(p, v)| TileReading { pixel: *p, v, flags: brdf_meter::protocol::flags::OUT_OF_PRIOR }),
            tile,
        );
        assert!(s.is_ok());
    }

    #[test]
    fn a_tile_is_checked() {
        assert!(Tile::new(0.99, 0.005).is_ok());
        for (rf, u, why) in
            [(0.0, 0.0, "--tile-rf 0"), (1.6, 0.0, "at most 1.5"), (f64::NAN, 0.0, "--tile-rf"), (0.9, 0.2, "--tile-u")]
        {
            let e = Tile::new(rf, u).unwrap_err().to_string();
            assert!(e.contains(why), "{e}");
        }
    }
}
