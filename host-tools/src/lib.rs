//! Host tools for the BRDF meter: optics, BRDF models, priors, training,
//! baselines, evaluation, the device link and the command line.
//!
//! Data flow: optics (instrument -> system matrix H) + prior (sample BRDFs ->
//! R_pp) + noise model (R_nn) -> training (W per zone) -> calibration blob
//! (format owned by the `brdf_meter` no_std library) -> device -> frames -> host.

pub mod brdf;
pub mod cli;
pub mod config;
pub mod estimators;
pub mod firmware_budget;
pub mod fitting;
pub mod grid;
pub mod held_out;
pub mod io;
pub mod link;
pub mod optics;
pub mod plot;
pub mod prior;
pub mod prior_measured;
pub mod scene;
pub mod stability;
pub mod reproduce;
pub mod tradeoff;
pub mod train;
pub mod train_scale_free;
pub mod swd;
