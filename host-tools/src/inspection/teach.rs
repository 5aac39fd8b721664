//! Teaching a recipe from lines of a reference ("golden") sample.
//!
//! Per pixel the mean of the normalised readings `f = k v` (k the line's
//! scale, the device's, `brdf_meter::inspect::decide`) and their standard
//! deviations; per group (the calibration's zones, merged until the recipe
//! fits its slot) the correlation of the standardised readings pooled over
//! the group's pixels and lines, whitened by its Cholesky factor, and the
//! gloss readings' gradient at the reference, by central differences of the
//! device's own readings (`PointEstimator`) averaged over the group (one-sided
//! where the reference sits on the border of two of the gloss rows'
//! clusters, so the jump between them is not taken for a slope).
//!
//! The distance threshold is set from the false-call rate asked for: a
//! false call needs `k = min_pixels` adjacent pixels out at the leaving
//! threshold (the hysteresis times the entering one), one of them at the
//! entering threshold, as the device decides. With each pixel out at them
//! with probabilities `q_off` and `q_on` (chi-square of m - 1 degrees of
//! freedom), that is `q_off^k - (q_off - q_on)^k` per place along the line,
//! and the threshold is where P places give the rate
//! ([`distance_threshold`]), times Hotelling's factor
//! `(N+1)(N-1) / (N (N-m+1))` for a mean and covariance estimated from N
//! lines. It assumes independent Gaussian pixels, which the handheld's are
//! not: the actual rate is measured by `inspection::roc`, never assumed.
//!
//! Refused, with the reason: fewer lines than [`MIN_LINES`]; a reference
//! whose points are saturated, under-exposed or not finite (in more than
//! 1 % of a pixel's lines); a reference the calibration flags out of its
//! prior in more than [`MAX_OUT_OF_PRIOR`] of its points (it flags about
//! 5 % of materials inside its prior by design).
use super::lines::{DeviceModel, Line};
use brdf_meter::inspect::recipe::{self, DelayUnit, RecipeData, RecipeSettings, group_len, pixel_len};
use brdf_meter::protocol::flags;
use brdf_meter::shape::{LEDS as M, READINGS};
use nalgebra::{DMatrix, SVector};

/// The slope of a reading from its values a step `h` above (`a`), at (`c`)
/// and below (`b`) the reference. The readings are smooth but for the
/// gloss rows' cluster choice, which jumps where the reference sits on the
/// border of two clusters (GU apart): a step across that border is a jump,
/// not a slope, and it would make the gradient of the whole group. Where
/// the two one-sided differences disagree, the smaller is the slope; else
/// the central difference.
fn slope(a: f64, c: f64, b: f64, h: f64) -> f64 {
    let (fwd, bwd) = ((a - c) / h, (c - b) / h);
    if (fwd - bwd).abs() <= 0.5 * fwd.abs().max(bwd.abs()) + 1e-9 {
        (a - b) / (2.0 * h)
    } else if fwd.abs() < bwd.abs() {
        fwd
    } else {
        bwd
    }
}

/// The leaving thresholds' share of the entering ones, by default. Along
/// the line it lets a defect's noisy pixel stay part of it; the lower it
/// is, the more a window close to the reference's own noise calls falsely.
/// On the handheld (gloss window +-1.5 GU, 0.55 GU of noise per pixel,
/// `inspect roc`): 0.85 keeps the asked false-call rate at the recipe's
/// operating point and finds a 2 GU step over 8 pixels in 99.3 % of lines
/// there; 0.7 finds 99.5 % at the same rate, but only with every threshold
/// raised by 9 %: as taught it calls 20 times the rate asked for.
pub const HYSTERESIS: f32 = 0.85;

/// Fewest lines a recipe is taught from.
pub const MIN_LINES: usize = 50;
/// Largest share of the reference's points out of the calibration's prior.
pub const MAX_OUT_OF_PRIOR: f64 = 0.2;

/// A tolerance window on one gloss reading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Window {
    /// No window.
    Off,
    /// The lowest and highest change allowed, in the reading's unit.
    Absolute(f64, f64),
    /// The same in % of the reference's mean reading over the line.
    Relative(f64, f64),
}

impl std::str::FromStr for Window {
    type Err = String;
    /// `off`, `LO:HI` (in the reading's unit) or `LO%:HI%`.
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "off" {
            return Ok(Self::Off);
        }
        let (lo, hi) = s.split_once(':').ok_or_else(|| format!("`{s}`: expected LO:HI, LO%:HI% or off"))?;
        let rel = lo.ends_with('%') && hi.ends_with('%');
        let num = |x: &str| x.trim_end_matches('%').parse::<f64>().map_err(|_| format!("`{s}`: `{x}` is not a number"));
        let (lo, hi) = (num(lo)?, num(hi)?);
        if !(lo <= 0.0 && hi >= 0.0 && lo < hi) {
            return Err(format!("`{s}`: a window must hold the reference (LO <= 0 <= HI, LO < HI)"));
        }
        Ok(if rel { Self::Relative(lo, hi) } else { Self::Absolute(lo, hi) })
    }
}

/// What to teach.
#[derive(Clone, Debug)]
pub struct TeachSpec {
    /// False calls per defect-free line the distance threshold is set for.
    pub false_call_rate: f64,
    /// Gloss, haze and distinctness windows.
    pub windows: [Window; READINGS],
    /// Smallest defect in pixels and in lines.
    pub min_pixels: u16,
    /// Smallest defect in lines.
    pub min_lines: u16,
    /// Leaving thresholds as a share of the entering ones.
    pub hysteresis: f32,
    /// Drift EWMA weight.
    pub ewma_lambda: f32,
    /// Drift alarm in standard deviations of the EWMA, or a limit in GU.
    pub drift_limit: DriftLimit,
    /// Reject pulse length, us.
    pub pulse_us: u32,
    /// Reject delay and its unit.
    pub delay: (u32, DelayUnit),
    /// The user's version number.
    pub version: u32,
    /// Bytes the signed recipe may take (the slot less its header).
    pub max_bytes: usize,
}

/// The drift alarm's limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DriftLimit {
    /// This many standard deviations of the EWMA of the reference's line means.
    Sigmas(f64),
    /// A fixed limit, GU.
    Gu(f64),
}

impl Default for TeachSpec {
    fn default() -> Self {
        Self {
            false_call_rate: 1e-4,
            windows: [Window::Absolute(-1.5, 1.5), Window::Off, Window::Off],
            min_pixels: 3,
            min_lines: 1,
            hysteresis: HYSTERESIS,
            ewma_lambda: 0.1,
            drift_limit: DriftLimit::Sigmas(4.0),
            pulse_us: 25_000,
            delay: (0, DelayUnit::Lines),
            version: 1,
            max_bytes: brdf_meter::shape::board::RECIPE_SLOT_LEN as usize
                - brdf_meter::store::SLOT_HEADER_LEN
                - brdf_meter::signed::TRAILER_LEN,
        }
    }
}

/// What teaching found, for the user.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TeachReport {
    /// Lines taught.
    pub lines: usize,
    /// Groups.
    pub groups: usize,
    /// The distance threshold (to enter, `d2`).
    pub threshold: f32,
    /// Per reading, the median over pixels of its standard deviation in
    /// the reference (NaN: no reading).
    pub reading_sd: [f64; READINGS],
    /// Per reading, the reference's mean over the line.
    pub reading_mean: [f64; READINGS],
    /// The windows as changes, in the readings' units.
    pub windows: [[f32; 2]; READINGS],
    /// Teach quality: the smallest window half-width over 3 standard
    /// deviations of the reference's own noise (>= 1: the tolerance stands
    /// beyond the reference's +-3 sd).
    pub quality: f64,
    /// Pixels with no gloss reading (their windows cannot apply).
    pub no_reading_pixels: usize,
    /// Share of the reference's points the calibration flags out of prior.
    pub out_of_prior: f64,
    /// The drift alarm's limit, GU.
    pub drift_limit_gu: f32,
    /// Recipe bytes (unsigned).
    pub bytes: usize,
}

/// A taught recipe.
pub struct Taught {
    /// The recipe's contents.
    pub data: RecipeData,
    /// The recipe's bytes (unsigned).
    pub bytes: Vec<u8>,
    /// What teaching found.
    pub report: TeachReport,
}

/// Teaches a recipe from `lines` of the reference through `model`.
pub fn teach(model: &DeviceModel<'_>, lines: &[Line], spec: &TeachSpec) -> anyhow::Result<Taught> {
    let p = model.pixels();
    let n = lines.len();
    anyhow::ensure!(
        n >= MIN_LINES,
        "{n} lines of the reference are too few to teach from: measure at least {MIN_LINES} (the covariance of {M} readings per pixel needs them)"
    );
    // Refusals: an unreadable or out-of-prior reference.
    const UNREADABLE: u8 = flags::SATURATED | flags::UNDER_EXPOSED | flags::NON_FINITE;
    let bad: Vec<usize> =
        (0..p).filter(|&px| lines.iter().filter(|l| l.flags[px] & UNREADABLE != 0).count() * 100 > n).collect();
    anyhow::ensure!(
        bad.is_empty(),
        "the reference is saturated, under-exposed or not finite at {} pixel(s) ({}): a recipe cannot be taught on readings the device cannot read; check the sample, the exposure and the calibration",
        bad.len(),
        pixel_list(&bad)
    );
    let mut oop = 0usize;
    for l in lines {
        oop += (0..p).filter(|&px| model.out_of_prior(px, &l.v[px])).count();
    }
    let oop_share = oop as f64 / (n * p) as f64;
    anyhow::ensure!(
        oop_share <= MAX_OUT_OF_PRIOR,
        "the calibration flags {:.0} % of the reference's points out of its prior (at most {:.0} % allowed): it cannot read this sample reliably; calibrate on a prior that holds it",
        100.0 * oop_share,
        100.0 * MAX_OUT_OF_PRIOR
    );
    // Normalised readings, per pixel: mean and sd. The line scale is the
    // device's (`brdf_meter::inspect::decide::line_scale`): 1 over the
    // median of the pixels' sums over their reference's; the reference
    // sums are the normalised means' own, so two rounds settle them.
    let sums: Vec<Vec<f64>> =
        lines.iter().map(|l| l.v.iter().map(|v| v.iter().map(|x| *x as f64).sum()).collect()).collect();
    let mut reference: Vec<f64> = (0..p).map(|px| sums.iter().map(|s| s[px]).sum::<f64>() / n as f64).collect();
    let mut scales = vec![1.0f64; n];
    for _ in 0..2 {
        for (k, s) in sums.iter().enumerate() {
            let mut r: Vec<f64> = (0..p).map(|px| s[px] / reference[px]).filter(|x| x.is_finite()).collect();
            r.sort_by(f64::total_cmp);
            scales[k] = 1.0 / r[r.len() / 2];
        }
        reference = (0..p).map(|px| sums.iter().zip(&scales).map(|(s, k)| k * s[px]).sum::<f64>() / n as f64).collect();
    }
    // Per line and pixel, the normalised readings.
    let normed: Vec<Vec<SVector<f64, M>>> =
        lines.iter().zip(&scales).map(|(l, k)| l.v.iter().map(|v| v.map(|x| x as f64) * *k).collect()).collect();
    let mean: Vec<SVector<f64, M>> =
        (0..p).map(|px| normed.iter().map(|l| l[px]).sum::<SVector<f64, M>>() / n as f64).collect();
    let sd: Vec<SVector<f64, M>> = (0..p)
        .map(|px| {
            let ss = normed.iter().map(|l| (l[px] - mean[px]).map(|x| x * x)).sum::<SVector<f64, M>>();
            (ss / (n - 1) as f64).map(f64::sqrt)
        })
        .collect();
    // The device computes with the f32 mean: its sum is the reference scale.
    let mean32: Vec<[f32; M]> = mean.iter().map(|m| core::array::from_fn(|i| m[i] as f32)).collect();
    // Groups: the calibration's zones, merged evenly until the recipe fits.
    let zone_starts: Vec<usize> =
        (0..p).filter(|&px| px == 0 || model.blob().zone_of_pixel(px) != model.blob().zone_of_pixel(px - 1)).collect();
    let mut groups = zone_starts.len();
    while groups > 1 && recipe::recipe_len(p, M, groups) > spec.max_bytes {
        groups -= 1;
    }
    let starts: Vec<usize> =
        if groups == zone_starts.len() { zone_starts } else { (0..groups).map(|g| g * p / groups).collect() };
    anyhow::ensure!(
        recipe::recipe_len(p, M, groups) <= spec.max_bytes,
        "a recipe for {p} pixels needs {} bytes, more than the slot's {}",
        recipe::recipe_len(p, M, groups),
        spec.max_bytes
    );
    let ends: Vec<usize> = starts.iter().skip(1).copied().chain([p]).collect();
    // Per pixel, the gloss readings' gradient at the reference (device's own readings).
    let gradient = |px: usize| -> DMatrix<f64> {
        let mut j = DMatrix::zeros(READINGS, M);
        for i in 0..M {
            let h = 1e-3 * mean[px][i].abs().max(1e-3);
            let at = |s: f64| {
                let mut v = mean[px];
                v[i] += s * h;
                model.estimate(px, &v.map(|x| x as f32)).readings
            };
            let (a, c, b) = (at(1.0), at(0.0), at(-1.0));
            for r in 0..READINGS {
                j[(r, i)] = slope(a[r].into(), c[r].into(), b[r].into(), h);
            }
        }
        j
    };
    let grads: Vec<DMatrix<f64>> = (0..p).map(gradient).collect();
    let has_reading = |px: usize| grads[px].iter().all(|x| x.is_finite());
    let mut group_values = Vec::with_capacity(groups);
    for (&a, &b) in starts.iter().zip(&ends) {
        // Pooled correlation of the first m - 1 standardised readings.
        let d = M - 1;
        let mut r = DMatrix::<f64>::zeros(d, d);
        let mut count = 0usize;
        for px in a..b {
            for l in &normed {
                let f = l[px];
                let z: Vec<f64> = (0..d).map(|i| (f[i] - mean[px][i]) / sd[px][i]).collect();
                for i in 0..d {
                    for k in 0..d {
                        r[(i, k)] += z[i] * z[k];
                    }
                }
                count += 1;
            }
        }
        r /= (count - 1) as f64;
        let chol = r.clone().cholesky().ok_or_else(|| {
            anyhow::anyhow!("pixels {a}..{b}: the reference's readings are degenerate (a reading constant over every line); the sensor may be saturated or dark")
        })?;
        let linv = chol.l().solve_lower_triangular(&DMatrix::identity(d, d)).expect("a Cholesky factor is regular");
        let mut values = Vec::with_capacity(group_len(M));
        for i in 0..d {
            for k in 0..=i {
                values.push(linv[(i, k)] as f32);
            }
        }
        let with: Vec<usize> = (a..b).filter(|&px| has_reading(px)).collect();
        for r in 0..READINGS {
            for i in 0..M {
                let g = if with.is_empty() {
                    0.0
                } else {
                    with.iter().map(|&px| grads[px][(r, i)]).sum::<f64>() / with.len() as f64
                };
                values.push(g as f32);
            }
        }
        group_values.push(values);
    }
    let group_of = |px: usize| starts.iter().rposition(|&s| s <= px).expect("group 0 starts at 0");
    // The readings' change per line and pixel through the recipe's gradient (for sd and drift).
    let delta = |l: &[SVector<f64, M>], px: usize| -> [f64; READINGS] {
        let f = l[px];
        let g = &group_values[group_of(px)];
        let off = (M - 1) * M / 2;
        core::array::from_fn(|r| (0..M).map(|i| g[off + r * M + i] as f64 * (f[i] - mean[px][i])).sum())
    };
    let with_reading: Vec<usize> = (0..p).filter(|&px| has_reading(px)).collect();
    let mut reading_sd = [f64::NAN; READINGS];
    let mut reading_mean = [f64::NAN; READINGS];
    if !with_reading.is_empty() {
        for r in 0..READINGS {
            let mut sds: Vec<f64> = with_reading
                .iter()
                .map(|&px| (normed.iter().map(|l| delta(l, px)[r].powi(2)).sum::<f64>() / (n - 1) as f64).sqrt())
                .collect();
            sds.sort_by(f64::total_cmp);
            reading_sd[r] = sds[sds.len() / 2];
            reading_mean[r] = with_reading
                .iter()
                .map(|&px| model.estimate(px, &mean[px].map(|x| x as f32)).readings[r] as f64)
                .sum::<f64>()
                / with_reading.len() as f64;
        }
    }
    let windows: [[f32; 2]; READINGS] = core::array::from_fn(|r| match spec.windows[r] {
        Window::Off => [f32::NEG_INFINITY, f32::INFINITY],
        Window::Absolute(lo, hi) => [lo as f32, hi as f32],
        Window::Relative(lo, hi) => {
            [(lo / 100.0 * reading_mean[r].abs()) as f32, (hi / 100.0 * reading_mean[r].abs()) as f32]
        }
    });
    let quality = (0..READINGS)
        .filter(|&r| windows[r][0].is_finite() || windows[r][1].is_finite())
        .map(|r| (windows[r][0].abs().min(windows[r][1].abs()) as f64) / (3.0 * reading_sd[r]))
        .fold(f64::INFINITY, f64::min);
    // Drift: the weighted line mean of the gloss change.
    let w = if with_reading.is_empty() { 0.0 } else { 1.0 / with_reading.len() as f64 };
    let line_means: Vec<f64> =
        normed.iter().map(|l| with_reading.iter().map(|&px| w * delta(l, px)[0]).sum()).collect();
    let lm = line_means.iter().sum::<f64>() / n as f64;
    let line_sd = (line_means.iter().map(|x| (x - lm).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
    let lambda = spec.ewma_lambda as f64;
    let drift_limit = match spec.drift_limit {
        DriftLimit::Gu(g) => g,
        DriftLimit::Sigmas(k) => k * line_sd * (lambda / (2.0 - lambda)).sqrt(),
    };
    let drift_limit = if drift_limit > 0.0 && drift_limit.is_finite() { drift_limit } else { f64::from(f32::MAX) };
    // The distance threshold from the false-call rate.
    let nf = n as f64;
    let hotelling = (nf + 1.0) * (nf - 1.0) / (nf * (nf - (M - 1) as f64));
    let chi2 = distance_threshold((M - 1) as f64, spec.hysteresis as f64, spec.min_pixels, p, spec.false_call_rate);
    let threshold = (chi2 * hotelling) as f32;
    let pixel_values = (0..p)
        .map(|px| {
            let mut v = Vec::with_capacity(pixel_len(M));
            v.extend_from_slice(&mean32[px]);
            v.extend((0..M - 1).map(|i| (1.0 / sd[px][i]) as f32));
            v.push(1.0 / mean32[px].iter().sum::<f32>());
            v.push(if has_reading(px) { w as f32 } else { 0.0 });
            v
        })
        .collect();
    let settings = RecipeSettings {
        calibration_crc: model.blob().crc(),
        version: spec.version,
        threshold_on: threshold,
        threshold_off: threshold * spec.hysteresis,
        min_pixels: spec.min_pixels,
        min_lines: spec.min_lines,
        ewma_lambda: spec.ewma_lambda,
        ewma_limit: drift_limit as f32,
        pulse_us: spec.pulse_us,
        delay: spec.delay.0,
        delay_unit: spec.delay.1,
        window_hysteresis: spec.hysteresis,
        windows,
        teach_quality: if quality.is_finite() { quality as f32 } else { 0.0 },
        teach_lines: n as u32,
        along_line_hysteresis: true,
    };
    let data = RecipeData {
        pixels: p,
        m: M,
        group_starts: starts.iter().map(|&s| s as u16).collect(),
        group_values,
        pixel_values,
        settings,
    };
    let bytes = recipe::write(&data)
        .map_err(|e| anyhow::anyhow!("the taught recipe is invalid ({e:?}): {:?}", data.settings))?;
    let report = TeachReport {
        lines: n,
        groups,
        threshold,
        reading_sd,
        reading_mean,
        windows,
        quality,
        no_reading_pixels: p - with_reading.len(),
        out_of_prior: oop_share,
        drift_limit_gu: drift_limit as f32,
        bytes: bytes.len(),
    };
    Ok(Taught { data, bytes, report })
}

fn pixel_list(px: &[usize]) -> String {
    let shown: Vec<String> = px.iter().take(8).map(|p| p.to_string()).collect();
    if px.len() > 8 { format!("{}, ...", shown.join(", ")) } else { shown.join(", ") }
}

/// The chi-square value t of `dof` degrees of freedom at which a line of
/// `pixels` independent pixels has a false call with probability `rate`
/// when a call needs `min_pixels` adjacent pixels above `hysteresis` x t,
/// one of them above t (see the module docs; `hysteresis` 1 gives the
/// quantile at `1 - (rate / pixels)^(1 / min_pixels)`).
pub fn distance_threshold(dof: f64, hysteresis: f64, min_pixels: u16, pixels: usize, rate: f64) -> f64 {
    let k = i32::from(min_pixels.max(1));
    let per_place = |t: f64| {
        let (on, off) = (upper_gamma(dof / 2.0, t / 2.0), upper_gamma(dof / 2.0, hysteresis * t / 2.0));
        off.powi(k) - (off - on).max(0.0).powi(k)
    };
    let target = rate / pixels.max(1) as f64;
    let (mut lo, mut hi) = (0.0f64, dof.max(1.0));
    while per_place(hi) > target {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if per_place(mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The chi-square distribution's quantile: x with `P(X <= x) = prob` for
/// `k` degrees of freedom (bisection on the regularised lower incomplete gamma).
pub fn chi_square_quantile(k: f64, prob: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, k.max(1.0));
    while upper_gamma(k / 2.0, hi / 2.0) > 1.0 - prob {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if upper_gamma(k / 2.0, mid / 2.0) > 1.0 - prob {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The regularised upper incomplete gamma `Q(a, x)` (statrs's, which
/// refuses `x <= 0`, where `Q` is 1).
fn upper_gamma(a: f64, x: f64) -> f64 {
    if x <= 0.0 { 1.0 } else { statrs::function::gamma::gamma_ur(a, x) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_jump_between_gloss_clusters_is_not_taken_for_a_slope() {
        let h = 1e-3;
        // Smooth (slope 3, a little curvature): the central difference.
        let f = |x: f64| 3.0 * x + 0.5 * x * x;
        assert!((slope(f(h), f(0.0), f(-h), h) - 3.0).abs() < 1e-9);
        // The step above the reference crosses to a cluster 2.2 GU higher:
        // the slope below it, not 1,100 GU per unit.
        assert!((slope(f(h) + 2.2, f(0.0), f(-h), h) - 3.0).abs() < 1e-3);
        // The step below crosses: the slope above it.
        assert!((slope(f(h), f(0.0), f(-h) - 2.2, h) - 3.0).abs() < 1e-3);
        // No reading stays no reading.
        assert!(slope(f64::NAN, f64::NAN, f64::NAN, h).is_nan());
    }

    #[test]
    fn the_distance_threshold_holds_the_rate_with_hysteresis_along_the_line() {
        // Without hysteresis: every pixel of the run out at t.
        let plain = distance_threshold(6.0, 1.0, 3, 128, 1e-4);
        let q = (1e-4f64 / 128.0).powf(1.0 / 3.0);
        assert!((plain - chi_square_quantile(6.0, 1.0 - q)).abs() < 1e-6 * plain, "{plain}");
        // Its neighbours held at 0.7 t: a higher threshold for the same rate,
        // below the one that would let a single pixel out at that rate.
        let held = distance_threshold(6.0, 0.7, 3, 128, 1e-4);
        assert!(held > plain && held < chi_square_quantile(6.0, 1.0 - 1e-4 / 128.0), "{held} against {plain}");
        // And that rate is what it gives.
        let (on, off) = (upper_gamma(3.0, held / 2.0), upper_gamma(3.0, 0.7 * held / 2.0));
        let rate = 128.0 * (off.powi(3) - (off - on).powi(3));
        assert!((rate - 1e-4).abs() < 1e-9, "{rate}");
    }

    #[test]
    fn chi_square_quantiles_match_the_tables() {
        // Published values: chi2(6) at 0.95 = 12.592, at 0.999 = 22.458; chi2(1) at 0.95 = 3.841.
        for (k, p, x) in [(6.0, 0.95, 12.5916), (6.0, 0.999, 22.4577), (1.0, 0.95, 3.8415), (2.0, 1.0 - 1e-8, 36.841)] {
            let got = chi_square_quantile(k, p);
            assert!((got - x).abs() < 1e-3 * x, "chi2({k}) at {p}: {got}, table {x}");
        }
    }

    #[test]
    fn windows_parse_and_refuse_with_their_reason() {
        assert_eq!("-2:2".parse::<Window>(), Ok(Window::Absolute(-2.0, 2.0)));
        assert_eq!("-5%:5%".parse::<Window>(), Ok(Window::Relative(-5.0, 5.0)));
        assert_eq!("off".parse::<Window>(), Ok(Window::Off));
        assert!("1:2".parse::<Window>().unwrap_err().contains("must hold the reference"));
        assert!("2".parse::<Window>().unwrap_err().contains("expected LO:HI"));
    }
}
