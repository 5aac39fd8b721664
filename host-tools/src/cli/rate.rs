//! `host-tools rate`: the instrument's line rate, end to end: device
//! compute and framing counted in QEMU by stage, acquisition derived from the
//! firmware's settings, the link's bytes and USB packets, and the stage that
//! limits the line rate. See `host_tools::evaluation::rate`.
use crate::evaluation::rate::{self, link, report};
use anyhow::ensure;
use std::path::PathBuf;

/// The line-rate budget per stage, for the board (P = 128) and QEMU (P = 32).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory for rate.md, rate.csv and rate.json.
    #[arg(long, value_name = "DIR", default_value = "out/rate")]
    pub out: PathBuf,
    /// USB full-speed bulk packets per 1 ms frame the budget takes as
    /// practical (theory: 19).
    #[arg(long, default_value_t = link::PRACTICAL_PACKETS_PER_MS)]
    pub usb_packets_per_ms: f64,
    /// Zones of the board build's calibration, 1..=8. Default 1: with more,
    /// some of the handheld scene's zones do not see the black-glass
    /// standard, so its calibration carries no gloss readings and the count
    /// would leave their cost out (the count per point does not otherwise
    /// depend on the zones).
    #[arg(long, default_value_t = 1)]
    pub board_zones: usize,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    ensure!(
        a.usb_packets_per_ms > 0.0 && a.usb_packets_per_ms <= link::THEORETICAL_PACKETS_PER_MS,
        "--usb-packets-per-ms {}: must be in (0, 19]",
        a.usb_packets_per_ms
    );
    let root = super::tradeoff::repo_root();
    eprintln!("training the builds' calibrations and simulating a line of each ...");
    let builds = rate::prepare(&root, a.board_zones)?;
    rate::write_bench_data(&root.join("target/line-bench/data.bin"), &builds)?;
    eprintln!("counting the line in QEMU (scripts/line-bench.sh) ...");
    let segments = rate::run_bench(&root)?;
    let costs = rate::stage_costs(&segments)?;
    let budget = rate::budget(&builds, &costs, a.usb_packets_per_ms)?;
    let md = report::markdown(&budget, a.usb_packets_per_ms);
    print!("{md}");
    std::fs::create_dir_all(&a.out)?;
    crate::output::io::write_atomic(&a.out.join("rate.md"), md.as_bytes())?;
    crate::output::io::write_atomic(&a.out.join("rate.csv"), report::csv(&budget).as_bytes())?;
    crate::output::io::write_json(&a.out.join("rate.json"), &budget)?;
    eprintln!("wrote {}/rate.md, rate.csv, rate.json", a.out.display());
    Ok(())
}
