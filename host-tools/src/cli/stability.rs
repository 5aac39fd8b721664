//! `host-tools stability`: the long run of the hard-case property checks.
//! Runs every family with the production solver and the device
//! kernel, prints one summary row per family, optionally writes the summary
//! and every failing case as JSON, and exits non-zero if any case failed.
//!
//! ```text
//! cargo run --release -p host-tools -- stability --cases 10000 --json out/stability.json
//! ```
use crate::evaluation::stability::{self, Family, Production};
use anyhow::bail;
use serde::Serialize;
use std::path::PathBuf;

/// Run the hard-case stability checks over many generated cases.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Total cases, split evenly over the families (at least one each).
    #[arg(long, default_value_t = 10_000)]
    pub cases: usize,
    /// First seed (case seeds are consecutive from here in each family).
    #[arg(long, default_value_t = 1_000_000)]
    pub seed: u64,
    /// Worker threads (default: available parallelism).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Only these families (comma-separated names; default: all).
    #[arg(long, value_delimiter = ',')]
    pub family: Vec<String>,
    /// Write the summary and the failing cases here as JSON.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let families: Vec<Family> = if a.family.is_empty() {
        Family::ALL.to_vec()
    } else {
        let mut v = Vec::new();
        for name in &a.family {
            match Family::ALL.iter().find(|f| f.name() == name) {
                Some(f) => v.push(*f),
                None => bail!(
                    "--family {name}: unknown; one of {}",
                    Family::ALL.iter().map(|f| f.name()).collect::<Vec<_>>().join(", ")
                ),
            }
        }
        v
    };
    let per = a.cases.div_ceil(families.len()).max(1);
    let threads = a.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let progress = crate::output::progress::bar((per * families.len()) as u64, "stability cases");
    let (summary, reports) =
        stability::run_observed(&families, per, a.seed, &Production, stability::device_kernel, threads, &|| {
            progress.inc(1)
        });
    progress.finish_and_clear();
    print!("{}", summary.table());
    if let Some(p) = &a.json {
        #[derive(Serialize)]
        struct Json<'a> {
            command: String,
            summary: &'a stability::RunSummary,
            failing_cases: Vec<&'a stability::CaseReport>,
        }
        let j = Json {
            command: std::env::args().collect::<Vec<_>>().join(" "),
            summary: &summary,
            failing_cases: reports.iter().filter(|r| !r.failures.is_empty()).collect(),
        };
        crate::output::io::write_json(p, &j)?;
        println!("wrote {}", p.display());
    }
    if summary.total_failures > 0 {
        bail!("{} of {} cases failed an invariant", summary.total_failures, summary.total_cases);
    }
    Ok(())
}
