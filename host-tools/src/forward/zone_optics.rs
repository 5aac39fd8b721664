//! The optics of each zone of pixels, as training consumes them: first pixel,
//! the system matrix H at the zone's centre and each LED's centre angle. The
//! forward model owns them (a scene computes them per position,
//! [`crate::forward::scene::training_optics`]); training only reads them.
use crate::forward::grid::AngleGrid;
use crate::forward::optics::{Instrument, system_matrix};
use anyhow::{Context, ensure};
use brdf_meter::blob::MAX_PIXELS;
use nalgebra::DMatrix;

/// The optics of one zone.
#[derive(Clone, Debug)]
pub struct ZoneOptics {
    /// First pixel of the zone.
    pub first_pixel: usize,
    /// System matrix, m x n.
    pub h: DMatrix<f64>,
    /// Incidence angle of each LED's centre ray at the zone's centre, degrees (m).
    pub centres_deg: Vec<f64>,
}

/// Zones of equal width, each with the same optics (the instrument's point).
pub fn uniform_zones(
    inst: &Instrument,
    grid: &AngleGrid,
    zones: usize,
    pixels: usize,
    far_field: bool,
) -> anyhow::Result<Vec<ZoneOptics>> {
    ensure!((1..=MAX_PIXELS).contains(&pixels), "pixels = {pixels}: must be 1..={MAX_PIXELS}");
    ensure!(zones >= 1 && zones <= pixels, "zones = {zones}: must be 1..=pixels ({pixels})");
    let h = system_matrix(inst, grid, far_field).context("computing the system matrix H")?;
    let centres = inst.centre_angles_deg();
    Ok((0..zones)
        .map(|z| ZoneOptics { first_pixel: z * pixels / zones, h: h.clone(), centres_deg: centres.clone() })
        .collect())
}
