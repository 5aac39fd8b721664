//! The optics of each zone of pixels, as training consumes them: the zone's
//! first pixel, its centre pixel's optics (the in-plane system matrix H, the
//! LEDs' centre angles and the view whose specular direction the zone's
//! gloss reference is read at) and the pixels its sample pairs are taken at
//! (`crate::forward::pairs`: each with its own rays, view and noise, so a
//! zone's estimator is trained for every pixel it serves, not only its
//! centre). The forward model owns them (a scene computes them per
//! position, [`crate::forward::scene::training_optics`]); training only
//! reads them.
use crate::forward::grid::AngleGrid;
use crate::forward::optics::{Instrument, Optics, RayModel};
use crate::forward::pairs::PixelOptics;
use crate::forward::reading_noise::ReadingNoise;
use anyhow::{Context, ensure};
use brdf_meter::blob::MAX_PIXELS;
use nalgebra::{DMatrix, Vector3};

/// Most pixels of one zone that its sample pairs are taken at (evenly
/// spread over the zone, its ends included): enough to follow how the
/// optics change across a zone, few enough that training stays fast.
pub const MAX_TRAINING_PIXELS: usize = 5;

/// The optics of one zone.
#[derive(Clone, Debug)]
pub struct ZoneOptics {
    /// First pixel of the zone.
    pub first_pixel: usize,
    /// The optics at the zone's centre.
    pub centre: PixelOptics,
    /// The pixels training's sample pairs are taken at.
    pub pixels: Vec<PixelOptics>,
    /// Every pixel of the zone, first to last (empty when the zone's pixels
    /// all have the centre's optics): where the zone's gloss reference is
    /// read, pixel by pixel.
    pub every: Vec<PixelOptics>,
}

impl ZoneOptics {
    /// System matrix at the zone's centre, m x n.
    pub fn h(&self) -> &DMatrix<f64> {
        &self.centre.h
    }

    /// Incidence angle of each LED's centre ray at the zone's centre, degrees (m).
    pub fn centres_deg(&self) -> &[f64] {
        &self.centre.centres_deg
    }

    /// The optics of pixel `p` of the zone (its own when known, else the centre's).
    pub fn pixel(&self, p: usize) -> &PixelOptics {
        p.checked_sub(self.first_pixel).and_then(|i| self.every.get(i)).unwrap_or(&self.centre)
    }

    /// A zone whose optics are only an in-plane system matrix `h` (seen
    /// along `view_deg`, readings `H rho`, noise `noise`): its centre is its
    /// one training pixel.
    pub fn from_h(
        first_pixel: usize,
        h: DMatrix<f64>,
        centres_deg: Vec<f64>,
        view_deg: f64,
        grid: &AngleGrid,
        noise: ReadingNoise,
    ) -> Self {
        let t = view_deg.to_radians();
        let centre = PixelOptics::from_h(0.0, h, Vector3::new(t.sin(), 0.0, t.cos()), centres_deg, noise, grid);
        Self { first_pixel, pixels: vec![centre.clone()], centre, every: Vec::new() }
    }
}

/// The pixels of a zone `first..=last` whose pairs train it: all of them up
/// to [`MAX_TRAINING_PIXELS`], else that many evenly spread, ends included.
pub fn training_pixels(first: usize, last: usize) -> Vec<usize> {
    let len = last - first + 1;
    if len <= MAX_TRAINING_PIXELS {
        return (first..=last).collect();
    }
    let k = MAX_TRAINING_PIXELS;
    let mut out: Vec<usize> = (0..k).map(|i| first + (i * (len - 1) + (k - 1) / 2) / (k - 1)).collect();
    out.dedup();
    out
}

/// Zones of equal width, each with the same optics (the instrument's point
/// and view; readings relative noise `noise_rel`).
pub fn uniform_zones(
    inst: &Instrument,
    grid: &AngleGrid,
    zones: usize,
    pixels: usize,
    far_field: bool,
    noise_rel: f64,
) -> anyhow::Result<Vec<ZoneOptics>> {
    ensure!((1..=MAX_PIXELS).contains(&pixels), "pixels = {pixels}: must be 1..={MAX_PIXELS}");
    ensure!(zones >= 1 && zones <= pixels, "zones = {zones}: must be 1..=pixels ({pixels})");
    let optics = Optics::new(inst, RayModel::legacy(far_field));
    let centre = PixelOptics::new(
        &optics,
        grid,
        0.0,
        &Vector3::from(inst.point.position_cm),
        optics.frame() * inst.view_dir(),
        inst.centre_angles_deg(),
        ReadingNoise::relative(noise_rel, inst.m()),
    )
    .context("computing the system matrix H")?;
    Ok((0..zones)
        .map(|z| ZoneOptics {
            first_pixel: z * pixels / zones,
            pixels: vec![centre.clone()],
            centre: centre.clone(),
            every: Vec::new(),
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn training_pixels_spread_over_the_zone_with_its_ends() {
        assert_eq!(training_pixels(4, 6), vec![4, 5, 6]);
        assert_eq!(training_pixels(0, 127), vec![0, 32, 64, 95, 127]);
        assert_eq!(training_pixels(8, 15), vec![8, 10, 12, 13, 15]);
        assert_eq!(training_pixels(3, 3), vec![3]);
    }
}
