//! The decision per point: the line's scale, a point's statistics against
//! its pixel's reference, and the limits that classify it.
use super::DefectKind;
use crate::inspect::recipe::{RecipeSettings, RecipeView, pixel_len};
use crate::protocol::flags;
use crate::shape::READINGS;
use nalgebra::SVector;

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
pub(super) fn read_f32s(bytes: &[u8], out: &mut [f32]) {
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
pub(super) fn group_values<'a>(r: &RecipeView<'a>, g: usize, room: &'a mut [f32; MAX_GROUP_VALUES]) -> &'a [f32] {
    match r.group_words(g) {
        Some(w) => w,
        None => {
            read_f32s(r.group_bytes(g), room);
            &room[..crate::inspect::recipe::group_len(r.leds())]
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

/// Pixel `p`'s reference mean, inverse standard deviations and drift
/// weight: read in place from the recipe's pixel `table` when it is aligned
/// (always on the device), else decoded into `decoded`.
#[inline(always)]
pub(super) fn pixel_ref<'a, const M: usize>(
    table: Option<&'a [f32]>,
    r: &RecipeView<'_>,
    p: usize,
    decoded: &'a mut PixelRef<M>,
) -> (&'a [f32; M], &'a [f32; M], f32) {
    match table.and_then(|t| split_pixel::<M>(&t[p * pixel_len(M)..])) {
        Some(x) => x,
        None => {
            decoded.load(r, p);
            (&decoded.mean, &decoded.inv_sd, decoded.weight)
        }
    }
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
pub(super) fn select(x: &mut [f32], k: usize) -> f32 {
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
/// group's values `group`, at the line's `scale` (see the module docs), in
/// one go and as the decision works them out: in two parts
/// ([`unscaled`](super::unscaled::unscaled), then
/// [`scaled`](super::unscaled::scaled)), or directly where the two parts
/// would lose precision. Only the first `readings` changes are worked out,
/// the rest left 0 (the decision skips those whose windows are off:
/// [`Limits::readings`]).
pub fn point_stat<const M: usize>(
    mean: &[f32; M],
    inv_sd: &[f32; M],
    group: &[f32],
    v: &[f32; M],
    scale: f32,
    readings: usize,
) -> PointStat {
    let u = super::unscaled::unscaled(mean, inv_sd, group, v, readings);
    let s = super::unscaled::LineScale::new(scale);
    super::unscaled::scaled::<M>(&u, v[M - 1], mean[M - 1], group, &s, readings)
        .unwrap_or_else(|| direct_stat(mean, inv_sd, group, v, scale, readings))
}

/// The per-point statistics worked out directly from the scaled readings,
/// `z = s .* (k v - mu)` then `y = L^-1 z` (the module docs): for a point
/// whose two parts would lose precision
/// ([`scaled`](super::unscaled::scaled) says which). Not inlined: a cold
/// path, and one symbol for its cost in QEMU.
#[inline(never)]
pub(super) fn direct_stat<const M: usize>(
    mean: &[f32; M],
    inv_sd: &[f32; M],
    group: &[f32],
    v: &[f32; M],
    scale: f32,
    readings: usize,
) -> PointStat {
    // One copy for every count of changes: the decision's fast path is the
    // two parts; this one is for the points they would not keep precise.
    const { assert!(M >= 2 && crate::inspect::recipe::group_len(M) <= MAX_GROUP_VALUES) };
    // One length check here, none per value below.
    let group = &group[..crate::inspect::recipe::group_len(M)];
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
    for d in delta.iter_mut().take(readings) {
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
/// reference (for callers that look at single points; [`Inspector::line`](super::Inspector::line)
/// reads each group once).
pub fn point_stat_at<const M: usize>(r: &RecipeView<'_>, g: usize, p: usize, v: &[f32; M], scale: f32) -> PointStat {
    let mut room = [0.0f32; MAX_GROUP_VALUES];
    let px = PixelRef::of(r, p);
    point_stat(&px.mean, &px.inv_sd, group_values(r, g, &mut room), v, scale, READINGS)
}

/// The reading flags that make a point unreadable.
pub(super) const UNREADABLE: u8 = flags::SATURATED | flags::UNDER_EXPOSED | flags::NON_FINITE;

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
