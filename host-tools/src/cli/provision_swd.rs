//! `provision-swd`: factory provisioning of a calibration blob over SWD with
//! the probe-rs command line (no USB link or running firmware needed).
use std::path::PathBuf;

use anyhow::Result;
use clap::Args as ClapArgs;

use crate::device::memory_map::SlotMap;
use crate::device::provision::{
    self,
    swd::{self, ProbeRs},
};

/// Writes a calibration blob into the board's calibration flash over SWD.
///
/// The blob is checked with the device's own parser, wrapped in the
/// calibration store's slot header and written with `probe-rs download` into
/// the slot that does not hold the device's newest valid calibration (with
/// the next sequence number, so it becomes the active one at the next boot);
/// then read back with `probe-rs read` and compared byte for byte.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The calibration blob (as written by training).
    pub blob: PathBuf,
    /// Write this slot instead of the inactive one (a or b).
    #[arg(long, value_parser = ["a", "b", "A", "B"])]
    pub slot: Option<String>,
    /// The probe-rs executable.
    #[arg(long, default_value = "probe-rs")]
    pub probe_rs: PathBuf,
    /// probe-rs chip name.
    #[arg(long, default_value = swd::CHIP)]
    pub chip: String,
    /// Probe selector (`VID:PID[:serial]`) when several probes are attached.
    #[arg(long)]
    pub probe: Option<String>,
    /// Only write the slot image (header + blob) to this file for slot A,
    /// sequence 1; touch no device.
    #[arg(long)]
    pub image_out: Option<PathBuf>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let blob = provision::read_blob(&args.blob)?;
    if let Some(out) = &args.image_out {
        let (len, addr) = swd::write_slot_image(&blob, out)?;
        println!("slot image: {len} bytes for address {addr:#010x} -> {}", out.display());
        return Ok(());
    }
    let force = args.slot.as_deref().map(|s| if s.eq_ignore_ascii_case("a") { 0 } else { 1 });
    let scratch = swd::scratch_dir()?;
    let probe =
        ProbeRs { program: args.probe_rs, chip: args.chip, probe: args.probe, scratch: scratch.path().to_path_buf() };
    let done = swd::provision(&probe, &SlotMap::board(), &blob, force)?;
    println!(
        "provisioned slot {} at {:#010x}: {} bytes, sequence {}, verified by read-back",
        provision::slot_name(done.slot),
        done.addr,
        done.len,
        done.sequence
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::{Cli, Command};
    use clap::Parser;

    #[test]
    fn the_command_line_parses_and_refuses_unknown_slots() {
        let cli =
            Cli::try_parse_from(["host-tools", "provision-swd", "cal.blob", "--slot", "b", "--probe", "0483:374b"])
                .unwrap();
        let Command::ProvisionSwd(a) = cli.command else { panic!("wrong subcommand") };
        assert_eq!(a.slot.as_deref(), Some("b"));
        assert_eq!(a.chip, "STM32L475VGTx");
        assert_eq!(a.probe_rs, PathBuf::from("probe-rs"));
        assert!(Cli::try_parse_from(["host-tools", "provision-swd", "cal.blob", "--slot", "c"]).is_err());
    }

    #[test]
    fn image_out_writes_the_slot_image_and_touches_no_device() {
        let dir = tempfile::tempdir().unwrap();
        let blob = crate::device::provision::swd::tests::test_blob(4.0);
        let blob_path = dir.path().join("cal.blob");
        std::fs::write(&blob_path, &blob).unwrap();
        let out = dir.path().join("slot.bin");
        run(Args {
            blob: blob_path.clone(),
            slot: None,
            // A probe-rs that cannot run: --image-out must not need one.
            probe_rs: dir.path().join("no-probe-rs"),
            chip: swd::CHIP.into(),
            probe: None,
            image_out: Some(out.clone()),
        })
        .unwrap();
        let image = std::fs::read(&out).unwrap();
        assert_eq!(image, swd::slot_image(1, &blob, SlotMap::board().slot_len()).unwrap());
        // A corrupted blob is refused and no image is written.
        let mut bad = blob;
        bad[100] ^= 0xFF;
        std::fs::write(&blob_path, &bad).unwrap();
        let out2 = dir.path().join("slot2.bin");
        let r = run(Args {
            blob: blob_path,
            slot: None,
            probe_rs: dir.path().join("no-probe-rs"),
            chip: swd::CHIP.into(),
            probe: None,
            image_out: Some(out2.clone()),
        });
        assert!(r.is_err());
        assert!(!out2.exists());
    }
}
