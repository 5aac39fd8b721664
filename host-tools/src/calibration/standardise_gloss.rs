//! Standardisation of the gloss scale on a certified black-glass standard,
//! as every ISO 2813 gloss meter is standardised: the calibration's gloss
//! references rescaled so the standard reads its certified value.
//!
//! The gloss reading is `G = q L_0`, `q = assigned / S` (`brdf_meter::gloss`),
//! where `S` is what training's model of the instrument read of the ideal
//! black glass. A real instrument's optics differ from its model a little
//! (a facet's tilt, stray light), and a working standard's certificate
//! states what it reads: so each reference `S` is multiplied by the
//! standard's mean reading over its certified value, and the standard then
//! reads that value.
//!
//! It corrects the gloss scale only. Standardise on the white tile first
//! ([`crate::calibration::standardise`]): drift since calibration belongs in
//! the white, where it corrects every bin; taken into the gloss scale it
//! would be counted twice when the white is standardised next. A black
//! glass reading beyond [`GLOSS_RATIO_RANGE`] of its value is refused for
//! that reason. The white's uncertainty stays in the gloss readings' (the
//! host adds both); this adds the gloss scale's: the certificate's and
//! the scatter of the standard's mean reading.
use crate::calibration::standardise::{MAX_SCATTER, check_standard_reading};
use anyhow::{bail, ensure};
use brdf_meter::blob::BlobView;
use brdf_meter::protocol::flags;
use serde::Serialize;

/// How far a gloss reference may move (the standard's reading over its
/// certified value): the blob's own rule,
/// [`brdf_meter::blob::GLOSS_RATIO_RANGE`].
pub const GLOSS_RATIO_RANGE: (f64, f64) =
    (brdf_meter::blob::GLOSS_RATIO_RANGE.0 as f64, brdf_meter::blob::GLOSS_RATIO_RANGE.1 as f64);

/// The flags that refuse a reading of a gloss standard (here and in
/// `verify_gloss`): saturated or not a number. Under-exposed is not one: a
/// glossy standard is dark under every LED but those near its mirror
/// direction, and the gloss rows read it as such (the out-of-prior flag
/// judges the estimate, as for the white tile).
pub(crate) const REFUSED: u8 = flags::SATURATED | flags::NON_FINITE;

/// The black-glass standard: its certified gloss at the instrument's
/// geometry and that value's standard uncertainty (k = 1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BlackGlass {
    /// Certified gloss, GU (the primary standard, n = 1.567, is 100).
    pub gu: f64,
    /// Its standard uncertainty (k = 1), GU.
    pub u_gu: f64,
}

impl BlackGlass {
    /// A standard, checked: `gu` in [10, 200], `u_gu` in [0, gu / 20].
    pub fn new(gu: f64, u_gu: f64) -> anyhow::Result<Self> {
        ensure!(
            gu.is_finite() && (10.0..=200.0).contains(&gu),
            "--black-glass-gu {gu}: a black-glass gloss standard's certified value is 10 to 200 GU (the primary \
             standard reads 100; take the value for this geometry from its certificate)"
        );
        ensure!(
            u_gu.is_finite() && u_gu >= 0.0 && u_gu <= gu / 20.0,
            "--black-glass-u: the certificate's standard uncertainty {u_gu} (k = 1) is not at least 0 and at most \
             5 % of --black-glass-gu (a certificate at k = 2 states twice it: give that with --black-glass-k 2)"
        );
        Ok(Self { gu, u_gu })
    }
}

/// One point's gloss reading of the standard.
#[derive(Clone, Copy, Debug)]
pub struct GlossReading {
    /// The line it was read in.
    pub line: u64,
    /// The pixel.
    pub pixel: usize,
    /// Its specular gloss, GU, with the calibration standardised.
    pub gu: f32,
    /// The point's flags (`brdf_meter::protocol::flags`).
    pub flags: u8,
}

/// A gloss standardisation: the new references and what they rest on.
#[derive(Clone, Debug, Serialize)]
pub struct GlossStandardisation {
    /// The standard.
    pub standard: BlackGlass,
    /// The fewest readings of a pixel (lines measured).
    pub lines: usize,
    /// The standard's mean reading over its certified value, per zone:
    /// median, least and greatest (1: the scale was right).
    pub ratio_median: f64,
    /// The least.
    pub ratio_min: f64,
    /// The greatest.
    pub ratio_max: f64,
    /// The largest relative standard error of a zone's mean reading.
    pub scatter_max: f64,
    /// The gloss scale's relative standard uncertainty (k = 1): the
    /// certificate's and the worst mean's scatter, in quadrature. The
    /// blob states it and the host adds it to gloss and haze.
    pub u_rel: f64,
    /// The CRC of the calibration standardised.
    pub crc_before: u32,
    /// The new gloss references, in the blob's order (NaN where a zone
    /// reads no gloss).
    #[serde(skip)]
    pub references: Vec<f32>,
}

/// Standardises the gloss scale of the calibration `view` on `standard`
/// from its gloss readings (made with this calibration), one factor per
/// zone: the zone is what training fits as one, and a factor per pixel
/// would carry each pixel's noise into its scale (on the handheld's scene
/// the pixels' own gloss scales differ by about 0.04 GU at 100 GU, less
/// than the 0.06 GU noise of a pixel's 64-line mean). Every pixel that reads gloss needs at
/// least two readings.
pub fn standardise_gloss(
    view: &BlobView<'_>,
    readings: impl IntoIterator<Item = GlossReading>,
    standard: BlackGlass,
) -> anyhow::Result<GlossStandardisation> {
    ensure!(
        view.has_gloss(),
        "this calibration reads no gloss (its blob has no gloss section): there is no gloss scale to standardise"
    );
    let (pixels, zones) = (view.dims().pixels, view.dims().zones);
    let reads_gloss = |z: usize| view.gloss_reference(view.zone_start(z) as usize).is_some_and(|s| !s.is_nan());
    // Per pixel: count; per zone and line: count, sum.
    let mut per_pixel = vec![0usize; pixels];
    let mut acc = vec![std::collections::BTreeMap::<u64, (usize, f64)>::new(); zones];
    for r in readings {
        check_standard_reading(
            r.pixel,
            pixels,
            r.flags & REFUSED,
            "the standard's reading",
            "the black glass is not under the instrument, or not lit as it should be; nothing was standardised",
        )?;
        let z = view.zone_of_pixel(r.pixel);
        if !reads_gloss(z) {
            continue;
        }
        ensure!(
            r.gu.is_finite() && r.gu > 0.0,
            "pixel {}: the black glass reads {} GU, not a gloss reading; nothing was standardised",
            r.pixel,
            r.gu
        );
        per_pixel[r.pixel] += 1;
        let a = acc[z].entry(r.line).or_default();
        *a = (a.0 + 1, a.1 + f64::from(r.gu));
    }
    let reading_pixels: Vec<usize> = (0..pixels).filter(|p| reads_gloss(view.zone_of_pixel(*p))).collect();
    ensure!(!reading_pixels.is_empty(), "no pixel of this calibration reads gloss: nothing to standardise");
    let lines = reading_pixels.iter().map(|p| per_pixel[*p]).min().unwrap_or(0);
    if lines < 2 {
        let p = *reading_pixels.iter().find(|p| per_pixel[**p] < 2).expect("the fewest is below 2");
        bail!(
            "pixel {p}: {} reading(s) of the black glass; a standardisation needs at least 2 of every pixel (measure \
             more lines)",
            per_pixel[p]
        );
    }
    // Per zone, the mean reading over the certified value (NaN: no gloss).
    let mut zone_ratio = vec![f64::NAN; zones];
    let (mut ratios, mut worst) = (Vec::new(), 0.0f64);
    for (z, by_line) in acc.iter().enumerate().filter(|(z, _)| reads_gloss(*z)) {
        // The zone's mean over each line, then over the lines: what moves
        // a whole line (the standard, the light) is in its scatter.
        let means: Vec<f64> = by_line.values().map(|(k, sum)| sum / *k as f64).collect();
        let n = means.len();
        let mean = means.iter().sum::<f64>() / n as f64;
        let var = means.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1).max(1) as f64;
        let sem = (var / n as f64).sqrt() / mean;
        let r = mean / standard.gu;
        let first = view.zone_start(z);
        ensure!(
            (GLOSS_RATIO_RANGE.0..=GLOSS_RATIO_RANGE.1).contains(&r),
            "zone {z} (from pixel {first}): the black glass reads {mean:.2} GU, {r:.3} times its certified {} GU: \
             outside {:.1}..{:.1} times. Standardise on the white tile first (the LEDs drift, and that belongs in the white \
             reference), and check that this is the standard certified at {} GU, clean and seated. Nothing was \
             standardised",
            standard.gu,
            GLOSS_RATIO_RANGE.0,
            GLOSS_RATIO_RANGE.1,
            standard.gu
        );
        ensure!(
            sem <= MAX_SCATTER,
            "zone {z} (from pixel {first}): the black glass's readings scatter by {:.2} % (the standard error of \
             their mean over {n} lines), above {} %: the standard moved, or light leaks in. Reseat it, or measure \
             more lines. Nothing was standardised",
            100.0 * sem,
            100.0 * MAX_SCATTER
        );
        zone_ratio[z] = r;
        ratios.push(r);
        worst = worst.max(sem);
    }
    let refs = view.gloss_reference_count();
    let references = (0..refs)
        .map(|k| {
            // A reference is a pixel's (format version 4) or a zone's (3).
            let (p, z) = if refs == pixels { (k, view.zone_of_pixel(k)) } else { (view.zone_start(k) as usize, k) };
            let old = view.gloss_reference(p).expect("the blob has the gloss section");
            if old.is_nan() { old } else { (f64::from(old) * zone_ratio[z]) as f32 }
        })
        .collect();
    ratios.sort_by(f64::total_cmp);
    let u_rel = ((standard.u_gu / standard.gu).powi(2) + worst * worst).sqrt();
    Ok(GlossStandardisation {
        standard,
        lines,
        ratio_median: ratios[ratios.len() / 2],
        ratio_min: ratios[0],
        ratio_max: ratios[ratios.len() - 1],
        scatter_max: worst,
        u_rel,
        crc_before: view.crc(),
        references,
    })
}

impl GlossStandardisation {
    /// The calibration `blob` (the one standardised, unsigned) with the new
    /// gloss references and the scale's uncertainty: a new calibration.
    pub fn blob(&self, blob: &[u8]) -> anyhow::Result<Vec<u8>> {
        crate::calibration::standardise::standardised_blob(
            blob,
            self.crc_before,
            (brdf_meter::blob::with_gloss_uncertainty, self.u_rel, "the gloss scale's uncertainty"),
            (
                |b: &mut [u8]| brdf_meter::blob::rewrite_gloss_references(b, &self.references),
                "the new gloss references",
            ),
        )
    }

    /// The report's lines.
    pub fn table(&self) -> String {
        format!(
            "black glass: certified {} GU (u = {} GU), {} lines\nit read {:+.2} % of its value (median over the zones; \
             {:+.2} .. {:+.2} %), the worst zone's mean known to {:.3} %\nthe gloss scale's relative \
             standard uncertainty: {:.3} % (certificate {:.3} %, scatter {:.3} %), stated in the calibration: every \
             gloss and haze reading carries it, with the white reference's\n",
            self.standard.gu,
            self.standard.u_gu,
            self.lines,
            100.0 * (self.ratio_median - 1.0),
            100.0 * (self.ratio_min - 1.0),
            100.0 * (self.ratio_max - 1.0),
            100.0 * self.scatter_max,
            100.0 * self.u_rel,
            100.0 * self.standard.u_gu / self.standard.gu,
            100.0 * self.scatter_max
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: usize = 8;

    /// A calibration with gloss readings, one reference per pixel; zone 1
    /// (pixels 4-7) reads no gloss when `dark_zone`.
    fn glossy(dark_zone: bool) -> Vec<u8> {
        brdf_meter::test_blobs::test_blob_with_gloss(9, 5, 2, P, 0.5, dark_zone.then_some(1))
    }

    /// `lines` readings of every pixel: `gu(p)` with an alternating wobble.
    fn lines(gu: impl Fn(usize) -> f32, wobble: f32, n: usize) -> Vec<GlossReading> {
        (0..n)
            .flat_map(|l| {
                let w = if l % 2 == 0 { 1.0 + wobble } else { 1.0 - wobble };
                (0..P).map(|p| GlossReading { line: l as u64, pixel: p, gu: gu(p) * w, flags: 0 }).collect::<Vec<_>>()
            })
            .collect()
    }

    #[test]
    fn the_scale_error_goes_into_the_references_and_the_standard_then_reads_its_value() {
        let blob = glossy(true);
        let view = BlobView::parse(&blob).unwrap();
        let standard = BlackGlass::new(94.0, 0.4).unwrap();
        // The instrument reads the standard 3 % high at pixel 0, rising to
        // 6 % at pixel 3: zone 0 reads 4.5 % high.
        let gu = |p: usize| if p < 4 { 94.0 * (1.03 + 0.01 * p as f32) } else { f32::NAN };
        let s = standardise_gloss(&view, lines(gu, 0.001, 6), standard).unwrap();
        assert_eq!(s.lines, 6);
        let new = s.blob(&blob).unwrap();
        let nv = BlobView::parse(&new).unwrap();
        assert_eq!(nv.gloss_uncertainty(), s.u_rel as f32);
        let mut zone_mean = 0.0;
        for p in 0..P {
            let (old, now) = (view.gloss_reference(p).unwrap(), nv.gloss_reference(p).unwrap());
            if p < 4 {
                // G = assigned L_0 / S: with S scaled by the zone's ratio,
                // the same L_0 reads the certified value on the zone's mean.
                let l0 = f64::from(gu(p)) * f64::from(old) / 100.0;
                zone_mean += 100.0 * l0 / f64::from(now) / 4.0;
                assert!((f64::from(now / old) - 1.045).abs() < 1e-5, "pixel {p}");
            } else {
                assert!(now.is_nan(), "a zone that reads no gloss keeps none");
            }
        }
        assert!((zone_mean - 94.0).abs() < 1e-3, "{zone_mean}");
        assert!((s.ratio_min - 1.045).abs() < 1e-4 && (s.ratio_max - 1.045).abs() < 1e-4, "{s:?}");
        // The certificate's 0.43 % and the zone's scatter (its pixels differ).
        assert!(s.u_rel > 0.4 / 94.0 && s.u_rel < 0.0065, "{}", s.u_rel);
        assert!(s.table().contains("certified 94 GU"), "{}", s.table());
        assert!(s.blob(&glossy(false)).unwrap_err().to_string().contains("was made for"));
    }

    #[test]
    fn readings_that_cannot_be_the_standards_are_refused() {
        let blob = glossy(false);
        let view = BlobView::parse(&blob).unwrap();
        let standard = BlackGlass::new(100.0, 0.0).unwrap();
        let refused = |r: Vec<GlossReading>, why: &str| {
            let e = format!("{:#}", standardise_gloss(&view, r, standard).unwrap_err());
            assert!(e.contains(why), "{why}: {e}");
        };
        // LEDs 20 % brighter than the white reference says: the white first.
        refused(lines(|_| 120.0, 0.0, 4), "Standardise on the white tile first");
        refused(
            lines(|p| if p >= 4 { 85.0 } else { 100.0 }, 0.0, 4),
            "zone 1 (from pixel 4): the black glass reads 85.00 GU",
        );
        refused(lines(|_| 100.0, 0.0, 1), "at least 2 of every pixel");
        refused(lines(|_| 100.0, 0.05, 4), "scatter by 2.89 %");
        refused(lines(|p| if p == 2 { f32::NAN } else { 100.0 }, 0.0, 4), "pixel 2: the black glass reads NaN GU");
        let mut flagged = lines(|_| 100.0, 0.0, 4);
        flagged[3].flags = flags::SATURATED;
        refused(flagged, "pixel 3: the device flagged the standard's reading (saturated)");
        // Dark under most LEDs, and unlike the prior: still the black glass.
        let mut dark = lines(|_| 100.0, 0.0, 4);
        for r in &mut dark {
            r.flags = flags::UNDER_EXPOSED | flags::OUT_OF_PRIOR;
        }
        assert!(standardise_gloss(&view, dark, standard).is_ok());
        // A calibration without gloss readings has no scale to standardise.
        let plain = brdf_meter::test_blobs::test_blob(9, 5, 2, P, 0.5);
        let e = standardise_gloss(&BlobView::parse(&plain).unwrap(), lines(|_| 100.0, 0.0, 4), standard)
            .unwrap_err()
            .to_string();
        assert!(e.contains("reads no gloss"), "{e}");
    }

    #[test]
    fn a_standard_is_checked() {
        assert!(BlackGlass::new(93.5, 0.5).is_ok());
        for (gu, u, why) in [(5.0, 0.0, "10 to 200 GU"), (f64::NAN, 0.0, "--black-glass-gu"), (100.0, 6.0, "5 %")] {
            assert!(BlackGlass::new(gu, u).unwrap_err().to_string().contains(why), "{gu} {u}");
        }
    }
}
