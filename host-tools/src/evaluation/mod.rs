//! Evaluation: how accurate and how fast the estimators are. Ward fitting
//! (the patent's baseline), the patent's Table 6 (`reproduce`), accuracy
//! against time (`tradeoff`), hard-case stability (`stability`), all timed
//! by one harness (`timing`).
pub mod timing;
pub mod fitting;
pub mod reproduce;
pub mod tradeoff;
pub mod stability;
pub mod held_out;
pub mod device_cost;
