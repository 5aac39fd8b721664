//! The metrology evaluation: how far a calibration's outputs can be trusted
//! on surfaces it was not trained on, measured the way the device computes
//! them, beside linear interpolation of the same readings.
//!
//! What it measures, and why:
//! - A calibration is trained by the production path
//!   (`calibration::train::train_on`, the same [`TrainSpec`] `host-tools
//!   train` builds) and applied by `device::reference::PointEstimator`, bit
//!   for bit the firmware's arithmetic: the figures are the instrument's,
//!   not a model of it.
//! - Test surfaces come in families ([`families`]): measured materials,
//!   the patent's Ward test patterns, GGX lobes and the gloss standards. A
//!   surface that is also a training sample is read only by calibrations
//!   trained without it, K-fold ([`folds`]); a family the calibration never
//!   saw is read by the calibration on everything. The black glass is the
//!   exception: it sets every calibration's gloss scale, so no calibration
//!   is trained without it (a fold without it would misread every surface
//!   by its misreading of the glass).
//! - Each surface is read from seeded noisy draws of its simulated readings
//!   on the instrument (near-field, every ray at its exact direction;
//!   [`reading`]) and compared with its truth by the definitions the
//!   outputs claim ([`truth`]): the binned BRDF, the gloss readings in
//!   three dimensions, the specular peak.
//! - The figures ([`metrics`]): BRDF error relative to the peak,
//!   physically impossible estimates, gloss errors split at 300 GU, k = 2
//!   coverage of the stated uncertainties per bin and per reading, whether
//!   the flag predicts a bad estimate, and the specular peak's height and
//!   width. Linear interpolation reads the same draws against the same
//!   truths: any figure without it beside cannot say whether the estimator
//!   earns its keep.
pub mod families;
pub mod folds;
pub mod metrics;
pub mod reading;
pub mod report;
pub mod truth;

use crate::calibration::gloss_rows::BLACK_GLASS_STANDARD;
use crate::calibration::train::{TrainSpec, ZonePairs, train_on};
use crate::forward::grid::AngleGrid;
use crate::forward::optics::Instrument;
use anyhow::{Context, ensure};
use families::TestFamily;
use folds::{Membership, matching, plan};
use metrics::Tally;
use rayon::prelude::*;
use reading::{Readers, Reading, noisy_draws};
pub use report::{FamilyProtocol, MaterialResult, NearestSample, Nearness, Report};
use truth::Truth;

/// How the surfaces are read.
#[derive(Clone, Debug)]
pub struct Config {
    /// Folds over the surfaces that are training samples.
    pub folds: usize,
    /// Noisy draws per surface.
    pub draws: usize,
    /// Seed of the folds and the draws.
    pub seed: u64,
    /// Relative noise of the readings (0.02: the patent's 2 %).
    pub noise_rel: f64,
}

impl Default for Config {
    fn default() -> Self {
        Self { folds: 5, draws: 4, seed: 2024, noise_rel: 0.02 }
    }
}

/// The seed of surface `material` of family `family`: its draws are the
/// same whichever calibration reads them and whatever else is evaluated.
fn draw_seed(seed: u64, family: &str, material: usize) -> u64 {
    let h = family.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3));
    seed ^ h ^ (material as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// Evaluates the calibration `spec` trains on `families`, read on `inst`
/// (whose grid is `grid`, the spec's) at zone 0. `progress` hears each stage.
pub fn run(
    spec: &TrainSpec<'_>,
    inst: &Instrument,
    grid: &AngleGrid,
    families: &[TestFamily],
    cfg: &Config,
    progress: &dyn Fn(&str),
) -> anyhow::Result<Report> {
    ensure!(cfg.draws >= 1, "draws = {}: at least one", cfg.draws);
    ensure!(cfg.folds >= 2, "folds = {}: at least two", cfg.folds);
    ensure!(cfg.noise_rel.is_finite() && (0.0..1.0).contains(&cfg.noise_rel), "noise {}: in [0, 1)", cfg.noise_rel);
    ensure!(grid.bins_deg() == spec.bins_deg, "the instrument's grid is not the calibration's");
    progress("the truth of every surface");
    let truths: Vec<Vec<Truth>> =
        families.iter().map(|f| f.materials.par_iter().map(|(_, b)| Truth::of(b, inst, grid)).collect()).collect();
    let prior_grid = spec.prior.on_grid(grid, inst.view_deg).samples;
    // The standards are told apart by their gloss readings too: the bare
    // polished dielectrics have one grid vector (no diffuse part, the mirror
    // spike left out), whatever their index.
    let standards = TestFamily::gloss_standards();
    let standards_sig: Vec<_> =
        standards.materials.par_iter().map(|(_, b)| Truth::of(b, inst, grid).signature()).collect();
    let standards_sig = nalgebra::DMatrix::from_columns(&standards_sig);
    let membership: Vec<Vec<Membership>> = truths
        .iter()
        .map(|ts| {
            ts.iter()
                .map(|t| {
                    let mut standards = matching(&t.signature(), &standards_sig);
                    // The black glass sets every calibration's gloss scale
                    // (as every gloss meter is set on it): it is never
                    // left out, and reads as the reference it is.
                    let reference = standards.contains(&BLACK_GLASS_STANDARD);
                    standards.retain(|s| *s != BLACK_GLASS_STANDARD);
                    Membership { prior: matching(&t.as_prior, &prior_grid), standards, reference }
                })
                .collect()
        })
        .collect();
    let plan = plan(&membership, cfg.folds, cfg.seed);
    progress("sample pairs of the prior and the standards");
    let all = ZonePairs::build(spec);
    let (mut blobs, mut clusters) = (Vec::with_capacity(plan.calibrations.len()), Vec::new());
    for held in &plan.calibrations {
        progress(&format!("training {}", held.label(plan.folds)));
        let t = train_on(spec, &held.pairs(&all)).with_context(|| format!("training {}", held.label(plan.folds)))?;
        clusters.push(t.clusters);
        blobs.push(t.blob);
    }
    let centres = inst.centre_angles_deg();
    let readers: Vec<Readers<'_>> =
        blobs.iter().map(|b| Readers::new(b, grid, &centres, inst.view_deg)).collect::<anyhow::Result<_>>()?;
    let flag_forms = readers.iter().map(|r| r.flag_statistic().to_string()).collect();
    let mut rows = Vec::new();
    let mut materials = Vec::new();
    let mut protocols = Vec::new();
    for (fi, fam) in families.iter().enumerate() {
        progress(&format!("reading the {} family ({} surfaces x {} draws)", fam.name, fam.materials.len(), cfg.draws));
        let read: Vec<(Vec<Reading>, Vec<Reading>)> = (0..fam.materials.len())
            .into_par_iter()
            .map(|i| {
                let r = &readers[plan.reader[fi][i]];
                let draws =
                    noisy_draws(&truths[fi][i].clean, cfg.noise_rel, cfg.draws, draw_seed(cfg.seed, &fam.name, i));
                (draws.iter().map(|v| r.estimator(v)).collect(), draws.iter().map(|v| r.interpolation(v)).collect())
            })
            .collect();
        let (mut est, mut interp) = (Tally::default(), Tally::default());
        for (i, ((name, _), (e, li))) in fam.materials.iter().zip(&read).enumerate() {
            let t = &truths[fi][i];
            est.add(name, t, e);
            interp.add(name, t, li);
            let held = &plan.calibrations[plan.reader[fi][i]];
            let nearest = NearestSample::in_prior(spec.prior, &prior_grid, (&t.rho, t.peak), &held.prior);
            materials.push(MaterialResult::new((&fam.name, name), (held.fold, nearest), t, e, li));
        }
        let in_training = membership[fi].iter().filter(|m| m.in_training()).count();
        let references = membership[fi].iter().filter(|m| m.reference && !m.in_training()).count();
        let mut protocol = FamilyProtocol::new(fam, in_training, references, plan.folds);
        let family_results = &materials[materials.len() - fam.materials.len()..];
        protocol.nearest = Nearness::of(
            &family_results
                .iter()
                .filter_map(|m: &MaterialResult| m.nearest_training.as_ref().map(|n| (n.distance, m.error_estimator)))
                .collect::<Vec<_>>(),
        );
        protocols.push(protocol);
        rows.push(est.row(&fam.name, "estimator"));
        rows.push(interp.row(&fam.name, "interpolation"));
    }
    Ok(Report {
        calibration: String::new(),
        noise_rel: cfg.noise_rel,
        draws: cfg.draws,
        folds: plan.folds,
        seed: cfg.seed,
        trainings: plan.calibrations.len(),
        clusters,
        flag_forms,
        families: protocols,
        rows,
        materials,
    })
}
