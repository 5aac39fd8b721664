//! The command line: one file per subcommand, each with its `Args` and `run`.
//! Register a new subcommand here (one enum variant, one match arm).
use clap::{Parser, Subcommand};

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
pub enum Command {}

/// Runs one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {}
}
