//! `design`: scores candidate LED layouts of an instrument before anyone
//! builds one. For each candidate (a variation of a base scene's LEDs, gain
//! and exposure, `candidate`):
//!
//! - the predicted per-pixel BRDF error over the prior, every sample held
//!   out of the estimator that reads it (`crate::evaluation::pixel_error`:
//!   sample pairs at the pixel through the candidate's own optics and noise),
//!   at a spread of pixels, beside linear interpolation's;
//! - the predicted gloss reading's error at the same pixels, every sample
//!   held out of the rows that read it (`gloss`), beside interpolation's;
//! - every pixel's specular coverage: how far inside an LED's die its mirror
//!   direction falls (negative: between LEDs), and the raw counts of the
//!   black-glass standard and of polished metals against the converter's
//!   full scale, long and short exposure (`coverage`);
//! - what it costs per line: the acquisition (frames of the board's timing,
//!   `crate::evaluation::rate::acquisition`, plus the short exposures of the
//!   frames a metal saturates) and the device's estimation of P points (the
//!   kernel's QEMU-counted cost per multiply-accumulate, times n m).
//!
//! It is general (any scene, any prior) and fast: the pairs are simulated
//! once per pixel, and held-out fits are m x m solves.
pub mod candidate;
pub mod coverage;
pub mod gloss;
pub mod report;

use crate::evaluation::pixel_error::{HeldOutSpec, held_out_errors, quantiles};
use crate::evaluation::rate::acquisition;
use crate::forward::optics::Optics;
use crate::forward::pairs::Pairs;
use crate::forward::prior_models::PriorModels;
use crate::forward::scene::pipeline::Simulator;
use crate::forward::scene::{Scene, training_optics};
use anyhow::Context;
use brdf_meter::platform::timing::{ACQUISITION, SYSCLK_HZ};
pub use candidate::{Candidate, CandidateFile};
pub use coverage::PixelCoverage;
use serde::Serialize;

/// The device's estimation cost per point of the Wiener kind at n = 81,
/// m = 7, M4 cycles (QEMU's exact count of the whole per-point path,
/// `scripts/qemu-icount.sh`, with the kernel bench's cycles per instruction
/// of 1): what [`device_cycles_per_point`] scales by the multiply-adds.
pub const WIENER_CYCLES_N81_M7: f64 = 868.0;

/// The device's estimation cycles per point for `n` bins and `m` LEDs: the
/// measured n = 81, m = 7 path scaled by its multiply-adds `(n + 4) m` (the
/// estimate's n rows and the gloss readings' four).
pub fn device_cycles_per_point(n: usize, m: usize) -> f64 {
    WIENER_CYCLES_N81_M7 * ((n + 4) * m) as f64 / ((81 + 4) * 7) as f64
}

/// What `design` is asked.
#[derive(Clone, Debug)]
pub struct DesignSpec {
    /// The instrument the candidates vary.
    pub base: Scene,
    /// The candidates.
    pub candidates: Vec<Candidate>,
    /// The prior the error is predicted over.
    pub prior: PriorModels,
    /// Pixels the error is predicted at.
    pub pixels: Vec<usize>,
    /// How the held-out errors are drawn.
    pub held_out: HeldOutSpec,
}

/// One candidate's score.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateScore {
    /// Name.
    pub name: String,
    /// LEDs m.
    pub m: usize,
    /// Their centre angles at the line's centre, degrees.
    pub centres_deg: Vec<f64>,
    /// Die side in the plane of incidence, mm (0 for point sources).
    pub die_mm: f64,
    /// Its extent across the plane, mm.
    pub die_height_mm: f64,
    /// Sensor gain.
    pub gain: f64,
    /// Ratios of the shorter exposures taken of a saturated frame (empty: none).
    pub short_exposure: Vec<f64>,
    /// Per evaluated pixel: (pixel, estimator median / 90th / worst,
    /// interpolation median / 90th / worst).
    pub pixel_errors: Vec<(usize, [f64; 3], [f64; 3])>,
    /// Over every evaluated pixel and sample: median, 90th, worst.
    pub error: [f64; 3],
    /// The same for linear interpolation.
    pub interpolation: [f64; 3],
    /// The gloss reading's relative error over every evaluated pixel and
    /// sample (`gloss`): median, 90th, worst (NaN: no pixel reads gloss).
    pub gloss: [f64; 3],
    /// Interpolation's.
    pub gloss_interpolation: [f64; 3],
    /// Every pixel's coverage.
    pub coverage: Vec<PixelCoverage>,
    /// Pixels whose specular direction falls between LEDs.
    pub uncovered: usize,
    /// Smallest margin over the line, degrees.
    pub min_margin_deg: f64,
    /// Pixels where the black glass saturates the long exposure, and the short one.
    pub black_glass_saturated: [usize; 2],
    /// Pixels where a polished metal saturates the long exposure, and the short one.
    pub metal_saturated: [usize; 2],
    /// Acquisition of a line without short exposures, ms.
    pub acquisition_ms: f64,
    /// With every shorter exposure of every LED (a metal under every LED), ms.
    pub acquisition_worst_ms: f64,
    /// Device estimation of one line (P points), ms at SYSCLK.
    pub estimation_ms: f64,
}

/// Scores every candidate.
pub fn run(spec: &DesignSpec, progress: &dyn Fn(usize, &str)) -> anyhow::Result<Vec<CandidateScore>> {
    spec.candidates
        .iter()
        .enumerate()
        .map(|(i, c)| {
            progress(i, &c.name);
            score(spec, c).with_context(|| format!("candidate {:?}", c.name))
        })
        .collect()
}

fn score(spec: &DesignSpec, c: &Candidate) -> anyhow::Result<CandidateScore> {
    let scene = c.apply(&spec.base);
    let inst = &scene.instrument;
    let p = inst.pixels();
    let sim = Simulator::new(&scene)?;
    let optics = Optics::new(inst, scene.ray_model());
    let per_pixel = training_optics(&scene, p, None)?;
    let pixels: Vec<_> = per_pixel.zones.into_iter().map(|z| z.centre).collect();
    let mut pixel_errors = Vec::new();
    let (mut all_e, mut all_i) = (Vec::new(), Vec::new());
    let (mut all_g, mut all_gi) = (Vec::new(), Vec::new());
    for &px in spec.pixels.iter().filter(|px| **px < p) {
        let po = &pixels[px];
        let pairs = Pairs::build(std::slice::from_ref(po), &spec.prior);
        let e = held_out_errors(po, &pairs, &spec.held_out).with_context(|| format!("pixel {px}"))?;
        pixel_errors.push((px, quantiles(&e.estimator), quantiles(&e.interpolation)));
        all_e.extend(e.estimator);
        all_i.extend(e.interpolation);
        let h = &spec.held_out;
        if let Some(g) = gloss::held_out_gloss(po, &spec.prior, h.folds, h.draws, h.seed)
            .with_context(|| format!("pixel {px}: gloss"))?
        {
            all_g.extend(g.estimator);
            all_gi.extend(g.interpolation);
        }
    }
    let cov = coverage::coverage(&scene, &optics, &sim, &pixels);
    let fs = inst.sensor.full_scale;
    let ratios = sim.pipeline().short_ratios().to_vec();
    let shortest = ratios.last().copied().unwrap_or(1.0);
    let dark = sim.dark().iter().copied().fold(0.0, f64::max);
    let sat = |x: f64| [usize::from(x >= fs), usize::from((x - dark) / shortest + dark >= fs)];
    let count = |f: &dyn Fn(&PixelCoverage) -> f64| {
        cov.iter().map(|c| sat(f(c))).fold([0, 0], |a, b| [a[0] + b[0], a[1] + b[1]])
    };
    let m = inst.m();
    let acq = acquisition::board(&ACQUISITION, p, acquisition::Frames::long_only(&ACQUISITION, m + 1));
    let long_us = ACQUISITION.exposure_us as f64;
    let shorter_us: Vec<f64> = ratios.iter().map(|r| long_us / r).collect();
    let worst = acquisition::board(&ACQUISITION, p, acquisition::Frames::every_exposure(long_us, &shorter_us, m + 1));
    let n = inst.grid()?.n();
    let die = inst.leds[0].extended.as_ref();
    let (die_mm, die_height_mm) = (die.map_or(0.0, |e| e.width_cm * 10.0), die.map_or(0.0, |e| e.height_cm * 10.0));
    Ok(CandidateScore {
        name: c.name.clone(),
        m,
        centres_deg: inst.centre_angles_deg(),
        die_mm,
        die_height_mm,
        gain: inst.sensor.gain,
        short_exposure: ratios.clone(),
        pixel_errors,
        error: quantiles(&all_e),
        interpolation: quantiles(&all_i),
        gloss: quantiles(&all_g),
        gloss_interpolation: quantiles(&all_gi),
        uncovered: cov.iter().filter(|c| c.margin_deg < 0.0).count(),
        min_margin_deg: cov.iter().map(|c| c.margin_deg).fold(f64::INFINITY, f64::min),
        black_glass_saturated: count(&|c| c.black_glass_counts),
        metal_saturated: count(&|c| c.metal_counts),
        coverage: cov,
        acquisition_ms: acq.line_us / 1e3,
        acquisition_worst_ms: worst.line_us / 1e3,
        estimation_ms: p as f64 * device_cycles_per_point(n, m) / SYSCLK_HZ as f64 * 1e3,
    })
}
