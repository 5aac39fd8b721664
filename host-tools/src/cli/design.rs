//! `host-tools design`: scores candidate LED layouts of an instrument by the
//! predicted per-pixel BRDF and gloss errors over the prior (held out),
//! specular coverage, saturation and time per line. See
//! `host_tools::evaluation::design`.
use crate::calibration::estimators::kind_name;
use crate::evaluation::design::{self, CandidateFile, DesignSpec, report};
use crate::evaluation::pixel_error::HeldOutSpec;
use crate::forward::prior_measured::PriorMix;
use crate::forward::scene::Scene;
use anyhow::{Context, ensure};
use brdf_meter::blob::EstimatorKind;
use std::path::PathBuf;

/// Score candidate LED layouts (count, angles, die width and height, gain, short exposure): BRDF and gloss error, coverage, time.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The instrument the candidates vary (its sensor, view, effects and noise).
    #[arg(long, value_name = "PATH", default_value = "scenes/handheld.toml")]
    pub scene: PathBuf,
    /// Candidates (TOML, `[[candidate]]` tables; see the module docs of
    /// `evaluation::design::candidate`). Default: the built-in grid of 7..13
    /// LEDs with 3..5 mm dies, square and as slits as wide across as the
    /// gloss window, at the scene's gain and at 8x with 1/16 and 1/80 short exposures.
    #[arg(long, value_name = "PATH")]
    pub candidates: Option<PathBuf>,
    /// The prior the error is predicted over (as `train --prior`).
    #[arg(long, default_value = "merl")]
    pub prior: String,
    /// How many times wider across the plane of incidence each prior
    /// material also trains, as `train --across` (default 1.5,3; `none`).
    #[arg(long, value_name = "S,...|none")]
    pub across: Option<String>,
    /// Estimator whose held-out error is predicted.
    #[arg(long, value_enum, default_value_t = DesignEstimator::Wiener)]
    pub estimator: DesignEstimator,
    /// Pixels the error is predicted at (comma list). Default: 9 spread over the line.
    #[arg(long, value_delimiter = ',')]
    pub pixels: Option<Vec<usize>>,
    /// Folds over the prior's samples (its size for leave one out).
    #[arg(long, default_value_t = 10)]
    pub folds: usize,
    /// Output directory: design.md, .csv, .json, summary and per-candidate plots.
    #[arg(long, value_name = "DIR", default_value = "out/design")]
    pub out: PathBuf,
}

/// The estimators `design` predicts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DesignEstimator {
    /// Wiener from sample pairs (fast).
    Wiener,
    /// Scale-free.
    ScaleFree,
    /// Scale-free piecewise.
    ScaleFreePiecewise,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let base = Scene::load(&a.scene)?;
    let candidates = match &a.candidates {
        Some(p) => crate::output::config::load_toml::<CandidateFile>(p)?.candidate,
        None => design::candidate::builtin(&base),
    };
    ensure!(a.folds >= 2, "--folds {}: at least 2", a.folds);
    let inst = &base.instrument;
    let grid = inst.grid().context("the scene's angle grid")?;
    let prior = PriorMix::parse(&a.prior)?
        .models(&grid, inst.view_deg, inst.spectral_weights)?
        .with_across(&crate::cli::train::across(a.across.as_deref())?);
    let p = inst.pixels();
    let pixels = a.pixels.clone().unwrap_or_else(|| (0..9).map(|i| i * (p - 1) / 8).collect());
    if let Some(bad) = pixels.iter().find(|x| **x >= p) {
        anyhow::bail!("--pixels: pixel {bad} is not one of the scene's {p} pixels (0..={})", p - 1);
    }
    let kind = match a.estimator {
        DesignEstimator::Wiener => EstimatorKind::Wiener,
        DesignEstimator::ScaleFree => EstimatorKind::ScaleFree,
        DesignEstimator::ScaleFreePiecewise => EstimatorKind::ScaleFreePiecewise,
    };
    let spec = DesignSpec {
        base,
        candidates,
        prior,
        pixels,
        held_out: HeldOutSpec { kind, folds: a.folds, ..Default::default() },
    };
    let bar = crate::output::progress::bar(spec.candidates.len() as u64, "candidates");
    let scores = design::run(&spec, &|i, name| {
        bar.set_position(i as u64);
        bar.set_message(name.to_string());
    })?;
    bar.finish_and_clear();
    let table = report::table(&scores, kind_name(kind));
    print!("{table}");
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let written = report::write(&a.out, &scores, kind_name(kind))?;
    eprintln!("wrote {} files in {}", written.len(), a.out.display());
    Ok(())
}
