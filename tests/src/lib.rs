//! Shared harness for the cross-part tests.
//!
//! - [`sim`]: the host simulation of the firmware: the application's three
//!   tasks on an embassy executor polled by the test, with embassy-time's mock
//!   driver (simulated time advances only when the device is idle, so runs are
//!   deterministic), an in-memory NOR flash and an in-memory link. It is a
//!   `host_tools::device::link::Transport`, so host-tools' own client drives it.
//! - [`fuzz_bodies`]: the fuzz targets' bodies, shared by the cargo-fuzz
//!   crate (`tests/fuzz/`) and the stable corpus replay (`fuzz_replay.rs`).
//! - [`link_faults`]: a seeded faulty link between the client and the
//!   simulated device, and the soak over it (`link_faults.rs`, example
//!   `link_soak`).
//! - [`qemu`]: building the QEMU firmware once and running it under QEMU.
pub mod fuzz_bodies;
pub mod link_faults;
pub mod qemu;
pub mod sim;
