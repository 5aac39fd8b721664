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
//! is never needed. Worked out in two parts (`unscaled`): the first needs
//! neither the last reading nor the line's scale, and the acquisition
//! works it out while the line's last LED frame integrates
//! ([`UnscaledLine`]); after that frame a point costs 3 multiply-adds for
//! its distance and 3 per change ([`scaled`]), bit for bit what the two
//! parts give worked out at once (the host's reference does that). Where
//! the rewriting would round worse than the direct form (a scale far off 1
//! on a reference far above its noise) the point is worked out directly.
//! A point within the leaving thresholds is out at neither (they are no
//! wider than the entering ones): one test ([`Limits::within`]) decides
//! most points.
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
//!
//! Where it lives: this file, the line's decision ([`Inspector`]);
//! `point`, the decision per point ([`point_stat`], [`line_scale`],
//! [`Limits`]); `unscaled`, a point's statistics in two parts, the first
//! worked out before the last frame ([`unscaled`], [`scaled`],
//! [`UnscaledLine`]); `defects`, what a line's decision says ([`Verdict`],
//! its [`DefectRun`]s, [`InspectCounters`]).
mod defects;
mod point;
mod unscaled;

pub use defects::{DefectKind, DefectRun, InspectCounters, MAX_RUNS, Runs, Verdict, verdict};
pub use point::{
    Limits, MAX_GROUP_VALUES, PixelRef, PointStat, classify, inverse_reference_sum, line_scale, point_stat,
    point_stat_at,
};
pub use unscaled::{LineScale, SCALED_BB_LIMIT, Unscaled, UnscaledLine, scaled, unscaled};

use super::recipe::RecipeView;
use nalgebra::SVector;
use point::{UNREADABLE, group_values, pixel_ref};

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
        out_of_prior: impl FnMut(usize) -> bool,
    ) -> Verdict {
        self.line_with(r, line, v, reading_flags, None, out_of_prior)
    }

    /// [`Self::line`] with the first parts of the points' statistics the
    /// acquisition worked out while the line's last frame integrated
    /// (`early`): only the rest is worked out here, and the verdict is
    /// [`Self::line`]'s bit for bit.
    pub fn line_with<const M: usize>(
        &mut self,
        r: &RecipeView<'_>,
        line: u32,
        v: &[SVector<f32, M>],
        reading_flags: &[u8],
        early: Option<&UnscaledLine<P>>,
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
        let raw_scale = line_scale(r, v, &mut [0.0f32; P]);
        let scale = LineScale::new(raw_scale);
        for p in 0..P {
            if p == next_group {
                g += 1;
                next_group = if g + 1 < r.groups() { r.group_start(g + 1) } else { P };
                group = group_values(r, g, &mut room);
            }
            let (mean, inv_sd, weight) = pixel_ref(table, r, p, &mut decoded);
            let vp = &v[p].data.0[0];
            let first = match early.and_then(|e| e.get(p)) {
                Some(u) => *u,
                None => unscaled(mean, inv_sd, group, vp, readings),
            };
            let stat = scaled::<M>(&first, vp[M - 1], mean[M - 1], group, &scale, readings)
                .unwrap_or_else(|| point::direct_stat(mean, inv_sd, group, vp, raw_scale, readings));
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
mod tests;
