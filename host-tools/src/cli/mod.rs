//! The command line: one file per subcommand, each with its `Args` and `run`.
//! Register a new subcommand here (one enum variant, one match arm).
use clap::{Parser, Subcommand};

pub mod firmware_budget;
pub mod provision_swd;

/// Host tools for the handheld gloss/BRDF meter.
#[derive(Debug, Parser)]
#[command(name = "host-tools", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Write a calibration blob into the board's flash over SWD (probe-rs).
    ProvisionSwd(provision_swd::Args),
    /// Check firmware images against the flash/RAM budget for Z = 128 zones.
    FirmwareBudget(firmware_budget::Args),
}

/// Runs one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::ProvisionSwd(a) => provision_swd::run(a),
        Command::FirmwareBudget(a) => firmware_budget::run(a),
    }
}
