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
//! the standard), the widest over the pixels that see it, so that it
//! holds for every pixel.
//!
//! The host then reads a specular peak whose width is within
//! `crate::output::peak::RESOLVED_WIDTH_FACTOR` of it as not resolved: its
//! height and width are the prior's, not the readings', so no uncertainty
//! is stated for them (`crate::output::peak::Peak::at_resolution`). On the
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

/// The widest specular peak of the black glass as `view`'s calibration
/// estimates it at the pixels of `zones` (with their f32 plans), each
/// sought about its pixel's own view; `None` when no pixel's estimate of
/// it has a width (no pixel sees it, or the grid does not hold its peak).
pub fn black_glass_width(view: &BlobView<'_>, zones: &[ZoneOptics], plans: &[F32Plan]) -> anyhow::Result<Option<f64>> {
    let d = view.dims();
    let grid: Vec<f32> = (0..d.n).map(|i| view.grid_deg(i)).collect();
    let mut widest: Option<f64> = None;
    for (z, (zo, plan)) in zones.iter().zip(plans).enumerate() {
        let est = PointEstimator::new(*view, z)?;
        let end = zones.get(z + 1).map_or(d.pixels, |n| n.first_pixel);
        for p in zo.first_pixel..end {
            let px = zo.pixel(p);
            let v = plan.readings(&gloss_rows::black_glass_readings(px));
            if v.iter().all(|x| *x == 0.0) {
                continue;
            }
            let e = est.apply_pixel(p, &v);
            let w = specular_peak(&grid, &e.rho, &e.sigma, px.theta_o_deg).width_deg;
            if w.is_finite() {
                widest = Some(widest.map_or(w, |x| x.max(w)));
            }
        }
    }
    Ok(widest)
}
