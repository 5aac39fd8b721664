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
    let blob =
        crate::calibration::signing::check_signed(image, name, crate::calibration::signing::Signed::Calibration)?;
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

/// The calibration a device runs, read to decode its points with
/// (`measure`, `inspect run`): a signed file is checked as [`read_blob`]
/// checks it; an unsigned blob (what `train` wrote before it was signed) is
/// taken as it parses, since what says whether it is the one the device
/// runs is the device's CRC ([`check_device_runs`]).
pub fn read_blob_to_decode(path: &Path) -> anyhow::Result<Vec<u8>> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let name = path.display().to_string();
    if brdf_meter::signed::split(&bytes).is_ok() {
        parse_signed(&bytes, &name)?;
    } else {
        parse_blob(&bytes, &name)?;
    }
    Ok(bytes)
}

/// Refuses a blob (CRC `crc`, from `path`) that is not the calibration the
/// device reports running (`runs`, from its `Info`).
pub fn check_device_runs(runs: Option<brdf_meter::protocol::CalInfo>, crc: u32, path: &Path) -> anyhow::Result<()> {
    match runs {
        None => {
            anyhow::bail!("the device has no calibration: provision {} first (`host-tools provision`)", path.display())
        }
        Some(cal) if cal.blob_crc != crc => anyhow::bail!(
            "the device runs calibration {:#010x} but {} is {crc:#010x}: give the blob it runs, or provision this one",
            cal.blob_crc,
            path.display()
        ),
        Some(_) => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_blob_to_decode_with_may_be_signed_or_not_but_must_be_whole() {
        let dir = tempfile::tempdir().unwrap();
        let blob = brdf_meter::test_blobs::test_blob(9, 3, 1, 4, 1.0);
        let unsigned = dir.path().join("cal.blob");
        std::fs::write(&unsigned, &blob).unwrap();
        assert_eq!(read_blob_to_decode(&unsigned).unwrap(), blob);
        use crate::calibration::signing::{DEV_SECRET, sign_blob};
        let signed_path = dir.path().join("cal.signed.blob");
        std::fs::write(&signed_path, sign_blob(&blob, &DEV_SECRET)).unwrap();
        assert_eq!(
            BlobView::parse(&read_blob_to_decode(&signed_path).unwrap()).unwrap().crc(),
            BlobView::parse(&blob).unwrap().crc()
        );
        let mut tampered = std::fs::read(&signed_path).unwrap();
        tampered[20] ^= 1;
        std::fs::write(&signed_path, &tampered).unwrap();
        assert!(read_blob_to_decode(&signed_path).unwrap_err().to_string().contains("refused"));
        std::fs::write(&unsigned, &blob[..blob.len() / 2]).unwrap();
        assert!(read_blob_to_decode(&unsigned).unwrap_err().to_string().contains("not a valid calibration blob"));
    }
}
