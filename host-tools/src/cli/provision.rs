//! `host-tools provision`: send a calibration blob to a device.
use crate::device::link::Endpoint;
use crate::device::provision;
use std::path::PathBuf;

/// Provision a signed calibration (made by `host-tools train --sign` or
/// `host-tools sign`) onto a device. Its signature is checked against the
/// keys the firmware trusts before anything is sent; the device verifies it
/// whole (CRC, signature, format, sizes) before it replaces the
/// active calibration; on any failure it keeps the one it had.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The device.
    #[command(flatten)]
    pub device: Endpoint,
    /// The signed calibration.
    #[arg(long, value_name = "PATH")]
    pub blob: PathBuf,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let bytes = provision::read_blob(&a.blob)?;
    let mut c = crate::device::link::Client::new(a.device.open()?)?;
    let mut last = 0;
    let cal = provision::usb::provision(&mut c, &bytes, &a.blob.display().to_string(), |done, total| {
        let pct = done * 100 / total.max(1);
        if pct >= last + 10 || done == total {
            eprintln!("  {done}/{total} bytes ({pct} %)");
            last = pct;
        }
    })?;
    println!(
        "provisioned {}: blob CRC {:#010x}, {} zones, slot {}, sequence {}, matrices {}",
        a.blob.display(),
        cal.blob_crc,
        cal.zones,
        provision::slot_name(cal.slot),
        cal.sequence,
        if cal.in_ram { "in RAM" } else { "read in place from flash" }
    );
    Ok(())
}
