//! Host tools for the BRDF meter. The modules follow the data flow: optics
//! (instrument -> system matrix H) + prior (sample BRDFs -> R_pp) + noise
//! model (R_nn) -> training (W per zone) -> calibration blob (format owned by
//! the `brdf_meter` no_std library) -> device -> frames -> host.
//!
//! Imports run one way: `cli` -> `evaluation` -> `calibration` -> `forward`
//! -> `brdf_meter`, with `device` beside `calibration` (it may use
//! `calibration` and `forward`, never `evaluation`). `output::io` and
//! `output::config` are leaves any layer may use, and so are
//! `output::progress` and the standard files (`output::bird`,
//! `output::astm_e1392` on `output::profile`'s plain numbers); `output::plot`
//! draws the forward model's, evaluation's and measurements' results for the CLI.

pub mod calibration; // estimators and training: H + prior + noise -> W per zone -> blob
pub mod cli; // one file per subcommand: parse arguments, call the library
pub mod device; // link, provisioning (USB, SWD), memory map, reference computation, firmware budget
pub mod evaluation; // accuracy and cost: fitting, reproduce, tradeoff, stability, metrology (held-out figures of one calibration as the device applies it), one timing harness
pub mod forward; // the forward model: BRDFs, angle grid, optics, priors, per-zone optics, scenes
pub mod inspection; // on-device inspection's host side: teach, the device's decision, SPC, defect map, ROC
pub mod output; // atomic file writes, plots, progress, TOML/CSV description parsing, BiRD JSON and ASTM E1392 files
