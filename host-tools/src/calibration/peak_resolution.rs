//! The calibration's peak resolution: the narrowest lobe it puts out.
//!
//! A mirror spike (the black-glass standard: all its light within a
//! fraction of a degree of the mirror direction) comes out of every
//! calibration as a lobe of some width, because seven readings through
//! LEDs degrees apart cannot say how narrow a lobe is below a certain
//! width: the prior says it. That width is the calibration's resolution,
//! as a spectrometer's bandwidth is the width it reads a line with. It is
//! measured here as metrologists measure a bandwidth, on the narrowest
//! thing there is: the full width at half maximum (`crate::output::peak`)
//! of the device's estimate of the black glass (`device::reference`, the
//! device's rule on the blob, from each pixel's own noise-free readings of
//! the standard). The widest over the pixels that see it is the
//! calibration's, which holds for every pixel; each pixel's own is
//! recorded beside it when some pixel resolves finer (`brdf_meter::blob`,
//! flag bit 7): on the handheld the mirror direction falls between the LEDs
//! at some pixels and on one at others, and the pixels' widths run from
//! 0.74 to 1.16 deg.
//!
//! The host then reads a specular peak whose width is within
//! `crate::output::peak::RESOLVED_WIDTH_FACTOR` of its pixel's resolution
//! as not resolved: its
//! height and width are the prior's, not the readings', so no uncertainty
//! is stated for them (`crate::output::peak::Peak::stated`). On the
//! patent profile the black glass comes out 0.76 deg wide, the gloss
//! standards' mirror spikes 0.75-0.96 deg against a truth of one 0.5 deg
//! bin, 45 % low at the peak; the measured set's polished materials come
//! out as wide (0.77-0.9 deg) whatever their own width (0.7-1.5 deg).
use crate::calibration::f32_gate::F32Plan;
use crate::calibration::gloss_rows;
use crate::device::reference::PointEstimator;
use crate::forward::zone_optics::ZoneOptics;
use crate::output::peak::specular_peak;
use brdf_meter::blob::BlobView;

/// The width of the black glass's specular peak as `view`'s calibration
/// estimates it at every pixel of `zones` (with their f32 plans), each
/// sought about its pixel's own view: one value per pixel, NaN where the
/// estimate has no width (the pixel does not see the standard, or the grid
/// does not hold its peak).
pub fn black_glass_widths(view: &BlobView<'_>, zones: &[ZoneOptics], plans: &[F32Plan]) -> anyhow::Result<Vec<f64>> {
    let d = view.dims();
    let grid: Vec<f32> = (0..d.n).map(|i| view.grid_deg(i)).collect();
    let mut widths = vec![f64::NAN; d.pixels];
    for (z, (zo, plan)) in zones.iter().zip(plans).enumerate() {
        let est = PointEstimator::new(*view, z)?;
        let end = zones.get(z + 1).map_or(d.pixels, |n| n.first_pixel);
        for (p, w) in widths.iter_mut().enumerate().take(end).skip(zo.first_pixel) {
            let px = zo.pixel(p);
            let v = plan.readings(&gloss_rows::black_glass_readings(px));
            if v.iter().all(|x| *x == 0.0) {
                continue;
            }
            let e = est.apply_pixel(p, &v);
            *w = specular_peak(&grid, &e.rho, &e.sigma, px.theta_o_deg).width_deg;
        }
    }
    Ok(widths)
}

/// What a blob records of the pixels' `widths` ([`black_glass_widths`]):
/// the calibration's resolution, the widest (`None` when no pixel has a
/// width), and each pixel's own, in f32 as the blob holds them; the
/// per-pixel values only when they say more than the widest does (some
/// pixel resolves finer), so a calibration whose pixels all resolve alike
/// (the patent profile's one pixel) writes the header's value alone.
pub fn recorded(widths: &[f64]) -> (Option<f32>, Vec<f32>) {
    let own: Vec<f32> = widths.iter().map(|w| if w.is_finite() { *w as f32 } else { f32::NAN }).collect();
    let widest = own.iter().copied().filter(|w| !w.is_nan()).reduce(f32::max);
    match widest {
        Some(r) if own.iter().any(|w| !w.is_nan() && *w < r) => (widest, own),
        _ => (widest, Vec::new()),
    }
}

#[cfg(test)]
mod tests {
    use super::recorded;

    #[test]
    fn the_widest_is_the_calibrations_and_each_pixel_keeps_its_own_only_when_finer() {
        let nan = f64::NAN;
        let (r, own) = recorded(&[0.8, nan, 1.1, 0.9]);
        assert_eq!(r, Some(1.1));
        assert_eq!(own[0], 0.8);
        assert!(own[1].is_nan());
        assert_eq!(&own[2..], &[1.1, 0.9]);
        // One pixel, or every pixel alike: the header's value says it all.
        assert_eq!(recorded(&[0.76]), (Some(0.76), vec![]));
        assert_eq!(recorded(&[1.0, nan, 1.0]), (Some(1.0), vec![]));
        // No pixel sees the standard: nothing recorded.
        assert_eq!(recorded(&[nan, nan]), (None, vec![]));
    }
}
