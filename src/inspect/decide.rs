//! The decision, per point and per line, defined once for the device and
//! the host (whose reference calls these same functions, so both give the
//! same bits).
//!
//! # Per point ([`point_stat`]), on the corrected readings v
//! The readings are first normalised to the reference's line scale,
//! `f = k v` with `1 / k` the median over the line's pixels of each pixel's
//! sum of readings over its reference's ([`line_scale`]): a change of the
//! light's intensity common to the line (LED drift, the web's height
//! moving) is not a defect, while a defect on fewer than half the pixels
//! does not move the median (a line mean would: a bright scratch would put
//! every pixel out; a point-by-point normalisation would hide a gloss step,
//! which on a broad lobe scales every reading of the point alike). With the
//! pixel's reference mean `mu` (of f), inverse standard deviations `s` and
//! its group's whitening `L^-1` of the normalised readings' correlation
//! and gradient `J` (all from the recipe):
//! - `z = s .* (f - mu)` over the first m - 1 readings (the last is fixed
//!   by them and the scale), `y = L^-1 z`, the squared distance
//!   `d2 = |y|^2` (Mahalanobis distance to the reference's distribution);
//! - the change of each gloss reading, to first order, `delta = J (f - mu)`
//!   (gloss GU, haze HU, distinctness %, at the reference's line scale),
//!   of the readings up to the last with a window (a window that is off
//!   puts no point out; the gloss always, for the drift).
//!
//! (m-1)m/2 + R m + m multiply-adds (the scale's sums: 2 m adds), R the
//! readings worked out: 35 for m = 7 with a gloss window only, 49 with all
//! three, against the estimation's 567 plus its gloss readings; the BRDF
//! is never needed. A point within the leaving thresholds is out at
//! neither (they are no wider than the entering ones): one test
//! ([`Limits::within`]) decides most points.
//!
//! # A point's kind (first that holds)
//! unreadable (a saturated, under-exposed or non-finite reading) > gloss
//! low > gloss high > haze > distinctness (a window of the recipe) > out of
//! the reference's distribution (`d2` above the threshold). A point that was out
//! on the previous line stays out until it is back inside the leaving
//! thresholds (the distance's `threshold_off`, the windows times
//! `window_hysteresis`): hysteresis.
//!
//! # Per line ([`Inspector::line`])
//! Hysteresis holds along the line as it does across lines: a defect is a
//! run of at least `min_pixels` consecutive pixels each out at least at the
//! leaving thresholds, at least one of them out at the entering ones
//! (hysteresis thresholding). A defect whose pixels all had to be out at
//! the entering thresholds was missed whenever the noise of one of them
//! brought it back in: a 2 GU gloss step over 8 pixels of the handheld in
//! 1.2 % of lines, 0.7 % now, at the same false-call rate. A pixel counts
//! once it has been out (at the leaving thresholds) for `min_lines`
//! consecutive lines. (A format 1 recipe, taught before, was taught for
//! every pixel of a defect out at the entering thresholds, and is decided
//! so.) A defect's kind is out-of-prior when the calibration
//! flags any of its pixels out of its prior (asked only of a defect's
//! pixels: an estimate each), else the highest of the kinds of its pixels
//! out at the entering thresholds, in the order above.
//! Any defect rejects the line. The drift statistic is the EWMA of each
//! line's weighted mean gloss change over its pixels that are not out,
//! with an alarm while `|EWMA|` exceeds the recipe's limit.
use super::recipe::{RecipeSettings, RecipeView, pixel_len};
use crate::protocol::flags;
use crate::shape::READINGS;
use nalgebra::SVector;
use serde::{Deserialize, Serialize};

/// Most defects a verdict lists (further ones are counted in
/// [`verdict::MORE_DEFECTS`]).
pub const MAX_RUNS: usize = 8;

/// What kind of defect a point or a run is.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DefectKind {
    /// Gloss below its window.
    GlossLow,
    /// Gloss above its window.
    GlossHigh,
    /// Haze outside its window.
    Haze,
    /// Distinctness outside its window.
    Distinctness,
    /// Out of the reference's distribution (distance above the threshold).
    OutOfDistribution,
    /// The calibration's out-of-prior flag: unlike anything it was trained on.
    OutOfPrior,
    /// A reading was saturated, under-exposed or not finite.
    Unreadable,
}

impl DefectKind {
    /// Every kind, in wire order.
    pub const ALL: [DefectKind; 7] = [
        Self::GlossLow,
        Self::GlossHigh,
        Self::Haze,
        Self::Distinctness,
        Self::OutOfDistribution,
        Self::OutOfPrior,
        Self::Unreadable,
    ];

    /// Precedence within a run (higher wins).
    fn rank(self) -> u8 {
        match self {
            Self::OutOfDistribution => 0,
            Self::Distinctness => 1,
            Self::Haze => 2,
            Self::GlossHigh => 3,
            Self::GlossLow => 4,
            Self::OutOfPrior => 5,
            Self::Unreadable => 6,
        }
    }

    /// Name, as the host's outputs write it.
    pub fn name(self) -> &'static str {
        match self {
            Self::GlossLow => "gloss-low",
            Self::GlossHigh => "gloss-high",
            Self::Haze => "haze",
            Self::Distinctness => "distinctness",
            Self::OutOfDistribution => "out-of-distribution",
            Self::OutOfPrior => "out-of-prior",
            Self::Unreadable => "unreadable",
        }
    }
}

/// One defect: a run of defective pixels of a line.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DefectRun {
    /// First pixel.
    pub first: u16,
    /// Pixels.
    pub len: u16,
    /// Kind.
    pub kind: DefectKind,
    /// Largest `d2` in the run.
    pub peak_d2: f32,
}

/// Bits of [`Verdict::flags`].
pub mod verdict {
    /// The line is rejected (it has a defect).
    pub const REJECT: u8 = 1 << 0;
    /// The drift alarm is on.
    pub const DRIFT_ALARM: u8 = 1 << 1;
    /// More defects than [`super::MAX_RUNS`]: only the first are listed.
    pub const MORE_DEFECTS: u8 = 1 << 2;
    /// The line's points follow (a defect line, when the host asked).
    pub const POINTS_FOLLOW: u8 = 1 << 3;
}

/// A line's defects: at most [`MAX_RUNS`], on the wire as a sequence of
/// as many as there are (a `Copy` type, so the reply enum stays `Copy`).
#[derive(Clone, Copy, Debug)]
pub struct Runs {
    len: u8,
    items: [DefectRun; MAX_RUNS],
}

const NO_RUN: DefectRun = DefectRun { first: 0, len: 0, kind: DefectKind::OutOfDistribution, peak_d2: 0.0 };

impl Runs {
    /// None.
    pub const fn new() -> Self {
        Self { len: 0, items: [NO_RUN; MAX_RUNS] }
    }
    /// Appends a defect; gives it back when full.
    pub fn push(&mut self, run: DefectRun) -> Result<(), DefectRun> {
        let slot = self.items.get_mut(self.len as usize).ok_or(run)?;
        *slot = run;
        self.len += 1;
        Ok(())
    }
    /// The defects.
    pub fn as_slice(&self) -> &[DefectRun] {
        &self.items[..self.len as usize]
    }
    /// How many.
    pub fn len(&self) -> usize {
        self.len as usize
    }
    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl Default for Runs {
    fn default() -> Self {
        Self::new()
    }
}

impl PartialEq for Runs {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl core::ops::Index<usize> for Runs {
    type Output = DefectRun;
    fn index(&self, i: usize) -> &DefectRun {
        &self.as_slice()[i]
    }
}

impl Serialize for Runs {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.as_slice())
    }
}

impl<'de> Deserialize<'de> for Runs {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Runs;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                write!(f, "at most {MAX_RUNS} defects")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Runs, A::Error> {
                let mut runs = Runs::new();
                while let Some(r) = seq.next_element::<DefectRun>()? {
                    runs.push(r).map_err(|_| serde::de::Error::invalid_length(MAX_RUNS + 1, &self))?;
                }
                Ok(runs)
            }
        }
        d.deserialize_seq(V)
    }
}

/// One line's verdict: what an inspection streams per line.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Verdict {
    /// Line number within the inspection.
    pub line: u32,
    /// [`verdict`] bits.
    pub flags: u8,
    /// The line's weighted mean gloss change over its pixels not out, GU
    /// (NaN when none has a reading): what the drift EWMA and the host's
    /// SPC figures take.
    pub mean_gloss: f32,
    /// The drift EWMA after this line, GU.
    pub ewma: f32,
    /// The line's largest point distance `d2`.
    pub max_d2: f32,
    /// Its defects, in pixel order.
    pub runs: Runs,
}

impl Verdict {
    /// Whether the line is rejected.
    pub fn rejected(&self) -> bool {
        self.flags & verdict::REJECT != 0
    }

    /// Whether the line is in a drift alarm.
    pub fn drift_alarm(&self) -> bool {
        self.flags & verdict::DRIFT_ALARM != 0
    }
}

/// The inspection's counters since it started.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InspectCounters {
    /// Lines decided.
    pub lines: u32,
    /// Lines rejected.
    pub rejected: u32,
    /// Defects (runs) found.
    pub defects: u32,
    /// Times the drift alarm came on.
    pub drift_alarms: u32,
    /// Reject pulses driven.
    pub pulses: u32,
}

/// One point's statistics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointStat {
    /// Squared distance to the reference's distribution.
    pub d2: f32,
    /// The change of each gloss reading from the reference.
    pub delta: [f32; READINGS],
}

/// Most values a group holds (its whitening and gradient): m up to 9.
pub const MAX_GROUP_VALUES: usize = 64;

/// Decodes little-endian f32 values into `out` (as many as it holds).
#[inline]
fn read_f32s(bytes: &[u8], out: &mut [f32]) {
    for (o, c) in out.iter_mut().zip(bytes.chunks_exact(4)) {
        *o = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
    }
}

/// One pixel's reference, decoded from the recipe.
#[derive(Clone, Copy, Debug)]
pub struct PixelRef<const M: usize> {
    /// The mean of the normalised readings.
    pub mean: [f32; M],
    /// Their inverse standard deviations (the first m - 1; the last is
    /// the inverse of the means' sum, [`inverse_reference_sum`]).
    pub inv_sd: [f32; M],
    /// The pixel's weight in the drift mean.
    pub weight: f32,
}

impl<const M: usize> PixelRef<M> {
    /// Zeros, to [`Self::load`] into.
    pub const fn new() -> Self {
        Self { mean: [0.0; M], inv_sd: [0.0; M], weight: 0.0 }
    }

    /// Pixel `p` of `r`.
    pub fn of(r: &RecipeView<'_>, p: usize) -> Self {
        let mut x = Self::new();
        x.load(r, p);
        x
    }

    /// Decodes pixel `p` of `r` in place (the decision's loop reuses one:
    /// no copy per pixel).
    #[inline(always)]
    pub fn load(&mut self, r: &RecipeView<'_>, p: usize) {
        if let Some(w) = r.pixel_words(p) {
            self.mean.copy_from_slice(&w[..M]);
            self.inv_sd.copy_from_slice(&w[M..2 * M]);
            self.weight = w[2 * M];
            return;
        }
        let b = r.pixel_bytes(p);
        read_f32s(&b[..4 * M], &mut self.mean);
        read_f32s(&b[4 * M..8 * M], &mut self.inv_sd);
        self.weight = f32::from_le_bytes([b[8 * M], b[8 * M + 1], b[8 * M + 2], b[8 * M + 3]]);
    }
}

impl<const M: usize> Default for PixelRef<M> {
    fn default() -> Self {
        Self::new()
    }
}

/// The inverse of the sum of pixel `p`'s reference means.
#[inline]
pub fn inverse_reference_sum<const M: usize>(r: &RecipeView<'_>, p: usize) -> f32 {
    match r.pixel_words(p) {
        Some(w) => w[2 * M - 1],
        None => r.pixel_value(p, 2 * M - 1),
    }
}

/// Group `g`'s values: in place when the recipe is aligned (always on the
/// device), else decoded into `room`.
#[inline]
fn group_values<'a>(r: &RecipeView<'a>, g: usize, room: &'a mut [f32; MAX_GROUP_VALUES]) -> &'a [f32] {
    match r.group_words(g) {
        Some(w) => w,
        None => {
            read_f32s(r.group_bytes(g), room);
            &room[..super::recipe::group_len(r.leds())]
        }
    }
}

/// A pixel's values read in place: its reference mean, inverse standard
/// deviations and drift weight (`None` if `w` is shorter than a pixel).
#[inline(always)]
fn split_pixel<const M: usize>(w: &[f32]) -> Option<(&[f32; M], &[f32; M], f32)> {
    let (mean, rest) = w.split_first_chunk::<M>()?;
    let (inv_sd, rest) = rest.split_first_chunk::<M>()?;
    Some((mean, inv_sd, *rest.first()?))
}

/// The line's scale `k` (see the module docs): 1 over the median of the
/// pixels' ratios of their readings' sum to their reference's (pixels
/// whose ratio is not finite left out; NaN when none is). `ratios` is
/// scratch room, at least one value per pixel.
pub fn line_scale<const M: usize>(r: &RecipeView<'_>, v: &[SVector<f32, M>], ratios: &mut [f32]) -> f32 {
    let table = r.pixel_table();
    let mut n = 0;
    for (p, vp) in v.iter().enumerate().take(ratios.len()) {
        let inverse_sum = match table {
            Some(t) => t[p * pixel_len(M) + 2 * M - 1],
            None => inverse_reference_sum::<M>(r, p),
        };
        let x = vp.iter().sum::<f32>() * inverse_sum;
        if x.is_finite() {
            ratios[n] = x;
            n += 1;
        }
    }
    if n == 0 {
        return f32::NAN;
    }
    1.0 / select(&mut ratios[..n], n / 2)
}

/// The `k`-th smallest of `x` (finite values), reordering `x`: Hoare's
/// quickselect with the middle element as pivot. A few hundred bytes of
/// code where core's `select_nth_unstable` brings about 5 KB into the
/// board's image; O(n) on the ratios of a line.
fn select(x: &mut [f32], k: usize) -> f32 {
    let (mut lo, mut hi) = (0usize, x.len() - 1);
    while lo < hi {
        let pivot = x[lo + (hi - lo) / 2];
        let (mut i, mut j) = (lo, hi);
        loop {
            while x[i] < pivot {
                i += 1;
            }
            while x[j] > pivot {
                j -= 1;
            }
            if i >= j {
                break;
            }
            x.swap(i, j);
            i += 1;
            j -= 1;
        }
        // x[lo..=j] <= pivot <= x[j+1..=hi]
        if k <= j {
            hi = j;
        } else {
            lo = j + 1;
        }
    }
    x[k]
}

/// The per-point statistics of a point with readings `v`, its pixel's
/// reference `mean` and inverse standard deviations `inv_sd` and its
/// group's values `group`, at the line's `scale` (see the module docs).
/// Only the first `readings` changes are worked out, the rest left 0 (the
/// decision skips those whose windows are off: [`Limits::readings`]).
pub fn point_stat<const M: usize>(
    mean: &[f32; M],
    inv_sd: &[f32; M],
    group: &[f32],
    v: &[f32; M],
    scale: f32,
    readings: usize,
) -> PointStat {
    // One copy per count, each unrolled whole: with the count known only
    // at run time the compiler keeps the differences in memory, which
    // costs what skipping the rows saves.
    match readings {
        1 => point_stat_of::<M, 1>(mean, inv_sd, group, v, scale),
        2 => point_stat_of::<M, 2>(mean, inv_sd, group, v, scale),
        _ => point_stat_of::<M, READINGS>(mean, inv_sd, group, v, scale),
    }
}

/// [`point_stat`] of the first `R` readings. Not inlined: one symbol for
/// the decision's per-point cost in QEMU.
#[inline(never)]
fn point_stat_of<const M: usize, const R: usize>(
    mean: &[f32; M],
    inv_sd: &[f32; M],
    group: &[f32],
    v: &[f32; M],
    scale: f32,
) -> PointStat {
    const { assert!(M >= 2 && super::recipe::group_len(M) <= MAX_GROUP_VALUES) };
    // One length check here, none per value below.
    let group = &group[..super::recipe::group_len(M)];
    let mut dv = [0.0f32; M];
    let mut z = [0.0f32; M];
    for i in 0..M {
        dv[i] = v[i] * scale - mean[i];
        z[i] = dv[i] * inv_sd[i];
    }
    // A scale that is not a positive number leaves d2 NaN: unreadable.
    let mut d2 = if scale > 0.0 && scale.is_finite() { 0.0f32 } else { f32::NAN };
    let mut k = 0;
    for i in 0..M - 1 {
        let mut y = 0.0f32;
        for zj in &z[..=i] {
            y += group[k] * *zj;
            k += 1;
        }
        d2 += y * y;
    }
    let mut delta = [0.0f32; READINGS];
    for d in delta.iter_mut().take(R) {
        let mut acc = 0.0f32;
        for dvi in &dv {
            acc += group[k] * *dvi;
            k += 1;
        }
        *d = acc;
    }
    PointStat { d2, delta }
}

/// [`point_stat`] of pixel `p` (in group `g`) of `r`, decoding its
/// reference (for callers that look at single points; [`Inspector::line`]
/// reads each group once).
pub fn point_stat_at<const M: usize>(r: &RecipeView<'_>, g: usize, p: usize, v: &[f32; M], scale: f32) -> PointStat {
    let mut room = [0.0f32; MAX_GROUP_VALUES];
    let px = PixelRef::of(r, p);
    point_stat(&px.mean, &px.inv_sd, group_values(r, g, &mut room), v, scale, READINGS)
}

/// The reading flags that make a point unreadable.
const UNREADABLE: u8 = flags::SATURATED | flags::UNDER_EXPOSED | flags::NON_FINITE;

/// The kind of a point from its statistics, before the out-of-prior
/// question; `was_out` selects the leaving thresholds (hysteresis).
pub fn classify(r: &RecipeView<'_>, stat: &PointStat, reading_flags: u8, was_out: bool) -> Option<DefectKind> {
    Limits::of(r.settings(), was_out).kind(stat, reading_flags)
}

/// The thresholds a point is judged by: the entering ones, or the leaving
/// ones (the windows times `window_hysteresis`, the distance's
/// `threshold_off`). Worked out once per line, not per point.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    windows: [[f32; 2]; READINGS],
    d2: f32,
}

impl Limits {
    /// The leaving thresholds if `leaving`, else the entering ones.
    pub fn of(s: &RecipeSettings, leaving: bool) -> Self {
        let f = if leaving { s.window_hysteresis } else { 1.0 };
        Self {
            windows: s.windows.map(|[lo, hi]| [lo * f, hi * f]),
            d2: if leaving { s.threshold_off } else { s.threshold_on },
        }
    }

    /// How many of the gloss readings' changes these thresholds judge:
    /// up to the last with a window (a window that is off, -inf to +inf,
    /// never puts a point out, whatever the change, NaN included), and
    /// at least the gloss, which the drift mean takes.
    pub fn readings(&self) -> usize {
        let on = |w: &[f32; 2]| w[0] != f32::NEG_INFINITY || w[1] != f32::INFINITY;
        self.windows.iter().rposition(on).map_or(1, |i| i + 1)
    }

    /// Whether a point's statistics are within every threshold (NaN is
    /// not). At the leaving thresholds, which are no wider than the
    /// entering ones (`check_settings`), a readable point within them is
    /// out at neither: the decision's one test for most points.
    #[inline]
    pub fn within(&self, stat: &PointStat) -> bool {
        // `&`, not `&&`: no order to keep, the compiler picks one.
        let mut within = stat.d2 <= self.d2;
        for (d, [lo, hi]) in stat.delta.iter().zip(&self.windows) {
            within &= (d >= lo) & (d <= hi);
        }
        within
    }

    /// The kind of a point with these thresholds (the first that holds, in
    /// the order of the module docs).
    #[inline]
    pub fn kind(&self, stat: &PointStat, reading_flags: u8) -> Option<DefectKind> {
        use crate::gloss::{DISTINCTNESS, HAZE_HU, SPECULAR_GU};
        if reading_flags & UNREADABLE != 0 || !stat.d2.is_finite() {
            return Some(DefectKind::Unreadable);
        }
        let (d, w) = (&stat.delta, &self.windows);
        if d[SPECULAR_GU] < w[SPECULAR_GU][0] {
            return Some(DefectKind::GlossLow);
        }
        if d[SPECULAR_GU] > w[SPECULAR_GU][1] {
            return Some(DefectKind::GlossHigh);
        }
        let outside = |i: usize| d[i] < w[i][0] || d[i] > w[i][1];
        if outside(HAZE_HU) {
            return Some(DefectKind::Haze);
        }
        if outside(DISTINCTNESS) {
            return Some(DefectKind::Distinctness);
        }
        (stat.d2 > self.d2).then_some(DefectKind::OutOfDistribution)
    }
}

/// The decision's state across lines for a sensor of P pixels.
pub struct Inspector<const P: usize> {
    /// Per pixel: its kind while out, else `None`.
    out: [Option<DefectKind>; P],
    /// Per pixel: out at least at the leaving thresholds this line (a
    /// pixel that extends a defect next to it).
    held: [bool; P],
    /// Per pixel: consecutive lines `held`.
    age: [u16; P],
    /// Per pixel: this line's `d2`.
    d2: [f32; P],
    ewma: f32,
    alarm: bool,
    counters: InspectCounters,
}

impl<const P: usize> Default for Inspector<P> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const P: usize> Inspector<P> {
    /// A fresh inspection: nothing out, EWMA 0, counters 0.
    pub const fn new() -> Self {
        Self {
            out: [None; P],
            held: [false; P],
            age: [0; P],
            d2: [0.0; P],
            ewma: 0.0,
            alarm: false,
            counters: InspectCounters { lines: 0, rejected: 0, defects: 0, drift_alarms: 0, pulses: 0 },
        }
    }

    /// The counters.
    pub fn counters(&self) -> InspectCounters {
        self.counters
    }

    /// Counts a reject pulse driven.
    pub fn count_pulse(&mut self) {
        self.counters.pulses = self.counters.pulses.wrapping_add(1);
    }

    /// Decides line `line` from its corrected readings `v` and reading
    /// flags (P each). `out_of_prior(p)` is asked only of the pixels of a
    /// defect, until one says yes (the calibration's flag: an estimate the
    /// device makes only there). `r` must be a recipe for P pixels and M
    /// readings.
    pub fn line<const M: usize>(
        &mut self,
        r: &RecipeView<'_>,
        line: u32,
        v: &[SVector<f32, M>],
        reading_flags: &[u8],
        mut out_of_prior: impl FnMut(usize) -> bool,
    ) -> Verdict {
        debug_assert!(r.pixels() == P && r.leds() == M && v.len() == P && reading_flags.len() == P);
        let s = *r.settings();
        let (entering, leaving) = (Limits::of(&s, false), Limits::of(&s, true));
        let readings = entering.readings();
        let (mut g, mut next_group) = (0usize, if r.groups() > 1 { r.group_start(1) } else { P });
        let mut room = [0.0f32; MAX_GROUP_VALUES];
        let mut group = group_values(r, 0, &mut room);
        // The pixels' references are read in place when the recipe is
        // aligned (always on the device); else decoded pixel by pixel.
        let table = r.pixel_table();
        let mut decoded = PixelRef::<M>::new();
        let (mut wsum, mut wdelta) = (0.0f32, 0.0f32);
        let mut max_d2 = 0.0f32;
        let scale = line_scale(r, v, &mut [0.0f32; P]);
        for p in 0..P {
            if p == next_group {
                g += 1;
                next_group = if g + 1 < r.groups() { r.group_start(g + 1) } else { P };
                group = group_values(r, g, &mut room);
            }
            let (mean, inv_sd, weight) = match table.and_then(|t| split_pixel::<M>(&t[p * pixel_len(M)..])) {
                Some(x) => x,
                None => {
                    decoded.load(r, p);
                    (&decoded.mean, &decoded.inv_sd, decoded.weight)
                }
            };
            let stat = point_stat(mean, inv_sd, group, &v[p].data.0[0], scale, readings);
            let was_out = self.out[p].is_some();
            let (kind, held) = if reading_flags[p] & UNREADABLE == 0 && leaving.within(&stat) {
                // Out at neither thresholds (see `Limits::within`).
                (None, false)
            } else {
                let kind = if was_out { &leaving } else { &entering }.kind(&stat, reading_flags[p]);
                // The leaving thresholds are looser: out at the entering ones
                // (or already judged at the leaving ones) is out at them too.
                let held = kind.is_some()
                    || (s.along_line_hysteresis && !was_out && leaving.kind(&stat, reading_flags[p]).is_some());
                (kind, held)
            };
            self.out[p] = kind;
            self.held[p] = held;
            self.age[p] = if held { self.age[p].saturating_add(1) } else { 0 };
            self.d2[p] = stat.d2;
            if stat.d2 > max_d2 {
                max_d2 = stat.d2;
            }
            if kind.is_none() {
                let w = weight;
                wsum += w;
                wdelta += w * stat.delta[crate::gloss::SPECULAR_GU];
            }
        }
        let mut verdict = Verdict { line, flags: 0, mean_gloss: f32::NAN, ewma: 0.0, max_d2, runs: Runs::new() };
        let mut p = 0;
        while p < P {
            if !self.counts(p, s.min_lines) {
                p += 1;
                continue;
            }
            let first = p;
            let mut run = DefectRun { first: p as u16, len: 0, kind: DefectKind::OutOfDistribution, peak_d2: 0.0 };
            let mut entered = false;
            while p < P && self.counts(p, s.min_lines) {
                if let Some(k) = self.out[p] {
                    entered = true;
                    if k.rank() > run.kind.rank() {
                        run.kind = k;
                    }
                }
                if self.d2[p] > run.peak_d2 || !self.d2[p].is_finite() {
                    run.peak_d2 = self.d2[p];
                }
                p += 1;
            }
            run.len = (p - first) as u16;
            if run.len >= s.min_pixels && entered {
                // The calibration's out-of-prior question, asked only here:
                // an estimate per pixel of a defect, none on a good line.
                if run.kind.rank() < DefectKind::OutOfPrior.rank()
                    && (first..p).any(|q| self.out[q] != Some(DefectKind::Unreadable) && out_of_prior(q))
                {
                    run.kind = DefectKind::OutOfPrior;
                }
                self.counters.defects = self.counters.defects.wrapping_add(1);
                if verdict.runs.push(run).is_err() {
                    verdict.flags |= verdict::MORE_DEFECTS;
                }
                verdict.flags |= verdict::REJECT;
            }
        }
        if wsum > 0.0 {
            verdict.mean_gloss = wdelta / wsum;
            self.ewma = s.ewma_lambda * verdict.mean_gloss + (1.0 - s.ewma_lambda) * self.ewma;
        }
        // A NaN EWMA (never, with finite readings) alarms too.
        let alarm = self.ewma.abs() > s.ewma_limit || self.ewma.is_nan();
        if alarm && !self.alarm {
            self.counters.drift_alarms = self.counters.drift_alarms.wrapping_add(1);
        }
        self.alarm = alarm;
        if alarm {
            verdict.flags |= verdict::DRIFT_ALARM;
        }
        verdict.ewma = self.ewma;
        self.counters.lines = self.counters.lines.wrapping_add(1);
        if verdict.rejected() {
            self.counters.rejected = self.counters.rejected.wrapping_add(1);
        }
        verdict
    }

    /// Pixel `p` is part of a run: out at least at the leaving thresholds
    /// for `min_lines` lines.
    fn counts(&self, p: usize, min_lines: u16) -> bool {
        self.held[p] && self.age[p] >= min_lines
    }
}

#[cfg(test)]
mod tests {
    use super::super::recipe::{RecipeData, RecipeSettings, check_settings, group_len, write};
    use super::*;

    const M: usize = 3;
    const P: usize = 8;

    /// A recipe whose reference is v = 1 at every pixel, sd 0.1, no
    /// correlation, gloss gradient 10 GU per unit of reading 0.
    fn recipe(min_pixels: u16, min_lines: u16) -> Vec<u8> {
        let mut settings = super::super::recipe::tests::settings();
        settings.threshold_on = 25.0; // 5 sd
        settings.threshold_off = 9.0;
        settings.windows = [[-2.0, 2.0], [f32::NEG_INFINITY, f32::INFINITY], [f32::NEG_INFINITY, f32::INFINITY]];
        settings.ewma_lambda = 0.5;
        settings.ewma_limit = 0.5;
        recipe_with(min_pixels, min_lines, settings)
    }

    /// [`recipe`]'s reference with `settings` and the minimum sizes.
    fn recipe_with(min_pixels: u16, min_lines: u16, mut settings: RecipeSettings) -> Vec<u8> {
        let mut group = vec![0.0f32; group_len(M)];
        // Identity whitening, packed lower triangle.
        let mut k = 0;
        for i in 0..M - 1 {
            for j in 0..=i {
                group[k] = if i == j { 1.0 } else { 0.0 };
                k += 1;
            }
        }
        group[k] = 10.0; // d gloss / d f_0
        settings.min_pixels = min_pixels;
        settings.min_lines = min_lines;
        write(&RecipeData {
            pixels: P,
            m: M,
            group_starts: vec![0],
            group_values: vec![group],
            pixel_values: (0..P).map(|_| [1.0, 1.0, 1.0, 10.0, 10.0, 1.0 / 3.0, 1.0 / P as f32].to_vec()).collect(),
            settings,
        })
        .unwrap()
    }

    fn line(values: &[(usize, [f32; M])]) -> Vec<SVector<f32, M>> {
        let mut v = vec![SVector::from([1.0f32; M]); P];
        for (p, x) in values {
            v[*p] = SVector::from(*x);
        }
        v
    }

    #[test]
    fn select_finds_the_kth_smallest() {
        let mut seed = 7u32;
        for n in 1..40 {
            let v: Vec<f32> = (0..n)
                .map(|_| {
                    seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                    ((seed >> 16) % 9) as f32
                })
                .collect();
            let mut sorted = v.clone();
            sorted.sort_by(f32::total_cmp);
            for (k, want) in sorted.iter().enumerate() {
                assert_eq!(select(&mut v.clone(), k), *want, "n {n}, k {k}, {v:?}");
            }
        }
    }

    #[test]
    fn point_statistics_are_the_distance_and_the_gradient() {
        let bytes = recipe(1, 1);
        let r = RecipeView::parse(&bytes).unwrap();
        let s = point_stat_at(&r, 0, 3, &[1.3, 0.9, 0.8], 1.0);
        assert!((s.d2 - (9.0 + 1.0)).abs() < 1e-4, "{}", s.d2);
        assert!((s.delta[0] - 3.0).abs() < 1e-5);
    }

    #[test]
    fn a_point_within_the_leaving_thresholds_is_out_at_neither() {
        // The decision's fast test (`Limits::within`) stands for both
        // classifications; it holds for any settings the recipe allows.
        let mut x = 0x9E37_79B9u32;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as f32 / u32::MAX as f32
        };
        let edges = [0.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        let mut within = 0;
        for case in 0..20_000 {
            let mut s = super::super::recipe::tests::settings();
            s.threshold_on = 1.0 + 40.0 * next();
            s.threshold_off = s.threshold_on * (0.05 + 0.95 * next());
            s.window_hysteresis = 0.05 + 0.95 * next();
            for w in s.windows.iter_mut() {
                *w = if next() < 0.2 { [f32::NEG_INFINITY, f32::INFINITY] } else { [-3.0 * next(), 3.0 * next()] };
                if w[0] == w[1] {
                    w[1] = 1.0;
                }
            }
            check_settings(&s).unwrap();
            let (entering, leaving) = (Limits::of(&s, false), Limits::of(&s, true));
            let mut value = |scale: f32| if next() < 0.05 { edges[case % edges.len()] } else { scale * (next() - 0.5) };
            let stat = PointStat { d2: value(8.0).abs(), delta: [value(4.0), value(4.0), value(4.0)] };
            // On a threshold exactly, now and then.
            let stat = if case % 7 == 0 { PointStat { d2: s.threshold_off, ..stat } } else { stat };
            // (Not within is no claim: a NaN change is neither, and the
            // decision then asks `kind`, as it always did.)
            if leaving.within(&stat) {
                within += 1;
                assert_eq!((entering.kind(&stat, 0), leaving.kind(&stat, 0)), (None, None), "{stat:?} {s:?}");
            }
        }
        assert!(within > 2_000 && within < 18_000, "{within}");
    }

    #[test]
    fn only_the_readings_with_a_window_are_worked_out() {
        let off = [f32::NEG_INFINITY, f32::INFINITY];
        let mut s = super::super::recipe::tests::settings();
        for (windows, readings) in [
            ([off, off, off], 1),
            ([[-2.0, 2.0], off, off], 1),
            ([off, [-1.0, f32::INFINITY], off], 2),
            ([[-2.0, 2.0], off, [f32::NEG_INFINITY, 3.0]], 3),
        ] {
            s.windows = windows;
            for leaving in [false, true] {
                assert_eq!(Limits::of(&s, leaving).readings(), readings, "{windows:?}");
            }
        }
        // The changes worked out are those of all three, bit for bit; the
        // rest are 0.
        let bytes = recipe(1, 1);
        let r = RecipeView::parse(&bytes).unwrap();
        let px = PixelRef::<M>::of(&r, 3);
        let mut group = [0.0f32; MAX_GROUP_VALUES];
        let mut room = [0.0f32; MAX_GROUP_VALUES];
        group[..group_len(M)].copy_from_slice(group_values(&r, 0, &mut room));
        for (k, g) in group.iter_mut().take(group_len(M)).enumerate() {
            *g += 0.37 * k as f32 - 1.1;
        }
        let v = [1.3, 0.9, 0.8];
        let all = point_stat(&px.mean, &px.inv_sd, &group, &v, 1.07, READINGS);
        assert!(all.delta.iter().all(|d| *d != 0.0), "{all:?}");
        for readings in 1..=READINGS {
            let some = point_stat(&px.mean, &px.inv_sd, &group, &v, 1.07, readings);
            assert_eq!(some.d2.to_bits(), all.d2.to_bits());
            for (i, (a, b)) in some.delta.iter().zip(&all.delta).enumerate() {
                assert_eq!(a.to_bits(), if i < readings { b.to_bits() } else { 0 }, "{readings}: {i}");
            }
        }
    }

    #[test]
    fn a_recipe_read_in_place_decides_as_one_decoded() {
        // On the device the recipe is aligned and read in place; a host's
        // byte slice may not be, and is decoded value by value.
        let bytes = recipe(2, 1);
        let mut shifted = vec![0u8; bytes.len() + 1];
        shifted[1..].copy_from_slice(&bytes);
        let (aligned, unaligned) = (RecipeView::parse(&bytes).unwrap(), RecipeView::parse(&shifted[1..]).unwrap());
        assert!(aligned.pixel_table().is_some() != unaligned.pixel_table().is_some());
        let (mut a, mut b) = (Inspector::<P>::new(), Inspector::<P>::new());
        let lines = [
            line(&[]),
            line(&[(2, [1.6, 1.0, 1.0]), (3, [1.5, 1.0, 1.0]), (4, [1.3, 1.0, 1.0])]),
            line(&[(3, [1.25, 1.0, 1.0]), (5, [0.7, 1.2, 1.0])]),
            line(&[(0, [f32::NAN, 1.0, 1.0]), (6, [1.0, 1.9, 0.2]), (7, [1.0, 1.9, 0.2])]),
        ];
        for (k, v) in lines.iter().enumerate() {
            let flags = [0u8; P];
            let (va, vb) =
                (a.line(&aligned, k as u32, v, &flags, |_| false), b.line(&unaligned, k as u32, v, &flags, |_| false));
            assert_eq!(format!("{va:?}"), format!("{vb:?}"));
        }
        assert!(a.counters().defects > 0);
    }

    #[test]
    fn runs_kinds_minimum_size_and_hysteresis() {
        let bytes = recipe(2, 1);
        let r = RecipeView::parse(&bytes).unwrap();
        let mut ins = Inspector::<P>::new();
        let flags = [0u8; P];
        // One pixel far out: below the minimum size, not a defect.
        let v = ins.line(&r, 0, &line(&[(2, [1.0, 2.0, 1.0])]), &flags, |_| false);
        assert!(!v.rejected() && v.runs.is_empty());
        // Pixels 4, 5 with gloss +3 GU (f0 + 0.3, d2 = 11.25 below the threshold): gloss high.
        let v = ins.line(&r, 1, &line(&[(4, [1.3, 0.85, 0.85]), (5, [1.3, 0.85, 0.85])]), &flags, |_| false);
        assert!(v.rejected());
        assert_eq!(
            v.runs.as_slice(),
            &[DefectRun { first: 4, len: 2, kind: DefectKind::GlossHigh, peak_d2: v.runs[0].peak_d2 }]
        );
        // Hysteresis: +1.8 GU stays out for pixels that were out (window x 0.8 = 1.6) ...
        let v = ins.line(&r, 2, &line(&[(4, [1.18, 0.91, 0.91]), (5, [1.18, 0.91, 0.91])]), &flags, |_| false);
        assert!(v.rejected());
        // ... but does not bring in pixels that were not.
        let v = ins.line(&r, 3, &line(&[(0, [1.18, 0.91, 0.91]), (1, [1.18, 0.91, 0.91])]), &flags, |_| false);
        assert!(!v.rejected());
        // Out-of-prior is asked only of a defect's pixels, until one says
        // yes, and wins over the window kinds.
        let mut asked = Vec::new();
        let v = ins.line(&r, 4, &line(&[(6, [1.0, 2.0, 1.0]), (7, [0.7, 1.0, 1.0])]), &flags, |p| {
            asked.push(p);
            p == 6
        });
        assert_eq!(asked, [6]);
        assert_eq!(v.runs[0].kind, DefectKind::OutOfPrior);
        // Saturation is unreadable whatever the readings.
        let mut f = [0u8; P];
        f[0] = flags::SATURATED;
        f[1] = flags::SATURATED;
        let v = ins.line(&r, 5, &line(&[]), &f, |_| false);
        assert_eq!((v.runs[0].first, v.runs[0].kind), (0, DefectKind::Unreadable));
        let c = ins.counters();
        assert_eq!((c.lines, c.rejected, c.defects), (6, 4, 4));
    }

    #[test]
    fn hysteresis_along_the_line_extends_a_defect_but_never_starts_one() {
        let bytes = recipe(3, 1);
        let r = RecipeView::parse(&bytes).unwrap();
        let (high, held, inside) = ([1.3, 0.85, 0.85], [1.18, 0.91, 0.91], [1.1, 0.95, 0.95]);
        let verdict =
            |values: &[(usize, [f32; M])]| Inspector::<P>::new().line(&r, 0, &line(values), &[0; P], |_| false);
        // +3, +1.8, +3 GU: the middle pixel is inside the entering window
        // (2 GU) but out of the leaving one (1.6 GU), so the three are one defect.
        let v = verdict(&[(3, high), (4, held), (5, high)]);
        assert_eq!(
            v.runs.as_slice(),
            &[DefectRun { first: 3, len: 3, kind: DefectKind::GlossHigh, peak_d2: v.runs[0].peak_d2 }]
        );
        // A neighbour at +1 GU is inside both: two pixels stay below the minimum.
        assert!(!verdict(&[(3, high), (4, high), (5, inside)]).rejected());
        // Pixels out only at the leaving thresholds are never a defect on their own.
        assert!(!verdict(&[(3, held), (4, held), (5, held), (6, held)]).rejected());
        // A format 1 recipe is decided as it was taught: every pixel at the entering thresholds.
        let mut old = *RecipeView::parse(&bytes).unwrap().settings();
        old.along_line_hysteresis = false;
        let bytes = recipe_with(3, 1, old);
        let r = RecipeView::parse(&bytes).unwrap();
        assert_eq!(super::super::recipe::FORMAT_VERSION_ENTERING_RUNS, u16::from_le_bytes([bytes[4], bytes[5]]));
        let line = line(&[(3, high), (4, held), (5, high)]);
        assert!(!Inspector::<P>::new().line(&r, 0, &line, &[0; P], |_| false).rejected());
    }

    #[test]
    fn a_defect_must_last_its_minimum_lines() {
        let bytes = recipe(1, 3);
        let r = RecipeView::parse(&bytes).unwrap();
        let mut ins = Inspector::<P>::new();
        let bad = line(&[(1, [1.0, 3.0, 1.0])]);
        let verdicts: Vec<bool> = (0..4).map(|l| ins.line(&r, l, &bad, &[0; P], |_| false).rejected()).collect();
        assert_eq!(verdicts, [false, false, true, true]);
        assert!(!ins.line(&r, 4, &line(&[]), &[0; P], |_| false).rejected());
    }

    #[test]
    fn drift_raises_the_alarm_once_and_clears() {
        let bytes = recipe(1, 1);
        let r = RecipeView::parse(&bytes).unwrap();
        let mut ins = Inspector::<P>::new();
        // Every pixel +0.9 GU (inside the window): EWMA 0.45, 0.675 -> alarm on the second line.
        let drifted = vec![SVector::from([1.09f32, 0.955, 0.955]); P];
        let a = ins.line(&r, 0, &drifted, &[0; P], |_| false);
        let b = ins.line(&r, 1, &drifted, &[0; P], |_| false);
        assert_eq!((a.flags & verdict::DRIFT_ALARM, b.flags & verdict::DRIFT_ALARM), (0, verdict::DRIFT_ALARM));
        assert!(!b.rejected());
        let _ = ins.line(&r, 2, &drifted, &[0; P], |_| false);
        for l in 3..8 {
            ins.line(&r, l, &line(&[]), &[0; P], |_| false);
        }
        assert_eq!(ins.counters().drift_alarms, 1);
        assert_eq!(ins.line(&r, 9, &line(&[]), &[0; P], |_| false).flags & verdict::DRIFT_ALARM, 0);
    }
}
