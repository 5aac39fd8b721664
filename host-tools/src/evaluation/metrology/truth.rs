//! What a surface really is, by the definitions the instrument's outputs
//! claim to estimate: its binned BRDF on the grid (each bin the kernel
//! average of the reflectance factor over the bin, a mirror spike projected
//! onto its bins: `forward::brdf::binned_reflectance_at`), its gloss
//! readings in three dimensions (`forward::gloss::model_readings`), its
//! specular peak, and the noise-free readings the instrument takes of it
//! (`forward::optics::simulate_readings`, near-field: every ray at its exact
//! direction, whatever field model the calibration was trained with).
use crate::forward::brdf::{Brdf, binned_reflectance_at};
use crate::forward::gloss::model_readings;
use crate::forward::grid::AngleGrid;
use crate::forward::optics::{Instrument, simulate_readings, surface_frame};
use crate::forward::prior_models::SampleModel;
use crate::output::peak::{Peak, specular_peak};
use nalgebra::DVector;

/// One surface's truth.
#[derive(Clone, Debug)]
pub struct Truth {
    /// The binned BRDF (reflectance factors, n).
    pub rho: DVector<f64>,
    /// Its largest bin: what every BRDF error is relative to.
    pub peak: f64,
    /// Gloss GU, haze HU, distinctness % by the definitions in three dimensions.
    pub readings: [f64; 3],
    /// The specular peak of the binned BRDF (no uncertainty).
    pub specular: Peak,
    /// Noise-free white-calibrated readings (m).
    pub clean: DVector<f64>,
    /// The surface as a prior's grid vector (no mirror spike): how a
    /// surface that is also a training sample is recognised.
    pub as_prior: DVector<f64>,
}

impl Truth {
    /// What tells two surfaces apart as training samples: the grid vector
    /// and the gloss readings (which see the mirror spike the grid vector
    /// leaves out).
    pub fn signature(&self) -> DVector<f64> {
        DVector::from_iterator(
            self.as_prior.len() + self.readings.len(),
            self.as_prior.iter().chain(&self.readings).map(|x| if x.is_finite() { *x } else { 0.0 }),
        )
    }

    /// The truth of `brdf` seen by `inst` on `grid`, at the view the
    /// readings are simulated with (the instrument's, in the surface frame).
    pub fn of(brdf: &std::sync::Arc<dyn Brdf>, inst: &Instrument, grid: &AngleGrid) -> Self {
        let wo = surface_frame(&inst.normal()) * inst.view_dir();
        let rho = DVector::from_iterator(
            grid.n(),
            grid.bins_deg().iter().map(|t| binned_reflectance_at(brdf.as_ref(), *t, &wo, grid.step_deg())),
        );
        let bins32: Vec<f32> = grid.bins_deg().iter().map(|x| *x as f32).collect();
        let rho32: Vec<f32> = rho.iter().map(|x| *x as f32).collect();
        let specular = specular_peak(&bins32, &rho32, &vec![0.0; grid.n()], inst.view_deg);
        Self {
            peak: rho.amax(),
            readings: model_readings(brdf.as_ref(), &wo),
            specular,
            clean: simulate_readings(inst, brdf.as_ref(), false),
            as_prior: SampleModel::Brdf(brdf.clone()).on_grid(grid, inst.view_deg),
            rho,
        }
    }
}
