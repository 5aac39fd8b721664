//! On-device inspection, the host's side: teaching a recipe from a
//! reference sample (`teach`), on lines simulated from a scene or measured
//! by the device itself (`measured`), deciding lines exactly as the device
//! does (`lines`), the statistics of a run (`spc`), the defect map (`defect_map`)
//! and the probability of detection against false calls on simulated runs
//! (`roc`). The decision itself is the device library's
//! (`brdf_meter::inspect`), called here as it is there.
pub mod bench;
pub mod defect_map;
pub mod lines;
pub mod measured;
pub mod roc;
pub mod spc;
pub mod teach;
