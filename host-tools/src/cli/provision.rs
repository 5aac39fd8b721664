//! `host-tools provision`: send a calibration blob to a device.
use crate::link::Endpoint;
use anyhow::{Context, bail};
use brdf_meter::blob::BlobView;
use std::path::PathBuf;

/// Provision a calibration blob (made by `host-tools train`) onto a device.
/// The device verifies it whole (CRC, format, sizes) before it replaces the
/// active calibration; on any failure it keeps the one it had.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The device.
    #[command(flatten)]
    pub device: Endpoint,
    /// The calibration blob.
    #[arg(long, value_name = "PATH")]
    pub blob: PathBuf,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let bytes = std::fs::read(&a.blob).with_context(|| format!("reading {}", a.blob.display()))?;
    let view = BlobView::parse(&bytes)
        .map_err(|e| anyhow::anyhow!("{} is not a valid calibration blob: {e} (make one with `host-tools train`)", a.blob.display()))?;
    let d = view.dims();
    let mut c = crate::link::Client::new(a.device.open()?)?;
    let info = c.info().context("asking the device for its sizes")?;
    if (d.n, d.m, d.pixels) != (info.bins as usize, info.leds as usize, info.pixels as usize) {
        bail!(
            "{} was made for n = {}, m = {}, P = {} but the device is n = {}, m = {}, P = {}: train for this device (e.g. `host-tools train --pixels {}`)",
            a.blob.display(), d.n, d.m, d.pixels, info.bins, info.leds, info.pixels, info.pixels
        );
    }
    if bytes.len() > info.max_blob as usize {
        bail!("{} is {} bytes; the device's slots hold {} (use fewer zones)", a.blob.display(), bytes.len(), info.max_blob);
    }
    let mut last = 0;
    let cal = c
        .provision(&bytes, |done, total| {
            let pct = done * 100 / total.max(1);
            if pct >= last + 10 || done == total {
                eprintln!("  {done}/{total} bytes ({pct} %)");
                last = pct;
            }
        })
        .context("provisioning (the device keeps its previous calibration)")?;
    println!(
        "provisioned {}: blob CRC {:#010x}, {} zones, slot {}, sequence {}, matrices {}",
        a.blob.display(),
        cal.blob_crc,
        cal.zones,
        if cal.slot == 0 { "A" } else { "B" },
        cal.sequence,
        if cal.in_ram { "in RAM" } else { "read in place from flash" }
    );
    Ok(())
}
