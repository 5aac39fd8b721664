//! Numerical stability on hard cases: reusable generators of
//! hard-case families ([`families`]), the invariants every case must satisfy
//! with their stated tolerances ([`invariants`]), the solvers under test
//! including deliberately broken ones ([`solvers`]), and a runner that
//! summarises many cases per family ([`run_observed`]).
//!
//! Used by the property tests (`host-tools/tests/stability.rs`, a fixed-seed
//! subset in the normal test run) and by the long run:
//!
//! ```text
//! cargo run --release -p host-tools -- stability --cases 10000 --json out/stability.json
//! ```
mod exact_limit;
pub mod families;
pub mod invariants;
pub mod solvers;

pub use families::{Case, Family, generate};
pub use invariants::{CaseReport, check_case};
pub use solvers::{DeviceKernel, Production, Solver, device_kernel};

use serde::Serialize;
use std::fmt::Write as _;

/// What a family's cases measured, worst case first.
#[derive(Clone, Debug, Default, Serialize)]
pub struct FamilySummary {
    /// Family name.
    pub family: String,
    /// Cases run.
    pub cases: usize,
    /// Cases with at least one failed invariant.
    pub failures: usize,
    /// Worst I2 error/bound ratio (<= 1 passes).
    pub worst_error_ratio: f64,
    /// Largest achieved / mmse.
    pub worst_achieved_over_mmse: f64,
    /// Diagnostic: largest achieved / mmse on the raw samples (with their
    /// components below R_pp's eigenvalue floor).
    pub worst_raw_over_mmse: f64,
    /// Diagnostic: cases whose raw achieved / mmse exceeds 2.
    pub raw_over_2: usize,
    /// Smallest and largest finite cond(H R_pp H^T).
    pub cond_min: f64,
    /// Largest finite cond(H R_pp H^T).
    pub cond_max: f64,
    /// Cases with singular H R_pp H^T (cond = inf).
    pub singular: usize,
    /// Worst I3 measured/tolerance.
    pub worst_continuity_ratio: f64,
    /// Cases whose sigma -> 0 limit f64 cannot resolve (I3 then checks finiteness only).
    pub continuity_unresolved: usize,
    /// Worst f32 relative error (of the estimate's scale) among the matrices
    /// the f32 gate accepted (what a device would run).
    pub worst_f32_rel_error: f64,
    /// Worst f32 error / rounding bound.
    pub worst_f32_bound_ratio: f64,
    /// Cases the f32 gate refused (the device would not get this matrix).
    pub f32_refused: usize,
    /// Worst normwise backward error.
    pub worst_backward_error: f64,
    /// Worst backward error / bound.
    pub worst_backward_ratio: f64,
    /// Worst I6 ratio (gain family).
    pub worst_gain_ratio: Option<f64>,
    /// Up to 5 failing cases: seed and the first failure.
    pub examples: Vec<String>,
}

/// Everything a run measured.
#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    /// Solver name.
    pub solver: String,
    /// Per family.
    pub families: Vec<FamilySummary>,
    /// Total cases.
    pub total_cases: usize,
    /// Total failing cases.
    pub total_failures: usize,
    /// Wall time, seconds.
    pub seconds: f64,
}

impl FamilySummary {
    fn add(&mut self, r: &CaseReport) {
        let mx = |a: f64, b: f64| if b.is_nan() { a } else { a.max(b) };
        if self.cases == 0 {
            self.cond_min = f64::INFINITY;
        }
        self.cases += 1;
        if !r.failures.is_empty() {
            self.failures += 1;
            if self.examples.len() < 5 {
                self.examples.push(format!("seed {}: {} [{}]", r.seed, r.failures[0], r.label));
            }
        }
        // A NaN ratio means the invariant could not be evaluated: count it as a failure above, worst as inf here.
        let nan_inf = |x: f64| if x.is_nan() { f64::INFINITY } else { x };
        self.worst_error_ratio = self.worst_error_ratio.max(nan_inf(r.error_bound_ratio));
        self.worst_achieved_over_mmse = mx(self.worst_achieved_over_mmse, r.achieved_over_mmse);
        self.worst_raw_over_mmse = mx(self.worst_raw_over_mmse, r.raw_achieved_over_mmse);
        if r.raw_achieved_over_mmse > 2.0 {
            self.raw_over_2 += 1;
        }
        if r.cond_hrh.is_finite() {
            self.cond_min = self.cond_min.min(r.cond_hrh);
            self.cond_max = self.cond_max.max(r.cond_hrh);
        } else {
            self.singular += 1;
        }
        self.worst_continuity_ratio = mx(self.worst_continuity_ratio, r.continuity_ratio);
        if !r.continuity_resolved {
            self.continuity_unresolved += 1;
        }
        if r.f32_accepted {
            self.worst_f32_rel_error = mx(self.worst_f32_rel_error, r.f32_rel_error);
        }
        self.worst_f32_bound_ratio = self.worst_f32_bound_ratio.max(nan_inf(r.f32_bound_ratio));
        if !r.f32_accepted {
            self.f32_refused += 1;
        }
        self.worst_backward_error = mx(self.worst_backward_error, r.backward_error);
        self.worst_backward_ratio = self.worst_backward_ratio.max(nan_inf(r.backward_ratio));
        if let Some(g) = r.gain_ratio {
            self.worst_gain_ratio = Some(self.worst_gain_ratio.unwrap_or(0.0).max(g));
        }
    }
}

/// Runs `cases` cases of each family (seeds `first_seed..first_seed + cases`)
/// on `threads` threads, calling `case_done` (from any worker thread) after
/// each case, so a caller can show progress.
pub fn run_observed(
    families: &[Family],
    cases: usize,
    first_seed: u64,
    solver: &dyn Solver,
    kernel: DeviceKernel,
    threads: usize,
    case_done: &(dyn Fn() + Sync),
) -> (RunSummary, Vec<CaseReport>) {
    let jobs: Vec<(Family, u64)> =
        families.iter().flat_map(|f| (0..cases as u64).map(move |s| (*f, first_seed + s))).collect();
    let threads = threads.max(1);
    let (mut reports, seconds) = crate::evaluation::timing::timed(|| -> Vec<CaseReport> {
        std::thread::scope(|sc| {
            let handles: Vec<_> = (0..threads)
                .map(|t| {
                    let jobs = &jobs;
                    sc.spawn(move || {
                        jobs.iter()
                            .skip(t)
                            .step_by(threads)
                            .map(|(f, s)| {
                                let r = check_case(&generate(*f, *s), solver, kernel);
                                case_done();
                                r
                            })
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            handles.into_iter().flat_map(|h| h.join().expect("worker panicked")).collect()
        })
    });
    reports.sort_by(|a, b| (a.family, a.seed).cmp(&(b.family, b.seed)));
    let mut fams = Vec::new();
    for f in families {
        let mut s = FamilySummary { family: f.name().into(), ..Default::default() };
        for r in reports.iter().filter(|r| r.family == f.name()) {
            s.add(r);
        }
        fams.push(s);
    }
    let total_cases = fams.iter().map(|f| f.cases).sum();
    let total_failures = fams.iter().map(|f| f.failures).sum();
    let summary = RunSummary { solver: solver.name().into(), families: fams, total_cases, total_failures, seconds };
    (summary, reports)
}

impl RunSummary {
    /// The summary table (plain text, one row per family).
    pub fn table(&self) -> String {
        let mut o = String::new();
        let _ = writeln!(
            o,
            "{:<21} {:>6} {:>5} {:>10} {:>10} {:>9} {:>19} {:>5} {:>9} {:>6} {:>9} {:>9} {:>7} {:>9} {:>8}",
            "family",
            "cases",
            "fail",
            "err/bound",
            "ach/mmse",
            "raw>2x",
            "cond(HRH^T) range",
            "sing",
            "cont/tol",
            "unres",
            "f32 acc",
            "f32/bnd",
            "f32 ref",
            "backward",
            "bwd/bnd"
        );
        for f in &self.families {
            let range =
                if f.cond_min.is_finite() { format!("{:.1e}..{:.1e}", f.cond_min, f.cond_max) } else { "-".into() };
            let _ = writeln!(
                o,
                "{:<21} {:>6} {:>5} {:>10.3} {:>10.3} {:>9} {:>19} {:>5} {:>9.2e} {:>6} {:>9.2e} {:>9.3} {:>7} {:>9.2e} {:>8.3}",
                f.family,
                f.cases,
                f.failures,
                f.worst_error_ratio,
                f.worst_achieved_over_mmse,
                format!("{}({:.1})", f.raw_over_2, f.worst_raw_over_mmse),
                range,
                f.singular,
                f.worst_continuity_ratio,
                f.continuity_unresolved,
                f.worst_f32_rel_error,
                f.worst_f32_bound_ratio,
                f.f32_refused,
                f.worst_backward_error,
                f.worst_backward_ratio
            );
        }
        let _ = writeln!(
            o,
            "total: {} cases, {} failing, solver {}, {:.1} s",
            self.total_cases, self.total_failures, self.solver, self.seconds
        );
        for f in &self.families {
            if let Some(g) = f.worst_gain_ratio {
                let _ = writeln!(o, "{}: worst gain-covariance measured/tolerance {g:.3e}", f.family);
            }
            for e in &f.examples {
                let _ = writeln!(o, "  FAIL {}: {e}", f.family);
            }
        }
        o
    }
}
