//! A measurement's result as a calibration laboratory states one: each
//! gloss reading's mean over the points of the zones asked for, and the
//! mean BRDF bin by bin, with its uncertainty budget (GUM: each
//! contribution's standard uncertainty in the reading's unit and its
//! degrees of freedom, their root sum of squares `u_c`, and `U = k u_c` at
//! a coverage probability of 95.45 %, k from the effective degrees of
//! freedom: 2 with many, [`crate::device::coverage_factor`]). `measure`
//! and `estimate` print it and write it as JSON; `verify` compares a
//! standard's zone means by the same budget.
//!
//! The contributions:
//! - **calibration**: the RMS of the uncertainty the calibration states
//!   for each point's reading (the estimator's error for such a surface,
//!   the sensor's noise included). Most of it is systematic for a surface,
//!   the same material read with the same error point after point, so
//!   averaging points does not reduce it: the mean keeps a reading's.
//! - **repeatability**: the points' sample standard deviation over the
//!   square root of their number (type A), how well the points pin the
//!   mean over the area read: the noise on a uniform sample, the sample's
//!   own variation on one that is not. Its `n - 1` degrees of freedom are
//!   the budget's only finite ones: few points that vary much widen k.
//!   The noise is then counted in both, which is the safe side: on the
//!   handheld, counting it once left the gloss results of materials from
//!   other databases within U 85 % of the time, not 98 %
//!   (`docs/guide/measuring.md`).
//! - **white reference** and **gloss scale**: a standardised calibration's
//!   relative uncertainties (`BlobView::white_uncertainty`,
//!   `gloss_uncertainty`) times the mean, on the readings that scale with
//!   them (gloss and haze; the BRDF the white's; distinctness, a ratio of
//!   two readings, neither), as `crate::output::points` adds them to each
//!   point.
//!
//! Each value is stated with its coverage interval: `value +- U`, within
//! what the quantity can be by its definition (`gloss::DOMAINS`; a
//! reflectance factor is never negative). The truth lies in that range, so
//! the interval keeps the coverage of `value +- U` and says only what is
//! possible: a matt sample's distinctness of 0.6 % with U = 4.3 % is
//! 0-4.9 %, not -3.7-4.9 %, and a bin's reflectance factor is never below
//! 0 however wide its uncertainty at a mirror bin the LEDs do not resolve.
//! (Clipping is the conservative statement; a shorter interval from the
//! distribution truncated at the bound would claim a shape of the
//! distribution the budget does not know.)
//!
//! Beside the result over the zones asked for, every zone with points has
//! one of its own ([`ZoneResult`]: its readings, the same budget over its
//! points alone), which says how the surface reads along the line.
//!
//! By default the points are those of the zones at the centre of the line
//! ([`centre_zones`]): a surface other than a mirror reads differently
//! where the pixels view it at other angles (the handheld's view at 41.5
//! to 48 deg along its line), and a result is stated for the instrument's
//! nominal geometry. Saturated points are left out (their values are not
//! to be used) and counted; readings without a stated uncertainty and
//! estimates that are not finite are left out too; out-of-prior points
//! are kept and counted (their stated uncertainty is already the
//! wider one the calibration states for such points); under-exposed ones
//! are kept, as the gloss standardisation keeps them:
//! a glossy surface is dark under every LED but those near its mirror
//! direction, which the gloss readings take.
use crate::device::coverage_factor;
use crate::device::measurement_summary::{Spread, spread};
use crate::output::points::{Point, Points};
use anyhow::Context;
use brdf_meter::blob::BlobView;
use brdf_meter::gloss;
use brdf_meter::protocol::flags;
use brdf_meter::shape::READINGS;
use serde::Serialize;
use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::Path;

/// The document's schema name.
pub const SCHEMA: &str = "brdf-meter/result";
/// Its version: bumped when a field is renamed, removed, added, moved or
/// changes its meaning or unit (`docs/point-schema.md`).
pub const SCHEMA_VERSION: u32 = 3;

/// Each reading's unit, in `gloss::NAMES` order.
const UNITS: [&str; READINGS] = ["GU", "HU", "%"];

/// A reflectance factor's range: never negative, unbounded above.
pub const REFLECTANCE_FACTOR_DOMAIN: (f64, f64) = (0.0, f64::INFINITY);

/// The coverage interval `value +- expanded_u` within `(lowest, highest)`,
/// the quantity's range by its definition. A value outside the range
/// altogether (never for the device's readings, which are within their
/// definitions) gives the nearest bound, an interval of no width, rather
/// than one whose ends cross.
pub fn coverage_interval(value: f64, expanded_u: f64, (lowest, highest): (f64, f64)) -> [f64; 2] {
    let lo = (value - expanded_u).clamp(lowest, highest);
    let hi = (value + expanded_u).clamp(lowest, highest);
    [lo, hi.max(lo)]
}

/// A calibration's standards' relative standard uncertainties (0 when it
/// was not standardised on them).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct References {
    /// The white reference's (the white tile).
    pub white: f64,
    /// The gloss scale's (the black glass).
    pub gloss_scale: f64,
}

impl References {
    /// Those the calibration `view` states.
    pub fn of(view: &BlobView<'_>) -> Self {
        Self { white: f64::from(view.white_uncertainty()), gloss_scale: f64::from(view.gloss_uncertainty()) }
    }
}

/// One contribution to a reading's uncertainty.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Contribution {
    /// Where it comes from: `calibration`, `repeatability`,
    /// `white_reference` or `gloss_scale`.
    pub source: &'static str,
    /// Its standard uncertainty, in the reading's unit.
    pub u: f64,
    /// Its degrees of freedom: the repeatability's `points - 1`; `None`
    /// (null) for infinitely many, as for the calibration's and the
    /// standards' (type B, known from many readings).
    pub dof: Option<f64>,
}

/// One reading's result.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReadingResult {
    /// The reading (`gloss_gu`, `haze_hu`, `distinctness_pct`).
    pub reading: &'static str,
    /// Its unit.
    pub unit: &'static str,
    /// Points that read it.
    pub points: usize,
    /// Their mean.
    pub value: f64,
    /// Their sample standard deviation (0 for one point).
    pub sd: f64,
    /// The contributions to its standard uncertainty.
    pub budget: Vec<Contribution>,
    /// The combined standard uncertainty (k = 1).
    pub u: f64,
    /// Its effective degrees of freedom (Welch-Satterthwaite; `None`, null:
    /// infinitely many, no part evaluated from few points).
    pub dof_eff: Option<f64>,
    /// The coverage factor `k` for them at 95.45 % (2 with many).
    pub coverage_factor: f64,
    /// The expanded uncertainty, `coverage_factor * u`.
    pub expanded_u: f64,
    /// The coverage interval, `[lowest, highest]`: `value +- expanded_u`
    /// within the reading's definition ([`coverage_interval`]).
    pub interval: [f64; 2],
}

impl ReadingResult {
    /// Whether the result covers `truth`: within its coverage interval
    /// (for a truth within the reading's definition, the same as within
    /// its expanded uncertainty).
    pub fn covers(&self, truth: f64) -> bool {
        (self.interval[0]..=self.interval[1]).contains(&truth)
    }

    /// One contribution's standard uncertainty (0 when it has none).
    pub fn contribution(&self, source: &str) -> f64 {
        self.budget.iter().find(|c| c.source == source).map_or(0.0, |c| c.u)
    }
}

/// A mean over points and its budget.
#[derive(Clone, Debug, PartialEq)]
struct Mean {
    /// Points, their mean and sample standard deviation.
    spread: Spread,
    /// The contributions to its standard uncertainty.
    budget: Vec<Contribution>,
    /// The combined standard uncertainty (k = 1).
    u: f64,
    /// Its effective degrees of freedom (`None`: infinitely many).
    dof_eff: Option<f64>,
    /// The coverage factor for them.
    k: f64,
}

/// The mean of `points` (each a value and the calibration's standard
/// uncertainty of it) with its budget: the calibration's, the
/// repeatability, and each of `relative` (a source and its relative
/// standard uncertainty) times the mean; `None` without a point.
fn mean_with_budget(points: &[(f64, f64)], relative: &[(&'static str, f64)]) -> Option<Mean> {
    let values: Vec<f64> = points.iter().map(|p| p.0).collect();
    let spread = spread(&values);
    if spread.count == 0 {
        return None;
    }
    let n = spread.count as f64;
    let calibration = (points.iter().map(|p| p.1 * p.1).sum::<f64>() / n).sqrt();
    let mut budget = vec![
        Contribution { source: "calibration", u: calibration, dof: None },
        Contribution { source: "repeatability", u: spread.sd / n.sqrt(), dof: Some(n - 1.0) },
    ];
    budget.extend(relative.iter().map(|&(source, rel)| Contribution { source, u: rel * spread.mean.abs(), dof: None }));
    let u = budget.iter().map(|c| c.u * c.u).sum::<f64>().sqrt();
    let dof_eff = coverage_factor::effective_dof(&budget.iter().map(|c| (c.u, c.dof)).collect::<Vec<_>>());
    Some(Mean { spread, budget, u, dof_eff, k: coverage_factor::coverage_factor(dof_eff) })
}

/// The result of reading `reading` (`gloss::NAMES`' index) over `points`
/// (value and calibration uncertainty each), with the references'
/// relative uncertainties `(white, gloss_scale)` on a reading that scales
/// with them; `None` without a point.
pub fn reading_result(
    reading: usize,
    points: &[(f64, f64)],
    (white, gloss_scale): (f64, f64),
) -> Option<ReadingResult> {
    let references = [("white_reference", white), ("gloss_scale", gloss_scale)];
    let relative: &[(&'static str, f64)] =
        if crate::output::points::READINGS_SCALE[reading] { &references } else { &[] };
    let m = mean_with_budget(points, relative)?;
    let expanded_u = m.k * m.u;
    let (lowest, highest) = gloss::DOMAINS[reading];
    Some(ReadingResult {
        reading: gloss::NAMES[reading],
        unit: UNITS[reading],
        points: m.spread.count,
        value: m.spread.mean,
        sd: m.spread.sd,
        interval: coverage_interval(m.spread.mean, expanded_u, (f64::from(lowest), f64::from(highest))),
        expanded_u,
        u: m.u,
        dof_eff: m.dof_eff,
        coverage_factor: m.k,
        budget: m.budget,
    })
}

/// The zones at the centre of the line (one or two), where the pixels view
/// a surface at the instrument's nominal geometry.
pub fn centre_zones(view: &BlobView<'_>) -> Vec<usize> {
    let pixels = view.dims().pixels;
    let set: BTreeSet<usize> =
        [view.zone_of_pixel(pixels.saturating_sub(1) / 2), view.zone_of_pixel(pixels / 2)].into();
    set.into_iter().collect()
}

/// The zones asked for (`asked`; empty: [`centre_zones`]), checked against
/// the calibration's; `option` names the flag in the error.
pub fn chosen_zones(view: &BlobView<'_>, asked: &[usize], option: &str) -> anyhow::Result<Vec<usize>> {
    let zones = view.dims().zones;
    if let Some(z) = asked.iter().find(|z| **z >= zones) {
        anyhow::bail!("{option} {z}: the calibration has zones 0..={}", zones - 1);
    }
    let set: BTreeSet<usize> = asked.iter().copied().collect();
    Ok(if set.is_empty() { centre_zones(view) } else { set.into_iter().collect() })
}

/// A zone's first and last pixel.
pub fn zone_pixels(view: &BlobView<'_>, zone: usize) -> (usize, usize) {
    let d = view.dims();
    let last = if zone + 1 < d.zones { usize::from(view.zone_start(zone + 1)) - 1 } else { d.pixels - 1 };
    (usize::from(view.zone_start(zone)), last)
}

/// The mean BRDF over the points and its uncertainty, bin by bin.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BrdfResult {
    /// Points with a finite estimate (not saturated).
    pub points: usize,
    /// Each bin's incidence (deg), as the points' files give them.
    pub bins_deg: Vec<f32>,
    /// The mean reflectance factor per bin.
    pub value: Vec<f64>,
    /// Its combined standard uncertainty per bin (k = 1).
    pub u: Vec<f64>,
    /// Its effective degrees of freedom per bin (`None`, null: infinitely
    /// many).
    pub dof_eff: Vec<Option<f64>>,
    /// The coverage factor per bin for them at 95.45 % (2 with many).
    pub coverage_factor: Vec<f64>,
    /// Its expanded uncertainty per bin, `coverage_factor * u`.
    pub expanded_u: Vec<f64>,
    /// Its coverage interval per bin, `[lowest, highest]`: `value +-
    /// expanded_u`, never below 0 ([`coverage_interval`]).
    pub interval: Vec<[f64; 2]>,
    /// The contributions per bin: `calibration`, `repeatability`,
    /// `white_reference` (the gloss scale is not the BRDF's).
    pub budget: Vec<BinContribution>,
}

/// One contribution to every bin's uncertainty.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BinContribution {
    /// Where it comes from.
    pub source: &'static str,
    /// Its standard uncertainty per bin.
    pub u: Vec<f64>,
    /// Its degrees of freedom, the same on every bin (`None`, null:
    /// infinitely many).
    pub dof: Option<f64>,
}

/// A measurement's result.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MeasurementResult {
    /// [`SCHEMA`].
    pub schema: &'static str,
    /// [`SCHEMA_VERSION`].
    pub schema_version: u32,
    /// The command that made it: `measure` or `estimate`.
    pub source: &'static str,
    /// The calibration that estimated the points.
    pub calibration_crc: String,
    /// The zones whose points it is over.
    pub zones: Vec<usize>,
    /// Their pixels, first and last, zone by zone.
    pub pixels: Vec<(usize, usize)>,
    /// Distinct lines among the points (`None`: offline, without lines).
    pub lines: Option<usize>,
    /// The zones' points.
    pub points: usize,
    /// Of them, left out: flagged saturated.
    pub saturated: usize,
    /// Of them, flagged out-of-prior (kept: their stated uncertainty is
    /// already the wider one the calibration states for such points).
    pub out_of_prior: usize,
    /// The coverage probability of every `expanded_u` (each with its own
    /// coverage factor).
    pub coverage_probability: f64,
    /// The references' relative standard uncertainties.
    pub references: References,
    /// Each reading the points have, in `gloss::NAMES` order.
    pub readings: Vec<ReadingResult>,
    /// The mean BRDF (`None`: no point with a finite estimate).
    pub brdf: Option<BrdfResult>,
    /// Every zone with points, each a result of its own (its readings):
    /// how the surface reads along the line.
    pub per_zone: Vec<ZoneResult>,
}

/// One zone's result: its readings over its points alone, each with the
/// same budget as the result's (the calibration's, the zone's own
/// repeatability, the references'). A surface other than a mirror reads
/// differently where the pixels view it at other angles, and a sample
/// that is not uniform, differently where it differs: these say which.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ZoneResult {
    /// The zone.
    pub zone: usize,
    /// Its first and last pixel.
    pub pixels: (usize, usize),
    /// Its points (saturated ones among them, left out of the readings).
    pub points: usize,
    /// Each reading its points have, in `gloss::NAMES` order.
    pub readings: Vec<ReadingResult>,
}

/// The result of the points of `zones` among `points`, whose uncertainties
/// are those calibration `view` states before its standards' (the
/// standards' are added here, as contributions of their own).
pub fn measurement_result(view: &BlobView<'_>, zones: &[usize], points: &Points) -> MeasurementResult {
    let references = References::of(view);
    let on_references = (references.white, references.gloss_scale);
    let g = Gathered::of(points, |z| zones.contains(&z));
    let per_zone = (0..view.dims().zones)
        .filter_map(|zone| {
            let z = Gathered::of(points, |p| p == zone);
            (z.count > 0).then(|| ZoneResult {
                zone,
                pixels: zone_pixels(view, zone),
                points: z.count,
                readings: z.readings(on_references),
            })
        })
        .collect();
    MeasurementResult {
        schema: SCHEMA,
        schema_version: SCHEMA_VERSION,
        source: points.source,
        calibration_crc: format!("{:#010x}", points.calibration_crc),
        zones: zones.to_vec(),
        pixels: zones.iter().map(|&z| zone_pixels(view, z)).collect(),
        lines: (!g.without_lines).then_some(g.lines.len()),
        points: g.count,
        saturated: g.saturated,
        out_of_prior: g.out_of_prior,
        coverage_probability: coverage_factor::COVERAGE_PROBABILITY,
        references,
        readings: g.readings(on_references),
        brdf: brdf_result(&points.bins_deg, &g.estimates, references.white),
        per_zone,
    }
}

/// The points of some zones, as a result takes them.
struct Gathered<'a> {
    count: usize,
    saturated: usize,
    out_of_prior: usize,
    lines: BTreeSet<u64>,
    without_lines: bool,
    /// Per reading, each point's value and stated uncertainty.
    kept: [Vec<(f64, f64)>; READINGS],
    /// The points with a finite estimate.
    estimates: Vec<&'a Point>,
}

impl<'a> Gathered<'a> {
    /// The points of `points` whose zone `wanted` takes.
    fn of(points: &'a Points, wanted: impl Fn(usize) -> bool) -> Self {
        let mut g = Gathered {
            count: 0,
            saturated: 0,
            out_of_prior: 0,
            lines: BTreeSet::new(),
            without_lines: false,
            kept: Default::default(),
            estimates: Vec::new(),
        };
        for p in points.points.iter().filter(|p| wanted(usize::from(p.zone))) {
            g.count += 1;
            match p.line {
                Some(l) => drop(g.lines.insert(l)),
                None => g.without_lines = true,
            }
            g.out_of_prior += usize::from(p.flags & flags::OUT_OF_PRIOR != 0);
            if p.flags & flags::SATURATED != 0 {
                g.saturated += 1;
                continue;
            }
            for (k, kept) in g.kept.iter_mut().enumerate() {
                let (x, u) = (f64::from(p.readings[k]), f64::from(p.u_readings[k]));
                // A reading without a stated uncertainty is not one to state a
                // result from (the device states one for every reading).
                if x.is_finite() && u.is_finite() && u >= 0.0 {
                    kept.push((x, u));
                }
            }
            let finite = |xs: &[f32]| xs.len() == points.bins_deg.len() && xs.iter().all(|x| x.is_finite());
            if p.flags & flags::NON_FINITE == 0 && finite(&p.rho) && finite(&p.u_rho) {
                g.estimates.push(p);
            }
        }
        g
    }

    /// Each reading's result over these points.
    fn readings(&self, on_references: (f64, f64)) -> Vec<ReadingResult> {
        (0..READINGS).filter_map(|k| reading_result(k, &self.kept[k], on_references)).collect()
    }
}

/// The mean of the estimates bin by bin, with the same budget as a
/// reading's (the white reference's on every bin).
fn brdf_result(bins_deg: &[f32], estimates: &[&Point], white: f64) -> Option<BrdfResult> {
    if bins_deg.is_empty() {
        return None;
    }
    let per_bin: Vec<Mean> = (0..bins_deg.len())
        .map(|j| {
            let xs: Vec<(f64, f64)> = estimates.iter().map(|p| (f64::from(p.rho[j]), f64::from(p.u_rho[j]))).collect();
            mean_with_budget(&xs, &[("white_reference", white)])
        })
        .collect::<Option<_>>()?;
    let part = |k: usize| BinContribution {
        source: per_bin[0].budget[k].source,
        u: per_bin.iter().map(|m| m.budget[k].u).collect(),
        dof: per_bin[0].budget[k].dof,
    };
    Some(BrdfResult {
        points: estimates.len(),
        bins_deg: bins_deg.to_vec(),
        value: per_bin.iter().map(|m| m.spread.mean).collect(),
        u: per_bin.iter().map(|r| r.u).collect(),
        dof_eff: per_bin.iter().map(|m| m.dof_eff).collect(),
        coverage_factor: per_bin.iter().map(|m| m.k).collect(),
        expanded_u: per_bin.iter().map(|m| m.k * m.u).collect(),
        interval: per_bin
            .iter()
            .map(|m| coverage_interval(m.spread.mean, m.k * m.u, REFLECTANCE_FACTOR_DOMAIN))
            .collect(),
        budget: (0..per_bin[0].budget.len()).map(part).collect(),
    })
}

impl MeasurementResult {
    /// What the result is of, as a standard file's sample names it: the
    /// mean of its points, their zones and pixels and lines.
    pub fn sample(&self) -> String {
        let zones: Vec<String> = self.zones.iter().map(|z| z.to_string()).collect();
        let (first, last) = (self.pixels.iter().map(|p| p.0).min(), self.pixels.iter().map(|p| p.1).max());
        let pixels = first.zip(last).map_or(String::new(), |(a, b)| format!(", pixels {a}-{b}"));
        let lines = self.lines.map_or(String::new(), |l| format!(", {l} line(s)"));
        let n = self.brdf.as_ref().map_or(0, |b| b.points);
        format!(
            "mean of {n} point(s): zone(s) {}{pixels}{lines}; u is the combined standard uncertainty",
            zones.join(", ")
        )
    }

    /// The result as a plain-text table.
    pub fn table(&self) -> String {
        let mut t = String::new();
        let zones: Vec<String> =
            self.zones.iter().zip(&self.pixels).map(|(z, (a, b))| format!("{z} (pixels {a}-{b})")).collect();
        let lines = self.lines.map_or(String::new(), |l| format!("{l} line(s), "));
        let mut notes = String::new();
        if self.saturated > 0 {
            notes += &format!(", {} saturated left out", self.saturated);
        }
        if self.out_of_prior > 0 {
            notes += &format!(", {} out-of-prior", self.out_of_prior);
        }
        let _ = writeln!(
            t,
            "result over zone(s) {}: {lines}{} point(s){notes}; U = k u_c at {:.2} % (k from the effective degrees of \
             freedom nu_eff, 2 with many), the interval value +- U within the reading's definition:",
            zones.join(", "),
            self.points,
            100.0 * self.coverage_probability
        );
        if let Some(b) = &self.brdf {
            let _ = writeln!(
                t,
                "  BRDF: the mean of {} point(s), {} bin(s) with their budgets in the JSON",
                b.points,
                b.value.len()
            );
        }
        if self.readings.is_empty() {
            let _ = writeln!(t, "  no gloss reading to state (no point of these zones read one)");
            return t;
        }
        let _ = writeln!(
            t,
            "  {:<20} {:>9} {:>8} {:>17} {:>8} {:>5} {:>6}  {:>11} {:>13} {:>7} {:>11}  points",
            "reading",
            "value",
            "U",
            "interval",
            "u_c",
            "k",
            "nu_eff",
            "calibration",
            "repeatability",
            "white",
            "gloss scale"
        );
        for r in &self.readings {
            let part = |s: &str| {
                if r.budget.iter().any(|c| c.source == s) { format!("{:.2}", r.contribution(s)) } else { "-".into() }
            };
            let _ = writeln!(
                t,
                "  {:<20} {:>9.2} {:>8.2} {:>17} {:>8.2} {:>5.2} {:>6}  {:>11} {:>13} {:>7} {:>11}  {}",
                format!("{} ({})", r.reading, r.unit),
                r.value,
                r.expanded_u,
                format!("{:.2} .. {:.2}", r.interval[0], r.interval[1]),
                r.u,
                r.coverage_factor,
                r.dof_eff.map_or("many".to_string(), |nu| if nu > 999.0 { ">999".into() } else { format!("{nu:.0}") }),
                part("calibration"),
                part("repeatability"),
                part("white_reference"),
                part("gloss_scale"),
                r.points
            );
        }
        self.per_zone_table(&mut t);
        t
    }

    /// Each zone's readings, `value (U)`, when more than one zone has
    /// points.
    fn per_zone_table(&self, t: &mut String) {
        if self.per_zone.len() < 2 {
            return;
        }
        let _ = writeln!(t, "  along the line, each zone over its own points: value (U)");
        let mut head = format!("  {:>5} {:>9} {:>7}", "zone", "pixels", "points");
        for r in &self.readings {
            head += &format!("  {:>20}", format!("{} ({})", r.reading, r.unit));
        }
        let _ = writeln!(t, "{head}");
        for z in &self.per_zone {
            let mut row = format!("  {:>5} {:>9} {:>7}", z.zone, format!("{}-{}", z.pixels.0, z.pixels.1), z.points);
            for r in &self.readings {
                let cell = z
                    .readings
                    .iter()
                    .find(|x| x.reading == r.reading)
                    .map_or("-".to_string(), |x| format!("{:.2} ({:.2})", x.value, x.expanded_u));
                row += &format!("  {cell:>20}");
            }
            let _ = writeln!(t, "{row}");
        }
    }

    /// The JSON document (pretty, ending in a newline).
    pub fn json(&self) -> anyhow::Result<Vec<u8>> {
        let mut out = serde_json::to_vec_pretty(self).context("serialising the result")?;
        out.push(b'\n');
        Ok(out)
    }

    /// Writes the JSON document atomically.
    pub fn write(&self, path: &Path) -> anyhow::Result<()> {
        crate::output::io::write_atomic(path, &self.json()?).with_context(|| format!("writing {}", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blob(white: f32, gloss_u: f32) -> Vec<u8> {
        let b = brdf_meter::test_blobs::test_blob_with_gloss(9, 5, 2, 8, 0.5, None);
        let mut w = vec![0; b.len() + 8];
        let n = brdf_meter::blob::with_white_uncertainty(&b, white, &mut w).unwrap();
        let mut g = vec![0; n + 8];
        let n = brdf_meter::blob::with_gloss_uncertainty(&w[..n], gloss_u, &mut g).unwrap();
        g.truncate(n);
        g
    }

    /// A point of 3 bins on `line` in `zone`, gloss `g` stated to `u`.
    fn point(line: u64, zone: u16, g: f32, u: f32) -> Point {
        Point {
            line: Some(line),
            pixel: None,
            zone,
            cluster: 0,
            flags: 0,
            rho: vec![0.5, g / 100.0, 0.5],
            u_rho: vec![0.02, 0.1, 0.02],
            readings: [g, 2.0, 80.0],
            u_readings: [u, 0.1, 1.5],
        }
    }

    fn points(ps: Vec<Point>) -> Points {
        Points {
            source: "measure",
            calibration_crc: 0x1234_5678,
            view_deg: 45.0,
            peak_resolution_deg: None,
            pixel_peak_resolution_deg: Vec::new(),
            peak_factors: None,
            bins_deg: vec![44.5, 45.0, 45.5],
            points: ps,
        }
    }

    #[test]
    fn the_budget_is_the_calibrations_the_repeatability_and_the_references_in_quadrature() {
        let b = blob(0.004, 0.003);
        let view = BlobView::parse(&b).unwrap();
        let ps = points((0..4).map(|l| point(l, 0, 99.0 + l as f32 * 2.0 / 3.0, 0.6)).collect());
        let r = measurement_result(&view, &[0], &ps);
        assert_eq!((r.points, r.lines, r.saturated, r.pixels.clone()), (4, Some(4), 0, vec![(0, 3)]));
        assert_eq!((r.source, r.calibration_crc.as_str()), ("measure", "0x12345678"));
        let g = &r.readings[0];
        assert_eq!((g.reading, g.unit, g.points), ("gloss_gu", "GU", 4));
        assert!((g.value - 100.0).abs() < 1e-5, "{g:?}");
        // The calibration's is the RMS of the points' (not shrunk by their count).
        assert!((g.contribution("calibration") - 0.6).abs() < 1e-6);
        // sd of 99, 99.67, 100.33, 101 over sqrt(4).
        let sd = (2.0f64 * (1.0 + 1.0 / 9.0) / 3.0).sqrt();
        assert!((g.sd - sd).abs() < 1e-5 && (g.contribution("repeatability") - sd / 2.0).abs() < 1e-5, "{g:?}");
        assert!((g.contribution("white_reference") - 0.4).abs() < 1e-4, "{g:?}");
        assert!((g.contribution("gloss_scale") - 0.3).abs() < 1e-4, "{g:?}");
        let u = (0.36f64 + (sd / 2.0).powi(2) + 0.16 + 0.09).sqrt();
        assert!((g.u - u).abs() < 1e-4, "{g:?}");
        // The repeatability's 3 degrees of freedom are the only finite
        // ones: nu_eff = u^4 / (u_rep^4 / 3), about 87, and k a little
        // above 2.
        let dofs: Vec<Option<f64>> = g.budget.iter().map(|c| c.dof).collect();
        assert_eq!(dofs, [None, Some(3.0), None, None]);
        let nu = u.powi(4) / ((sd / 2.0).powi(4) / 3.0);
        assert!((g.dof_eff.unwrap() - nu).abs() < 1e-3 * nu, "{g:?} against {nu}");
        assert!(g.coverage_factor > 2.03 && g.coverage_factor < 2.05, "{g:?}");
        assert!((g.expanded_u - g.coverage_factor * g.u).abs() < 1e-12, "{g:?}");
        // Distinctness, a ratio, carries neither reference.
        let d = &r.readings[2];
        assert_eq!(d.reading, "distinctness_pct");
        assert_eq!(d.budget.iter().map(|c| c.source).collect::<Vec<_>>(), ["calibration", "repeatability"]);
        assert!((d.u - 1.5).abs() < 1e-6, "{d:?}");
        // The BRDF bin by bin: the white's on every bin, not the gloss scale's.
        let brdf = r.brdf.as_ref().unwrap();
        assert_eq!((brdf.points, brdf.bins_deg.clone()), (4, vec![44.5, 45.0, 45.5]));
        let sources: Vec<&str> = brdf.budget.iter().map(|c| c.source).collect();
        assert_eq!(sources, ["calibration", "repeatability", "white_reference"]);
        assert!((brdf.value[1] - 1.0).abs() < 1e-6 && (brdf.value[0] - 0.5).abs() < 1e-9, "{brdf:?}");
        let want = (0.01f64 + (sd / 200.0).powi(2) + 0.004f64.powi(2)).sqrt();
        assert!((brdf.u[1] - want).abs() < 1e-6, "{} vs {want}", brdf.u[1]);
        assert!((brdf.u[0] - 0.02f64.hypot(0.002)).abs() < 1e-6, "{brdf:?}");
        // Bins 0 and 2 do not vary: no repeatability, k = 2; bin 1 does.
        assert_eq!((brdf.dof_eff[0], brdf.coverage_factor[0], brdf.expanded_u[0]), (None, 2.0, 2.0 * brdf.u[0]));
        assert!(brdf.coverage_factor[1] > 2.0 && brdf.expanded_u[1] == brdf.coverage_factor[1] * brdf.u[1]);
        assert_eq!(brdf.budget[1].dof, Some(3.0));
        let t = r.table();
        assert!(t.contains("result over zone(s) 0 (pixels 0-3): 4 line(s), 4 point(s); U = k u_c at 95.45 %"), "{t}");
        assert!(t.contains(&format!("{:>5.2} {:>6}", g.coverage_factor, format!("{:.0}", g.dof_eff.unwrap()))), "{t}");
        assert!(t.contains("gloss_gu (GU)") && t.contains("100.00"), "{t}");
        assert!(t.contains("BRDF: the mean of 4 point(s), 3 bin(s) with their budgets in the JSON"), "{t}");
        let j: serde_json::Value = serde_json::from_slice(&r.json().unwrap()).unwrap();
        assert_eq!(j["schema"], SCHEMA);
        assert_eq!(j["coverage_probability"], coverage_factor::COVERAGE_PROBABILITY);
        assert_eq!(j["readings"][0]["budget"][3]["source"], "gloss_scale");
        assert_eq!(j["readings"][0]["budget"][1]["dof"], 3.0);
        assert!(j["readings"][0]["budget"][0]["dof"].is_null());
        assert_eq!(j["readings"][0]["coverage_factor"], g.coverage_factor);
        assert_eq!(j["brdf"]["value"].as_array().unwrap().len(), 3);
    }

    #[test]
    fn few_points_that_vary_much_widen_the_coverage_factor() {
        let b = blob(0.0, 0.0);
        let view = BlobView::parse(&b).unwrap();
        // Three points, 90 / 100 / 110 GU, each stated to 0.5 GU: the
        // repeatability (5.8 GU, 2 degrees of freedom) is nearly all of
        // u_c, so k is nearly Student's t for 2 (4.53), not 2.
        let ps = points(vec![point(0, 0, 90.0, 0.5), point(1, 0, 100.0, 0.5), point(2, 0, 110.0, 0.5)]);
        let g = &measurement_result(&view, &[0], &ps).readings[0];
        let rep = g.contribution("repeatability");
        assert!((rep - 10.0 / 3f64.sqrt()).abs() < 1e-4, "{g:?}");
        let nu = g.dof_eff.unwrap();
        assert!(nu > 2.0 && nu < 2.1, "{g:?}");
        assert!(g.coverage_factor > 4.4 && g.coverage_factor < 4.53, "{g:?}");
        assert!((g.expanded_u - g.coverage_factor * g.u).abs() < 1e-12);
        // Many points of the same spread keep k at 2 to the second decimal.
        let many: Vec<Point> = (0..300).map(|l| point(l, 0, 90.0 + 20.0 * (l % 3) as f32 / 2.0, 0.5)).collect();
        let g = &measurement_result(&view, &[0], &points(many)).readings[0];
        assert!(g.coverage_factor < 2.01 && g.dof_eff.unwrap() > 250.0, "{g:?}");
        // One point: nothing evaluated from the points, k = 2.
        let one = &measurement_result(&view, &[0], &points(vec![point(0, 0, 90.0, 0.5)])).readings[0];
        assert_eq!((one.dof_eff, one.coverage_factor), (None, 2.0));
    }

    #[test]
    fn coverage_intervals_lie_within_the_definitions() {
        // Away from the bounds, value +- U; at a bound, cut there; a value
        // past a bound gives that bound, never crossed ends.
        assert_eq!(coverage_interval(10.0, 2.0, (0.0, 100.0)), [8.0, 12.0]);
        assert_eq!(coverage_interval(0.6, 4.3, (0.0, 100.0)), [0.0, 0.6 + 4.3]);
        assert_eq!(coverage_interval(99.0, 3.0, (0.0, 100.0)), [96.0, 100.0]);
        assert_eq!(coverage_interval(-5.0, 2.0, (0.0, f64::INFINITY)), [0.0, 0.0]);
        assert_eq!(coverage_interval(0.5, 0.0, (0.0, f64::INFINITY)), [0.5, 0.5]);
        // Every reading's result and every bin: a matt sample whose
        // distinctness is near 0 and a bin whose u is far above its value
        // (the mirror bin the LEDs do not resolve).
        let b = blob(0.0, 0.0);
        let view = BlobView::parse(&b).unwrap();
        let matt = |line: u64, d: f32| Point {
            readings: [3.0, 0.4, d],
            u_readings: [1.0, 0.3, 2.2],
            rho: vec![0.05, 0.3, 0.05],
            u_rho: vec![0.01, 0.9, 0.01],
            ..point(line, 0, 3.0, 1.0)
        };
        let r = measurement_result(&view, &[0], &points(vec![matt(0, 0.5), matt(1, 0.7)]));
        let d = &r.readings[2];
        assert!((d.value - 0.6).abs() < 1e-6 && d.expanded_u > d.value, "{d:?}");
        assert_eq!(d.interval[0], 0.0, "{d:?}");
        assert!((d.interval[1] - (d.value + d.expanded_u)).abs() < 1e-12, "{d:?}");
        let h = &r.readings[1];
        assert_eq!(h.interval[0], 0.0, "haze 0.4 HU with U 0.6: {h:?}");
        let g = &r.readings[0];
        assert_eq!(g.interval, [g.value - g.expanded_u, g.value + g.expanded_u], "{g:?}");
        assert!(g.covers(g.value + g.expanded_u) && !g.covers(g.value + 1.01 * g.expanded_u));
        assert!(d.covers(0.0) && !d.covers(-0.1), "a truth below 0 % is no distinctness");
        let brdf = r.brdf.as_ref().unwrap();
        assert_eq!(brdf.interval[1][0], 0.0, "{brdf:?}");
        assert!((brdf.interval[1][1] - (0.3 + brdf.expanded_u[1])).abs() < 1e-6, "{brdf:?}");
        assert!((brdf.interval[0][0] - (0.05 - brdf.expanded_u[0])).abs() < 1e-9, "{brdf:?}");
        let t = r.table();
        assert!(t.contains(&format!("0.00 .. {:.2}", d.interval[1])), "{t}");
        let j: serde_json::Value = serde_json::from_slice(&r.json().unwrap()).unwrap();
        assert_eq!(j["schema_version"], 3);
        assert_eq!(j["readings"][2]["interval"][0], 0.0);
        assert_eq!(j["brdf"]["interval"].as_array().unwrap().len(), 3);
    }

    #[test]
    fn every_zone_with_points_has_a_result_of_its_own() {
        let b = blob(0.004, 0.0);
        let view = BlobView::parse(&b).unwrap();
        // Zone 0 reads 50 GU, zone 1 70 and 74 (and a saturated point).
        let mut ps = vec![point(0, 0, 50.0, 1.0), point(0, 1, 70.0, 1.0), point(1, 1, 74.0, 2.0)];
        ps.push(Point { flags: flags::SATURATED, ..point(2, 1, 500.0, 1.0) });
        let r = measurement_result(&view, &[1], &points(ps.clone()));
        assert_eq!(
            r.per_zone.iter().map(|z| (z.zone, z.pixels, z.points)).collect::<Vec<_>>(),
            [(0, (0, 3), 1), (1, (4, 7), 3)]
        );
        // Each zone's reading is the result over its points alone: zone 1's
        // is the result's own (the zones asked for are zone 1).
        assert_eq!(r.per_zone[1].readings, r.readings);
        let g0 = &r.per_zone[0].readings[0];
        assert_eq!((g0.points, g0.value, g0.sd), (1, 50.0, 0.0));
        assert!((g0.contribution("white_reference") - 0.2).abs() < 1e-6, "{g0:?}");
        // Over both zones the result differs from either.
        let both = measurement_result(&view, &[0, 1], &points(ps.clone()));
        assert!((both.readings[0].value - 194.0 / 3.0).abs() < 1e-9 && both.per_zone == r.per_zone);
        let t = r.table();
        assert!(t.contains("along the line, each zone over its own points: value (U)"), "{t}");
        assert!(t.contains(&format!("{:.2} ({:.2})", g0.value, g0.expanded_u)), "{t}");
        let j: serde_json::Value = serde_json::from_slice(&r.json().unwrap()).unwrap();
        assert_eq!(j["per_zone"][1]["pixels"], serde_json::json!([4, 7]));
        assert_eq!(j["per_zone"][0]["readings"][0]["reading"], "gloss_gu");
        // One zone with points: no table along the line (the result is it).
        let one = measurement_result(&view, &[0], &points(vec![point(0, 0, 50.0, 1.0)]));
        assert_eq!(one.per_zone.len(), 1);
        assert!(!one.table().contains("along the line"), "{}", one.table());
    }

    #[test]
    fn only_the_zones_asked_for_count_and_saturated_points_are_left_out() {
        let b = blob(0.0, 0.0);
        let view = BlobView::parse(&b).unwrap();
        let mut ps = vec![point(0, 0, 50.0, 1.0), point(0, 1, 70.0, 1.0), point(1, 1, 72.0, 1.0)];
        ps.push(Point { flags: flags::SATURATED, ..point(2, 1, 500.0, 1.0) });
        ps.push(Point { flags: flags::UNDER_EXPOSED | flags::OUT_OF_PRIOR, ..point(3, 1, 74.0, 1.0) });
        let mut no_u = point(3, 1, 900.0, f32::NAN);
        no_u.readings[1] = f32::NAN;
        no_u.rho[0] = f32::NAN;
        ps.push(no_u);
        let r = measurement_result(&view, &[1], &points(ps));
        assert_eq!((r.points, r.saturated, r.out_of_prior, r.lines), (5, 1, 1, Some(4)));
        let g = &r.readings[0];
        assert_eq!(g.points, 3, "the saturated point and the one without an uncertainty are left out");
        assert!((g.value - 72.0).abs() < 1e-9);
        assert_eq!((g.contribution("white_reference"), g.contribution("gloss_scale")), (0.0, 0.0));
        assert_eq!(r.readings[1].points, 3);
        assert_eq!(r.brdf.as_ref().unwrap().points, 3, "nor a point whose estimate is not finite");
        assert!(r.table().contains("1 saturated left out, 1 out-of-prior"), "{}", r.table());
        // Without lines, and without readings or estimates.
        let r = measurement_result(&view, &[0], &points(vec![Point { line: None, ..point(0, 0, 1.0, 1.0) }]));
        assert_eq!(r.lines, None);
        let nothing = Point { readings: gloss::NO_READINGS, flags: flags::NON_FINITE, ..point(0, 0, 1.0, 1.0) };
        let r = measurement_result(&view, &[0], &points(vec![nothing]));
        assert!(r.readings.is_empty() && r.brdf.is_none() && r.table().contains("no gloss reading"), "{}", r.table());
    }

    #[test]
    fn the_default_zones_are_the_centre_and_others_are_checked() {
        let b = blob(0.0, 0.0);
        let view = BlobView::parse(&b).unwrap();
        // 8 pixels in 2 zones of 4: the centre pixels 3 and 4 are in both.
        assert_eq!(centre_zones(&view), vec![0, 1]);
        assert_eq!(chosen_zones(&view, &[], "--zones").unwrap(), vec![0, 1]);
        assert_eq!(chosen_zones(&view, &[1, 1], "--zones").unwrap(), vec![1]);
        let e = chosen_zones(&view, &[2], "--result-zones").unwrap_err().to_string();
        assert!(e.contains("--result-zones 2: the calibration has zones 0..=1"), "{e}");
        assert_eq!(zone_pixels(&view, 1), (4, 7));
    }
}
