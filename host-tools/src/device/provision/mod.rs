//! Provisioning: putting a calibration blob on a device, in one place.
//!
//! - [`usb`]: over the device link; the running firmware verifies the blob
//!   whole and stores it, keeping its previous calibration on any failure;
//! - [`swd`]: factory provisioning over SWD with the probe-rs command line
//!   (no firmware needed), writing the slot the device's store would write.
//!
//! Both read the signed calibration with [`read_blob`], which refuses what
//! the device refuses (an unsigned, tampered or foreign-key signature, a
//! malformed blob) before anything reaches a device.
pub mod swd;
pub mod usb;

use anyhow::Context;
use brdf_meter::blob::BlobView;
use std::path::Path;

/// Reads a signed calibration file (blob and signature trailer), checks its
/// signature against the keys the firmware trusts and the blob with the
/// device's parser; returns all its bytes (what is sent to the device).
pub fn read_blob(path: &Path) -> anyhow::Result<Vec<u8>> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    parse_signed(&bytes, &path.display().to_string())?;
    Ok(bytes)
}

/// Checks a signed calibration (named `name` in the error): the signature
/// against the keys the firmware trusts, then the blob with the device's
/// parser; returns the blob's view.
pub fn parse_signed<'a>(image: &'a [u8], name: &str) -> anyhow::Result<BlobView<'a>> {
    let blob = crate::calibration::signing::check_signed(image, name)?;
    let view = parse_blob(blob, name)?;
    anyhow::ensure!(
        view.as_bytes().len() == blob.len(),
        "{name} has {} bytes between the blob and its signature",
        blob.len() - view.as_bytes().len()
    );
    Ok(view)
}

/// Parses blob bytes (named `name` in the error) with the device's parser.
pub fn parse_blob<'a>(bytes: &'a [u8], name: &str) -> anyhow::Result<BlobView<'a>> {
    BlobView::parse(bytes)
        .map_err(|e| anyhow::anyhow!("{name} is not a valid calibration blob: {e} (make one with `host-tools train`)"))
}

/// A calibration slot's name for people: 0 = A, 1 = B.
pub fn slot_name(slot: u8) -> &'static str {
    if slot == 0 { "A" } else { "B" }
}
