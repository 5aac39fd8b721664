//! `host-tools info`: what a device is, and what it runs on.
use crate::device::link::Endpoint;
use anyhow::Context;
use std::path::PathBuf;

/// Show a device's identity, build-time sizes, calibration and status.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The device.
    #[command(flatten)]
    pub device: Endpoint,
    /// Also write the information as JSON here.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let mut c = crate::device::link::Client::new(a.device.open()?)?;
    let info = c.info().context("asking the device for its information")?;
    let status = c.status().context("asking the device for its status")?;
    let fw = info.firmware;
    println!("protocol {}, firmware {}.{}.{}", info.protocol, fw[0], fw[1], fw[2]);
    println!(
        "sizes: n = {} bins, m = {} LEDs, P = {} pixels, full scale {}, slot holds {} bytes, RAM for {} matrix words",
        info.bins, info.leds, info.pixels, info.full_scale, info.max_blob, info.ram_matrix_words
    );
    println!("sensor: {}", if info.simulated { "simulated (accepts scenes)" } else { "real" });
    match info.calibration {
        Some(cal) => println!(
            "calibration: blob CRC {:#010x}, {} bytes, {} zones, slot {}, sequence {}, matrices {}",
            cal.blob_crc,
            cal.blob_len,
            cal.zones,
            crate::device::provision::slot_name(cal.slot),
            cal.sequence,
            if cal.in_ram { "in RAM" } else { "read in place from flash" }
        ),
        None => println!("calibration: none (provision one with `host-tools provision`)"),
    }
    println!(
        "status: {}, {} lines measured, {} bad frames, {} requests refused{}",
        if status.measuring { "measuring" } else { "idle" },
        status.lines_total,
        status.bad_frames,
        status.refused,
        status.provisioning.map(|b| format!(", provisioning ({b} bytes received)")).unwrap_or_default()
    );
    if let Some(p) = &a.json {
        let j = serde_json::json!({
            "protocol": info.protocol,
            "firmware": fw,
            "bins": info.bins, "leds": info.leds, "pixels": info.pixels, "full_scale": info.full_scale,
            "max_blob": info.max_blob, "ram_matrix_words": info.ram_matrix_words, "simulated": info.simulated,
            "calibration": info.calibration.map(|c| serde_json::json!({
                "blob_crc": c.blob_crc, "blob_len": c.blob_len, "zones": c.zones, "slot": c.slot,
                "sequence": c.sequence, "in_ram": c.in_ram })),
            "status": { "measuring": status.measuring, "lines_total": status.lines_total,
                        "bad_frames": status.bad_frames, "refused": status.refused },
        });
        crate::output::io::write_json(p, &j)?;
    }
    Ok(())
}
