//! `firmware-budget`: checks firmware images against the flash and RAM
//! budget for the largest calibration (Z = 128 zones of 81 x 7 matrices).
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args as ClapArgs;

use crate::firmware_budget;

/// Prints the flash/RAM budget table of firmware ELF images and fails if any
/// is over budget.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Firmware ELF files (e.g. target/thumbv7em-none-eabihf/release/board-fw).
    #[arg(required = true)]
    pub elf: Vec<PathBuf>,
    /// The linker script the images were linked with (default: the
    /// repository's memory.x, built into this tool).
    #[arg(long)]
    pub memory_x: Option<PathBuf>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let script = match &args.memory_x {
        Some(p) => std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?,
        None => crate::swd::MEMORY_X.to_string(),
    };
    let mut failed = Vec::new();
    for elf in &args.elf {
        let b = firmware_budget::check_file(elf, &script)?;
        print!("{}", b.table());
        if !b.ok() {
            failed.push(b.name);
        }
    }
    if !failed.is_empty() {
        bail!("over the flash/RAM budget: {}", failed.join(", "));
    }
    Ok(())
}
