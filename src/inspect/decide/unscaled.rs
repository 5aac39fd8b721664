//! A point's statistics in two parts: what its first m - 1 readings give
//! before the line's scale is known ([`unscaled`]), and the rest once the
//! line's last frame is in ([`scaled`]).
//!
//! The distance and the changes are those of the module docs,
//! `y = L^-1 (s .* (k v - mu))` and `delta = J (k v - mu)`, rewritten with
//! `k v - mu = k (v - mu) + (k - 1) mu`:
//! - `y = k d + (k - 1) b`, with `d = L^-1 (s .* (v - mu))` and `b = L^-1
//!   (s .* mu)` over the first m - 1 readings, so
//!   `d2 = k^2 |d|^2 + 2 k (k - 1) d.b + (k - 1)^2 |b|^2`;
//! - `delta = k g + (k - 1) e`, with `g = J (v - mu)` and `e = J mu`.
//!
//! `|d|^2`, `d.b`, `|b|^2`, `e` and `g` over the first m - 1 readings need
//! neither the line's scale (which needs every pixel's last reading) nor
//! the last reading: the acquisition works them out while the line's last
//! LED frame integrates ([`UnscaledLine`]), and after that frame each
//! point costs 3 multiply-adds for its distance and 3 per gloss change,
//! against (m-1)m/2 + R m + m for the whole statistic.
//!
//! Precision: at k = 1 the distance is `|d|^2`, the deviation taken before
//! any product. Off 1, the `(k - 1)` terms round with `|b|^2`, the
//! reference's squared signal-to-noise in the whitened metric: an error of
//! about `eps (k - 1)^2 |b|^2` (eps = 6e-8), where the direct statistic's
//! was about `2 eps |y| |b|`. A reference 300 times its noise on a line 3 %
//! off its scale gives 5e-4, against a threshold of about 20; readings
//! correlated to 0.999, 10^4 times their noise, on a line 20 % off, would
//! give hundreds. So [`scaled`] declines past [`SCALED_BB_LIMIT`], and
//! such a point is worked out directly, as before (a test bounds both on
//! hard references).
use super::point::PointStat;
use crate::inspect::recipe::RecipeView;
use crate::shape::READINGS;
use nalgebra::SVector;

/// A point's statistics over its first m - 1 readings, before the line's
/// scale (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unscaled {
    /// `|d|^2`.
    dd: f32,
    /// `d.b`.
    db: f32,
    /// `|b|^2`.
    bb: f32,
    /// `J (v - mu)` over the first m - 1 readings (the first R; the rest 0).
    g: [f32; READINGS],
    /// `J mu` over all m readings (the first R; the rest 0).
    e: [f32; READINGS],
}

impl Unscaled {
    /// Zeros.
    pub const ZERO: Self = Self { dd: 0.0, db: 0.0, bb: 0.0, g: [0.0; READINGS], e: [0.0; READINGS] };
}

/// The line's scale as the second part uses it: `k`, `k - 1` and the
/// distance's three coefficients, worked out once a line.
#[derive(Clone, Copy, Debug)]
pub struct LineScale {
    k: f32,
    k1: f32,
    c_dd: f32,
    c_db: f32,
    c_bb: f32,
}

impl LineScale {
    /// The coefficients of scale `k`. A scale that is not a positive
    /// number leaves every distance NaN: unreadable.
    pub fn new(k: f32) -> Self {
        let k1 = k - 1.0;
        let c_dd = if k > 0.0 && k.is_finite() { k * k } else { f32::NAN };
        Self { k, k1, c_dd, c_db: 2.0 * k * k1, c_bb: k1 * k1 }
    }
}

/// The first part of the statistics of a point with readings `v` (only the
/// first m - 1 are read), its pixel's reference `mean` and inverse standard
/// deviations `inv_sd` and its group's values `group`; only the first
/// `readings` changes (see [`super::Limits::readings`]).
pub fn unscaled<const M: usize>(
    mean: &[f32; M],
    inv_sd: &[f32; M],
    group: &[f32],
    v: &[f32; M],
    readings: usize,
) -> Unscaled {
    // One copy for every count of changes: it runs while the last frame
    // integrates, where a copy per count (as the direct statistic has)
    // would buy time nobody waits for with 1 KB of the board's flash each.
    const { assert!(M >= 2 && crate::inspect::recipe::group_len(M) <= super::MAX_GROUP_VALUES) };
    let group = &group[..crate::inspect::recipe::group_len(M)];
    let (mut dv, mut zd, mut zb) = ([0.0f32; M], [0.0f32; M], [0.0f32; M]);
    for i in 0..M - 1 {
        dv[i] = v[i] - mean[i];
        zd[i] = dv[i] * inv_sd[i];
        zb[i] = mean[i] * inv_sd[i];
    }
    let mut u = Unscaled::ZERO;
    let mut k = 0;
    for i in 0..M - 1 {
        let (mut d, mut b) = (0.0f32, 0.0f32);
        for j in 0..=i {
            d += group[k] * zd[j];
            b += group[k] * zb[j];
            k += 1;
        }
        u.dd += d * d;
        u.db += d * b;
        u.bb += b * b;
    }
    for r in 0..readings.min(READINGS) {
        let row = &group[k + r * M..k + (r + 1) * M];
        let (mut g, mut e) = (0.0f32, 0.0f32);
        for i in 0..M - 1 {
            g += row[i] * dv[i];
            e += row[i] * mean[i];
        }
        u.g[r] = g;
        u.e[r] = e + row[M - 1] * mean[M - 1];
    }
    u
}

/// The most `(k - 1)^2 |b|^2` for which [`scaled`] works the distance out
/// from the two parts: its rounding then stays below about
/// `eps (k - 1)^2 |b|^2 = 0.001`, against a threshold of about 20.
pub const SCALED_BB_LIMIT: f32 = 16_384.0;

/// The point's statistics from their first part `u`, its last reading
/// `v_last` and its reference mean there `mean_last`, its group's values
/// and the line's scale: 3 multiply-adds for the distance, 3 for each of the
/// first `readings` changes (the rest 0). `None` where that would lose
/// precision: a scale far enough off 1 on a reference far enough above its
/// noise that `(k - 1)^2 |b|^2` exceeds [`SCALED_BB_LIMIT`] (the statistic
/// is then worked out directly, from the scaled readings).
#[inline(always)]
pub fn scaled<const M: usize>(
    u: &Unscaled,
    v_last: f32,
    mean_last: f32,
    group: &[f32],
    s: &LineScale,
    readings: usize,
) -> Option<PointStat> {
    if s.c_bb * u.bb > SCALED_BB_LIMIT {
        return None;
    }
    let d2 = s.c_dd * u.dd + s.c_db * u.db + s.c_bb * u.bb;
    // Rounding can take a distance of 0 just below it (NaN stays NaN).
    let d2 = if d2 < 0.0 { 0.0 } else { d2 };
    let mut delta = [0.0f32; READINGS];
    let last = v_last - mean_last;
    let j = crate::inspect::recipe::group_len(M) - READINGS * M + M - 1;
    for r in 0..readings.min(READINGS) {
        delta[r] = s.k * (u.g[r] + group[j + r * M] * last) + s.k1 * u.e[r];
    }
    Some(PointStat { d2, delta })
}

/// The first parts of a line's points, worked out while its last frame
/// integrates, for the pixels whose first m - 1 readings were final by then.
pub struct UnscaledLine<const P: usize> {
    ready: [bool; P],
    points: [Unscaled; P],
}

impl<const P: usize> Default for UnscaledLine<P> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const P: usize> UnscaledLine<P> {
    /// None worked out.
    pub const fn new() -> Self {
        Self { ready: [false; P], points: [Unscaled::ZERO; P] }
    }

    /// Forgets every point (a new line, or readings corrected again).
    pub fn clear(&mut self) {
        self.ready = [false; P];
    }

    /// Pixel `p`'s first part, if it was worked out.
    #[inline(always)]
    pub fn get(&self, p: usize) -> Option<&Unscaled> {
        self.ready[p].then(|| &self.points[p])
    }

    /// How many pixels have theirs.
    pub fn ready(&self) -> usize {
        self.ready.iter().filter(|r| **r).count()
    }

    /// Works out the first part of every pixel `p` whose first m - 1
    /// readings `v[p]` are final (`final_through(p)`), against recipe `r`
    /// (for P pixels and M readings): the same values, bit for bit, as the
    /// decision would work out from the whole line. Returns how many it
    /// worked out.
    pub fn work_out<const M: usize>(
        &mut self,
        r: &RecipeView<'_>,
        v: &[SVector<f32, M>; P],
        final_through: impl Fn(usize) -> bool,
    ) -> usize {
        let mut n = 0;
        let readings = super::Limits::of(r.settings(), false).readings();
        let table = r.pixel_table();
        let mut room = [0.0f32; super::MAX_GROUP_VALUES];
        let mut decoded = super::PixelRef::<M>::new();
        for g in 0..r.groups() {
            let end = if g + 1 < r.groups() { r.group_start(g + 1) } else { P };
            let group = super::point::group_values(r, g, &mut room);
            for (p, vp) in v.iter().enumerate().take(end).skip(r.group_start(g)) {
                if !final_through(p) {
                    continue;
                }
                let (mean, inv_sd, _) = super::point::pixel_ref(table, r, p, &mut decoded);
                self.points[p] = unscaled(mean, inv_sd, group, &vp.data.0[0], readings);
                self.ready[p] = true;
                n += 1;
            }
        }
        n
    }
}

#[cfg(test)]
mod tests {
    use super::super::Inspector;
    use super::*;
    use crate::inspect::recipe::{RecipeData, group_len, write};

    const M: usize = 7;
    const P: usize = 24;

    /// xorshift32 in [0, 1).
    struct Rng(u32);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 17;
            self.0 ^= self.0 << 5;
            (self.0 >> 8) as f32 / (1u32 << 24) as f32
        }
        fn normal(&mut self) -> f32 {
            let (a, b) = (self.next().max(1e-7), self.next());
            (-2.0 * a.ln()).sqrt() * (core::f32::consts::TAU * b).cos()
        }
    }

    /// A hard recipe: three groups, whitening of readings correlated up to
    /// `rho` (entries up to 1 / sqrt(1 - rho^2)), references `snr` times
    /// their noise, every gloss window on.
    fn hard_recipe(rng: &mut Rng, snr: f32, rho: f32) -> Vec<u8> {
        let mut settings = crate::inspect::recipe::tests::settings();
        settings.windows = [[-2.0, 2.0], [-1.0, 1.0], [-5.0, 5.0]];
        let group = |rng: &mut Rng| {
            let mut g = vec![0.0f32; group_len(M)];
            let w = 1.0 / (1.0 - rho * rho).sqrt();
            let mut k = 0;
            for i in 0..M - 1 {
                for j in 0..=i {
                    g[k] = if i == j { w } else { -w * rho * rng.next() };
                    k += 1;
                }
            }
            for x in &mut g[k..] {
                *x = 40.0 * (rng.next() - 0.5);
            }
            g
        };
        let pixel = |rng: &mut Rng| {
            let mean: Vec<f32> = (0..M).map(|_| 0.05 + 3.0 * rng.next()).collect();
            let mut px = mean.clone();
            px.extend(mean[..M - 1].iter().map(|m| snr / m));
            px.push(1.0 / mean.iter().sum::<f32>());
            px.push(1.0 / P as f32);
            px
        };
        write(&RecipeData {
            pixels: P,
            m: M,
            group_starts: vec![0, 5, 17],
            group_values: (0..3).map(|_| group(rng)).collect(),
            pixel_values: (0..P).map(|_| pixel(rng)).collect(),
            settings,
        })
        .unwrap()
    }

    /// A line of the recipe's reference, `drift` off its scale, each
    /// reading with noise of `1 / snr`, times `spread` at some pixels.
    fn noisy_line(rng: &mut Rng, r: &RecipeView<'_>, snr: f32, drift: f32, spread: f32) -> [SVector<f32, M>; P] {
        core::array::from_fn(|p| {
            let s = if rng.next() < 0.3 { spread } else { 1.0 };
            SVector::from(core::array::from_fn(|i| {
                let mean = r.pixel_value(p, i);
                drift * mean * (1.0 + s * rng.normal() / snr)
            }))
        })
    }

    /// The statistic's definition in f64: (d2, delta, |y|, |b|).
    fn exact(r: &RecipeView<'_>, g: usize, p: usize, v: &[f32; M], k: f64) -> (f64, [f64; 3], f64, f64) {
        let group: Vec<f64> = (0..group_len(M))
            .map(|i| {
                let b = &r.group_bytes(g)[4 * i..4 * i + 4];
                f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64
            })
            .collect();
        let mean: Vec<f64> = (0..M).map(|i| r.pixel_value(p, i) as f64).collect();
        let s: Vec<f64> = (0..M).map(|i| r.pixel_value(p, M + i) as f64).collect();
        let f: Vec<f64> = (0..M).map(|i| k * v[i] as f64 - mean[i]).collect();
        let (mut d2, mut bb, mut kk) = (0.0, 0.0, 0);
        for i in 0..M - 1 {
            let (mut y, mut b) = (0.0, 0.0);
            for j in 0..=i {
                y += group[kk] * s[j] * f[j];
                b += group[kk] * s[j] * mean[j];
                kk += 1;
            }
            d2 += y * y;
            bb += b * b;
        }
        let delta = core::array::from_fn(|r| (0..M).map(|i| group[kk + r * M + i] * f[i]).sum());
        (d2, delta, d2.sqrt(), bb.sqrt())
    }

    #[test]
    fn the_statistic_is_its_definition_to_a_few_roundings_on_hard_references() {
        // In two parts the distance rounds with (k - 1)^2 |b|^2, at most
        // SCALED_BB_LIMIT; directly, with |y| |b|. On references up to
        // 10^4 times their noise, readings correlated to 0.999 and lines
        // 20 % off their scale, both paths are taken and both hold.
        let eps = f32::EPSILON as f64;
        let mut rng = Rng(0x2545_f491);
        let (mut two_parts, mut direct) = (0, 0);
        for (snr, rho) in [(30.0, 0.5), (300.0, 0.9), (1e4, 0.999)] {
            let bytes = hard_recipe(&mut rng, snr, rho);
            let r = RecipeView::parse(&bytes).unwrap();
            let group_of = |p: usize| (0..r.groups()).rev().find(|g| r.group_start(*g) <= p).unwrap();
            for drift in [0.8f32, 0.97, 1.0, 1.03, 1.25] {
                for _ in 0..20 {
                    let v = noisy_line(&mut rng, &r, snr, drift, 6.0);
                    let k = super::super::line_scale(&r, &v, &mut [0.0; P]);
                    for (p, vp) in v.iter().enumerate() {
                        let g = group_of(p);
                        let px = super::super::PixelRef::<M>::of(&r, p);
                        let mut room = [0.0f32; super::super::MAX_GROUP_VALUES];
                        let group = super::super::point::group_values(&r, g, &mut room);
                        let vp = &vp.data.0[0];
                        let u = unscaled(&px.mean, &px.inv_sd, group, vp, READINGS);
                        match scaled::<M>(&u, vp[M - 1], px.mean[M - 1], group, &LineScale::new(k), READINGS) {
                            Some(_) => two_parts += 1,
                            None => direct += 1,
                        }
                        let got = super::super::point_stat(&px.mean, &px.inv_sd, group, vp, k, READINGS);
                        let (d2, delta, y, b) = exact(&r, g, p, vp, k as f64);
                        let bound = 16.0 * eps * (SCALED_BB_LIMIT as f64 + 2.0 * y * b + y * y);
                        assert!(
                            (got.d2 as f64 - d2).abs() <= bound,
                            "snr {snr}, rho {rho}, k {k}: d2 {} against {d2} (bound {bound})",
                            got.d2
                        );
                        for (gr, want) in got.delta.iter().zip(delta) {
                            assert!((*gr as f64 - want).abs() <= 1e-4 * want.abs().max(1.0), "{gr} against {want}");
                        }
                    }
                }
            }
        }
        assert!(two_parts > direct && direct > 100, "{two_parts} in two parts, {direct} directly");
    }

    #[test]
    fn a_line_decided_from_its_early_parts_is_the_line_decided_whole_bit_for_bit() {
        let mut rng = Rng(0x9e37_79b9);
        let bytes = hard_recipe(&mut rng, 200.0, 0.9);
        let r = RecipeView::parse(&bytes).unwrap();
        let (mut whole, mut early) = (Inspector::<P>::new(), Inspector::<P>::new());
        let mut parts = UnscaledLine::<P>::new();
        for line in 0..30u32 {
            let drift = 0.9 + 0.2 * rng.next();
            let v = noisy_line(&mut rng, &r, 200.0, drift, 8.0);
            // The last reading is not read: it is not there yet.
            let mut before = v;
            for x in before.iter_mut() {
                x[M - 1] = f32::NAN;
            }
            // Some pixels still wait for a shorter exposure.
            let waiting: Vec<bool> = (0..P).map(|_| rng.next() < 0.25).collect();
            parts.clear();
            let n = parts.work_out(&r, &before, |p| !waiting[p]);
            assert_eq!((n, parts.ready()), (waiting.iter().filter(|w| !**w).count(), n));
            let flags = [0u8; P];
            let a = whole.line(&r, line, &v, &flags, |_| false);
            let b = early.line_with(&r, line, &v, &flags, Some(&parts), |_| false);
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "line {line}");
            assert_eq!(whole.d2.map(f32::to_bits), early.d2.map(f32::to_bits), "line {line}");
        }
        // Lines with defects among them, so runs and kinds are compared too.
        assert!(whole.counters().defects > 0, "{:?}", whole.counters());
    }

    #[test]
    fn a_scale_that_is_not_a_positive_number_leaves_the_distance_nan() {
        let u = Unscaled { dd: 1.0, db: 2.0, bb: 3.0, g: [1.0; READINGS], e: [1.0; READINGS] };
        let group = [0.5f32; group_len(M)];
        for k in [0.0f32, -1.0, f32::NAN, f32::INFINITY] {
            let s = LineScale::new(k);
            let d2 = scaled::<M>(&u, 1.0, 1.0, &group, &s, READINGS).map(|s| s.d2);
            // Directly, as before: NaN too.
            let direct = super::super::point::direct_stat(&[1.0; M], &[1.0; M], &group, &[1.0; M], k, READINGS).d2;
            assert!(d2.is_none_or(f32::is_nan) && direct.is_nan(), "{k}: {d2:?}, {direct}");
        }
        // A point exactly on its reference at a scale off 1 is at distance
        // 0, not just below it.
        let bytes = hard_recipe(&mut Rng(7), 300.0, 0.9);
        let r = RecipeView::parse(&bytes).unwrap();
        let px = super::super::PixelRef::<M>::of(&r, 3);
        let mut room = [0.0f32; super::super::MAX_GROUP_VALUES];
        let group = super::super::point::group_values(&r, 0, &mut room);
        let v: [f32; M] = core::array::from_fn(|i| px.mean[i] / 1.25);
        let s = super::super::point_stat(&px.mean, &px.inv_sd, group, &v, 1.25, READINGS);
        assert!(s.d2 >= 0.0 && s.d2 < 1e-2, "{}", s.d2);
    }
}
