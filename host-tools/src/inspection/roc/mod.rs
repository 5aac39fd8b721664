//! Probability of detection against false calls, from simulated runs: a
//! recipe taught on the defect-free scene, then defect-free lines and lines
//! with each defect, every line through the device's own correction and
//! decision (`lines`).
//!
//! The ROC: each line gets a score, the smallest factor by which every
//! threshold of the recipe (distance and windows, entering and leaving)
//! would have to be raised for the line to pass: the line is rejected at
//! threshold factor c when a run of at least `min_pixels` adjacent pixels
//! is out at c times the leaving thresholds, one of them at c times the
//! entering ones, as the device decides (an unreadable pixel is out at
//! any factor). c = 1 is the recipe's operating point; sweeping c gives
//! the curve. Defect lines reuse the defect-free
//! lines' numbers (and so their noise draws): each defect is compared with
//! the same noise without it. Lines are decided one by one (`min_lines` 1,
//! no hysteresis carried between lines: a line's own verdict).
use super::lines::{DeviceModel, Line};
use super::teach::{Taught, TeachSpec, teach};
use crate::forward::brdf::BrdfSpec;
use crate::forward::scene::Scene;
use crate::forward::scene::defects::{DefectScene, DefectSpec, Extent};
use brdf_meter::inspect::RecipeView;
use brdf_meter::inspect::decide::point_stat_at;
use brdf_meter::protocol::flags;
use brdf_meter::shape::{LEDS as M, READINGS};
use rayon::prelude::*;
use serde::Serialize;

/// One defect case.
#[derive(Clone, Debug, Serialize)]
pub struct Case {
    /// Kind, as the table names it.
    pub kind: String,
    /// Size in pixels.
    pub pixels: usize,
    /// The defect's magnitude, as the table names it.
    pub magnitude: String,
    /// The defect (at pixel 0; placed along the line by the run).
    #[serde(skip)]
    pub defect: fn(Extent) -> DefectSpec,
}

/// The library's defect cases: gloss steps, scratches, a matt patch, a
/// contamination film.
pub fn cases() -> Vec<Case> {
    let case = |kind: &str, pixels, magnitude: &str, defect| Case {
        kind: kind.into(),
        pixels,
        magnitude: magnitude.into(),
        defect,
    };
    vec![
        case("gloss step", 8, "+1 GU", |at| DefectSpec::GlossStep { at, delta_gu: 1.0 }),
        case("gloss step", 8, "+2 GU", |at| DefectSpec::GlossStep { at, delta_gu: 2.0 }),
        case("gloss step", 8, "-2 GU", |at| DefectSpec::GlossStep { at, delta_gu: -2.0 }),
        case("gloss step", 8, "+3 GU", |at| DefectSpec::GlossStep { at, delta_gu: 3.0 }),
        case("gloss step", 4, "+2 GU", |at| DefectSpec::GlossStep { at, delta_gu: 2.0 }),
        case("gloss step", 4, "+3 GU", |at| DefectSpec::GlossStep { at, delta_gu: 3.0 }),
        case("scratch", 1, SCRATCH, scratch),
        case("scratch", 2, SCRATCH, scratch),
        case("scratch", 4, SCRATCH, scratch),
        case("matt patch", 16, "alpha 0.12 -> 0.2", |at| DefectSpec::MattPatch { at, alpha: 0.2 }),
        case("film", 16, "albedo 0.8, 3 %", |at| DefectSpec::Film { at, albedo: 0.8, coverage: 0.03 }),
    ]
}

/// The scratch's surface: rough grooves, brighter diffuse.
const SCRATCH: &str = "ward rho_d 0.6, rho_s 0.2, alpha 0.3";

fn scratch(at: Extent) -> DefectSpec {
    DefectSpec::Scratch { at, brdf: BrdfSpec::Ward { rho_d: 0.6, rho_s: Some(0.2), alpha: 0.3 } }
}

/// What to run.
#[derive(Clone, Debug)]
pub struct RocSpec {
    /// Lines the recipe is taught from.
    pub teach_lines: usize,
    /// Defect-free lines.
    pub clean_lines: usize,
    /// Lines per defect case.
    pub defect_lines: usize,
    /// The recipe's settings.
    pub teach: TeachSpec,
}

impl RocSpec {
    /// The small run (`inspect roc --quick`, the tests): the full run's
    /// 1,000 teach lines (fewer leave the per-pixel covariances noisy
    /// enough to multiply the false calls), 2,000 defect-free lines and
    /// 40 per case.
    pub fn quick(teach: TeachSpec) -> Self {
        Self { teach_lines: 1000, clean_lines: 2000, defect_lines: 40, teach }
    }
}

/// One case's result.
#[derive(Clone, Debug, Serialize)]
pub struct CaseResult {
    /// The case.
    pub case: Case,
    /// Lines.
    pub lines: usize,
    /// Lines the device rejected (its own verdicts).
    pub detected: usize,
    /// Probability of detection at the operating point.
    pub pod: f64,
    /// The lines' scores (for the curve).
    #[serde(skip)]
    pub scores: Vec<f64>,
}

/// The whole run.
#[derive(Clone, Debug, Serialize)]
pub struct Roc {
    /// The teach report.
    pub teach: super::teach::TeachReport,
    /// Defect-free lines.
    pub clean_lines: usize,
    /// The recipe's smallest defect, pixels.
    pub min_pixels: u16,
    /// Of them, rejected by the device.
    pub false_calls: usize,
    /// Their scores.
    #[serde(skip)]
    pub clean_scores: Vec<f64>,
    /// Per case.
    pub cases: Vec<CaseResult>,
}

impl Roc {
    /// False calls per 10^4 defect-free lines at threshold factor `c`.
    pub fn false_calls_at(&self, c: f64) -> f64 {
        1e4 * self.clean_scores.iter().filter(|s| **s > c).count() as f64 / self.clean_scores.len() as f64
    }

    /// The smallest factor c with at most `per_1e4` false calls per 10^4
    /// defect-free lines (over the lines run).
    pub fn factor_for(&self, per_1e4: f64) -> f64 {
        let mut s = self.clean_scores.clone();
        s.sort_by(f64::total_cmp);
        let allowed = (per_1e4 * s.len() as f64 / 1e4).floor() as usize;
        if allowed >= s.len() { 0.0 } else { s[s.len() - 1 - allowed] }
    }
}

/// A line's score (see the module docs).
pub fn line_score(recipe: &RecipeView<'_>, line: &Line) -> f64 {
    let s = recipe.settings();
    let p = recipe.pixels();
    let mut group = 0;
    let scale = brdf_meter::inspect::decide::line_scale(recipe, &line.v, &mut vec![0.0f32; p]);
    // Per pixel, the factor up to which it is out at the entering
    // thresholds and at the leaving ones.
    let scores: Vec<[f64; 2]> = (0..p)
        .map(|px| {
            while group + 1 < recipe.groups() && recipe.group_start(group + 1) <= px {
                group += 1;
            }
            let st = point_stat_at::<M>(recipe, group, px, &line.v[px].data.0[0], scale);
            if line.flags[px] & (flags::SATURATED | flags::UNDER_EXPOSED | flags::NON_FINITE) != 0 || !st.d2.is_finite()
            {
                return [f64::INFINITY; 2];
            }
            let score = |threshold: f32, window_factor: f32| {
                let mut score = st.d2 as f64 / threshold as f64;
                for r in 0..READINGS {
                    let [lo, hi] = s.windows[r].map(|x| x as f64 * window_factor as f64);
                    let d = st.delta[r] as f64;
                    if d < 0.0 && lo.is_finite() {
                        score = score.max(d / lo);
                    }
                    if d > 0.0 && hi.is_finite() {
                        score = score.max(d / hi);
                    }
                }
                score
            };
            let on = score(s.threshold_on, 1.0);
            // A format 1 recipe's defect needs every pixel at the entering thresholds.
            [on, if s.along_line_hysteresis { score(s.threshold_off, s.window_hysteresis) } else { on }]
        })
        .collect();
    run_score(&scores, s.min_pixels as usize)
}

/// The largest factor c at which a line with these per-pixel factors
/// (entering, leaving) is still rejected: a run of at least `k` adjacent
/// pixels whose leaving factor is at least c, one of whose entering factor
/// is too. 0 when no factor rejects it.
fn run_score(scores: &[[f64; 2]], k: usize) -> f64 {
    let rejected_at = |c: f64| {
        let (mut len, mut entered) = (0, false);
        for &[on, off] in scores {
            if off >= c {
                len += 1;
                entered |= on >= c;
                if len >= k.max(1) && entered {
                    return true;
                }
            } else {
                (len, entered) = (0, false);
            }
        }
        false
    };
    // Rejection only gets harder as c grows, and changes only at a pixel's
    // factor: the largest of them that still rejects.
    let mut candidates: Vec<f64> = scores.iter().flatten().copied().filter(|c| *c > 0.0).collect();
    candidates.sort_by(f64::total_cmp);
    let passing = candidates.partition_point(|&c| rejected_at(c));
    if passing == 0 { 0.0 } else { candidates[passing - 1] }
}

/// Runs teach, defect-free lines and every case on `scene` with `model`.
pub fn run(
    scene: &Scene,
    model: &DeviceModel<'_>,
    spec: &RocSpec,
    progress: &(dyn Fn(&str) + Sync),
) -> anyhow::Result<Roc> {
    let p = model.pixels();
    let clean = DefectScene::new("defect-free", scene.clone(), &[])?;
    let lines_of = |ds: &DefectScene, from: u64, count: usize| -> anyhow::Result<Vec<Line>> {
        (from..from + count as u64).into_par_iter().map(|l| Ok(model.correct(&ds.raw_frames_at(l)?))).collect()
    };
    progress("teaching");
    let taught: Taught = teach(model, &lines_of(&clean, 0, spec.teach_lines)?, &spec.teach)?;
    let recipe = RecipeView::parse(&taught.bytes).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let first = spec.teach_lines as u64;
    progress("defect-free lines");
    let (clean_scores, false_calls) = decide(&recipe, model, &clean, first, spec.clean_lines)?;
    let mut results = Vec::new();
    for case in cases() {
        progress(&format!("{} {} px {}", case.kind, case.pixels, case.magnitude));
        // Four places along the line, a quarter of the lines each.
        let mut scores = Vec::new();
        let mut detected = 0;
        for q in 0..4 {
            let centre = (2 * q + 1) * p / 8;
            let at = Extent {
                first_pixel: centre - case.pixels / 2,
                pixels: case.pixels,
                first_line: 0,
                lines: u64::MAX / 4,
            };
            let ds = DefectScene::new(&case.kind, scene.clone(), &[(case.defect)(at)])?;
            let n = spec.defect_lines / 4;
            let (s, d) = decide(&recipe, model, &ds, first + (q * n) as u64, n)?;
            scores.extend(s);
            detected += d;
        }
        let lines = scores.len();
        results.push(CaseResult { case, lines, detected, pod: detected as f64 / lines as f64, scores });
    }
    Ok(Roc {
        teach: taught.report,
        clean_lines: spec.clean_lines,
        min_pixels: spec.teach.min_pixels,
        false_calls,
        clean_scores,
        cases: results,
    })
}

/// Scores and device verdicts of `count` lines of `ds` from `first`.
fn decide(
    recipe: &RecipeView<'_>,
    model: &DeviceModel<'_>,
    ds: &DefectScene,
    first: u64,
    count: usize,
) -> anyhow::Result<(Vec<f64>, usize)> {
    let out: Vec<(f64, bool)> = (first..first + count as u64)
        .into_par_iter()
        .map(|l| {
            let line = model.correct(&ds.raw_frames_at(l)?);
            // A fresh inspector per line: the line's own verdict.
            let mut ins = super::lines::HostInspector::new(model.pixels())?;
            let v = ins.line(recipe, model, l as u32, &line);
            Ok((line_score(recipe, &line), v.rejected()))
        })
        .collect::<anyhow::Result<_>>()?;
    Ok((out.iter().map(|x| x.0).collect(), out.iter().filter(|x| x.1).count()))
}

pub mod report;

#[cfg(test)]
mod tests {
    use super::run_score;

    #[test]
    fn a_line_scores_the_largest_factor_its_runs_reject_at() {
        // Pixels 1-3 are out at the leaving thresholds up to 1.2, and one of
        // them at the entering ones beyond it: rejected up to 1.2 (all three
        // at the entering thresholds only up to 0.9).
        let line = [[0.5, 0.6], [2.0, 2.5], [0.9, 1.2], [1.5, 1.9], [0.1, 0.1]];
        assert_eq!(run_score(&line, 3), 1.2);
        // Two pixels far out and a third barely: the run is only as far out as its weakest.
        assert_eq!(run_score(&[[3.0, 3.0], [3.0, 3.0], [0.2, 0.3]], 3), 0.3);
        // The entering factor bounds it when no pixel of the run is out at it.
        assert_eq!(run_score(&[[0.4, 2.0], [0.5, 2.0], [0.3, 2.0]], 3), 0.5);
        // Unreadable pixels reject at any factor; too short a line at none.
        assert_eq!(run_score(&[[f64::INFINITY; 2]; 3], 3), f64::INFINITY);
        assert_eq!(run_score(&line, 6), 0.0);
    }
}
