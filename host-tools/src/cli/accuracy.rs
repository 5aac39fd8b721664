//! `host-tools accuracy`: the figures a metrologist signs for the
//! calibration `host-tools train` would write with the same flags
//! (`evaluation::metrology`): BRDF error, physically impossible estimates,
//! gloss readings, k = 2 coverage of the stated uncertainties, the flag and
//! the specular peak, per family of surfaces held out, beside linear
//! interpolation of the same readings.
use crate::calibration::estimators::kind_name;
use crate::cli::train::CalibrationArgs;
use crate::evaluation::metrology::families::TestFamily;
use crate::evaluation::metrology::{Config, run as evaluate};
use crate::forward::brdf::NbrdfSet;
use anyhow::{Context, ensure};
use std::path::PathBuf;

/// Evaluate a calibration as the device applies it, family by family held out.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The calibration evaluated: exactly `train`'s flags and defaults.
    #[command(flatten)]
    pub cal: CalibrationArgs,
    /// Measured surfaces: an NBRDF JSON set (the vendored set's format), a
    /// MERL .binary table, or a directory or comma-separated list of them;
    /// default: the vendored MERL set. Surfaces that are also prior samples
    /// are read K-fold by calibrations trained without them.
    #[arg(long, value_name = "FILE|DIR|LIST")]
    pub set: Option<String>,
    /// Folds over the surfaces that are training samples.
    #[arg(long, default_value_t = 5)]
    pub folds: usize,
    /// Noisy draws of each surface's readings.
    #[arg(long, default_value_t = 4)]
    pub draws: usize,
    /// Seed of the folds and the draws.
    #[arg(long, default_value_t = 2024)]
    pub seed: u64,
    /// Relative noise of the simulated readings (0.02: the patent's 2 %).
    #[arg(long, default_value_t = 0.02)]
    pub reading_noise: f64,
    /// At most this many surfaces per family, evenly spread (a quicker run).
    #[arg(long, value_name = "N")]
    pub limit: Option<usize>,
    /// Also write the report (every row and every surface) as JSON here.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
}

/// Runs the command: prints the tables; writes the JSON only when the run succeeds.
pub fn run(a: Args) -> anyhow::Result<()> {
    ensure!(
        a.cal.scene.is_none(),
        "--scene: the evaluation reads surfaces on one point of the instrument; use `host-tools pixel-map` for a scene's line"
    );
    ensure!(a.draws >= 1, "--draws {}: at least 1", a.draws);
    ensure!(a.folds >= 2, "--folds {}: at least 2", a.folds);
    ensure!(a.limit != Some(0), "--limit 0: at least one surface per family");
    ensure!(
        a.reading_noise.is_finite() && (0.0..1.0).contains(&a.reading_noise),
        "--reading-noise {}: a relative level in [0, 1)",
        a.reading_noise
    );
    let t0 = std::time::Instant::now();
    let setup = a.cal.setup()?;
    let spectral = setup.inst.spectral_weights;
    let measured = match &a.set {
        Some(arg) => TestFamily::measured_files(arg, spectral)?,
        None => TestFamily::measured("the vendored MERL set", &NbrdfSet::merl(), spectral),
    };
    let mut families = vec![measured, TestFamily::ward(), TestFamily::ggx(), TestFamily::gloss_standards()];
    if let Some(n) = a.limit {
        families = families.into_iter().map(|f| f.at_most(n)).collect();
    }
    let cfg = Config { folds: a.folds, draws: a.draws, seed: a.seed, noise_rel: a.reading_noise };
    let spinner = crate::output::progress::spinner("accuracy");
    let spec = setup.spec();
    let result =
        evaluate(&spec, &setup.inst, &setup.grid, &families, &cfg, &|s| spinner.set_message(format!("accuracy: {s}")));
    spinner.finish_and_clear();
    let mut report = result?;
    report.calibration = format!(
        "{} ({} form) on prior {}, criterion {:?}, {} zone(s), trained at {} % noise",
        kind_name(setup.kind),
        crate::calibration::train::Form::of_root(setup.root).name(),
        a.cal.prior,
        setup.criterion,
        spec.zones.len(),
        100.0 * spec.noise_rel
    );
    print!("{}", report.tables());
    if let Some(p) = &a.json {
        crate::output::io::write_json(p, &report).with_context(|| format!("writing {}", p.display()))?;
        println!("\nwrote {}", p.display());
    }
    eprintln!("accuracy: {:.1} s", t0.elapsed().as_secs_f64());
    Ok(())
}
