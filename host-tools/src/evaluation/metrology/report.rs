//! The evaluation's report: how each family was held out, one row of
//! figures per family and method, one line per surface, and the tables
//! printed from them.
use super::families::TestFamily;
use super::folds::nearest;
use super::metrics::{BAD_ERROR, GLOSS_SPLIT_GU, Row, Spread, bins_within, peak_relative_rms};
use super::reading::Reading;
use super::truth::Truth;
use crate::evaluation::coverage_interval::percent_with_interval;
use crate::forward::prior_models::PriorModels;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// How one family was held out.
#[derive(Clone, Debug, Serialize)]
pub struct FamilyProtocol {
    /// Family.
    pub family: String,
    /// Where its surfaces come from.
    pub source: String,
    /// Surfaces.
    pub materials: usize,
    /// Of them, training samples (read by the fold that left them out).
    pub in_training: usize,
    /// In words.
    pub protocol: String,
    /// How near its surfaces are to what read them (`None`: no surface
    /// has a nearest training sample).
    pub nearest: Option<Nearness>,
}

/// How near a family's surfaces are to the prior samples of the
/// calibrations that read them (`MaterialResult::nearest_training`): a
/// family of near twins says little of materials unlike the prior's.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Nearness {
    /// Median over the surfaces of the distance to the nearest sample.
    pub median: f64,
    /// Surfaces within [`NEAR_TWIN`] of one.
    pub near_twins: usize,
    /// Surfaces the estimator reads better than its nearest sample is
    /// to them (its error below that distance).
    pub read_better: usize,
    /// Surfaces with a nearest sample.
    pub surfaces: usize,
}

/// A surface this near a training sample (RMS over the bins / its peak)
/// is a near twin: taking it for that sample would read it about as well
/// as the estimator reads the measured materials (median 0.02 of the peak).
pub const NEAR_TWIN: f64 = 0.02;

impl std::fmt::Display for Nearness {
    /// As the reports' rows show it: `median; near twins of surfaces; read better`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.3}; {} of {}; {}", self.median, self.near_twins, self.surfaces, self.read_better)
    }
}

impl Nearness {
    /// Over one family's surfaces, each its nearest sample's distance and
    /// the estimator's error on it (`None`: no surface has a nearest sample).
    pub fn of(with: &[(f64, f64)]) -> Option<Self> {
        let d: Vec<f64> = with.iter().map(|w| w.0).collect();
        (!d.is_empty()).then(|| Self {
            median: Spread::of(&d).median,
            near_twins: with.iter().filter(|w| w.0 < NEAR_TWIN).count(),
            read_better: with.iter().filter(|w| w.1 < w.0).count(),
            surfaces: with.len(),
        })
    }
}

impl FamilyProtocol {
    /// The protocol of `fam`, `in_training` of whose surfaces are training
    /// samples held out by folds and `references` the gloss scale's
    /// reference (in every calibration).
    pub fn new(fam: &TestFamily, in_training: usize, references: usize, folds: usize) -> Self {
        let n = fam.materials.len();
        let mut protocol = match (in_training, n - in_training - references) {
            (0, _) => "never in training: read by the calibration on the whole prior".to_string(),
            (k, 0) => format!("{k} in training: {folds}-fold, each read by a calibration trained without it"),
            (k, rest) => format!(
                "{k} in training ({folds}-fold, each read by a calibration trained without it), {rest} never in training"
            ),
        };
        if references > 0 {
            protocol.push_str(&format!(
                "; {references} the black glass, the gloss scale's reference: in every calibration (as every gloss \
                 meter is set on it), read by the one on everything"
            ));
        }
        Self {
            family: fam.name.clone(),
            source: fam.source.clone(),
            materials: n,
            in_training,
            protocol,
            nearest: None,
        }
    }
}

/// One surface's result.
#[derive(Clone, Debug, Serialize)]
pub struct MaterialResult {
    /// Family.
    pub family: String,
    /// Name.
    pub name: String,
    /// The fold whose calibration read it (`None`: the calibration on everything).
    pub fold: Option<usize>,
    /// The prior sample nearest it among those that calibration trained
    /// on (`None`: the prior holds only in-plane profiles or nothing left).
    pub nearest_training: Option<NearestSample>,
    /// Its peak bin.
    pub peak: f64,
    /// Its gloss GU, haze HU, distinctness % by the definitions.
    pub readings_true: [f64; 3],
    /// The estimator's BRDF error (RMS over bins and draws / peak).
    pub error_estimator: f64,
    /// Interpolation's.
    pub error_interpolation: f64,
    /// The estimator's gloss readings, mean over the draws.
    pub readings_estimator: [f64; 3],
    /// Interpolation's.
    pub readings_interpolation: [f64; 3],
    /// Share of the draws flagged.
    pub flagged: f64,
    /// The estimator's draws one by one: what a flag or a per-point
    /// uncertainty could be built on, beside the error it would predict.
    pub draws: Vec<DrawResult>,
}

/// The training sample nearest a surface (`folds::nearest`).
#[derive(Clone, Debug, Serialize)]
pub struct NearestSample {
    /// The sample's name, e.g. `merl:blue-acrylic`.
    pub name: String,
    /// RMS over the bins of the difference / the surface's peak.
    pub distance: f64,
}

impl NearestSample {
    /// The sample of `prior` (its grid vectors the columns of `grid`, none
    /// of `left_out`) nearest the binned BRDF `rho` of peak `peak`
    /// (`folds::nearest`), by its name.
    pub fn in_prior(
        prior: &PriorModels,
        grid: &DMatrix<f64>,
        (rho, peak): (&DVector<f64>, f64),
        left_out: &[usize],
    ) -> Option<Self> {
        nearest(rho, peak, grid, left_out).map(|(k, distance)| Self { name: prior.samples[k].name.clone(), distance })
    }
}

impl std::fmt::Display for NearestSample {
    /// As the lists of surfaces read worst show it: `name (distance)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({:.3})", self.name, self.distance)
    }
}

/// One draw of a surface read by the estimator.
#[derive(Clone, Debug, Serialize)]
pub struct DrawResult {
    /// BRDF error (RMS over the bins / the truth's peak).
    pub error: f64,
    /// Share of the bins within k = 2 of the stated uncertainty (NaN: none stated).
    pub bin_coverage: f64,
    /// The out-of-prior statistic (NaN: the calibration has none).
    pub stat: f64,
    /// The largest reading over the readings' sum.
    pub brightest_share: f64,
    /// Whether a flag was raised.
    pub flagged: bool,
}

impl DrawResult {
    fn of(r: &Reading, t: &Truth) -> Self {
        let bin_coverage = r.sigma.as_ref().map_or(f64::NAN, |s| {
            let (inside, all) = bins_within(&r.rho, t, s);
            inside as f64 / all.max(1) as f64
        });
        Self {
            error: peak_relative_rms(&r.rho, t),
            bin_coverage,
            stat: r.stat,
            brightest_share: r.brightest_share,
            flagged: r.flagged == Some(true),
        }
    }
}

fn rms_over(rs: &[Reading], t: &Truth) -> f64 {
    (rs.iter().map(|r| peak_relative_rms(&r.rho, t).powi(2)).sum::<f64>() / rs.len().max(1) as f64).sqrt()
}

fn mean_readings(rs: &[Reading]) -> [f64; 3] {
    core::array::from_fn(|i| rs.iter().map(|r| r.gloss[i]).sum::<f64>() / rs.len().max(1) as f64)
}

impl MaterialResult {
    /// The result of one surface from its estimates by each method.
    pub fn new(
        (family, name): (&str, &str),
        (fold, nearest_training): (Option<usize>, Option<NearestSample>),
        t: &Truth,
        est: &[Reading],
        interp: &[Reading],
    ) -> Self {
        Self {
            family: family.into(),
            name: name.into(),
            fold,
            nearest_training,
            peak: t.peak,
            readings_true: t.readings,
            error_estimator: rms_over(est, t),
            error_interpolation: rms_over(interp, t),
            readings_estimator: mean_readings(est),
            readings_interpolation: mean_readings(interp),
            flagged: est.iter().filter(|r| r.flagged == Some(true)).count() as f64 / est.len().max(1) as f64,
            draws: est.iter().map(|r| DrawResult::of(r, t)).collect(),
        }
    }
}

/// The whole evaluation.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// What was evaluated (the calibration's kind, prior, form; set by the caller).
    pub calibration: String,
    /// Relative noise of the readings.
    pub noise_rel: f64,
    /// Draws per surface.
    pub draws: usize,
    /// Folds K (0: no surface was a training sample).
    pub folds: usize,
    /// Seed.
    pub seed: u64,
    /// Calibrations trained.
    pub trainings: usize,
    /// Each calibration's matrices per zone (the piecewise kind's cluster
    /// count, chosen in each training; 1 for the other kinds).
    pub clusters: Vec<usize>,
    /// Each calibration's out-of-prior statistic (`linear`, `log-ratio`,
    /// or `none` for a kind without the flag), chosen in each training.
    pub flag_forms: Vec<String>,
    /// How each family was held out.
    pub families: Vec<FamilyProtocol>,
    /// Per family, the estimator's row then interpolation's.
    pub rows: Vec<Row>,
    /// Per surface.
    pub materials: Vec<MaterialResult>,
}

fn pct(x: f64) -> String {
    if x.is_finite() { format!("{:.1} %", 100.0 * x) } else { "-".into() }
}

/// A BRDF error (over the truth's peak) to four places, `-` for none.
fn opt_err(x: f64) -> String {
    if x.is_finite() { format!("{x:.4}") } else { "-".into() }
}

fn opt_pct(x: Option<f64>) -> String {
    x.map_or("-".into(), pct)
}

fn pair_pct(s: &Spread) -> String {
    if s.median.is_finite() { format!("{:.1} / {:.1} %", 100.0 * s.median, 100.0 * s.p90) } else { "-".into() }
}

fn pair(s: &Spread, digits: usize) -> String {
    if s.median.is_finite() { format!("{:.digits$} / {:.digits$}", s.median, s.p90) } else { "-".into() }
}

impl Report {
    /// The tables, as Markdown.
    pub fn tables(&self) -> String {
        let mut s = String::new();
        s += &format!(
            "Calibration: {}\nReadings: patent-profile optics, {} % proportional noise, {} draw(s) per surface, seed {}; {} calibration(s) trained, matrices per zone (K) {}; flag statistic {}\n\n",
            self.calibration,
            100.0 * self.noise_rel,
            self.draws,
            self.seed,
            self.trainings,
            self.clusters.iter().map(usize::to_string).collect::<Vec<_>>().join(", "),
            self.flag_forms.join(", ")
        );
        for f in &self.families {
            s += &format!("- {} ({} surfaces, {}): {}", f.family, f.materials, f.source, f.protocol);
            if let Some(n) = f.nearest {
                s += &format!(
                    "; the nearest prior sample in its calibration's training (RMS over the bins / the peak): median; \
                     within {NEAR_TWIN} (near twins); surfaces the estimator reads better than that sample is to them: {n}"
                );
            }
            s += "\n";
        }
        s += &format!(
            "\nBRDF (error = RMS over the 81 bins / the truth's peak; impossible = a bin below -1 % of the estimate's peak; \
             coverage = |est - truth| <= 2 u, with its 95 % interval over the surfaces; band = RMS of u over the bins / the truth's peak, median; flag: of estimates worse than {BAD_ERROR:.2}, share flagged / of the rest, and the median error of the flagged / of the rest; \
             peak coverage: of the peaks the calibration resolves, an unresolved one states no u)\n\n"
        );
        s += "| family | method | surfaces | median | 90 % | worst | worst surface | impossible | bin coverage k=2 | band u p50 | flag caught (n bad) | false flags | error p50 flagged / not | peak height rel. err. p50 / p90 (coverage k=2) | FWHM err. p50 / p90 (deg) (coverage k=2) | peaks unresolved |\n";
        s += "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
        for r in &self.rows {
            s += &format!(
                "| {} | {} | {} | {:.4} | {:.4} | {:.4} | {} | {} | {} | {} | {} ({}) | {} | {} | {} ({}) | {} ({}) | {} |\n",
                r.family,
                r.method,
                r.materials,
                r.error.median,
                r.error.p90,
                r.error.max,
                r.worst_material,
                pct(r.impossible),
                r.bin_coverage.map_or("-".into(), |x| percent_with_interval(x, r.bin_coverage_interval)),
                r.band.map_or("-".into(), |b| format!("{:.4}", b.median)),
                opt_pct(r.flag_caught),
                r.bad,
                opt_pct(r.flag_false),
                r.flag_error_medians.map_or("-".into(), |[f, n]| format!("{} / {}", opt_err(f), opt_err(n))),
                pair_pct(&r.peak_height_rel),
                opt_pct(r.peak_height_coverage),
                pair(&r.peak_width_abs_deg, 2),
                opt_pct(r.peak_width_coverage),
                opt_pct(r.peak_unresolved),
            );
        }
        s += &format!(
            "\nGloss readings (|G_est - G_true| / G_true per estimate, split at {GLOSS_SPLIT_GU} GU of the truth; haze HU and distinctness % absolute; coverage k=2 of the stated u; result: per surface, the mean of its draws with U = k sqrt(RMS of their u^2 + the mean's repeatability^2), k from the effective degrees of freedom (2 with many), as `measure` states it)\n\n"
        );
        s += "| family | method | G <= 300: p50 / p90 (n) | G <= 300: GU p50 / p90 | G > 300: p50 / p90 (n) | haze HU p50 / p90 | distinctness % p50 / p90 | no reading | coverage G / H / D | result coverage G / H / D |\n";
        s += "|---|---|---|---|---|---|---|---|---|---|\n";
        let three =
            |c: Option<[f64; 3]>| c.map_or("-".into(), |c| format!("{} / {} / {}", pct(c[0]), pct(c[1]), pct(c[2])));
        for r in &self.rows {
            let (cov, result) = (three(r.reading_coverage), three(r.result_coverage));
            s += &format!(
                "| {} | {} | {} ({}) | {} | {} ({}) | {} | {} | {} | {} | {} |\n",
                r.family,
                r.method,
                pair_pct(&r.gloss_rel_low),
                r.gloss_low_count,
                pair(&r.gloss_abs_low_gu, 2),
                pair_pct(&r.gloss_rel_high),
                r.gloss_high_count,
                pair(&r.haze_abs, 2),
                pair(&r.distinctness_abs, 1),
                r.no_reading,
                cov,
                result
            );
        }
        s += &self.read_worst();
        s
    }

    /// Per family, the surfaces with estimates worse than [`BAD_ERROR`] (at
    /// most [`READ_WORST`], by the share of their draws that are, then by
    /// their error), each with what the flag raised on it and
    /// interpolation's error beside: which surfaces of a set the
    /// calibration cannot read, and whether its flag says so. Empty when
    /// no estimate is worse.
    fn read_worst(&self) -> String {
        let bad = |m: &MaterialResult| m.draws.iter().filter(|d| d.error > BAD_ERROR).count();
        let mut s = String::new();
        for f in &self.families {
            let mut worst: Vec<&MaterialResult> =
                self.materials.iter().filter(|m| m.family == f.family && bad(m) > 0).collect();
            if worst.is_empty() {
                continue;
            }
            if s.is_empty() {
                s += &format!(
                    "\nSurfaces read worst (estimates worse than {BAD_ERROR:.2} of the truth's peak; error = RMS over the bins and draws / peak)\n\n\
                     | family | surface | draws worse than {BAD_ERROR:.2} | flagged | error | interpolation | nearest prior sample (RMS over the bins / peak) |\n|---|---|---|---|---|---|---|\n"
                );
            }
            let share = |m: &MaterialResult| bad(m) as f64 / m.draws.len().max(1) as f64;
            worst.sort_by(|a, b| share(b).total_cmp(&share(a)).then(b.error_estimator.total_cmp(&a.error_estimator)));
            let (with_bad, total) = (worst.len(), worst.iter().map(|m| bad(m)).sum::<usize>());
            worst.truncate(READ_WORST);
            for m in &worst {
                let nearest = m.nearest_training.as_ref().map_or("-".into(), NearestSample::to_string);
                s += &format!(
                    "| {} | {} | {} of {} | {} | {:.4} | {:.4} | {nearest} |\n",
                    f.family,
                    m.name,
                    bad(m),
                    m.draws.len(),
                    pct(m.flagged),
                    m.error_estimator,
                    m.error_interpolation
                );
            }
            if with_bad > worst.len() {
                s += &format!(
                    "| {} | ({} more surfaces; {total} such estimates in all) | | | | | |\n",
                    f.family,
                    with_bad - worst.len()
                );
            }
        }
        s
    }
}

/// How many surfaces of a family the report lists as read worst.
pub const READ_WORST: usize = 8;
