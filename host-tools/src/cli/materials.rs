//! `host-tools materials`: leave-one-material-out over the measured set
//! (`host_tools::evaluation::held_out`): per-material error, flag, predicted vs achieved,
//! the summary table, and a plot of the worst materials.
use crate::evaluation::held_out::{HeldOutConfig, WorstPlot, run as run_loo};
use crate::forward::brdf::NbrdfSet;
use crate::forward::prior_measured::PriorMix;
use anyhow::{Context, ensure};
use std::path::PathBuf;

/// Leave-one-material-out evaluation over measured materials.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory: materials.md, materials.json, materials-worst.svg/.png.
    #[arg(long, value_name = "DIR", default_value = "out/materials")]
    pub out: PathBuf,
    /// Measured set (NBRDF JSON); default: the vendored MERL set.
    #[arg(long, value_name = "PATH")]
    pub set: Option<PathBuf>,
    /// Noise draws per material.
    #[arg(long, default_value_t = 8)]
    pub draws: usize,
    /// Relative noise.
    #[arg(long, default_value_t = 0.02)]
    pub noise: f64,
    /// Hold out only the first N materials (all still train the others).
    #[arg(long)]
    pub limit: Option<usize>,
    /// Skip the Ward fit (condition 2) baseline.
    #[arg(long)]
    pub no_ward_fit: bool,
    /// Mix a parametric family into every training prior, `FAMILY@WEIGHT`
    /// (e.g. `patent@0.2`): the measured materials get 1 - WEIGHT.
    #[arg(long, value_name = "FAMILY@W")]
    pub mix: Option<String>,
    /// False-alarm rate of the out-of-prior flag on held-out prior samples.
    #[arg(long, default_value_t = 0.05)]
    pub false_alarm: f64,
    /// Worst materials plotted.
    #[arg(long, default_value_t = 6)]
    pub plot_worst: usize,
    /// Also count the device's cost per point exactly in QEMU
    /// (scripts/qemu-icount.sh for Wiener, scale-free and piecewise; minutes).
    #[arg(long)]
    pub qemu: bool,
}

/// Runs the command; writes nothing unless the run succeeds.
pub fn run(a: Args) -> anyhow::Result<()> {
    ensure!(a.draws >= 1, "--draws must be >= 1");
    ensure!(a.noise.is_finite() && (0.0..1.0).contains(&a.noise), "--noise {}: must be in [0, 1)", a.noise);
    ensure!(a.false_alarm > 0.0 && a.false_alarm < 1.0, "--false-alarm {}: must be in (0, 1)", a.false_alarm);
    let set = match &a.set {
        Some(p) => NbrdfSet::load(p)?,
        None => NbrdfSet::merl(),
    };
    let mix_with = match &a.mix {
        Some(text) => {
            let (fam, w) = text.rsplit_once('@').with_context(|| format!("--mix {text:?}: expected FAMILY@WEIGHT"))?;
            let w: f64 = w.parse().with_context(|| format!("--mix {text:?}: weight is not a number"))?;
            ensure!(w > 0.0 && w < 1.0, "--mix {text:?}: weight must be in (0, 1)");
            let mix = PriorMix::parse(fam)?;
            ensure!(mix.families.len() == 1, "--mix {text:?}: one family");
            Some((mix.families[0].1.clone(), w))
        }
        None => None,
    };
    let cfg = HeldOutConfig {
        noise_rel: a.noise,
        draws: a.draws,
        limit: a.limit,
        ward_fit: !a.no_ward_fit,
        mix_with,
        false_alarm: a.false_alarm,
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    let report = run_loo(&set, &cfg)?;
    let mut md = report.markdown();
    let costs = if a.qemu {
        let root = crate::device::link::qemu::workspace_root();
        let c = crate::evaluation::device_cost::measure(&root, &["wiener", "scale-free", "scale-free-piecewise"])?;
        md.push_str("\nDevice cost per point (QEMU exact count, Cortex-M4F, n = 81, m = 7):\n\n");
        md.push_str(&crate::evaluation::device_cost::markdown(&c));
        Some(c)
    } else {
        None
    };
    let (svg, png) = crate::output::plot::render(&WorstPlot { report: &report, count: a.plot_worst }, (1200, 800))?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    crate::output::io::write_atomic(&a.out.join("materials.md"), md.as_bytes())?;
    crate::output::io::write_json(
        &a.out.join("materials.json"),
        &serde_json::json!({ "report": &report, "device_cost": costs }),
    )?;
    crate::output::io::write_atomic(&a.out.join("materials-worst.svg"), svg.as_bytes())?;
    crate::output::io::write_atomic(&a.out.join("materials-worst.png"), &png)?;
    let summary_end = md.find("\nPer material").unwrap_or(md.len());
    println!("{}", &md[..summary_end]);
    if let Some(c) = &costs {
        println!("device cost per point (QEMU exact count):\n{}", crate::evaluation::device_cost::markdown(c));
    }
    println!(
        "({:.1} s) wrote {}/materials.md, materials.json, materials-worst.svg/.png",
        t0.elapsed().as_secs_f64(),
        a.out.display()
    );
    Ok(())
}
