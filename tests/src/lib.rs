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
//! - [`meta_bits`] / [`expected_meta_bits`]: what a streamed point and the
//!   host's reproduction of it must share bit for bit besides the values.
pub mod fuzz_bodies;
pub mod link_faults;
pub mod qemu;
pub mod sim;

use host_tools::device::link::PointRecord;
use host_tools::device::reference::ExpectedPoint;

/// A point's fields besides its values, floats as bits: zone, cluster, flags,
/// sigma_scale, the gloss readings and their uncertainties.
pub type MetaBits = (u16, u8, u8, u32, [u32; 3], [u32; 3]);

/// [`MetaBits`] of a streamed point.
pub fn meta_bits(p: &PointRecord) -> MetaBits {
    (
        p.zone,
        p.cluster,
        p.flags,
        p.sigma_scale.to_bits(),
        p.readings.map(f32::to_bits),
        p.reading_sigma.map(f32::to_bits),
    )
}

/// [`MetaBits`] of the host's reproduction of a point.
pub fn expected_meta_bits(w: &ExpectedPoint) -> MetaBits {
    (
        w.zone,
        w.cluster,
        w.flags,
        w.sigma_scale.to_bits(),
        w.readings.map(f32::to_bits),
        w.reading_sigma.map(f32::to_bits),
    )
}
