//! `--corrected-with CAL`: logged readings that were corrected with another
//! calibration's white reference than the one they are now estimated or
//! standardised with.
//!
//! The device divides every raw reading by the white reference of the
//! calibration it runs. A white standardisation changes only that white
//! (`crate::calibration::standardise`), so readings logged under the
//! calibration as trained, or written by `simulate` (whose readings are
//! corrected with the scene's own white, the white the calibration was
//! trained with), are not what the standardised instrument would have
//! read: estimated with the standardised calibration as they are, they
//! still carry the drift it corrects. This puts them back: each reading
//! times the white it was divided by over the one it is now divided by,
//! pixel by pixel and LED by LED, which is `(raw - dark) / white` with the
//! new white. It is how a standardisation is replayed offline, and how a
//! gloss standardisation or a `verify` is made from readings logged before
//! the white was standardised.
use crate::cli::estimate::ReadingsRow;
use crate::forward::scene::frames::SAME_OPTICS_TOLERANCE;
use anyhow::{Context, bail, ensure};
use brdf_meter::blob::{BlobView, WHITE_RATIO_RANGE};
use std::path::{Path, PathBuf};

/// The calibration whose white reference logged readings were corrected with.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct CorrectedWith {
    /// The calibration whose white reference the logged readings were
    /// corrected with, when it is not --blob's: e.g. the calibration as
    /// trained, for `simulate`'s points.csv read by its white-standardised
    /// successor. Each reading is taken times that white over --blob's,
    /// pixel by pixel, as the device running --blob would have corrected it
    #[arg(long = "corrected-with", value_name = "CAL")]
    pub path: Option<PathBuf>,
}

impl CorrectedWith {
    /// Refuses the option for readings taken from the device now, which
    /// corrects them with the calibration it runs (`logged`: whether the
    /// readings are logged ones).
    pub fn check_logged(&self, logged: bool) -> anyhow::Result<()> {
        ensure!(
            logged || self.path.is_none(),
            "--corrected-with applies to logged readings (--readings): the device corrects the readings it takes \
             now with the calibration it runs"
        );
        Ok(())
    }

    /// Takes `rows`, read from `readings`, to `to`'s white when a
    /// calibration is named (row by row, each with its pixel's factors).
    pub fn apply(&self, to: &BlobView<'_>, readings: &Path, rows: &mut [ReadingsRow]) -> anyhow::Result<()> {
        if let Some(t) = self.transfer(to, readings)? {
            for (k, r) in rows.iter_mut().enumerate() {
                t.apply(k + 1, r.pixel, &mut r.v)?;
            }
        }
        Ok(())
    }

    /// The transfer from the named calibration's white to `to`'s (`None`
    /// when none is named). `readings` names the readings in messages.
    fn transfer(&self, to: &BlobView<'_>, readings: &Path) -> anyhow::Result<Option<WhiteTransfer>> {
        let Some(path) = &self.path else { return Ok(None) };
        let bytes = crate::device::provision::read_blob_to_decode(path)
            .with_context(|| format!("--corrected-with {}", path.display()))?;
        let from = BlobView::parse(&bytes).expect("read_blob_to_decode checked it");
        WhiteTransfer::new(&from, to, &format!("--corrected-with {}", path.display()), readings).map(Some)
    }
}

/// Per pixel and reading, the factor that takes a reading corrected with
/// one white reference to the same reading corrected with another.
#[derive(Clone, Debug, PartialEq)]
pub struct WhiteTransfer {
    m: usize,
    /// Pixel-major `P x m`: `white_from / white_to`.
    factor: Vec<f32>,
    /// The readings, as messages name them.
    readings: String,
}

impl WhiteTransfer {
    /// From the white of `from` (named `name`) to the white of `to`. Both
    /// must be for the same sensor and LEDs, fired in the same order, and
    /// `to`'s white must be `from`'s as a standardisation leaves it (below):
    /// another instrument's is refused, not taken for this one drifted.
    pub fn new(from: &BlobView<'_>, to: &BlobView<'_>, name: &str, readings: &Path) -> anyhow::Result<Self> {
        let (df, dt) = (from.dims(), to.dims());
        ensure!(
            (df.pixels, df.m) == (dt.pixels, dt.m),
            "{name} is a calibration for {} pixels x {} LEDs, --blob's for {} x {}: the readings were not \
             corrected for this instrument",
            df.pixels,
            df.m,
            dt.pixels,
            dt.m
        );
        ensure!(
            from.led_order() == to.led_order(),
            "{name} fires its LEDs in the order {:?}, --blob in {:?}: the readings' columns would be other LEDs'",
            from.led_order(),
            to.led_order()
        );
        // The standardisation's rule (`forward::scene::frames::check_optics`
        // judges a scene against a calibration by the same): under each
        // LED, the whites' ratio over the pixels is one level, within the
        // range a standardisation may move it, and each pixel's within
        // `SAME_OPTICS_TOLERANCE` of it. A standardisation rescales each
        // pixel by its own mean over the tile, which differs from the
        // level by the tile's noise (a few tenths of a percent); another
        // instrument's white differs in its profile over the pixels.
        let (lo, hi) = WHITE_RATIO_RANGE;
        let (pixels, m) = (dt.pixels, dt.m);
        let ratio = |p: usize, i: usize| f64::from(to.white(p, i)) / f64::from(from.white(p, i));
        for i in 0..m {
            let led = to.led_order()[i];
            let mut levels: Vec<f64> = (0..pixels).map(|p| ratio(p, i)).collect();
            levels.sort_by(f64::total_cmp);
            let level = levels[pixels / 2];
            if !(level >= f64::from(lo) && level <= f64::from(hi)) {
                bail!(
                    "{name}: under LED {led}, --blob's white reference is {level:.3} times its own (a \
                     standardisation moves it by {lo} to {hi} times): not the same instrument's; name the \
                     calibration the readings were logged with"
                );
            }
            for p in 0..pixels {
                let r = ratio(p, i);
                if !(r.is_finite() && (r - level).abs() <= SAME_OPTICS_TOLERANCE * r.abs().max(level)) {
                    bail!(
                        "{name}: at pixel {p}, LED {led}, --blob's white reference is {r:.4} times its own, where \
                         the other pixels' are {level:.4} times: not the same instrument's white, drifted; name \
                         the calibration the readings were logged with"
                    );
                }
            }
        }
        let factor = (0..pixels * m)
            .map(|k| (f64::from(from.white(k / m, k % m)) / f64::from(to.white(k / m, k % m))) as f32)
            .collect();
        Ok(Self { m: dt.m, factor, readings: readings.display().to_string() })
    }

    /// Re-corrects the readings `v` of pixel `pixel` (row `row` of the
    /// readings, as messages name it; `None`: the row names no pixel).
    pub fn apply(&self, row: usize, pixel: Option<usize>, v: &mut [f32]) -> anyhow::Result<()> {
        let Some(p) = pixel else {
            bail!(
                "{}: row {row}: no `pixel` column; --corrected-with needs each reading's pixel, whose white it was \
                 corrected with (simulate's points.csv has it)",
                self.readings
            );
        };
        let Some(f) = self.factor.get(p * self.m..(p + 1) * self.m) else {
            bail!("{}: row {row}: pixel {p} is not one of the calibration's pixels", self.readings);
        };
        for (x, f) in v.iter_mut().zip(f) {
            *x *= f;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A calibration of 4 pixels x 3 LEDs, its white values scaled by
    /// `scale(pixel, reading)`.
    fn blob_with_white(scale: impl Fn(usize, usize) -> f32) -> Vec<u8> {
        let mut parts = brdf_meter::test_blobs::TestBlobParts::new(9, 3, 1, 4, 0.5);
        for (k, w) in parts.white.iter_mut().enumerate() {
            *w *= scale(k / 3, k % 3);
        }
        parts.encode()
    }

    #[test]
    fn readings_are_taken_to_the_new_white_pixel_by_pixel_and_led_by_led() {
        let old = blob_with_white(|_, _| 1.0);
        let new = blob_with_white(|p, i| 1.0 + 0.1 * i as f32 + 0.002 * p as f32);
        let (vo, vn) = (BlobView::parse(&old).unwrap(), BlobView::parse(&new).unwrap());
        let t = WhiteTransfer::new(&vo, &vn, "old", Path::new("r.csv")).unwrap();
        // A reading the old white gave x is raw / w_old; the new white
        // gives raw / w_new = x w_old / w_new.
        let mut v = [0.5f32, 0.5, 0.5];
        t.apply(1, Some(2), &mut v).unwrap();
        for (i, x) in v.iter().enumerate() {
            let want = 0.5 * vo.white(2, i) / vn.white(2, i);
            assert!((x - want).abs() <= 1e-6 * want, "LED {i}: {x} against {want}");
        }
        // The same calibration on both sides changes nothing.
        let same = WhiteTransfer::new(&vo, &vo, "old", Path::new("r.csv")).unwrap();
        let mut w = [0.25f32, 0.5, 0.75];
        same.apply(1, Some(0), &mut w).unwrap();
        assert_eq!(w, [0.25, 0.5, 0.75]);
        // A row without a pixel, or past the calibration's, is refused.
        let e = t.apply(7, None, &mut w).unwrap_err().to_string();
        assert!(e.contains("r.csv: row 7") && e.contains("`pixel`"), "{e}");
        assert!(t.apply(8, Some(4), &mut w).unwrap_err().to_string().contains("pixel 4"));
    }

    const WHITE_TRANSFER_NAME: &str = "--corrected-with a.blob";

    fn refused_not(from: &[u8], to: &[u8]) {
        let (f, t) = (BlobView::parse(from).unwrap(), BlobView::parse(to).unwrap());
        WhiteTransfer::new(&f, &t, WHITE_TRANSFER_NAME, Path::new("r.csv")).unwrap();
    }

    #[test]
    fn the_option_is_for_logged_readings_only() {
        let named = CorrectedWith { path: Some("cal.blob".into()) };
        assert!(named.check_logged(true).is_ok() && CorrectedWith::default().check_logged(false).is_ok());
        let e = named.check_logged(false).unwrap_err().to_string();
        assert!(e.contains("--corrected-with applies to logged readings"), "{e}");
    }

    #[test]
    fn another_instruments_white_or_shape_is_refused() {
        let old = blob_with_white(|_, _| 1.0);
        let refused = |to: &[u8]| {
            let (f, t) = (BlobView::parse(&old).unwrap(), BlobView::parse(to).unwrap());
            WhiteTransfer::new(&f, &t, WHITE_TRANSFER_NAME, Path::new("r.csv")).unwrap_err().to_string()
        };
        // An LED 2.5 times brighter, or one pixel's white 5 % off the
        // others' under an LED: another instrument's.
        let e = refused(&blob_with_white(|_, i| if i == 1 { 2.5 } else { 1.0 }));
        assert!(e.starts_with(WHITE_TRANSFER_NAME) && e.contains("under LED") && e.contains("2.500 times"), "{e}");
        let e = refused(&blob_with_white(|p, i| if (p, i) == (3, 1) { 1.25 } else { 1.2 }));
        assert!(e.contains("at pixel 3") && e.contains("not the same instrument's"), "{e}");
        // Each pixel by its own noise about the LED's level: the same.
        refused_not(&old, &blob_with_white(|p, i| 1.2 + 0.1 * i as f32 + 0.002 * p as f32));
        let other = brdf_meter::test_blobs::test_blob(9, 3, 1, 5, 0.5);
        let e = WhiteTransfer::new(
            &BlobView::parse(&other).unwrap(),
            &BlobView::parse(&old).unwrap(),
            "--corrected-with b.blob",
            Path::new("r.csv"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("5 pixels x 3 LEDs") && e.contains("4 x 3"), "{e}");
    }
}
