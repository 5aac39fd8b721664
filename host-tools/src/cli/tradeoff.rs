//! `host-tools tradeoff`: every estimator on the same data, accuracy against
//! time per point, with the Pareto front; device kernels counted in QEMU; the
//! host batch kernel against numpy. See `host_tools::evaluation::tradeoff`.
use crate::evaluation::tradeoff::{Config, report, run_observed as run_tradeoff};
use crate::output::plot::tradeoff as plot;
use anyhow::Context;
use std::path::PathBuf;

/// Measure accuracy against time for every estimator (table, JSON, plot).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Reduced configuration (seconds; what the test command runs).
    #[arg(long)]
    pub quick: bool,
    /// Output directory for tradeoff.md, tradeoff.json, tradeoff.svg and tradeoff.png.
    #[arg(long, value_name = "DIR", default_value = "out/tradeoff")]
    pub out: PathBuf,
    /// Noise draws of the 120-pattern test set (default: 10, quick: 1).
    #[arg(long)]
    pub draws: Option<usize>,
    /// First noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Skip the QEMU kernel bench (scripts/kernel-bench.sh).
    #[arg(long)]
    pub no_qemu: bool,
    /// Skip the numpy comparison (scripts/numpy_matmul.py).
    #[arg(long)]
    pub no_numpy: bool,
    /// Points of the host batch speed test (default 1 000 000; quick 20 000).
    #[arg(long)]
    pub batch_points: Option<usize>,
    /// Dense prior size: rho_d values x alpha values over Table 5's ranges (e.g. 18x60).
    #[arg(long, value_name = "RxA")]
    pub dense: Option<String>,
    /// Training margin of the piecewise Wiener's clusters.
    #[arg(long)]
    pub margin: Option<f64>,
    /// Skip the zone and LED-count sweeps.
    #[arg(long)]
    pub skip_sweeps: bool,
}

/// The repository root: the current directory if it holds scripts/ and
/// scenes/, else the one this binary was built from.
pub(crate) fn repo_root() -> PathBuf {
    let cwd = std::env::current_dir().unwrap_or_default();
    if cwd.join("scripts/kernel-bench.sh").exists() && cwd.join("scenes").exists() {
        return cwd;
    }
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let root = repo_root();
    let mut cfg = if a.quick { Config::quick(&root) } else { Config::full(&root) };
    cfg.seed = a.seed;
    if let Some(d) = a.draws {
        anyhow::ensure!(d >= 1, "--draws must be at least 1");
        cfg.draws = d;
    }
    if let Some(p) = a.batch_points {
        anyhow::ensure!(p >= 1, "--batch-points must be at least 1");
        cfg.batch_points = p;
    }
    if let Some(d) = &a.dense {
        let parse = || -> Option<(usize, usize)> {
            let (r, al) = d.split_once('x')?;
            Some((r.trim().parse().ok()?, al.trim().parse().ok()?))
        };
        let (r, al) = parse().with_context(|| format!("--dense {d}: expected RxA, e.g. 18x60"))?;
        anyhow::ensure!(r >= 1 && al >= 1, "--dense {d}: both counts must be at least 1");
        cfg.dense = (r, al);
    }
    if let Some(mg) = a.margin {
        anyhow::ensure!(mg.is_finite() && mg >= 0.0, "--margin {mg}: must be >= 0");
        cfg.margin = mg;
    }
    if a.skip_sweeps {
        cfg.zones.clear();
        cfg.leds.clear();
    }
    if a.no_qemu {
        cfg.qemu = false;
    }
    if a.no_numpy {
        cfg.numpy = false;
    }
    let progress = crate::output::progress::spinner("tradeoff");
    let rep = run_tradeoff(&cfg, &|s| progress.set_message(format!("tradeoff: {s}")));
    progress.finish_and_clear();
    let rep = rep.context("measuring the trade-off")?;
    let md = report::markdown(&rep);
    print!("{md}");
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    crate::output::io::write_atomic(&a.out.join("tradeoff.md"), md.as_bytes())?;
    crate::output::io::write_json(&a.out.join("tradeoff.json"), &rep)?;
    let title = format!("BRDF estimation: accuracy vs host time per point ({} points, patent profile)", rep.points);
    let (svg, png) = plot::write(&a.out.join("tradeoff"), &rep.rows, &title).context("plotting")?;
    println!(
        "\nwrote {}, {}, {}, {}",
        a.out.join("tradeoff.md").display(),
        a.out.join("tradeoff.json").display(),
        svg.display(),
        png.display()
    );
    Ok(())
}
