//! The figures a metrologist signs, per family and method, from every
//! estimate (one per noise draw) of every surface:
//!
//! - BRDF error: per surface, the RMS over bins and draws of `est - truth`
//!   over the truth's peak bin; median, 90th percentile and worst surface.
//! - Physically impossible: the share of estimates with a bin below
//!   [`IMPOSSIBLE`] of the estimate's own peak (its largest |bin|).
//! - Gloss: `|G_est - G_true| / G_true` per estimate, median and 90th
//!   percentile, split at [`GLOSS_SPLIT_GU`] of the truth (up to it also in
//!   GU); haze (HU) and distinctness (%) as absolute errors.
//! - Coverage at k = 2: the share of bins with `|est - truth| <= 2 u`, `u`
//!   the bin's own stated uncertainty, with its 95 % interval over the
//!   surfaces (`evaluation::coverage_interval`); the same per gloss reading.
//! - Flag: of estimates worse than [`BAD_ERROR`] of the truth's peak, the
//!   share flagged (any flag); of the rest, the share flagged.
//! - Specular peak (`output::peak`): height relative error, full width at
//!   half maximum absolute error, their k = 2 coverage over the peaks the
//!   calibration resolves (an unresolved one states no uncertainty), and
//!   the share it does not resolve.
//!
//! Interpolation states no uncertainty and raises no flag: its coverage
//! and flag figures are absent (`None`), never zero.
use super::reading::Reading;
use super::truth::Truth;
use crate::device::measurement_result::reading_result;
use crate::evaluation::pixel_error::quantiles;
use serde::Serialize;

/// A bin below this fraction of the estimate's peak is physically impossible
/// (a reflectance factor is never negative; 1 % leaves room for rounding).
pub const IMPOSSIBLE: f64 = -0.01;
/// Gloss readings are split here: a gloss meter's usual range, and the
/// near-mirror surfaces above it.
pub const GLOSS_SPLIT_GU: f64 = 300.0;
/// An estimate worse than this (RMS over bins / truth's peak) should be flagged.
pub const BAD_ERROR: f64 = crate::calibration::estimators::out_of_prior::BAD_ESTIMATE;
/// The coverage factor of the stated uncertainties checked (the GUM's ~95 %).
pub const K: f64 = 2.0;
/// The seed of the coverage's bootstrap interval: one report, one interval.
const COVERAGE_INTERVAL_SEED: u64 = 2813;

/// Median, 90th percentile and largest.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// 90th percentile.
    pub p90: f64,
    /// Largest.
    pub max: f64,
}

impl Spread {
    /// Of the values `x` (NaN when empty).
    pub fn of(x: &[f64]) -> Self {
        let [median, p90, max] = quantiles(x);
        Self { median, p90, max }
    }
}

/// One family and method's figures.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Family.
    pub family: String,
    /// `estimator` or `interpolation`.
    pub method: String,
    /// Surfaces.
    pub materials: usize,
    /// Estimates (surfaces x draws).
    pub estimates: usize,
    /// Per-surface BRDF error (RMS over bins and draws / truth's peak).
    pub error: Spread,
    /// The surface with the largest.
    pub worst_material: String,
    /// Share of estimates with a bin below [`IMPOSSIBLE`] of their peak.
    pub impossible: f64,
    /// Gloss relative error of surfaces up to [`GLOSS_SPLIT_GU`] (truth).
    pub gloss_rel_low: Spread,
    /// Estimates in it.
    pub gloss_low_count: usize,
    /// Their absolute error, GU (a low-gloss surface's relative error says
    /// little: 1 GU off a 2 GU matt paint is 50 %).
    pub gloss_abs_low_gu: Spread,
    /// The same above.
    pub gloss_rel_high: Spread,
    /// Estimates in it.
    pub gloss_high_count: usize,
    /// |haze error|, HU.
    pub haze_abs: Spread,
    /// |distinctness error|, %.
    pub distinctness_abs: Spread,
    /// Estimates with a gloss reading missing (NaN) where the truth has one.
    pub no_reading: usize,
    /// Share of bins within k = 2 of their stated uncertainty.
    pub bin_coverage: Option<f64>,
    /// Its 95 % interval, resampling the surfaces
    /// (`evaluation::coverage_interval`).
    pub bin_coverage_interval: Option<[f64; 2]>,
    /// How wide that band is: per estimate, the RMS over the bins of the
    /// stated uncertainty over the truth's peak (the error's own scale, so a
    /// band that is right has its median near the error's).
    pub band: Option<Spread>,
    /// The same for gloss, haze and distinctness.
    pub reading_coverage: Option<[f64; 3]>,
    /// The same for the result a user states of a surface
    /// (`crate::device::measurement_result`): the mean of its draws with
    /// `U` = k times the root sum of squares of the RMS of their stated
    /// uncertainties and the mean's repeatability; the share of the
    /// surfaces whose truth it covers.
    pub result_coverage: Option<[f64; 3]>,
    /// Estimates worse than [`BAD_ERROR`].
    pub bad: usize,
    /// Of those, the share flagged.
    pub flag_caught: Option<f64>,
    /// Of the rest, the share flagged.
    pub flag_false: Option<f64>,
    /// The median BRDF error of the flagged estimates and of the rest
    /// ([`FlagErrors`]; NaN for a side with none).
    pub flag_error_medians: Option<[f64; 2]>,
    /// Specular peak height, relative error.
    pub peak_height_rel: Spread,
    /// Its full width at half maximum, absolute error (deg).
    pub peak_width_abs_deg: Spread,
    /// Share of peak heights within k = 2 of their stated uncertainty
    /// (the resolved peaks': an unresolved one states none).
    pub peak_height_coverage: Option<f64>,
    /// Share of peak widths within k = 2 of theirs.
    pub peak_width_coverage: Option<f64>,
    /// Estimates without a peak where the truth has one.
    pub peak_missed: usize,
    /// Of the estimates' peaks, the share the calibration does not resolve
    /// (`output::peak`; `None`: no peak, or no resolution recorded).
    pub peak_unresolved: Option<f64>,
}

pub use crate::calibration::estimators::out_of_prior::FlagScore;

/// The BRDF errors of the flagged estimates and of the rest, apart. A
/// [`FlagScore`] says whether the flag is raised on either side of one
/// error ([`BAD_ERROR`]); these say how much worse, in the error's own
/// unit, a flagged point is read than one without the flag: what a user
/// may take a raised flag to mean.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FlagErrors {
    /// Errors of the flagged estimates.
    pub flagged: Vec<f64>,
    /// Errors of the rest.
    pub rest: Vec<f64>,
}

impl FlagErrors {
    /// Tallies one estimate's error (over its truth's peak).
    pub fn add(&mut self, error: f64, flagged: bool) {
        if flagged { &mut self.flagged } else { &mut self.rest }.push(error);
    }

    /// Both tallies together.
    pub fn merged(mut self, other: &Self) -> Self {
        self.flagged.extend_from_slice(&other.flagged);
        self.rest.extend_from_slice(&other.rest);
        self
    }

    /// The medians of the flagged and of the rest (NaN for a side with none).
    pub fn medians(&self) -> [f64; 2] {
        [Spread::of(&self.flagged).median, Spread::of(&self.rest).median]
    }
}

/// The running tally of one family and method.
#[derive(Debug, Default)]
pub struct Tally {
    materials: Vec<(String, f64)>,
    estimates: usize,
    impossible: usize,
    gloss_low: Vec<f64>,
    gloss_low_abs: Vec<f64>,
    gloss_high: Vec<f64>,
    haze: Vec<f64>,
    distinctness: Vec<f64>,
    no_reading: usize,
    bins: Option<(usize, usize)>,
    /// Per surface, bins within k = 2 and bins counted.
    bins_per_surface: Vec<(f64, f64)>,
    band: Vec<f64>,
    readings: Option<[(usize, usize); 3]>,
    /// Per reading, surfaces whose result covers the truth and surfaces.
    results: Option<[(usize, usize); 3]>,
    flag: FlagScore,
    flag_errors: FlagErrors,
    flags: bool,
    height: Vec<f64>,
    width: Vec<f64>,
    height_cov: Option<(usize, usize)>,
    width_cov: Option<(usize, usize)>,
    peak_missed: usize,
    unresolved: Option<(usize, usize)>,
}

/// `(hits, total)` as a share (`None` when there was nothing to count).
fn share((hit, total): (usize, usize)) -> Option<f64> {
    (total > 0).then(|| hit as f64 / total as f64)
}

fn count(acc: &mut Option<(usize, usize)>, hit: bool) {
    let a = acc.get_or_insert((0, 0));
    a.0 += usize::from(hit);
    a.1 += 1;
}

/// RMS over the bins of `est - truth`, over the truth's peak.
pub fn peak_relative_rms(est: &[f64], truth: &Truth) -> f64 {
    let n = est.len() as f64;
    let ss: f64 = est.iter().zip(truth.rho.iter()).map(|(e, t)| (e - t).powi(2)).sum();
    (ss / n).sqrt() / truth.peak.max(f64::MIN_POSITIVE)
}

/// How many bins of `est` lie within [`K`] of their stated uncertainty
/// `sigma` of the truth, and of how many.
pub fn bins_within(est: &[f64], truth: &Truth, sigma: &[f64]) -> (usize, usize) {
    let inside = est.iter().zip(truth.rho.iter()).zip(sigma).filter(|((x, t), u)| (*x - *t).abs() <= K * **u);
    (inside.count(), sigma.len())
}

/// Whether a bin of `est` is below [`IMPOSSIBLE`] of its largest |bin|.
pub fn impossible(est: &[f64]) -> bool {
    let top = est.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    est.iter().any(|x| *x < IMPOSSIBLE * top)
}

impl Tally {
    /// Adds every estimate of one surface.
    pub fn add(&mut self, name: &str, truth: &Truth, estimates: &[Reading]) {
        let mut ss = 0.0;
        let mut surface_bins = (0usize, 0usize);
        for r in estimates {
            let e = peak_relative_rms(&r.rho, truth);
            ss += e * e;
            self.estimates += 1;
            self.impossible += usize::from(impossible(&r.rho));
            let [gt, ht, dt] = truth.readings;
            let [g, h, d] = r.gloss;
            if gt.is_finite() && gt > 0.0 {
                if g.is_finite() {
                    let rel = (g - gt).abs() / gt;
                    if gt <= GLOSS_SPLIT_GU {
                        self.gloss_low.push(rel);
                        self.gloss_low_abs.push((g - gt).abs());
                    } else {
                        self.gloss_high.push(rel);
                    }
                } else {
                    self.no_reading += 1;
                }
            }
            if ht.is_finite() && h.is_finite() {
                self.haze.push((h - ht).abs());
            }
            if dt.is_finite() && d.is_finite() {
                self.distinctness.push((d - dt).abs());
            }
            if let Some(s) = &r.sigma {
                let b = self.bins.get_or_insert((0, 0));
                let (inside, all) = bins_within(&r.rho, truth, s);
                b.0 += inside;
                b.1 += all;
                surface_bins.0 += inside;
                surface_bins.1 += all;
                let ms = s.iter().map(|u| u * u).sum::<f64>() / s.len().max(1) as f64;
                self.band.push(ms.sqrt() / truth.peak.max(f64::MIN_POSITIVE));
            }
            if let Some(u) = r.gloss_u {
                let acc = self.readings.get_or_insert([(0, 0); 3]);
                for i in 0..3 {
                    let (x, t) = (r.gloss[i], truth.readings[i]);
                    if x.is_finite() && t.is_finite() && u[i].is_finite() {
                        acc[i].0 += usize::from((x - t).abs() <= K * u[i]);
                        acc[i].1 += 1;
                    }
                }
            }
            self.flag.add(e, r.flagged == Some(true));
            if let Some(f) = r.flagged {
                self.flag_errors.add(e, f);
            }
            self.flags |= r.flagged.is_some();
            let (tp, ep) = (truth.specular, r.specular);
            if tp.rf.is_finite() {
                if ep.rf.is_finite() {
                    if let Some(resolved) = ep.resolved {
                        count(&mut self.unresolved, !resolved);
                    }
                    self.height.push((ep.rf - tp.rf).abs() / tp.rf);
                    if ep.u_rf.is_finite() && r.sigma.is_some() {
                        count(&mut self.height_cov, (ep.rf - tp.rf).abs() <= K * ep.u_rf);
                    }
                } else {
                    self.peak_missed += 1;
                }
                if tp.width_deg.is_finite() && ep.width_deg.is_finite() {
                    self.width.push((ep.width_deg - tp.width_deg).abs());
                    if ep.u_width_deg.is_finite() && r.sigma.is_some() {
                        count(&mut self.width_cov, (ep.width_deg - tp.width_deg).abs() <= K * ep.u_width_deg);
                    }
                }
            }
        }
        self.add_result(truth, estimates);
        let rms = (ss / estimates.len().max(1) as f64).sqrt();
        self.materials.push((name.to_string(), rms));
        if surface_bins.1 > 0 {
            self.bins_per_surface.push((surface_bins.0 as f64, surface_bins.1 as f64));
        }
    }

    /// Whether the result of one surface's estimates (the mean of its
    /// draws, as `measure` states one) covers the truth, reading by reading.
    fn add_result(&mut self, truth: &Truth, estimates: &[Reading]) {
        if estimates.iter().any(|r| r.gloss_u.is_none()) {
            return;
        }
        let acc = self.results.get_or_insert([(0, 0); 3]);
        for (i, a) in acc.iter_mut().enumerate() {
            let t = truth.readings[i];
            let points: Vec<(f64, f64)> = estimates
                .iter()
                .filter_map(|r| Some((r.gloss[i], r.gloss_u?[i])))
                .filter(|(x, u)| x.is_finite() && u.is_finite())
                .collect();
            // The evaluation's readings carry no standards' uncertainties.
            if let (true, Some(r)) = (t.is_finite(), reading_result(i, &points, (0.0, 0.0))) {
                a.0 += usize::from(r.covers(t));
                a.1 += 1;
            }
        }
    }

    /// The figures.
    pub fn row(&self, family: &str, method: &str) -> Row {
        let errors: Vec<f64> = self.materials.iter().map(|m| m.1).collect();
        let worst = self
            .materials
            .iter()
            .filter(|m| m.1.is_finite())
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(String::new(), |m| m.0.clone());
        Row {
            family: family.into(),
            method: method.into(),
            materials: self.materials.len(),
            estimates: self.estimates,
            error: Spread::of(&errors),
            worst_material: worst,
            impossible: share((self.impossible, self.estimates)).unwrap_or(f64::NAN),
            gloss_rel_low: Spread::of(&self.gloss_low),
            gloss_low_count: self.gloss_low.len(),
            gloss_abs_low_gu: Spread::of(&self.gloss_low_abs),
            gloss_rel_high: Spread::of(&self.gloss_high),
            gloss_high_count: self.gloss_high.len(),
            haze_abs: Spread::of(&self.haze),
            distinctness_abs: Spread::of(&self.distinctness),
            no_reading: self.no_reading,
            bin_coverage: self.bins.and_then(share),
            bin_coverage_interval: crate::evaluation::coverage_interval::coverage_interval(
                &self.bins_per_surface,
                COVERAGE_INTERVAL_SEED,
            ),
            band: (!self.band.is_empty()).then(|| Spread::of(&self.band)),
            reading_coverage: self.readings.map(|r| r.map(|x| share(x).unwrap_or(f64::NAN))),
            result_coverage: self.results.map(|r| r.map(|x| share(x).unwrap_or(f64::NAN))),
            bad: self.flag.bad,
            flag_caught: if self.flags { share((self.flag.bad_flagged, self.flag.bad)) } else { None },
            flag_false: if self.flags { share((self.flag.good_flagged, self.flag.good)) } else { None },
            flag_error_medians: self.flags.then(|| self.flag_errors.medians()),
            peak_height_rel: Spread::of(&self.height),
            peak_width_abs_deg: Spread::of(&self.width),
            peak_height_coverage: self.height_cov.and_then(share),
            peak_width_coverage: self.width_cov.and_then(share),
            peak_missed: self.peak_missed,
            peak_unresolved: self.unresolved.and_then(share),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_flag_score_counts_bad_and_good_points_apart() {
        let mut a = FlagScore::default();
        for (e, f) in [(0.2, true), (0.3, false), (0.05, true), (0.01, false), (0.02, false), (BAD_ERROR, false)] {
            a.add(e, f);
        }
        // An error of exactly BAD_ERROR is not worse than it.
        assert_eq!(a, FlagScore { bad: 2, bad_flagged: 1, good: 4, good_flagged: 1 });
        assert_eq!((a.caught(), a.false_alarms()), (0.5, 0.25));
        let b = a.merged(FlagScore { bad: 2, bad_flagged: 2, good: 0, good_flagged: 0 });
        assert_eq!((b.caught(), b.false_alarms()), (0.75, 0.25));
        assert!(
            FlagScore::<usize>::default().caught().is_nan() && FlagScore::<usize>::default().false_alarms().is_nan()
        );
    }

    #[test]
    fn the_flagged_and_the_rest_have_their_own_error_medians() {
        let mut a = FlagErrors::default();
        for (e, f) in [(0.2, true), (0.3, false), (0.05, true), (0.01, false), (0.02, false), (0.08, true)] {
            a.add(e, f);
        }
        assert_eq!(a.medians(), [0.08, 0.02]);
        let b = a.clone().merged(&FlagErrors { flagged: vec![0.5, 0.6], rest: vec![] });
        assert_eq!(b.medians()[0], 0.2);
        let none = FlagErrors::default().merged(&FlagErrors { flagged: vec![], rest: vec![0.1] });
        assert!(none.medians()[0].is_nan() && none.medians()[1] == 0.1);
    }

    /// A surface's draws reading gloss `g` (each stated to `u`) against a
    /// truth of 100 GU.
    fn surface(g: &[f64], u: f64) -> (Truth, Vec<Reading>) {
        let zero = nalgebra::DVector::zeros(3);
        let truth = Truth {
            rho: zero.clone(),
            peak: 1.0,
            readings: [100.0, 10.0, f64::NAN],
            specular: crate::output::peak::Peak::NONE,
            clean: zero.clone(),
            as_prior: zero,
        };
        let draws = g
            .iter()
            .map(|&g| Reading {
                rho: vec![0.0; 3],
                sigma: None,
                gloss: [g, 10.0, f64::NAN],
                gloss_u: Some([u, 0.5, f64::NAN]),
                flagged: None,
                specular: crate::output::peak::Peak::NONE,
                stat: f64::NAN,
                brightest_share: f64::NAN,
            })
            .collect();
        (truth, draws)
    }

    #[test]
    fn a_surfaces_result_is_its_draws_mean_with_the_budget_measure_states() {
        let mut t = Tally::default();
        // Off by 1.9 with u 1: within U = 2 sqrt(1 + 0) = 2.
        let (truth, draws) = surface(&[101.9, 101.9, 101.9, 101.9], 1.0);
        t.add("a", &truth, &draws);
        // Off by 2.3 on average, beyond 2 u, but the draws scatter (sd
        // 2.66): the mean's repeatability (1.33, 3 degrees of freedom)
        // widens u_c to 1.66 and k to 2.4 (nu_eff 7.4): U about 4.0.
        let (truth, draws) = surface(&[100.0, 104.6, 100.0, 104.6], 1.0);
        t.add("b", &truth, &draws);
        // Off by 2.1: not covered; a reading of a surface each draw of which
        // is not covered is not covered as a mean either.
        let (truth, draws) = surface(&[102.1, 102.1], 1.0);
        t.add("c", &truth, &draws);
        let r = t.row("f", "estimator").result_coverage.unwrap();
        assert_eq!((r[0], r[1]), (2.0 / 3.0, 1.0), "{r:?}");
        assert!(r[2].is_nan(), "no truth, no result to judge");
        // A method without stated uncertainties states no result.
        let mut none = Tally::default();
        let (truth, mut draws) = surface(&[100.0], 1.0);
        draws[0].gloss_u = None;
        none.add("a", &truth, &draws);
        assert_eq!(none.row("f", "interpolation").result_coverage, None);
    }

    #[test]
    fn impossible_is_relative_to_the_estimates_own_peak() {
        assert!(!impossible(&[0.0, 1.0, -0.009]));
        assert!(impossible(&[0.0, 1.0, -0.011]));
        assert!(impossible(&[-0.5, -0.2]));
        assert!(!impossible(&[0.0, 0.0]));
    }
}
