//! The cross-part tests, one test binary: each file below is a module of it.
//!
//! One binary rather than one per file, because cargo runs test binaries one
//! after another and links each against host-tools: in one binary the QEMU
//! tests run beside the host-simulation ones on the other core, and the
//! linking is done once. Run one area with its module as the filter:
//! `cargo test --release -p system-tests --test system -- qemu_e2e::`.
//! (The host simulations take turns anyway: they share embassy-time's mock
//! clock, `system_tests::sim`.)

mod board_golden;
mod device_guards;
mod firmware_update;
mod fuzz_replay;
mod golden_bytes;
mod host_sim;
mod inspection;
mod link_faults;
mod power_cut;
mod qemu_e2e;
mod qemu_inspection;
mod qemu_stack_overflow;
mod qemu_update;
mod signed_calibration;
mod update_over_link;
