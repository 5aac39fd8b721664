//! Evaluation: how accurate and how fast the estimators are. Ward fitting
//! (the patent's baseline), the patent's Table 6 (`reproduce`), accuracy
//! against time (`tradeoff`), hard-case stability (`stability`), all timed
//! by one harness (`timing`); the figures a metrologist signs for one
//! calibration, held out family by family (`metrology`).
pub mod coverage_interval;
pub mod design;
pub mod device_cost;
pub mod fitting;
pub mod held_out;
pub mod metrology;
pub mod pixel_error;
pub mod pixel_map;
pub mod rate;
pub mod reproduce;
pub mod stability;
pub mod timing;
pub mod tradeoff;
