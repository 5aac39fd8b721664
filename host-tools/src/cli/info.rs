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
    // An error here (the link failing now) leaves the identity and status
    // above standing: `info` shows what it got.
    let firmware = c.firmware_info().ok();
    if let Some(f) = &firmware {
        let v = f.version;
        println!(
            "firmware: {}.{}.{} for {:?}, boot state {:?}, self-test: {}{}{}",
            v[0],
            v[1],
            v[2],
            f.target,
            f.boot,
            self_test_text(f.self_test, f.boot),
            f.pending.map(|p| format!(", update {}.{}.{} waiting for a reset", p[0], p[1], p[2])).unwrap_or_default(),
            f.receiving.map(|b| format!(", update in progress ({b} bytes received)")).unwrap_or_default(),
        );
        if f.updates {
            println!("updates: over the link and USB DFU (board), images up to {} bytes", f.max_image);
        } else {
            println!("updates: not over the link on this build (no update partition)");
        }
        if let Some(e) = f.refused {
            println!("last update refused: {e}");
        }
        println!("calibration formats read: {} to {}", f.blob_formats[0], f.blob_formats[1]);
        let ids: Vec<String> = f.trusted[..(f.trusted_count as usize).min(f.trusted.len())]
            .iter()
            .map(|id| id.iter().map(|b| format!("{b:02x}")).collect())
            .collect();
        println!(
            "trusted keys ({}): {}{}",
            f.trusted_count,
            ids.join(", "),
            if f.trusts_development_key { " (includes the DEVELOPMENT key, NOT FOR PRODUCTION)" } else { "" }
        );
    }
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
            "firmware_info": firmware.map(|f| serde_json::json!({
                "version": f.version, "target": format!("{:?}", f.target), "boot": format!("{:?}", f.boot),
                "self_test": { "store": f.self_test.store, "sensor": f.self_test.sensor, "link": f.self_test.link },
                "updates": f.updates, "max_image": f.max_image, "pending": f.pending,
                "refused": f.refused.map(|e| e.to_string()),
                "trusted_key_ids": f.trusted[..(f.trusted_count as usize).min(f.trusted.len())]
                    .iter().map(|id| id.iter().map(|b| format!("{b:02x}")).collect::<String>()).collect::<Vec<_>>(),
                "trusts_development_key": f.trusts_development_key })),
        });
        crate::output::io::write_json(p, &j)?;
    }
    Ok(())
}

/// The self-test's parts in words. A part not passed is not a failure
/// until the device has had the chance: the sensor's frame is read at a
/// trial boot (the image then confirms itself) or by the first
/// measurement, so a confirmed image reports "no frame yet" until then.
fn self_test_text(t: brdf_meter::protocol::SelfTest, boot: brdf_meter::protocol::BootState) -> String {
    let trial = boot == brdf_meter::protocol::BootState::Trial;
    let store = if t.store { "store read" } else { "store NOT read" };
    let sensor = match (t.sensor, trial) {
        (true, _) => "sensor delivered a frame",
        (false, true) => "sensor: no frame yet (the image on trial confirms itself once it has one)",
        (false, false) => "sensor: no frame since boot (the first measurement reads one)",
    };
    let link = if t.link { "link ok" } else { "link: no valid request yet" };
    format!("{store}, {sensor}, {link}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf_meter::protocol::{BootState, SelfTest};

    #[test]
    fn a_sensor_not_yet_read_is_not_called_a_failure() {
        let t = SelfTest { store: true, sensor: false, link: true };
        assert_eq!(
            self_test_text(t, BootState::Confirmed),
            "store read, sensor: no frame since boot (the first measurement reads one), link ok"
        );
        assert!(self_test_text(t, BootState::Trial).contains("confirms itself once it has one"));
        assert_eq!(
            self_test_text(SelfTest { sensor: true, ..t }, BootState::Confirmed),
            "store read, sensor delivered a frame, link ok"
        );
    }
}
