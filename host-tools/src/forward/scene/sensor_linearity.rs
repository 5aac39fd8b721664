//! The factory's measurement of the sensor's linearity: an exposure sweep of
//! a steady source, from which the correction the device applies to every
//! reading (`brdf_meter::acquire::Linearity`) is fitted.
//!
//! The rig lights the whole line evenly, at a level that fills about 90 %
//! of the converter at the longest exposure, and takes a dark frame and a
//! lit frame at exposures falling by a quarter of an octave each, down to
//! about two counts, [`LINES`] times over. Exposure times are exact
//! (integer microseconds on the device), so the light a frame collects is
//! known up to one scale: `K e_j`. Its mean dark-corrected signal `s_j`
//! over the lines and pixels is what the sensor made of it; the fit asks
//! the correction to give the light back, `s_j f(s_j) = K e_j`, weighted by
//! each mean's standard error (measured from the spread, as a factory
//! would), with the factor 1 at the knot above the brightest frame (the
//! scale white calibration divides out anyway) and a weak smoothness tie
//! between neighbouring octaves, so a knot only the noisiest frames reach
//! stays near its neighbours. Knots below the dimmest frame take its
//! octave's factor; those above the brightest, 1.
//!
//! The sweep runs the scene's own light and sensor stages, noise included,
//! on the frames of lines `0..LINES` (the LEDs' drift over so few frames is
//! a common scale, which `K` absorbs).
use super::pipeline::{FrameCtx, Mode, Pipeline};
use anyhow::{Context, bail};
use brdf_meter::acquire::Linearity;
use brdf_meter::acquire::linearity::{FACTOR_RANGE, LINEARITY_KNOTS};
use nalgebra::{DMatrix, DVector};

/// Times the sweep is repeated (each a scene line, with its own noise).
pub const LINES: u64 = 16;

/// Frames per octave of exposure.
const STEPS_PER_OCTAVE: i32 = 4;

/// The source's level at the longest exposure, a share of full scale.
const TOP_LEVEL: f64 = 0.9;

/// Dimmest frame of the sweep, counts of light.
const BOTTOM_COUNTS: f64 = 2.0;

/// The variance of a whole count's rounding, counts^2.
const STEP_VARIANCE: f64 = 1.0 / 12.0;

/// How far a knot's factor may bend from the line through its neighbours'
/// before the tie costs as much as one frame's standard error (relative).
const SMOOTHNESS: f64 = 0.01;

/// What the sweep found.
#[derive(Clone, Debug)]
pub struct SensorLinearity {
    /// The correction, for the calibration blob.
    pub correction: Linearity,
    /// Frames of the sweep used (unsaturated exposures).
    pub exposures: usize,
    /// Root mean square of the fit's relative residuals over the frames
    /// the device would read (at least `brdf_meter::acquire::MIN_SIGNAL_COUNTS`).
    pub residual_rms: f64,
    /// Whether the sensor bends further than a correction may undo
    /// ([`brdf_meter::acquire::linearity::FACTOR_RANGE`]), so the fitted
    /// factors were limited and the dimmest readings stay partly bent.
    pub clamped: bool,
}

impl SensorLinearity {
    /// How much the correction raises a reading of `counts` against one of
    /// `reference` counts (about 0.037 for a sensor that reads 3.7 % low
    /// there, relative to the reference).
    pub fn bend(&self, counts: f64, reference: f64) -> f64 {
        let f = |c: f64| f64::from(self.correction.linear(c as f32)) / c;
        f(counts) / f(reference) - 1.0
    }
}

/// Measures the sensor of `pipeline` (`pixels` pixels, `m` LEDs, saturating
/// at `full_scale` counts) by an exposure sweep.
pub fn measure(pipeline: &Pipeline, m: usize, pixels: usize, full_scale: f64) -> anyhow::Result<SensorLinearity> {
    let top = TOP_LEVEL * full_scale;
    let steps = (f64::from(STEPS_PER_OCTAVE) * (top / BOTTOM_COUNTS).log2()).floor() as i32;
    let mut sweep = Vec::new();
    for j in 0..=steps {
        let e = 2f64.powf(-f64::from(j) / f64::from(STEPS_PER_OCTAVE));
        let (mut sum, mut sum2, mut n, mut saturated) = (0.0, 0.0, 0.0, false);
        for line in 0..LINES {
            let mut dark = vec![0.0; pixels];
            pipeline.run(&mut dark, &FrameCtx { line, frame: 0, m, exposure: e }, Mode::Full);
            let mut lit = vec![top * e; pixels];
            pipeline.run(&mut lit, &FrameCtx { line, frame: 1, m, exposure: e }, Mode::Full);
            for (l, d) in lit.iter().zip(&dark) {
                // The device's frames are whole counts: what the link carries.
                let (l, d) = (l.round().max(0.0), d.round().max(0.0));
                saturated |= l >= full_scale;
                sum += l - d;
                sum2 += (l - d) * (l - d);
                n += 1.0;
            }
        }
        if saturated {
            continue;
        }
        let mean = sum / n;
        // The spread's standard error, and the converter's step, which
        // averaging removes only where noise dithers it: a whole count's
        // rounding, at worst, stays in the mean.
        let se = ((sum2 / n - mean * mean).max(0.0) / (n - 1.0) + STEP_VARIANCE).sqrt();
        if mean >= 1.0 {
            sweep.push((e, mean, se));
        }
    }
    if sweep.len() < 2 * STEPS_PER_OCTAVE as usize {
        bail!(
            "the linearity sweep has only {} unsaturated frames above one count (full scale {full_scale}): \
             check the scene's sensor (gain, full scale, dark offset)",
            sweep.len()
        );
    }
    fit(&sweep).context("the sensor's linearity sweep")
}

/// [`measure`], once per sensor: the sweep is a function of the pipeline's
/// stages and the sensor's shape alone (every draw is seeded), and every
/// simulator of a scene (one per material an evaluation reads) would
/// otherwise sweep again, 4.4 ms each on the handheld (+39 % on a line
/// simulated from scratch, `examples/scene_speed`).
pub fn measure_once(pipeline: &Pipeline, m: usize, pixels: usize, full_scale: f64) -> anyhow::Result<SensorLinearity> {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    /// Sensors kept; a process that meets more starts the cache again.
    const KEPT: usize = 64;
    static DONE: OnceLock<Mutex<HashMap<String, SensorLinearity>>> = OnceLock::new();
    let key = format!("{pipeline:?} m={m} pixels={pixels} full_scale={full_scale}");
    let done = DONE.get_or_init(Default::default);
    if let Some(l) = done.lock().expect("not poisoned").get(&key) {
        return Ok(l.clone());
    }
    let l = measure(pipeline, m, pixels, full_scale)?;
    let mut done = done.lock().expect("not poisoned");
    if done.len() >= KEPT {
        done.clear();
    }
    done.insert(key, l.clone());
    Ok(l)
}

/// Octave of `s` counts and the position within it, as the device reads
/// them (`brdf_meter::acquire::Linearity::linear`): `s = 2^k (1 + t)`.
fn octave(s: f64) -> (usize, f64) {
    let k = s.log2().floor().max(0.0) as usize;
    (k, s / 2f64.powi(k as i32) - 1.0)
}

/// Fits the factors to `(exposure, mean signal, its standard error)` frames.
fn fit(sweep: &[(f64, f64, f64)]) -> anyhow::Result<SensorLinearity> {
    let brightest = sweep.iter().map(|f| f.1).fold(0.0, f64::max);
    let dimmest = sweep.iter().map(|f| f.1).fold(f64::INFINITY, f64::min);
    let top = (octave(brightest).0 + 1).min(LINEARITY_KNOTS - 1);
    let low = octave(dimmest).0;
    // Unknowns: factors of knots low..top (top's fixed at 1), then K.
    let free = top - low;
    let cols = free + 1;
    let rows = sweep.len() + free.saturating_sub(1);
    let mut a = DMatrix::zeros(rows, cols);
    let mut b = DVector::zeros(rows);
    for (r, &(e, s, se)) in sweep.iter().enumerate() {
        let (k, t) = octave(s);
        let w = 1.0 / se;
        for (knot, share) in [(k, 1.0 - t), (k + 1, t)] {
            if knot >= top {
                b[r] -= w * s * share;
            } else {
                a[(r, knot - low)] += w * s * share;
            }
        }
        a[(r, free)] = -w * e;
    }
    // The smoothness ties: f_{k-1} - 2 f_k + f_{k+1} = 0 for the free knots
    // with two neighbours, weighted as one frame of the brightest's error.
    let tie = sweep.iter().map(|f| f.1 / f.2).fold(0.0, f64::max) * SMOOTHNESS;
    for (r, k) in (low + 1..top).enumerate() {
        let r = sweep.len() + r;
        for (knot, c) in [(k - 1, 1.0), (k, -2.0), (k + 1, 1.0)] {
            if knot >= top {
                b[r] -= tie * c;
            } else {
                a[(r, knot - low)] += tie * c;
            }
        }
    }
    let x = a.clone().svd(true, true).solve(&b, 1e-12).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut factors = [1.0f32; LINEARITY_KNOTS];
    for (k, f) in factors.iter_mut().enumerate().take(top) {
        *f = x[k.max(low) - low] as f32;
    }
    let k_scale = x[free];
    // A sensor bent further than a correction may go is corrected as far as
    // it may, from the top down (where the readings that matter are).
    let (lo, hi) = FACTOR_RANGE;
    let mut clamped = false;
    for k in (0..top).rev() {
        let above = factors[k + 1];
        let f = factors[k].clamp(lo, hi).min(1.5 * above);
        clamped |= f != factors[k];
        factors[k] = f;
    }
    let correction = Linearity::new(factors).map_err(|e| {
        anyhow::anyhow!("the fitted correction is not one a device can run ({e:?}; factors {factors:?})")
    })?;
    let read: Vec<f64> = sweep
        .iter()
        .filter(|f| f.1 >= f64::from(brdf_meter::acquire::MIN_SIGNAL_COUNTS))
        .map(|&(e, s, _)| (f64::from(correction.linear(s as f32)) / (k_scale * e) - 1.0).powi(2))
        .collect();
    let residual_rms = (read.iter().sum::<f64>() / read.len().max(1) as f64).sqrt();
    Ok(SensorLinearity { correction, exposures: sweep.len(), residual_rms, clamped })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sweep of a sensor reading `c = FS (x / FS)^gamma`, no noise.
    fn power_law_sweep(gamma: f64) -> Vec<(f64, f64, f64)> {
        let (fs, top) = (4095.0, 0.9 * 4095.0);
        (0..=43)
            .map(|j| {
                let e = 2f64.powf(-f64::from(j) / 4.0);
                let c = fs * (top * e / fs).powf(gamma);
                (e, c, 1e-3 * c.sqrt())
            })
            .collect()
    }

    #[test]
    fn a_power_law_sensor_is_read_linearly_after_the_correction() {
        let m = fit(&power_law_sweep(1.01)).unwrap();
        // Every frame of the sweep is given back within 0.1 %.
        assert!(m.residual_rms < 1e-3, "rms {}", m.residual_rms);
        // The sensor reads 100 counts 3.0 % low against 2,000 (the ratio of
        // (100/2000)^0.01); the correction raises them by as much.
        let truth = (2000.0f64 / 100.0).powf(0.01 / 1.01) - 1.0;
        assert!((m.bend(100.0, 2000.0) - truth).abs() < 1e-3, "{} against {truth}", m.bend(100.0, 2000.0));
        // Above the brightest frame the factor is 1.
        assert_eq!(m.correction.factors()[LINEARITY_KNOTS - 1], 1.0);
    }

    #[test]
    fn a_linear_sensor_gets_the_identity_back() {
        let m = fit(&power_law_sweep(1.0)).unwrap();
        for f in m.correction.factors() {
            assert!((f - 1.0).abs() < 1e-4, "{:?}", m.correction.factors());
        }
    }

    #[test]
    fn a_sensor_bent_beyond_what_a_correction_may_undo_is_corrected_as_far_as_it_may() {
        // gamma 1.6 needs a factor 4096^0.375 = 22 at one count.
        let m = fit(&power_law_sweep(1.6)).unwrap();
        assert!(m.clamped);
        assert_eq!(m.correction.factors()[0], FACTOR_RANGE.1);
        assert!(!fit(&power_law_sweep(1.01)).unwrap().clamped);
    }
}
