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
//! - [`inspection`]: the inspection tests' calibration, recipe, scene and
//!   the host's reference verdicts (host simulation and QEMU).
//! - [`meta_bits`] / [`expected_meta_bits`]: what a streamed point and the
//!   host's reproduction of it must share bit for bit besides the values.
pub mod fuzz_bodies;
pub mod fw_sim;
pub mod inspection;
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

/// `blob` (unsigned, with the gloss section) with zone `zone` marked as
/// without a gloss reading, as training marks a zone that cannot see the
/// standard (`brdf_meter::blob`, format version 3): its reference and its
/// blocks NaN, the CRC resealed. The section is the last before the CRC.
pub fn without_gloss_reading(blob: &[u8], zone: usize) -> Vec<u8> {
    let view = brdf_meter::blob::BlobView::parse(blob).unwrap();
    assert!(view.has_gloss(), "the blob carries the gloss section");
    let (z, k, m, p) = (view.dims().zones, view.clusters(), view.dims().m, view.dims().pixels);
    // Format 4 holds one reference per pixel, format 3 one per zone.
    let refs = if view.version() >= 4 { p } else { z };
    let crc_at = blob.len() - 4;
    let start = crc_at - 4 * brdf_meter::blob::gloss_len(refs, z, k, m);
    let bl = k * brdf_meter::gloss::block_len(m);
    let mut out = blob.to_vec();
    let head = 2;
    let nan = f32::NAN.to_le_bytes();
    let mut mark = |i: usize| out[start + 4 * i..start + 4 * i + 4].copy_from_slice(&nan);
    if refs == p {
        for px in (0..p).filter(|px| view.zone_of_pixel(*px) == zone) {
            mark(head + px);
        }
    } else {
        mark(head + zone);
    }
    for i in 0..bl {
        mark(head + refs + zone * bl + i);
    }
    let crc = brdf_meter::blob::CRC32.checksum(&out[..crc_at]);
    out[crc_at..].copy_from_slice(&crc.to_le_bytes());
    brdf_meter::blob::BlobView::parse(&out).expect("the marked blob parses");
    out
}

/// Whether zone `zone` of `view` has gloss readings (the section present
/// and the zone not marked as without one).
pub fn zone_has_gloss_reading(view: &brdf_meter::blob::BlobView<'_>, zone: usize) -> bool {
    let mut block = vec![0.0f32; brdf_meter::gloss::block_len(view.dims().m)];
    view.copy_gloss(zone, 0, &mut block).is_some_and(|(_, _, s)| !s.is_nan())
}
