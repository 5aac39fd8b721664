//! `host-tools reproduce`: the patent's experiment (Table 6) on the patent profile.
use crate::evaluation::reproduce::{Config, format_table, run as run_experiment, write_json};
use anyhow::Context;
use std::path::PathBuf;

/// Run the patent's experiment: 120 test BRDFs, every method, a table like Table 6.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Also write the results as JSON here.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Seed of the simulated measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Relative measurement noise (standard deviation / value).
    #[arg(long, default_value_t = 0.02)]
    pub noise: f64,
    /// Instrument description (TOML); default: the built-in patent profile.
    #[arg(long, value_name = "PATH")]
    pub instrument: Option<PathBuf>,
    /// Prior description (TOML); default: the patent's Table 5.
    #[arg(long, value_name = "PATH")]
    pub prior: Option<PathBuf>,
    /// Also write the fitting problem (rays, noisy readings, truth) as JSON
    /// here, for `scripts/fit_scipy.py`.
    #[arg(long, value_name = "PATH")]
    pub dump_fit_problem: Option<PathBuf>,
    /// Full runs of each fit for timing (median reported).
    #[arg(long, default_value_t = 3)]
    pub fit_runs: usize,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    if !a.noise.is_finite() || a.noise < 0.0 || a.noise > 1.0 {
        anyhow::bail!("--noise {}: must be a relative level in [0, 1] (0.02 is 2 %)", a.noise);
    }
    let mut cfg = Config::patent();
    cfg.seed = a.seed;
    cfg.noise_rel = a.noise;
    cfg.fit_runs = a.fit_runs.max(1);
    if let Some(p) = &a.instrument {
        cfg.instrument = crate::output::config::load_toml(p)?;
    }
    if let Some(p) = &a.prior {
        let (spec, base) = crate::forward::prior::PriorSpec::load(p)?;
        cfg.prior = spec;
        cfg.prior_base = base;
    }
    let report = run_experiment(&cfg).context("running the reproduction")?;
    print!("{}", format_table(&report));
    if let Some(p) = &a.dump_fit_problem {
        let v = crate::evaluation::reproduce::fit_problem_json(&cfg)?;
        crate::output::io::write_json(p, &v).with_context(|| format!("writing {}", p.display()))?;
        println!("wrote {}", p.display());
    }
    if let Some(p) = &a.json {
        write_json(p, &report).with_context(|| format!("writing {}", p.display()))?;
        println!("wrote {}", p.display());
    }
    Ok(())
}
