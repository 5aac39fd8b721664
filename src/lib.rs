//! The instrument's shared library: everything the firmware and the host tools
//! must agree on lives here, once, so both sides compute bit-identical results.
//!
//! Data flow (each stage in the module named for it):
//! host training --> [`blob`] (calibration blob) --> device flash --> [`kernel`]
//! (`rho = W v` per point) --> frames --> host.
//!
//! The library is `no_std`, never depends on host code or on a board, and
//! allocates nothing.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]

pub mod blob;
pub mod hw;
pub mod kernel;
pub mod acquire;
#[cfg(feature = "app")]
pub mod app;
pub mod estimate;
pub mod protocol;
pub mod scale_free;
pub mod scene;
#[cfg(any(test, feature = "sim"))]
pub mod sim;
pub mod store;

// The board firmware's watchdog health rule is pure logic: its tests run here,
// on the host (the board layer itself only builds for the chip).
#[cfg(test)]
#[path = "board/health.rs"]
mod board_health;
