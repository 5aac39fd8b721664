//! The forward model: what the instrument reads for a surface.
//! BRDF models -> angle grid -> optics (rays, system matrix H) -> priors ->
//! per-zone optics -> scenes (the scene simulator and raw frames); and
//! what the instrument reports from a BRDF besides it: the gloss readings'
//! definitions (`gloss`).
pub mod brdf;
pub mod gloss;
pub mod grid;
pub mod optics;
pub mod pairs;
pub mod prior;
pub mod prior_measured;
pub mod prior_models;
pub mod reading_noise;
pub mod scene;
pub mod zone_optics;
