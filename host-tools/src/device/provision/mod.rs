//! Provisioning: putting a calibration blob on a device, in one place.
//!
//! - [`usb`]: over the device link; the running firmware verifies the blob
//!   whole and stores it, keeping its previous calibration on any failure;
//! - [`swd`]: factory provisioning over SWD with the probe-rs command line
//!   (no firmware needed), writing the slot the device's store would write.
//!
//! Both read the blob with [`read_blob`], which refuses what the device's
//! own parser refuses before anything reaches a device.
pub mod swd;
pub mod usb;

use anyhow::Context;
use brdf_meter::blob::BlobView;
use std::path::Path;

/// Reads a calibration blob file and checks it with the device's parser.
pub fn read_blob(path: &Path) -> anyhow::Result<Vec<u8>> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    parse_blob(&bytes, &path.display().to_string())?;
    Ok(bytes)
}

/// Parses blob bytes (named `name` in the error) with the device's parser.
pub fn parse_blob<'a>(bytes: &'a [u8], name: &str) -> anyhow::Result<BlobView<'a>> {
    BlobView::parse(bytes).map_err(|e| anyhow::anyhow!("{name} is not a valid calibration blob: {e} (make one with `host-tools train`)"))
}

/// A calibration slot's name for people: 0 = A, 1 = B.
pub fn slot_name(slot: u8) -> &'static str {
    if slot == 0 { "A" } else { "B" }
}
