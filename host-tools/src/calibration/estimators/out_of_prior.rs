//! Training of the out-of-prior flag (the device's statistic is
//! `brdf_meter::kernel::scale_free`, its two forms `OutOfPriorForm`).
//!
//! Each form is a Gaussian model of a point's coordinates (the linear form:
//! the readings' shares `u'`, with the estimator's predictive covariance;
//! the log-ratio form: their centred logarithms `l'`, fitted to the
//! prior's noisy readings, so the noise is in its covariance): mean and
//! packed `chol(C)^-1`. A zone's threshold is the `1 - alpha` quantile of
//! the statistic of held-out prior readings (k-fold, each scored by a model
//! fitted without its fold), the largest of the materials' as they are, of
//! their variants' and of both together, so that neither sees more false
//! alarms than alpha (`threshold_of`); it is folded into G so that every
//! zone's threshold is [`FOLDED_THRESHOLD`] (the blob holds one).
//!
//! Which form a calibration flags with is decided by what the flag is for,
//! telling badly estimated points from the rest ([`choose_form`]), on
//! training data only, never an evaluation's held-out materials. First on
//! kinds of the prior held out whole (the band's folds), which is where a
//! flag is needed: the form whose flag there catches more of the bad
//! estimates beyond the share of the rest it raises, if either does better
//! than chance ([`FlagOnKinds`], which `train` also prints as the
//! calibration's own statement of its flag). Otherwise on random folds: the
//! form whose flagged readings are the worse estimated (the larger mean
//! error). Not the share of bad estimates caught there: a fold of random
//! samples leaves a near twin of each held-out one in training, so hardly
//! any held-out estimate is bad (none worse than 0.10 of its peak on the
//! patent profile). Neither form wins everywhere: on the handheld's
//! extended LEDs the prior's shares span decades and the log-ratio form
//! sees what the linear form cannot, while on the patent profile's compact
//! LEDs the few points read badly are the most specular, whose one bright
//! share the linear form measures directly (`docs/guide/real-materials.md`,
//! `docs/handheld.md`).
use crate::calibration::families::weighted_quantile_of_each;
use anyhow::{Context, ensure};
use brdf_meter::kernel::scale_free::{LOG_RATIO_FLOOR, OutOfPriorForm, scale, whitening_len};
use nalgebra::{DMatrix, DVector};

/// Every zone's out-of-prior threshold once its own is folded into its G.
pub const FOLDED_THRESHOLD: f32 = 1.0;

/// An estimate worse than this share of its truth's peak (RMS over the
/// bins) is a bad one: what the flag is judged against, in training
/// ([`FlagOnKinds`]) as in every evaluation.
pub const BAD_ESTIMATE: f64 = 0.10;

/// Whether a flag predicts error: estimates worse than [`BAD_ESTIMATE`] of
/// their truth's peak and the rest, each counted (`usize`: an evaluation's
/// estimates) or weighed (`f64`: training's held-out readings by the
/// prior's weights), and how much of each was flagged.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct FlagScore<T = usize> {
    /// Estimates worse than [`BAD_ESTIMATE`].
    pub bad: T,
    /// Of them, flagged out of prior.
    pub bad_flagged: T,
    /// The other estimates.
    pub good: T,
    /// Of them, flagged out of prior (false alarms).
    pub good_flagged: T,
}

/// What a [`FlagScore`] tallies: counts or weights.
pub trait Tally: Copy + Default + std::ops::Add<Output = Self> {
    /// As a real number, for shares.
    fn real(self) -> f64;
}

impl Tally for usize {
    fn real(self) -> f64 {
        self as f64
    }
}

impl Tally for f64 {
    fn real(self) -> f64 {
        self
    }
}

/// `part / whole`, NaN when there is no whole.
fn share<T: Tally>(part: T, whole: T) -> f64 {
    if whole.real() > 0.0 { part.real() / whole.real() } else { f64::NAN }
}

impl<T: Tally> FlagScore<T> {
    /// Tallies one estimate of weight `w` and BRDF error `error` (over its
    /// truth's peak).
    pub fn add_weighted(&mut self, w: T, error: f64, flagged: bool) {
        let (all, raised) = if error > BAD_ESTIMATE {
            (&mut self.bad, &mut self.bad_flagged)
        } else {
            (&mut self.good, &mut self.good_flagged)
        };
        *all = *all + w;
        if flagged {
            *raised = *raised + w;
        }
    }

    /// Both tallies summed.
    pub fn merged(self, o: Self) -> Self {
        Self {
            bad: self.bad + o.bad,
            bad_flagged: self.bad_flagged + o.bad_flagged,
            good: self.good + o.good,
            good_flagged: self.good_flagged + o.good_flagged,
        }
    }

    /// Share of the bad estimates flagged (NaN with none).
    pub fn caught(&self) -> f64 {
        share(self.bad_flagged, self.bad)
    }

    /// Share of the other estimates flagged (NaN with none).
    pub fn false_alarms(&self) -> f64 {
        share(self.good_flagged, self.good)
    }

    /// Share of all the estimates that are bad (NaN with none).
    pub fn bad_share(&self) -> f64 {
        share(self.bad, self.bad + self.good)
    }
}

impl FlagScore<usize> {
    /// Counts one estimate of BRDF error `error` (over its truth's peak).
    pub fn add(&mut self, error: f64, flagged: bool) {
        self.add_weighted(1, error, flagged);
    }
}

/// What the flag is worth on kinds of material the calibration never saw,
/// measured in training: each kind of the prior held out whole (the band's
/// folds), its readings estimated by the fit without it and scored by the
/// flag's model fitted without it; the prior's weights. A calibration's own
/// statement of how far its flag can be trusted, made before it meets a
/// surface.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FlagOnKinds {
    /// The held-out readings, weighed.
    pub weights: FlagScore<f64>,
    /// How many there were.
    pub readings: usize,
}

impl FlagOnKinds {
    /// Counts one held-out reading of weight `w` and error `error`.
    pub fn add(&mut self, w: f64, error: f64, flagged: bool) {
        self.weights.add_weighted(w, error, flagged);
        self.readings += 1;
    }

    /// Both summed (zones of one calibration).
    pub fn merged(self, o: Self) -> Self {
        Self { weights: self.weights.merged(o.weights), readings: self.readings + o.readings }
    }

    /// Youden's J: the share of the bad caught less the share of the rest
    /// raised (0 when either is unknown): above 0, the flag tells them
    /// apart better than one that knew nothing.
    pub fn youden(&self) -> f64 {
        let j = self.weights.caught() - self.weights.false_alarms();
        if j.is_finite() { j } else { 0.0 }
    }

    /// One line for a user: what the flag caught and raised in vain.
    pub fn note(&self) -> String {
        let pct = |x: f64| if x.is_finite() { format!("{:.0} %", 100.0 * x) } else { "-".into() };
        let w = &self.weights;
        format!(
            "the flag on kinds of material held out of training ({} readings, each kind read by a fit without it): {} of them read worse than {BAD_ESTIMATE} of their peak; it caught {} of those and was raised on {} of the rest (a flag that knew nothing would catch as many as it raises)",
            self.readings,
            pct(w.bad_share()),
            pct(w.caught()),
            pct(w.false_alarms()),
        )
    }
}

/// One zone's out-of-prior model in one form.
#[derive(Clone, Debug)]
pub struct OutOfPrior {
    /// Which statistic.
    pub form: OutOfPriorForm,
    /// Mean of the form's coordinates (m-1).
    pub mean: Vec<f32>,
    /// Packed lower-triangular G (m(m-1)/2), the zone's threshold folded in.
    pub g: Vec<f32>,
    /// Threshold on the statistic: [`FOLDED_THRESHOLD`].
    pub threshold: f32,
    /// False-alarm rate the threshold was set for.
    pub false_alarm: f64,
    /// Held-out evidence for choosing the form: the prior's weight of the
    /// held-out readings this form's flag raised.
    pub held_out_flagged: f64,
    /// ... and the same weights times those readings' estimates' errors.
    pub held_out_flagged_error: f64,
    /// The threshold on the statistic before it was folded into G: what a
    /// model fitted on part of the prior is compared with.
    pub unfolded_threshold: f64,
    /// Held-out evidence for a flagged point's band ([`band_factor`]):
    /// (ratio, weight) per bin of each held-out reading of a kind left out
    /// of training that this form's flag raised, the ratio of the smallest
    /// unit uncertainty that covers its error to the band's.
    pub band_ratios: Vec<(f64, f64)>,
    /// This form's flag on kinds of material held out whole.
    pub on_kinds: FlagOnKinds,
}

impl OutOfPrior {
    /// The statistic for readings `v` (the device's function).
    pub fn stat(&self, v: &[f32]) -> f32 {
        self.form.stat(&self.g, &self.mean, v, scale(v))
    }

    /// Whether readings `v` are flagged.
    pub fn flags(&self, v: &[f32]) -> bool {
        self.stat(v) > self.threshold
    }
}

/// A form's model of some of the prior's pairs: (mean, packed G).
pub type ModelOf<'a> = dyn Fn(&[usize]) -> anyhow::Result<(Vec<f32>, Vec<f32>)> + Sync + 'a;

/// The prior's noisy readings the models are fitted on and scored with.
pub struct HeldOut<'a> {
    /// Per pair, its noise draws.
    pub readings: &'a [Vec<DVector<f64>>],
    /// Per pair, its weight in the prior (per draw).
    pub weight: &'a [f64],
    /// Per pair, its fold.
    pub fold: &'a [usize],
    /// Per pair, which variant of its sample it reads (`Pairs::variant`: 0
    /// the material as it is): the threshold's false-alarm rate holds for
    /// the materials as they are and for their variants, each on its own.
    pub variant: &'a [usize],
    /// Per pair and draw, the peak-normalised error of its estimate by the
    /// calibration's fit without its fold.
    pub error: &'a [Vec<f64>],
    /// The linear form's model of pairs `idx` (mean, packed G): the
    /// estimator's own predictive covariance of `u'` (`scale_free`), with
    /// its weights.
    pub linear_model: &'a ModelOf<'a>,
}

/// Both forms' models for one zone, each with its threshold set at
/// `false_alarm` on the held-out readings and its held-out evidence.
pub fn train(held: &HeldOut<'_>, false_alarm: f64) -> anyhow::Result<[OutOfPrior; 2]> {
    Ok([
        train_form(held, false_alarm, OutOfPriorForm::Linear)?,
        train_form(held, false_alarm, OutOfPriorForm::LogRatio)?,
    ])
}

/// Each held-out reading's statistic (a model fitted without its fold)
/// with its pair: (statistic, pair, draw).
fn held_out_stats(held: &HeldOut<'_>, form: OutOfPriorForm) -> anyhow::Result<Vec<(f64, usize, usize)>> {
    let (pairs, fold) = (held.readings.len(), held.fold);
    let nf = fold.iter().copied().max().map_or(0, |x| x + 1);
    let mut out = Vec::with_capacity(pairs * 2);
    for f in 0..nf {
        let train_idx: Vec<usize> = (0..pairs).filter(|k| fold[*k] != f).collect();
        let (mean, g) = model(held, &train_idx, form)?;
        for k in (0..pairs).filter(|k| fold[*k] == f) {
            for (d, v) in held.readings[k].iter().enumerate() {
                let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
                out.push((f64::from(form.stat(&g, &mean, &v32, scale(&v32))), k, d));
            }
        }
    }
    Ok(out)
}

/// The threshold on the statistic from held-out readings' (statistic,
/// weight, whether a variant of its material): the smallest that raises at
/// most `false_alarm` of the weight of the materials as they are, of their
/// variants and of both together, each on its own
/// (`crate::calibration::families`). Pooled, the variants set the rate
/// the materials see: on the patent profile the rougher finishes are
/// flagged less often, and the pooled 5 % threshold raised 9 % of the
/// materials as they are. No readings: `f64::MAX` (it never flags).
fn threshold_of(stats: impl IntoIterator<Item = (f64, f64, bool)>, false_alarm: f64) -> f64 {
    let mut families = [Vec::new(), Vec::new()];
    for (s, w, variant) in stats {
        families[usize::from(variant)].push((s, w));
    }
    weighted_quantile_of_each(&families, 1.0 - false_alarm).unwrap_or(f64::MAX)
}

fn train_form(held: &HeldOut<'_>, false_alarm: f64, form: OutOfPriorForm) -> anyhow::Result<OutOfPrior> {
    let scored = held_out_stats(held, form)?;
    let threshold = threshold_of(scored.iter().map(|&(s, k, _)| (s, held.weight[k], held.variant[k] > 0)), false_alarm);
    // The evidence: how bad the flagged held-out estimates are.
    let flagged = scored.iter().filter(|x| x.0 > threshold);
    let (weight, error) =
        flagged.fold((0.0, 0.0), |(w, e), &(_, k, d)| (w + held.weight[k], e + held.weight[k] * held.error[k][d]));
    let all: Vec<usize> = (0..held.readings.len()).collect();
    let (mean, mut g) = model(held, &all, form)?;
    // |G x|^2 / t = |(G / sqrt t) x|^2. A zone whose held-out statistics
    // are all zero or not finite has no usable model: it never flags.
    let fold = if threshold.is_finite() && threshold > 0.0 { 1.0 / threshold.sqrt() } else { 0.0 };
    for x in &mut g {
        *x = (f64::from(*x) * fold) as f32;
    }
    Ok(OutOfPrior {
        form,
        mean,
        g,
        threshold: FOLDED_THRESHOLD,
        false_alarm,
        held_out_flagged: weight,
        held_out_flagged_error: error,
        unfolded_threshold: threshold,
        band_ratios: Vec::new(),
        on_kinds: FlagOnKinds::default(),
    })
}

/// The held-out readings (pair, draw) that `o`'s flag raises when each is
/// scored by `o`'s form fitted without its fold (`held.fold`), against
/// `o`'s threshold: how a kind of material the prior lacks is flagged (a
/// statistic that is not a number flags, as on the device).
pub fn held_out_flagged(held: &HeldOut<'_>, o: &OutOfPrior) -> anyhow::Result<Vec<(usize, usize)>> {
    Ok(held_out_stats(held, o.form)?
        .into_iter()
        .filter(|(s, _, _)| s.is_nan() || *s > o.unfolded_threshold)
        .map(|(_, k, d)| (k, d))
        .collect())
}

/// What a flagged point's unit uncertainty is multiplied by: the
/// `COVERAGE` quantile of `zones`' pooled [`OutOfPrior::band_ratios`], so
/// that the held-out readings of left-out kinds the flag raised are
/// covered as the band covers all of them; never below 1 (a flag does not
/// narrow a band), and 1 without evidence.
pub fn band_factor<'a>(zones: impl IntoIterator<Item = &'a OutOfPrior>) -> f64 {
    let mut xs: Vec<(f64, f64)> = zones.into_iter().flat_map(|o| o.band_ratios.iter().copied()).collect();
    if xs.iter().all(|x| x.1 <= 0.0) {
        return 1.0;
    }
    crate::calibration::estimators::scale_free::weighted_quantile(&mut xs, crate::calibration::gloss_rows::COVERAGE)
        .max(1.0)
}

/// The name of the statistic `blob` flags with (`none` for a kind without
/// the flag): what evaluations report of each calibration they train.
pub fn statistic_name(blob: &brdf_meter::blob::BlobView<'_>) -> &'static str {
    blob.out_of_prior_form().map_or("none", |f| f.name())
}

/// The flag of `zones` (each zone's chosen form) on kinds of material held
/// out whole, summed over the zones.
pub fn flag_on_kinds<'a>(zones: impl IntoIterator<Item = &'a OutOfPrior>) -> FlagOnKinds {
    zones.into_iter().fold(FlagOnKinds::default(), |a, o| a.merged(o.on_kinds))
}

/// The form whose flag better tells bad estimates from good, over all of
/// `zones` (each zone's [`train`] result):
///
/// 1. on kinds of material held out whole ([`FlagOnKinds`]), the form whose
///    flag catches the larger share of the bad estimates beyond the share
///    of the rest it raises (Youden's J), when either form's flag does
///    better there than one that knew nothing (J > 0);
/// 2. otherwise, the larger mean error of the held-out readings it flagged
///    in random folds; the log-ratio form on a tie (also when neither
///    flagged anything).
///
/// Kinds held out first, because a surface of a family the prior lacks is
/// where a flag is needed: on the patent profile the log-ratio form, which
/// the random folds prefer, caught 1 % of the bad estimates of kinds held
/// out and was raised on 41 % of the rest, the linear form 62 % and 34 %;
/// on the held-out Ward surfaces it then raised 4 % of estimates in place
/// of 20 %. On the handheld neither form does better than chance on kinds
/// held out (J -0.10 and -0.08), and the random folds' choice, the
/// log-ratio form, is the one that catches anything there (16 % of the bad
/// held-out points against 0.4 % for the linear form).
pub fn choose_form<'a>(zones: impl IntoIterator<Item = &'a [OutOfPrior; 2]>) -> OutOfPriorForm {
    let (mut weight, mut error) = ([0.0f64; 2], [0.0f64; 2]);
    let mut kinds = [FlagOnKinds::default(); 2];
    for z in zones {
        for (i, o) in z.iter().enumerate() {
            weight[i] += o.held_out_flagged;
            error[i] += o.held_out_flagged_error;
            kinds[i] = kinds[i].merged(o.on_kinds);
        }
    }
    let (j_linear, j_log_ratio) = (kinds[0].youden(), kinds[1].youden());
    if j_linear.max(j_log_ratio) > 0.0 && j_linear != j_log_ratio {
        return if j_linear > j_log_ratio { OutOfPriorForm::Linear } else { OutOfPriorForm::LogRatio };
    }
    let mean = |i: usize| if weight[i] > 0.0 { error[i] / weight[i] } else { 0.0 };
    if mean(0) > mean(1) { OutOfPriorForm::Linear } else { OutOfPriorForm::LogRatio }
}

/// A point's coordinates in `form` (m-1 values), in f64: the device's
/// transform. `None` when the readings' sum is not positive and finite.
fn coordinates(v: &DVector<f64>, form: OutOfPriorForm) -> Option<DVector<f64>> {
    let s: f64 = v.iter().sum();
    if !(s.is_finite() && s > 0.0) {
        return None;
    }
    let m1 = v.len() - 1;
    Some(match form {
        OutOfPriorForm::Linear => v.rows(0, m1) / s,
        OutOfPriorForm::LogRatio => {
            let l = v.map(|x| (x / s).max(f64::from(LOG_RATIO_FLOOR)).ln());
            let centre = l.mean();
            l.rows(0, m1).map(|x| x - centre)
        }
    })
}

/// The model of pairs `idx` in `form`. The log-ratio form: the weighted
/// mean of their noisy readings' coordinates and the packed `chol(C)^-1` of
/// their covariance (noise included, since the readings are noisy; the
/// logarithm has no closed-form noise term). The linear form: the
/// estimator's predictive covariance ([`HeldOut::linear_model`]).
fn model(held: &HeldOut<'_>, idx: &[usize], form: OutOfPriorForm) -> anyhow::Result<(Vec<f32>, Vec<f32>)> {
    if form == OutOfPriorForm::Linear {
        return (held.linear_model)(idx);
    }
    let xs: Vec<(DVector<f64>, f64)> = idx
        .iter()
        .flat_map(|&k| held.readings[k].iter().filter_map(move |v| coordinates(v, form).map(|x| (x, held.weight[k]))))
        .collect();
    ensure!(!xs.is_empty(), "no readings with a positive sum to fit the out-of-prior model on");
    let m1 = xs[0].0.len();
    let total: f64 = xs.iter().map(|x| x.1).sum();
    ensure!(total > 0.0, "the out-of-prior model's readings all have zero weight");
    let mean = xs.iter().fold(DVector::zeros(m1), |a, (x, w)| a + x * (w / total));
    let mut c = DMatrix::zeros(m1, m1);
    for (x, w) in &xs {
        let d = x - &mean;
        c += &d * d.transpose() * (w / total);
    }
    let jitter = 1e-9 * (c.trace() / m1 as f64).max(f64::MIN_POSITIVE);
    let l = (c + DMatrix::identity(m1, m1) * jitter)
        .cholesky()
        .context("the covariance of the prior's readings is singular")?
        .l();
    let g = l.solve_lower_triangular(&DMatrix::identity(m1, m1)).context("whitening")?;
    let mut packed = Vec::with_capacity(whitening_len(m1 + 1));
    for k in 0..m1 {
        for i in 0..=k {
            packed.push(g[(k, i)] as f32);
        }
    }
    Ok((mean.iter().map(|x| *x as f32).collect(), packed))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn zone(weight: [f64; 2], error: [f64; 2]) -> [OutOfPrior; 2] {
        let one = |i: usize, form| OutOfPrior {
            form,
            mean: vec![],
            g: vec![],
            threshold: FOLDED_THRESHOLD,
            false_alarm: 0.05,
            held_out_flagged: weight[i],
            held_out_flagged_error: error[i],
            unfolded_threshold: 1.0,
            band_ratios: Vec::new(),
            on_kinds: FlagOnKinds::default(),
        };
        [one(0, OutOfPriorForm::Linear), one(1, OutOfPriorForm::LogRatio)]
    }

    #[test]
    fn the_band_factor_covers_the_flagged_held_out_readings_and_never_narrows() {
        let with = |ratios: Vec<(f64, f64)>| {
            let mut z = zone([1.0, 1.0], [0.0, 0.0]);
            z[1].band_ratios = ratios;
            z
        };
        // Two zones pooled: 100 ratios 0.01..1.00 and 100 of 1.01..2.00,
        // equal weights; 95 % of them are covered at 1.90.
        let a = with((1..=100).map(|i| (f64::from(i) / 100.0, 1.0)).collect());
        let b = with((101..=200).map(|i| (f64::from(i) / 100.0, 1.0)).collect());
        assert_eq!(band_factor([&a[1], &b[1]]), 1.90);
        // Weights count: the wide ones weigh nothing, the band is enough.
        let light = with((101..=200).map(|i| (f64::from(i) / 100.0, 0.0)).collect());
        assert_eq!(band_factor([&a[1], &light[1]]), 1.0);
        // Flagged readings the band already covers do not narrow it, and
        // no evidence leaves it as it is.
        let covered = with(vec![(0.3, 1.0); 10]);
        assert_eq!(band_factor([&covered[1]]), 1.0);
        assert_eq!(band_factor([&a[0]]), 1.0);
    }

    #[test]
    fn the_threshold_raises_at_most_the_false_alarm_rate_of_each_family() {
        // 100 materials as they are, statistics 1..100, and 300 variants
        // read at 0.5, all of equal weight. Pooled, the 95 % quantile is
        // the 80th material's: 20 % of the materials would be flagged.
        let materials = (1..=100).map(|i| (f64::from(i), 1.0, false));
        let easy = std::iter::repeat_n((0.5, 1.0, true), 300);
        assert_eq!(threshold_of(materials.clone().chain(easy), 0.05), 95.0);
        // Variants flagged more often set it where they would be flagged
        // more than 5 % (statistics 11..110).
        let hard = (11..=110).map(|i| (f64::from(i), 1.0, true));
        assert_eq!(threshold_of(materials.clone().chain(hard), 0.05), 105.0);
        // A family too small to set its own still counts in the pool
        // (39 variants at 1000: 39 of 139 above the materials' 95th).
        let few = std::iter::repeat_n((1000.0, 1.0, true), 39);
        assert_eq!(threshold_of(materials.chain(few), 0.05), 1000.0);
        // Nothing held out: a threshold that never flags.
        assert_eq!(threshold_of(std::iter::empty(), 0.05), f64::MAX);
    }

    #[test]
    fn the_flag_on_kinds_weighs_bad_and_good_readings_apart_and_sums_the_zones() {
        let mut a = FlagOnKinds::default();
        a.add(0.5, 0.3, true);
        a.add(0.25, 0.2, false);
        // Exactly BAD_ESTIMATE is not worse than it.
        a.add(0.125, BAD_ESTIMATE, true);
        a.add(0.125, 0.01, false);
        let w = a.weights;
        assert_eq!((w.caught(), w.false_alarms(), w.bad_share(), a.readings), (2.0 / 3.0, 0.5, 0.75, 4));
        assert_eq!(a.youden(), 2.0 / 3.0 - 0.5);
        let mut b = FlagOnKinds::default();
        b.add(1.0, 0.01, true);
        let mut zones = zone([1.0, 1.0], [0.0, 0.0]);
        zones[0].on_kinds = a;
        zones[1].on_kinds = b;
        let both = flag_on_kinds(&zones);
        assert_eq!((both.weights.caught(), both.weights.false_alarms(), both.readings), (2.0 / 3.0, 1.125 / 1.25, 5));
        // No bad estimates: the catch is unknown, and J says nothing.
        assert!(FlagOnKinds::default().weights.caught().is_nan() && b.weights.caught().is_nan());
        assert_eq!((b.weights.false_alarms(), b.youden()), (1.0, 0.0));
        // Counted estimates tally as weighed ones do.
        let mut c = FlagScore::default();
        for (e, f) in [(0.2, true), (0.3, false), (0.05, true), (0.01, false)] {
            c.add(e, f);
        }
        assert_eq!((c.bad, c.bad_flagged, c.good, c.good_flagged), (2, 1, 2, 1));
        assert_eq!((c.caught(), c.false_alarms(), c.bad_share()), (0.5, 0.5, 0.5));
    }

    #[test]
    fn the_form_that_flags_worse_estimates_over_all_zones_is_chosen() {
        // Zone by zone they disagree; over both, the linear form's flagged
        // estimates err by 0.5 on average, the log-ratio form's by 0.4.
        let zones = [zone([8.0, 8.0], [5.0, 2.0]), zone([2.0, 2.0], [0.0, 2.0])];
        assert_eq!(choose_form(&zones), OutOfPriorForm::Linear);
        let zones = [zone([8.0, 8.0], [2.0, 5.0]), zone([2.0, 2.0], [2.0, 0.0])];
        assert_eq!(choose_form(&zones), OutOfPriorForm::LogRatio);
        // A tie, or nothing bad: the log-ratio form.
        assert_eq!(choose_form(&[zone([1.0, 1.0], [1.0, 1.0])]), OutOfPriorForm::LogRatio);
        assert_eq!(choose_form(&[zone([0.0, 0.0], [0.0, 0.0])]), OutOfPriorForm::LogRatio);
    }

    #[test]
    fn kinds_held_out_decide_the_form_when_a_flag_tells_bad_from_good_there() {
        // Kinds held out, 40 % bad: `caught` of the bad and `raised` of
        // the rest flagged, on two zones of equal evidence.
        let on_kinds = |caught: f64, raised: f64| FlagOnKinds {
            weights: FlagScore { bad: 0.4, bad_flagged: 0.4 * caught, good: 0.6, good_flagged: 0.6 * raised },
            readings: 10,
        };
        let with = |linear: FlagOnKinds, log_ratio: FlagOnKinds| {
            // The random folds prefer the log-ratio form.
            let mut z = zone([1.0, 1.0], [0.1, 0.2]);
            (z[0].on_kinds, z[1].on_kinds) = (linear, log_ratio);
            z
        };
        // The patent profile's measured case: the linear form tells them
        // apart (J 0.28), the log-ratio form does worse than chance.
        let patent = with(on_kinds(0.62, 0.34), on_kinds(0.01, 0.41));
        assert_eq!(choose_form(&[patent.clone(), patent]), OutOfPriorForm::Linear);
        // Either form better than chance: the higher J, whichever it is.
        assert_eq!(choose_form(&[with(on_kinds(0.3, 0.2), on_kinds(0.5, 0.2))]), OutOfPriorForm::LogRatio);
        // The handheld's case: neither better than chance; the random
        // folds decide, against a linear J less negative.
        assert_eq!(choose_form(&[with(on_kinds(0.08, 0.18), on_kinds(0.07, 0.25))]), OutOfPriorForm::LogRatio);
        // Evidence summed over zones: one zone's large J does not decide
        // alone when the other zone's counts say otherwise.
        let a = with(on_kinds(0.9, 0.1), on_kinds(0.1, 0.1));
        let mut b = with(on_kinds(0.0, 0.9), on_kinds(0.1, 0.1));
        for o in &mut b {
            let w = o.on_kinds.weights;
            let four = FlagScore {
                bad: 4.0 * w.bad,
                bad_flagged: 4.0 * w.bad_flagged,
                good: 4.0 * w.good,
                good_flagged: 4.0 * w.good_flagged,
            };
            o.on_kinds.weights = four;
        }
        // Linear: caught (0.36 + 0) / 2.0 = 0.18, raised (0.06 + 2.16) / 3.0
        // = 0.74; log-ratio J 0: the random folds decide.
        assert_eq!(choose_form(&[a, b]), OutOfPriorForm::LogRatio);
    }

    /// A prior of matte and glossy materials, and glossy readings whose
    /// dark LEDs' ratio is swapped: in the shares the swap is a thousandth
    /// against a spread of tenths (the matte ones'), in their logarithms it
    /// is as large as the step from glossy to matte. The log-ratio form
    /// flags them, the linear form hardly does, and when they are the
    /// badly estimated ones the choice falls on the log-ratio form.
    #[test]
    fn the_log_ratio_form_sees_dark_ratios_and_is_chosen_when_they_matter() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let nd = Normal::new(0.0, 1.0).unwrap();
        // 10 % log-normal spread on each share.
        let mut reading = |kind: usize| {
            let base = [[0.3, 0.3, 0.2, 0.2], [0.9, 0.09, 0.009, 0.001], [0.9, 0.09, 0.001, 0.009]][kind];
            DVector::from_fn(4, |i, _| base[i] * (0.1f64 * nd.sample(&mut rng)).exp())
        };
        let (pairs, draws) = (200, 2);
        // One pair in forty is odd (fewer than the false-alarm rate, as
        // the prior's own oddities are), spread over the folds.
        let odd = |k: usize| k % 40 == 3;
        let kind = |k: usize| if odd(k) { 2 } else { k % 2 };
        let readings: Vec<Vec<DVector<f64>>> =
            (0..pairs).map(|k| (0..draws).map(|_| reading(kind(k))).collect()).collect();
        let weight = vec![1.0 / (pairs * draws) as f64; pairs];
        let fold: Vec<usize> = (0..pairs).map(|k| k % 5).collect();
        // The odd pairs are the badly estimated ones.
        let error: Vec<Vec<f64>> = (0..pairs).map(|k| vec![if odd(k) { 0.3 } else { 0.02 }; draws]).collect();
        // The linear form's model: the shares' own Gaussian.
        let shares: Vec<Vec<DVector<f64>>> = readings.iter().map(|r| r.iter().map(|v| v / v.sum()).collect()).collect();
        let linear_model = |idx: &[usize]| {
            let xs: Vec<DVector<f64>> =
                idx.iter().flat_map(|&k| shares[k].iter().map(|u| u.rows(0, 3).into_owned())).collect();
            let mu = xs.iter().fold(DVector::zeros(3), |a, x| a + x) / xs.len() as f64;
            let c =
                xs.iter().fold(DMatrix::zeros(3, 3), |a, x| a + (x - &mu) * (x - &mu).transpose()) / xs.len() as f64;
            let g = c.cholesky().unwrap().l().solve_lower_triangular(&DMatrix::identity(3, 3)).unwrap();
            let packed = (0..3).flat_map(|k| (0..=k).map(move |i| (k, i))).map(|(k, i)| g[(k, i)] as f32).collect();
            Ok((mu.iter().map(|x| *x as f32).collect(), packed))
        };
        let variant = vec![0; pairs];
        let held = HeldOut {
            readings: &readings,
            weight: &weight,
            fold: &fold,
            variant: &variant,
            error: &error,
            linear_model: &linear_model,
        };
        let [linear, log_ratio] = train(&held, 0.05).unwrap();
        assert_eq!((linear.threshold, log_ratio.threshold), (FOLDED_THRESHOLD, FOLDED_THRESHOLD));
        // Fresh readings of each kind.
        let rate = |o: &OutOfPrior, kinds: &[usize], rng_reading: &mut dyn FnMut(usize) -> DVector<f64>| {
            let n = 400;
            let hits = (0..n)
                .filter(|i| {
                    let v32: Vec<f32> = rng_reading(kinds[i % kinds.len()]).iter().map(|x| *x as f32).collect();
                    o.flags(&v32)
                })
                .count();
            hits as f64 / n as f64
        };
        let (lr_odd, lr_good) = (rate(&log_ratio, &[2], &mut reading), rate(&log_ratio, &[0, 1], &mut reading));
        let (lin_odd, lin_good) = (rate(&linear, &[2], &mut reading), rate(&linear, &[0, 1], &mut reading));
        assert!(lr_odd > 0.8 && lr_good < 0.1, "log-ratio: {lr_odd} of the odd, {lr_good} of the rest");
        assert!(lin_odd < 0.5 * lr_odd && lin_good < 0.1, "linear: {lin_odd} of the odd ({lin_good} of the rest)");
        assert_eq!(choose_form([&[linear, log_ratio]]), OutOfPriorForm::LogRatio);
    }

    #[test]
    fn coordinates_are_the_devices_transform() {
        let v = DVector::from_vec(vec![2.0, 1.0, 1.0, 0.0]);
        let lin = coordinates(&v, OutOfPriorForm::Linear).unwrap();
        assert_eq!(lin.as_slice(), &[0.5, 0.25, 0.25]);
        let lr = coordinates(&v, OutOfPriorForm::LogRatio).unwrap();
        let l = [0.5f64.ln(), 0.25f64.ln(), 0.25f64.ln(), f64::from(LOG_RATIO_FLOOR).ln()];
        let c = l.iter().sum::<f64>() / 4.0;
        for i in 0..3 {
            assert!((lr[i] - (l[i] - c)).abs() < 1e-12);
        }
        // The device's f32 statistic with G = I and mean 0 is |l'|^2.
        let g = [1.0f32, 0.0, 1.0, 0.0, 0.0, 1.0];
        let v32 = [2.0f32, 1.0, 1.0, 0.0];
        let d2 = OutOfPriorForm::LogRatio.stat(&g, &[0.0; 3], &v32, scale(&v32));
        assert!((f64::from(d2) - lr.norm_squared()).abs() < 1e-5 * lr.norm_squared());
        assert!(coordinates(&DVector::from_vec(vec![0.0, 0.0]), OutOfPriorForm::LogRatio).is_none());
    }
}
