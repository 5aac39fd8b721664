//! Scale-free estimation and the out-of-prior statistic, per point, in f32
//! with one fixed accumulation order, so the device and the host (which
//! calls these same functions) give the same bits.
//!
//! # Scale-free estimation
//! Real materials span orders of magnitude in peak reflectance; one linear
//! map trained on them is dominated by the shiniest. So the shape is
//! estimated from the readings divided by their scale and multiplied back:
//!
//! - scale `s = sum_i v_i` (plain sum, sequential). Why the sum: every LED
//!   contributes, so it is the least noisy scale of the readings themselves
//!   (a max would follow one noisy reading), and with it the normalised
//!   readings `u = v / s` lie exactly on the hyperplane `sum u = 1`: one
//!   coordinate is redundant, which is the singular direction of their
//!   covariance. Training drops the last coordinate, so the shape estimate is
//!   the affine Wiener map `y = mu_y + W' (u' - mu')` of `u' = u_0..u_{m-2}`.
//! - multiplied back, `rho = s y = W' v' + s (mu_y - W' mu')`. The blob's
//!   n x m matrix is `[W' | b]` with `b = mu_y - W' mu'`: its last column
//!   multiplies the scale instead of the last reading. So the estimate costs
//!   exactly the plain Wiener's n*m multiply-adds plus m-1 adds for s, and
//!   no division; and it scales with the readings (`rho(c v) = c rho(v)`,
//!   bit for bit when c is a power of two).
//!
//! # Out-of-prior statistic
//! How typical the readings' shape is for the prior: a squared Mahalanobis
//! distance `d2 = |G (x - mu)|^2` under the prior's covariance of `x`
//! (noise included), `G = chol(C)^-1` lower triangular, (m-1) x (m-1),
//! stored packed row by row (row k holds k+1 entries). Two forms of `x`
//! (training fits both and keeps the one whose flag lands on the worse
//! estimates; the blob records which):
//!
//! - **log-ratio** ([`out_of_prior_stat_log_ratio`]): the centred
//!   logarithms of the shares `u_i = v_i / s` (floored at
//!   [`LOG_RATIO_FLOOR`]), the last dropped since they sum to zero. Why the
//!   logarithm: the shares of glossy and matte materials differ by orders
//!   of magnitude, so a distance in `u` measures mostly how bright the
//!   brightest LED is; in the logarithm a dark LED's ratio counts as much
//!   as a bright one's (on the handheld this is what tells a bad estimate:
//!   `docs/handheld.md`). Cost: m `logf` on top of the linear form's (373
//!   instructions per point for m = 7 on the M4, QEMU's count).
//! - **linear** ([`out_of_prior_stat`]): `x = u'`, the first m-1 shares.
//!   Cost: one division, m-1 multiplies and subtracts.
//!
//! Both then take (m-1)m/2 multiply-adds and m-1 squares accumulated.
//! Training sets the threshold from cross-validated prior samples at a
//! stated false-alarm rate; a point above it is flagged. Readings whose sum
//! is not positive and finite give `+inf`.

/// The scale of the readings: `s = sum_i v_i`, summed in index order.
#[inline]
pub fn scale(v: &[f32]) -> f32 {
    let mut s = 0.0f32;
    for x in v {
        s += *x;
    }
    s
}

/// Scale-free estimate of one point: `out[j] = sum_{i<m-1} w[j*m+i] v[i] +
/// w[j*m+m-1] s`, with `s = scale(v)`, accumulated in that order (unfused).
/// Returns `s`. `w` is the blob's row-major n x m matrix `[W' | b]`.
///
/// # Panics
/// If `w.len() != out.len() * v.len()` or `v` is empty.
#[inline]
pub fn estimate_scale_free(w: &[f32], v: &[f32], out: &mut [f32]) -> f32 {
    let m = v.len();
    assert!(m > 0 && w.len() == out.len() * m, "w must be n x m");
    let s = scale(v);
    let head = &v[..m - 1];
    for (row, o) in w.chunks_exact(m).zip(out.iter_mut()) {
        let mut acc = 0.0f32;
        for (wi, x) in row[..m - 1].iter().zip(head) {
            acc += *wi * *x;
        }
        acc += row[m - 1] * s;
        *o = acc;
    }
    s
}

/// Scale-free estimate of one point in the root form (`crate::blob`'s flag
/// bit 3): the kernel's input `x = [v_0 .. v_{m-2}, s] / sqrt(s)`
/// (`crate::kernel::root_scales`), `out[j] = (sum_i w[j*m+i] x[i])^2`
/// accumulated in index order (unfused), never negative. Returns
/// `(s, sqrt(s))`; readings of no light give an estimate of 0.
///
/// # Panics
/// If `w.len() != out.len() * v.len()` or `v` is empty.
#[inline]
pub fn estimate_scale_free_root(w: &[f32], v: &[f32], out: &mut [f32]) -> (f32, f32) {
    let m = v.len();
    assert!(m > 0 && w.len() == out.len() * m, "w must be n x m");
    let s = scale(v);
    let (sqrt_s, r) = crate::kernel::root_scales(s);
    for (row, o) in w.chunks_exact(m).zip(out.iter_mut()) {
        let mut acc = 0.0f32;
        for (i, wi) in row.iter().enumerate() {
            let x = if i + 1 == m { s } else { v[i] };
            acc += *wi * (x * r);
        }
        *o = acc * acc;
    }
    (s, sqrt_s)
}

/// Piecewise scale-free estimate: picks the cluster with the device's rule
/// ([`crate::kernel::select_cluster`], nearest centroid of `v / sum|v|`),
/// then [`estimate_scale_free`] with that cluster's matrix. `ws` holds K
/// matrices n x m back to back, `centroids` K x m. Returns (cluster, scale).
///
/// # Panics
/// If the lengths disagree.
#[inline]
pub fn estimate_scale_free_piecewise(ws: &[f32], centroids: &[f32], v: &[f32], out: &mut [f32]) -> (usize, f32) {
    let nm = out.len() * v.len();
    let c = crate::kernel::select_cluster(centroids, v);
    assert!(ws.len() == nm * (centroids.len() / v.len()), "ws must be K x n x m");
    let s = estimate_scale_free(&ws[c * nm..(c + 1) * nm], v, out);
    (c, s)
}

/// Number of packed entries of the whitening matrix for m readings.
pub const fn whitening_len(m: usize) -> usize {
    m * (m - 1) / 2
}

/// The out-of-prior statistic `d2 = |G (v'/s - mean)|^2` (see the module
/// docs), the linear form. `g` is packed lower triangular (m-1) x (m-1)
/// ([`whitening_len`]), `mean` the prior's mean of `u'` (m-1 values), `s`
/// the readings' scale ([`scale`]; [`estimate_scale_free`] returns it).
/// Not positive or not finite `s`: `+inf`.
///
/// # Panics
/// If `mean.len() + 1 != v.len()` or `g.len() != whitening_len(v.len())`.
#[inline]
pub fn out_of_prior_stat(g: &[f32], mean: &[f32], v: &[f32], s: f32) -> f32 {
    let m = v.len();
    let Some(inv) = inverse_scale(g, mean, v, s) else {
        return f32::INFINITY;
    };
    // The centred normalised readings, computed once into a small buffer
    // (zeroing a larger one costs the device more than the statistic); more
    // readings than it holds are recomputed per use, with the same bits.
    let mut held = [0.0f32; HELD];
    let fits = m - 1 <= HELD;
    if fits {
        for i in 0..m - 1 {
            held[i] = v[i] * inv - mean[i];
        }
    }
    whitened_norm2(g, m - 1, |i| if fits { held[i] } else { v[i] * inv - mean[i] })
}

/// Readings' shares below this are read as this before their logarithm
/// ([`out_of_prior_stat_log_ratio`]): a share that small is the sensor's
/// noise, and the logarithm of noise around zero would be the statistic.
pub const LOG_RATIO_FLOOR: f32 = 1.0e-3;

/// `ln(max(x / s, LOG_RATIO_FLOOR))` with `inv = 1 / s`: libm's `logf`,
/// plain f32 operations, so the same bits on the device and the host.
#[inline]
fn log_share(x: f32, inv: f32) -> f32 {
    let u = x * inv;
    libm::logf(if u > LOG_RATIO_FLOOR { u } else { LOG_RATIO_FLOOR })
}

/// The out-of-prior statistic of the log-ratio form (`crate::blob`'s flag
/// bit 4; see the module docs): `d2 = |G (l' - mean)|^2` where `l_i =
/// ln(max(v_i / s, LOG_RATIO_FLOOR)) - (1/m) sum_k ln(max(v_k / s, ...))`
/// (the centred log shares, whose last is redundant and dropped). `g`,
/// `mean` and `s` as for [`out_of_prior_stat`], with the prior's moments
/// of `l'`. Not positive or not finite `s`: `+inf`.
///
/// # Panics
/// If `mean.len() + 1 != v.len()` or `g.len() != whitening_len(v.len())`.
#[inline]
pub fn out_of_prior_stat_log_ratio(g: &[f32], mean: &[f32], v: &[f32], s: f32) -> f32 {
    let m = v.len();
    let Some(inv) = inverse_scale(g, mean, v, s) else {
        return f32::INFINITY;
    };
    // The logarithms are the statistic's cost: computed once into the
    // buffer when they fit, recomputed per use (same bits) when not.
    let mut held = [0.0f32; HELD];
    let fits = m <= HELD;
    let mut sum = 0.0f32;
    for (i, x) in v.iter().enumerate() {
        let l = log_share(*x, inv);
        if fits {
            held[i] = l;
        }
        sum += l;
    }
    let centre = sum / m as f32;
    whitened_norm2(g, m - 1, |i| (if fits { held[i] } else { log_share(v[i], inv) }) - centre - mean[i])
}

/// Which out-of-prior statistic a calibration's model is for (`crate::blob`
/// records it in flag bit 4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OutOfPriorForm {
    /// [`out_of_prior_stat`]: the shares themselves.
    Linear,
    /// [`out_of_prior_stat_log_ratio`]: their centred logarithms.
    LogRatio,
}

impl OutOfPriorForm {
    /// Its name in reports and files: `linear` or `log-ratio`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Linear => "linear",
            Self::LogRatio => "log-ratio",
        }
    }

    /// This form's statistic of readings `v` with scale `s`.
    #[inline]
    pub fn stat(self, g: &[f32], mean: &[f32], v: &[f32], s: f32) -> f32 {
        match self {
            Self::Linear => out_of_prior_stat(g, mean, v, s),
            Self::LogRatio => out_of_prior_stat_log_ratio(g, mean, v, s),
        }
    }
}

/// Both statistics' checks: `1 / s`, or `None` when `s` is not positive
/// and finite (the statistic is then `+inf`).
///
/// # Panics
/// If `mean.len() + 1 != v.len()` or `g.len() != whitening_len(v.len())`.
#[inline(always)]
fn inverse_scale(g: &[f32], mean: &[f32], v: &[f32], s: f32) -> Option<f32> {
    let m = v.len();
    assert!(m >= 2 && mean.len() == m - 1 && g.len() == whitening_len(m), "g, mean and v disagree");
    // NaN is neither positive nor finite: caught here too.
    (s.is_finite() && s > 0.0).then(|| 1.0 / s)
}

/// Readings the statistics hold in a stack buffer (more are recomputed).
const HELD: usize = 16;

/// `|G x|^2` for packed lower-triangular `g` ((m1 (m1 + 1)) / 2 entries,
/// row by row) and `x(i)`, i < m1, accumulated row by row in index order.
#[inline(always)]
fn whitened_norm2(g: &[f32], m1: usize, x: impl Fn(usize) -> f32) -> f32 {
    let mut d2 = 0.0f32;
    let mut off = 0;
    for k in 0..m1 {
        let mut y = 0.0f32;
        for i in 0..=k {
            y += g[off + i] * x(i);
        }
        off += k + 1;
        d2 += y * y;
    }
    d2
}

/// Per-bin standard uncertainty of a scale-free estimate: the blob's
/// uncertainty per unit scale times `|s|`.
#[inline]
pub fn scaled_uncertainty(sigma_unit: &[f32], s: f32, out: &mut [f32]) {
    assert_eq!(sigma_unit.len(), out.len());
    let a = s.abs();
    for (o, x) in out.iter_mut().zip(sigma_unit) {
        *o = *x * a;
    }
}

/// One bin's standard uncertainty of a root-form estimate (`crate::blob`'s
/// flag bit 3): with the root's uncertainty per unit scale `sigma` and the
/// estimate `rho = t^2 / s`, `sigma (2 sqrt(rho s) + sqrt(2) s sigma)`, an
/// upper bound within 1.21x of the standard deviation of `(t + e)^2 / s`
/// for a normal root error `e` of standard deviation `s sigma`
/// (`sqrt(4 t^2 sigma^2 + 2 s^2 sigma^4)`). So the uncertainty follows the
/// point: large on its lobe, small in its dark tails.
#[inline]
pub fn root_uncertainty(sigma: f32, rho: f32, s: f32) -> f32 {
    let s = s.abs();
    sigma * (2.0 * crate::kernel::sqrt0(rho * s) + core::f32::consts::SQRT_2 * s * sigma)
}

/// A point's `sigma_scale` (the frame's, what its per-bin uncertainties
/// are computed with): its scale `s`, and for a point the out-of-prior flag
/// raised, the calibration's band factor `f` applied to the unit
/// uncertainty through it: `f^2 s` in the root form (exactly,
/// `root_uncertainty(sigma, rho, f^2 s)` is `root_uncertainty(f sigma,
/// rho, s)`), `f s` in the linear form.
#[inline]
pub fn flagged_sigma_scale(s: f32, f: f32, root: bool) -> f32 {
    if root { s * (f * f) } else { s * f }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flagged_points_scale_widens_its_unit_uncertainty_by_the_factor() {
        let (sigma, rho, s, f) = (0.03f32, 0.7f32, 2.5f32, 1.75f32);
        let wide = root_uncertainty(sigma, rho, flagged_sigma_scale(s, f, true));
        let want = root_uncertainty(f * sigma, rho, s);
        assert!((wide - want).abs() <= 4.0 * f32::EPSILON * want, "{wide} {want}");
        assert_eq!(flagged_sigma_scale(s, f, false), s * f);
        assert_eq!(flagged_sigma_scale(s, 1.0, true), s);
    }

    /// More readings than the statistic's buffer holds: the recomputed path
    /// gives the same bits as the straightforward definition.
    #[test]
    fn the_statistic_is_the_same_for_many_readings() {
        for m in [7usize, 17, 18, 24] {
            let v: [f32; 24] = core::array::from_fn(|i| 0.5 + ((i * 7) % 5) as f32 * 0.25);
            let mean: [f32; 23] = core::array::from_fn(|i| 0.03 + (i % 3) as f32 * 0.01);
            let g: [f32; 276] = core::array::from_fn(|k| ((k * 13 % 7) as f32 - 3.0) * 0.5);
            let (v, mean, g) = (&v[..m], &mean[..m - 1], &g[..whitening_len(m)]);
            let s = scale(v);
            let inv = 1.0 / s;
            let (mut want, mut off) = (0.0f32, 0);
            for k in 0..m - 1 {
                let mut y = 0.0f32;
                for i in 0..=k {
                    y += g[off + i] * (v[i] * inv - mean[i]);
                }
                off += k + 1;
                want += y * y;
            }
            assert_eq!(out_of_prior_stat(g, mean, v, s).to_bits(), want.to_bits(), "m = {m}");
            assert!(want > 0.0);
        }
    }

    fn sample_w(n: usize, m: usize) -> alloc_free::Buf {
        let mut w = alloc_free::Buf::default();
        for k in 0..n * m {
            w.0[k] = ((k * 37 % 11) as f32 - 5.0) * 0.125;
        }
        w
    }

    // Fixed-size buffers: the library allocates nothing, nor do its tests need to.
    mod alloc_free {
        pub struct Buf(pub [f32; 256]);
        impl Default for Buf {
            fn default() -> Self {
                Self([0.0; 256])
            }
        }
    }

    #[test]
    fn estimate_is_w_prime_v_plus_scale_times_offset() {
        let (n, m) = (9, 4);
        let w = sample_w(n, m);
        let w = &w.0[..n * m];
        let v = [0.5f32, 1.25, 0.75, 2.0];
        let mut out = [0.0f32; 9];
        let s = estimate_scale_free(w, &v, &mut out);
        assert_eq!(s, 4.5);
        for j in 0..n {
            let r = &w[j * m..(j + 1) * m];
            let want = r[0] as f64 * 0.5 + r[1] as f64 * 1.25 + r[2] as f64 * 0.75 + r[3] as f64 * 4.5;
            assert!((out[j] as f64 - want).abs() < 1e-5, "{j}");
        }
    }

    #[test]
    fn estimate_scales_with_the_readings() {
        let (n, m) = (9, 4);
        let w = sample_w(n, m);
        let w = &w.0[..n * m];
        let v = [0.31f32, 1.7, 0.05, 0.9];
        let (mut a, mut b) = ([0.0f32; 9], [0.0f32; 9]);
        estimate_scale_free(w, &v, &mut a);
        // A power of two: exactly, bit for bit.
        let v4 = v.map(|x| x * 4.0);
        estimate_scale_free(w, &v4, &mut b);
        for j in 0..n {
            assert_eq!(b[j], a[j] * 4.0);
        }
        // Any other factor: within f32 rounding.
        let v3 = v.map(|x| x * 3.7);
        estimate_scale_free(w, &v3, &mut b);
        for j in 0..n {
            assert!((b[j] - 3.7 * a[j]).abs() <= 1e-5 * (1.0 + (3.7 * a[j]).abs()), "{j}");
        }
    }

    #[test]
    fn statistic_is_the_whitened_distance_and_scale_free() {
        // m = 3: G = diag(2, 4) (packed: 2, 0, 4), mean (0.25, 0.25).
        let g = [2.0f32, 0.0, 4.0];
        let mean = [0.25f32, 0.25];
        let v = [0.5f32, 0.25, 0.25]; // s = 1, x = (0.25, 0)
        assert_eq!(out_of_prior_stat(&g, &mean, &v, scale(&v)), 0.25);
        let v8 = v.map(|x| x * 8.0);
        assert_eq!(out_of_prior_stat(&g, &mean, &v8, scale(&v8)), 0.25);
        let at_mean = [0.25f32, 0.25, 0.5];
        assert_eq!(out_of_prior_stat(&g, &mean, &at_mean, scale(&at_mean)), 0.0);
        // Off-diagonal term: G = [[1, 0], [1, 1]], x = (0.25, 0) -> y = (0.25, 0.25).
        let g2 = [1.0f32, 1.0, 1.0];
        assert_eq!(out_of_prior_stat(&g2, &mean, &v, 1.0), 0.125);
        assert_eq!(out_of_prior_stat(&g, &mean, &[0.0; 3], 0.0), f32::INFINITY);
        assert_eq!(out_of_prior_stat(&g, &mean, &[1.0, -2.0, 0.5], -0.5), f32::INFINITY);
        assert_eq!(out_of_prior_stat(&g, &mean, &[f32::NAN, 0.0, 0.0], f32::NAN), f32::INFINITY);
    }

    #[test]
    fn log_ratio_statistic_is_the_whitened_distance_of_centred_log_shares() {
        // G = I, mean 0: d2 = |l'|^2 with l the centred log shares.
        let g = [1.0f32, 0.0, 1.0];
        let v = [2.0f32, 1.0, 1.0];
        let s = scale(&v);
        let l = [0.5f32.ln(), 0.25f32.ln(), 0.25f32.ln()];
        let c = (l[0] + l[1] + l[2]) / 3.0;
        let want = (l[0] - c).powi(2) + (l[1] - c).powi(2);
        let d2 = out_of_prior_stat_log_ratio(&g, &[0.0; 2], &v, s);
        assert!((d2 - want).abs() <= 1e-6 * want, "{d2} {want}");
        // Scale-free: a power of two, bit for bit.
        let v8 = v.map(|x| x * 8.0);
        assert_eq!(out_of_prior_stat_log_ratio(&g, &[0.0; 2], &v8, scale(&v8)).to_bits(), d2.to_bits());
        // At the mean: zero. Equal shares have l' = 0.
        assert_eq!(out_of_prior_stat_log_ratio(&g, &[0.0; 2], &[3.0; 3], 9.0), 0.0);
        // A dark or negative reading is the floor, not -inf or NaN.
        // (The same scale passed for both, so only the dark shares differ.)
        let dark = out_of_prior_stat_log_ratio(&g, &[0.0; 2], &[1.0, 0.0, -0.25], 1.0);
        let floored = out_of_prior_stat_log_ratio(&g, &[0.0; 2], &[1.0, 1e-4, 1e-6], 1.0);
        assert!(dark.is_finite() && dark == floored, "{dark} {floored}");
        // Readings whose sum is not positive and finite: +inf.
        assert_eq!(out_of_prior_stat_log_ratio(&g, &[0.0; 2], &[0.0; 3], 0.0), f32::INFINITY);
        assert_eq!(out_of_prior_stat_log_ratio(&g, &[0.0; 2], &[f32::NAN, 0.0, 0.0], f32::NAN), f32::INFINITY);
        // The form's dispatch gives each function's bits.
        assert_eq!(OutOfPriorForm::LogRatio.stat(&g, &[0.0; 2], &v, s).to_bits(), d2.to_bits());
        let lin = out_of_prior_stat(&g, &[0.0; 2], &v, s);
        assert_eq!(OutOfPriorForm::Linear.stat(&g, &[0.0; 2], &v, s).to_bits(), lin.to_bits());
    }

    /// More readings than the buffer holds: the recomputed logarithms give
    /// the same bits as the buffered ones would.
    #[test]
    fn the_log_ratio_statistic_is_the_same_for_many_readings() {
        for m in [7usize, 16, 17, 24] {
            let v: [f32; 24] = core::array::from_fn(|i| 0.5 + ((i * 7) % 5) as f32 * 0.25);
            let mean: [f32; 23] = core::array::from_fn(|i| 0.03 + (i % 3) as f32 * 0.01);
            let g: [f32; 276] = core::array::from_fn(|k| ((k * 13 % 7) as f32 - 3.0) * 0.5);
            let (v, mean, g) = (&v[..m], &mean[..m - 1], &g[..whitening_len(m)]);
            let s = scale(v);
            let inv = 1.0 / s;
            let l: [f32; 24] = core::array::from_fn(|i| if i < m { log_share(v[i], inv) } else { 0.0 });
            let mut sum = 0.0f32;
            for x in &l[..m] {
                sum += *x;
            }
            let centre = sum / m as f32;
            let (mut want, mut off) = (0.0f32, 0);
            for k in 0..m - 1 {
                let mut y = 0.0f32;
                for i in 0..=k {
                    y += g[off + i] * (l[i] - centre - mean[i]);
                }
                off += k + 1;
                want += y * y;
            }
            assert_eq!(out_of_prior_stat_log_ratio(g, mean, v, s).to_bits(), want.to_bits(), "m = {m}");
            assert!(want > 0.0);
        }
    }

    #[test]
    fn piecewise_uses_the_selected_clusters_matrix() {
        let (n, m) = (3, 2);
        // Cluster 0: rho = s * 1; cluster 1: rho = s * 2 (last column multiplies s).
        let ws = [0.0f32, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 2.0, 0.0, 2.0, 0.0, 2.0];
        let centroids = [1.0f32, 0.0, 0.0, 1.0];
        let mut out = [0.0f32; 3];
        assert_eq!(estimate_scale_free_piecewise(&ws, &centroids, &[3.0, 1.0], &mut out), (0, 4.0));
        assert_eq!(out, [4.0; 3]);
        assert_eq!(estimate_scale_free_piecewise(&ws, &centroids, &[1.0, 3.0], &mut out), (1, 4.0));
        assert_eq!(out, [8.0; 3]);
        let _ = (n, m);
        let mut sig = [0.0f32; 2];
        scaled_uncertainty(&[0.5, 0.25], -4.0, &mut sig);
        assert_eq!(sig, [2.0, 1.0]);
    }
}
