//! The instrument's shared library: everything the firmware and the host tools
//! must agree on lives here, once, so both sides compute bit-identical results.
//!
//! Data flow (each stage in the module named for it):
//! host training --> [`blob`] (calibration blob) --> [`store`] (device flash)
//! --> [`acquire`] (frames to readings) --> [`estimate`] / [`kernel`]
//! (`rho = W v` per point) --> [`protocol`] (frames) --> host.
//!
//! # Module map
//! The library (no_std, allocates nothing, never depends on host code):
//! - [`shape`]: build-time shape (n, m, P per build) and flash geometry.
//! - [`blob`]: the calibration blob format (writer and in-place reader).
//! - [`band`]: which of a calibration's per-bin uncertainty tables a point
//!   takes (sharp or broad estimate).
//! - [`signed`]: signed calibrations (the signature trailer, the trusted keys).
//! - [`store`]: the two-slot calibration store on any NOR flash.
//! - [`firmware`]: firmware updates: the signed image format and (feature
//!   `app`) the updater on embassy-boot.
//! - [`kernel`]: the estimator kernels (f32, Q15, cluster selection).
//! - [`estimate`]: the active calibration and one point's estimate.
//! - [`in_place`]: large statics zeroed where they live, not on the stack.
//! - [`gloss`]: the gloss readings (specular gloss, haze, distinctness) and
//!   their uncertainties, from a point's estimate.
//! - [`inspect`]: on-device inspection: the recipe taught from a reference,
//!   the per-point and per-line decision, the reject output's schedule.
//! - [`acquire`]: raw frames to corrected readings.
//! - [`protocol`]: the wire protocol (messages, errors, framing).
//! - [`hw`]: the hardware traits the application needs.
//! - [`frame_store`]: the frames a simulated line sensor serves.
//! - [`app`] (feature `app`): the platform-agnostic application tasks.
//! - [`test_blobs`] (std or tests): valid blobs for tests.
//!
//! The platforms, each behind its feature ([`platform`]):
//! - `platform::board` (feature `board`, chip only): the B-L475E-IOT01A.
//! - `platform::qemu` (feature `qemu`, chip only): QEMU's b-l475e-iot01a.
//! - `platform::host_sim` (feature `sim`): the host simulation's fakes.
//!
//! The firmware binaries (src/bin/) only wire a platform to [`app`].
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(missing_docs)]

pub mod acquire;
#[cfg(feature = "app")]
pub mod app;
pub mod band;
pub mod blob;
pub mod estimate;
pub mod firmware;
pub mod frame_store;
pub mod gloss;
pub mod hw;
pub mod in_place;
pub mod inspect;
pub mod kernel;
pub mod platform;
pub mod protocol;
pub mod shape;
pub mod signed;
pub mod store;
#[cfg(any(test, feature = "std"))]
pub mod test_blobs;

/// The linear algebra of the estimator's fixed-size types (W, readings, BRDF
/// vectors), re-exported so every user of this library names one version.
pub use nalgebra;
