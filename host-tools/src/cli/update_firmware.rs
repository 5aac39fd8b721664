//! `host-tools update-firmware`: a signed firmware image onto a device over
//! its link, then a reset into it (on trial until its self-test passes).
use crate::device::link::{Client, Endpoint, LinkError};
use anyhow::{Context, bail};
use brdf_meter::firmware::image;
use std::path::PathBuf;
use std::time::Instant;

/// Send a signed firmware image (`host-tools sign-firmware`) to a device:
/// the device checks it whole (CRC, target, signature) before it marks it
/// for the bootloader, then resets into it on trial. A refused or
/// interrupted update leaves the running firmware as it is; run the
/// command again to resume an interrupted transfer.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The device.
    #[command(flatten)]
    pub device: Endpoint,
    /// The signed firmware image.
    #[arg(long, value_name = "IMAGE", required_unless_present = "reboot_only")]
    pub image: Option<PathBuf>,
    /// Commit without resetting (the update starts at the next reset).
    #[arg(long)]
    pub no_reboot: bool,
    /// Send nothing, only reset the device (into an update committed
    /// earlier with --no-reboot or by dfu-util).
    #[arg(long, conflicts_with_all = ["image", "no_reboot"])]
    pub reboot_only: bool,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let Some(path) = &a.image else {
        let mut c = Client::new(a.device.open()?)?;
        c.reboot().context("asking the device to reset")?;
        println!("the device resets (into a committed update, if one is waiting)");
        return Ok(());
    };
    let name = path.display().to_string();
    let bytes = std::fs::read(path).with_context(|| format!("reading {name}"))?;
    let mut trailer = [0u8; image::FW_TRAILER_LEN];
    if bytes.len() < trailer.len() {
        bail!("{name} is not a signed firmware image (sign it with `host-tools sign-firmware`)");
    }
    trailer.copy_from_slice(&bytes[bytes.len() - image::FW_TRAILER_LEN..]);
    let (manifest, _) =
        image::decode_trailer(&trailer, bytes.len() as u32).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let mut c = Client::new(a.device.open()?)?;
    let fw = c.firmware_info().context("asking the device for its firmware")?;
    if fw.target != manifest.target {
        bail!("{name} is built for {:?}, the device is {:?}: nothing was sent", manifest.target, fw.target);
    }
    let t0 = Instant::now();
    // When the last chunk was acknowledged: the rest is the device's check.
    let mut sent = t0;
    let version = c
        .update_firmware(&bytes, |done, total| {
            eprint!("\rsent {done} of {total} bytes");
            sent = Instant::now();
        })
        .map_err(|e| match e {
            LinkError::Device(d) => anyhow::anyhow!("{d}"),
            e => anyhow::anyhow!("{e} (run the command again to resume; the running firmware is untouched)"),
        })?;
    eprintln!();
    let (transfer, total) = ((sent - t0).as_secs_f64(), t0.elapsed().as_secs_f64());
    println!(
        "{name}: firmware {}.{}.{} ({} bytes) sent in {transfer:.2} s ({:.1} KiB/s), verified and marked by the device in {:.2} s more: {total:.2} s in all",
        version[0],
        version[1],
        version[2],
        bytes.len(),
        bytes.len() as f64 / 1024.0 / transfer.max(1e-9),
        total - transfer
    );
    if a.no_reboot {
        println!("not reset: the update starts at the device's next reset");
    } else {
        c.reboot().context("asking the device to reset")?;
        println!("the device resets into it; it confirms itself after its self-test, else the next reset reverts it");
    }
    Ok(())
}
