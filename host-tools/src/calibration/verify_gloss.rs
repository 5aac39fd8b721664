//! Verification on a certified gloss standard: does the instrument read a
//! standard it was not standardised on within what both state?
//!
//! ISO 2813 has a gloss meter, once standardised on the high-gloss
//! standard, checked on a working standard of another gloss level. The
//! comparison a calibration laboratory signs is the normalised error
//! `E_n = |x - X| / sqrt(U_x^2 + U_X^2)`, both expanded uncertainties at
//! about 95 %: `x` what the instrument read, `X` the certified value, `U_X`
//! the certificate's at the coverage factor it states (2 unless told).
//! `E_n <= 1` is agreement. Here `x` is a zone's mean reading over the lines read and
//! `U_x` the expanded uncertainty `measure` states for such a mean
//! (`crate::device::measurement_result`): its calibration's (the RMS of
//! what it states for each reading, mostly the estimator's error for this
//! kind of surface, which averaging points does not reduce), the
//! repeatability of the mean, the white reference's and the gloss
//! scale's. A zone that fails says the stated uncertainty does not hold
//! there: standardise again, and if it still fails, calibrate the unit
//! again.
use crate::calibration::standardise::check_standard_reading;
use crate::calibration::standardise_gloss::REFUSED;
use crate::device::measurement_result::{Contribution, References, reading_result, zone_pixels};
use anyhow::ensure;
use brdf_meter::blob::BlobView;
use brdf_meter::gloss::SPECULAR_GU;
use serde::Serialize;

/// A certified gloss standard: its value at the instrument's geometry,
/// that value's standard uncertainty (k = 1), GU, and the coverage factor
/// of the expanded uncertainty its certificate states.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GlossStandard {
    /// Certified gloss, GU.
    pub gu: f64,
    /// Its standard uncertainty (k = 1), GU.
    pub u_gu: f64,
    /// The certificate's coverage factor: its expanded uncertainty, which
    /// E_n takes, is `k u_gu`.
    pub k: f64,
}

impl GlossStandard {
    /// A standard, checked: `gu` above 0 and at most 2,000 GU (a mirror),
    /// `u_gu` at least 0 and at most `gu`, `k` at least 1 (the command
    /// line's `crate::cli::certificate` checks what the user entered).
    pub fn new(gu: f64, u_gu: f64, k: f64) -> anyhow::Result<Self> {
        ensure!(
            gu.is_finite() && gu > 0.0 && gu <= 2000.0,
            "--gloss-gu {gu}: a gloss standard's certified value is above 0 and at most 2000 GU (take the value for \
             this geometry from its certificate)"
        );
        ensure!(
            u_gu.is_finite() && u_gu >= 0.0 && u_gu <= gu,
            "--gloss-u: the certificate's standard uncertainty {u_gu} GU (k = 1) is not at least 0 and at most \
             --gloss-gu (a certificate at k = 2 states twice it: give that with --gloss-k 2)"
        );
        ensure!(k.is_finite() && k >= 1.0, "the certificate's coverage factor {k} is not one: at least 1");
        Ok(Self { gu, u_gu, k })
    }
}

/// One point's gloss reading of the standard and the uncertainty its
/// calibration stated for it (k = 1, before the references' are added).
#[derive(Clone, Copy, Debug)]
pub struct StatedGloss {
    /// The pixel.
    pub pixel: usize,
    /// Its specular gloss, GU.
    pub gu: f32,
    /// The calibration's standard uncertainty of it, GU.
    pub u_gu: f32,
    /// The point's flags (`brdf_meter::protocol::flags`).
    pub flags: u8,
}

/// One zone's verdict.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ZoneVerdict {
    /// The zone.
    pub zone: usize,
    /// Its first pixel.
    pub first_pixel: usize,
    /// Its last pixel.
    pub last_pixel: usize,
    /// Points read.
    pub points: usize,
    /// Their mean gloss, GU.
    pub mean_gu: f64,
    /// Its combined standard uncertainty, GU: the budget's.
    pub u_gu: f64,
    /// The budget (`crate::device::measurement_result`).
    pub budget: Vec<Contribution>,
    /// Mean minus the certified value, GU.
    pub deviation_gu: f64,
    /// The normalised error (k = 2 on both sides).
    pub e_n: f64,
    /// `e_n <= 1`.
    pub agrees: bool,
}

/// A verification: the standard and every zone's verdict.
#[derive(Clone, Debug, Serialize)]
pub struct Verification {
    /// The standard.
    pub standard: GlossStandard,
    /// The zones that read gloss.
    pub zones: Vec<ZoneVerdict>,
    /// Every zone agrees.
    pub agrees: bool,
    /// The calibration verified.
    pub crc: u32,
}

/// Verifies the calibration `view` on `standard` from its stated gloss
/// readings, zone by zone.
pub fn verify_gloss(
    view: &BlobView<'_>,
    readings: impl IntoIterator<Item = StatedGloss>,
    standard: GlossStandard,
) -> anyhow::Result<Verification> {
    ensure!(view.has_gloss(), "this calibration reads no gloss (its blob has no gloss section): nothing to verify");
    let (pixels, zones) = (view.dims().pixels, view.dims().zones);
    // Per zone: each reading and its calibration's uncertainty.
    let mut acc: Vec<Vec<(f64, f64)>> = vec![Vec::new(); zones];
    for r in readings {
        check_standard_reading(
            r.pixel,
            pixels,
            r.flags & REFUSED,
            "the standard's reading",
            "it is not read as a gloss standard is; nothing was verified",
        )?;
        if r.gu.is_nan() {
            // A zone that reads no gloss.
            continue;
        }
        ensure!(
            r.gu.is_finite() && r.u_gu.is_finite() && r.u_gu >= 0.0,
            "pixel {}: gloss {} GU, stated uncertainty {} GU: not a reading to verify",
            r.pixel,
            r.gu,
            r.u_gu
        );
        acc[view.zone_of_pixel(r.pixel)].push((f64::from(r.gu), f64::from(r.u_gu)));
    }
    let references = References::of(view);
    let zones: Vec<ZoneVerdict> = acc
        .iter()
        .enumerate()
        .filter_map(|(zone, points)| {
            let r = reading_result(SPECULAR_GU, points, (references.white, references.gloss_scale))?;
            let deviation = r.value - standard.gu;
            // Each side's expanded uncertainty: the reading's with its own
            // coverage factor, the certificate's at k = 2.
            let e_n = deviation.abs() / r.expanded_u.hypot(standard.k * standard.u_gu);
            let (first_pixel, last_pixel) = zone_pixels(view, zone);
            Some(ZoneVerdict {
                zone,
                first_pixel,
                last_pixel,
                points: r.points,
                mean_gu: r.value,
                u_gu: r.u,
                budget: r.budget,
                deviation_gu: deviation,
                e_n,
                agrees: e_n <= 1.0,
            })
        })
        .collect();
    ensure!(!zones.is_empty(), "no point read gloss: nothing to verify");
    let agrees = zones.iter().all(|z| z.agrees);
    Ok(Verification { standard, zones, agrees, crc: view.crc() })
}

impl Verification {
    /// The report's lines.
    pub fn table(&self) -> String {
        let mut s = format!(
            "standard: certified {} GU (u = {} GU, U = {:.3} GU at k = {}); E_n = |reading - certified| / \
             sqrt(U_reading^2 + U_certified^2), U = k u (the reading's k from its effective degrees of freedom, 2 \
             with many; the certificate's as it states)\nzone  pixels  points  reads GU  stated u GU  deviation GU   E_n  verdict\n",
            self.standard.gu,
            self.standard.u_gu,
            self.standard.k * self.standard.u_gu,
            self.standard.k
        );
        for z in &self.zones {
            s += &format!(
                "{:>4}  {:>6}  {:>6}  {:>8.2}  {:>11.2}  {:>+12.2}  {:>4.2}  {}\n",
                z.zone,
                format!("{}-{}", z.first_pixel, z.last_pixel),
                z.points,
                z.mean_gu,
                z.u_gu,
                z.deviation_gu,
                z.e_n,
                if z.agrees { "agrees" } else { "DOES NOT AGREE" }
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blob() -> Vec<u8> {
        brdf_meter::test_blobs::test_blob_with_gloss(9, 5, 2, 8, 0.5, Some(1))
    }

    fn points(gu: impl Fn(usize) -> f32, u: f32) -> Vec<StatedGloss> {
        (0..4)
            .flat_map(|_| {
                (0..8).map(|p| StatedGloss { pixel: p, gu: if p < 4 { gu(p) } else { f32::NAN }, u_gu: u, flags: 0 })
            })
            .collect()
    }

    #[test]
    fn a_zone_agrees_within_what_both_state_and_not_beyond() {
        let b = blob();
        let view = BlobView::parse(&b).unwrap();
        let standard = GlossStandard::new(48.0, 0.4, 2.0).unwrap();
        // Reading 49 with u 0.8: E_n = 1 / (2 sqrt(0.8^2 + 0.4^2)) = 0.56.
        let v = verify_gloss(&view, points(|_| 49.0, 0.8), standard).unwrap();
        assert_eq!(v.zones.len(), 1, "the zone without gloss is not verified");
        let z = &v.zones[0];
        assert_eq!((z.points, z.first_pixel), (16, 0));
        assert!((z.e_n - 1.0 / (2.0 * 0.8f64.hypot(0.4))).abs() < 1e-6, "{z:?}");
        assert!(v.agrees && z.agrees);
        assert!(v.table().contains("agrees"), "{}", v.table());
        // Reading 50.5: E_n 1.40.
        let v = verify_gloss(&view, points(|_| 50.5, 0.8), standard).unwrap();
        assert!(!v.agrees && (v.zones[0].e_n - 1.398).abs() < 1e-3, "{:?}", v.zones[0]);
        assert!(v.table().contains("DOES NOT AGREE"));
        // Reading 50: E_n = 2 / sqrt(1.6^2 + 0.8^2) = 1.12 with the
        // certificate's u at k = 2; the same u stated at k = 3.5 (U 1.4 GU):
        // 2 / sqrt(1.6^2 + 1.4^2) = 0.94, which agrees.
        let v = verify_gloss(&view, points(|_| 50.0, 0.8), standard).unwrap();
        assert!(!v.agrees && (v.zones[0].e_n - 2.0 / 1.6f64.hypot(0.8)).abs() < 1e-6, "{:?}", v.zones[0]);
        let wide = GlossStandard { k: 3.5, ..standard };
        let v = verify_gloss(&view, points(|_| 50.0, 0.8), wide).unwrap();
        assert!(v.agrees && (v.zones[0].e_n - 2.0 / 1.6f64.hypot(1.4)).abs() < 1e-6, "{:?}", v.zones[0]);
        assert!(v.table().contains("(u = 0.4 GU, U = 1.400 GU at k = 3.5)"), "{}", v.table());
        // The zone's u is the budget of its mean as `measure` states it:
        // the RMS of the points' (not shrunk by their count) and the
        // mean's repeatability.
        let v = verify_gloss(&view, points(|p| 48.0 + p as f32 * 0.1, 0.5), standard).unwrap();
        let z = &v.zones[0];
        let gu: Vec<f64> = (0..16).map(|i| f64::from(48.0 + (i % 4) as f32 * 0.1)).collect();
        let mean = gu.iter().sum::<f64>() / 16.0;
        let sd = (gu.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 15.0).sqrt();
        assert_eq!(z.budget[0].source, "calibration");
        assert!((z.budget[0].u - 0.5).abs() < 1e-6, "{z:?}");
        assert!((z.u_gu - 0.5f64.hypot(sd / 4.0)).abs() < 1e-6, "{z:?}");
    }

    #[test]
    fn what_cannot_be_verified_is_refused() {
        let b = blob();
        let view = BlobView::parse(&b).unwrap();
        let standard = GlossStandard::new(48.0, 0.4, 2.0).unwrap();
        let mut ps = points(|_| 48.0, 0.8);
        ps[2].flags = brdf_meter::protocol::flags::SATURATED;
        let e = verify_gloss(&view, ps, standard).unwrap_err().to_string();
        assert!(e.contains("pixel 2: the device flagged the standard's reading (saturated)"), "{e}");
        let mut ps = points(|_| 48.0, 0.8);
        ps[1].u_gu = f32::NAN;
        assert!(verify_gloss(&view, ps, standard).unwrap_err().to_string().contains("pixel 1"));
        assert!(verify_gloss(&view, points(|_| f32::NAN, 0.8), standard).is_err());
        let plain = brdf_meter::test_blobs::test_blob(9, 5, 2, 8, 0.5);
        let e = verify_gloss(&BlobView::parse(&plain).unwrap(), points(|_| 48.0, 0.8), standard).unwrap_err();
        assert!(e.to_string().contains("reads no gloss"));
        for (gu, u) in [(0.0, 0.0), (2500.0, 1.0), (50.0, 60.0), (f64::NAN, 0.0)] {
            assert!(GlossStandard::new(gu, u, 2.0).is_err(), "{gu} {u}");
        }
        for k in [0.5, f64::NAN] {
            assert!(GlossStandard::new(48.0, 0.4, k).is_err(), "{k}");
        }
    }
}
