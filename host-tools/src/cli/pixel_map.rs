//! `host-tools pixel-map`: the per-pixel accuracy map of a calibration kind
//! on a scene: held-out BRDF error beside interpolation's, the black glass
//! and gloss tiles read at every pixel, flags and saturation. See
//! `host_tools::evaluation::pixel_map`.
use crate::cli::train::{CriterionArg, Estimator};
use crate::evaluation::pixel_map::{self, MapSpec, report};
use crate::forward::prior_measured::PriorMix;
use crate::forward::scene::Scene;
use anyhow::{Context, ensure};
use std::path::PathBuf;

/// Per-pixel accuracy of a calibration kind on a scene (held out, simulated with every effect).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The instrument and effects.
    #[arg(long, value_name = "PATH", default_value = "scenes/handheld.toml")]
    pub scene: PathBuf,
    /// Zones of the calibrations.
    #[arg(long, default_value_t = 32)]
    pub zones: usize,
    /// Estimator.
    #[arg(long, value_enum, default_value_t = Estimator::ScaleFreePiecewise)]
    pub estimator: Estimator,
    /// Training criterion.
    #[arg(long, value_enum, default_value_t = CriterionArg::PeakRelative)]
    pub criterion: CriterionArg,
    /// The piecewise kind's cluster count (default: by cross-validation).
    #[arg(long)]
    pub clusters: Option<usize>,
    /// Prior (as `train --prior`); its reflection models are the held-out materials.
    #[arg(long, default_value = "merl")]
    pub prior: String,
    /// The out-of-prior flag's false-alarm rate on held-out prior samples,
    /// as `train --false-alarm`: what the flag rows' trade between points
    /// caught and points flagged needlessly is measured at.
    #[arg(long, default_value_t = crate::calibration::estimators::scale_free::DEFAULT_FALSE_ALARM)]
    pub false_alarm: f64,
    /// Rougher finishes each prior material also trains at, as `train
    /// --finishes` on a scene: none unless given (each finish multiplies the
    /// prior's evaluations on every pixel).
    #[arg(long, value_name = "DEG,...|none")]
    pub finishes: Option<String>,
    /// How many times wider across the plane of incidence each prior
    /// material also trains, as `train --across` (default 1.5,3; `none`).
    #[arg(long, value_name = "S,...|none")]
    pub across: Option<String>,
    /// Measured surfaces of your own, read at every pixel by the calibration
    /// on the whole prior beside the held-out figures: NBRDF .json sets,
    /// MERL .binary tables, or a directory or comma list of them (as
    /// `accuracy --set`); surfaces that are prior samples are left out.
    #[arg(long, value_name = "FILE|DIR|LIST")]
    pub set: Option<String>,
    /// Folds over the prior's samples (its size: leave one material out).
    #[arg(long, default_value_t = 10)]
    pub folds: usize,
    /// Lines simulated per held-out material (at least 4 for the figures).
    #[arg(long, default_value_t = 4)]
    pub lines: u64,
    /// Lines of the black glass (its repeatability is over these).
    #[arg(long, default_value_t = 30)]
    pub gloss_lines: u64,
    /// Every how many pixels the printed table has a row.
    #[arg(long, default_value_t = 8)]
    pub stride: usize,
    /// Output directory: pixel-map.md, .csv, .json, .svg, .png.
    #[arg(long, value_name = "DIR", default_value = "out/pixel-map")]
    pub out: PathBuf,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    ensure!(a.lines >= 1 && a.gloss_lines >= 2, "--lines >= 1 and --gloss-lines >= 2");
    ensure!(a.folds >= 2, "--folds {}: at least 2", a.folds);
    ensure!(
        a.false_alarm > 0.0 && a.false_alarm < 1.0,
        "--false-alarm {}: a rate in (0, 1), such as the default 0.05",
        a.false_alarm
    );
    let scene = Scene::load(&a.scene)?;
    let inst = &scene.instrument;
    let grid = inst.grid().context("the scene's angle grid")?;
    let prior = PriorMix::parse(&a.prior)?
        .models(&grid, inst.view_deg, inst.spectral_weights)?
        .with_finishes(&crate::cli::train::finishes_deg(a.finishes.as_deref(), true)?)
        .with_across(&crate::cli::train::across(a.across.as_deref())?);
    let unseen = match &a.set {
        Some(arg) => {
            let f = crate::evaluation::metrology::families::TestFamily::measured_files(arg, inst.spectral_weights)?;
            Some(pixel_map::unseen::UnseenSpec { source: arg.clone(), materials: f.materials })
        }
        None => None,
    };
    let spec = MapSpec {
        scene,
        zones: a.zones,
        kind: a.estimator.into(),
        criterion: a.criterion.into(),
        clusters: a.clusters,
        false_alarm: a.false_alarm,
        prior,
        folds: a.folds,
        lines: a.lines,
        gloss_lines: a.gloss_lines,
        acq: brdf_meter::platform::timing::ACQUISITION,
        seed: 17,
        unseen,
    };
    let spinner = crate::output::progress::spinner("pixel map");
    let map = pixel_map::run(&spec, &|what| spinner.set_message(what.to_string()))?;
    spinner.finish_and_clear();
    print!("{}", report::markdown(&map, a.stride));
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let files = report::write(&a.out, &map, a.stride)?;
    eprintln!("wrote {} files in {}", files.len(), a.out.display());
    Ok(())
}
