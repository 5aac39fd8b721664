//! The predicted error of an estimator at one pixel over a prior, every
//! sample held out of the estimator that reads it: the prior's samples are
//! split into folds (one sample per fold is leave-one-material-out), each
//! fold read by an estimator trained on the other folds' sample pairs, from
//! noisy draws of its noise-free readings (the pixel's own noise model).
//! What `design` scores candidate layouts by and the accuracy map's
//! prediction beside its simulated lines.
//!
//! The error of one estimate is the RMS over the bins relative to the
//! truth's peak (the error a user judges an estimate by); linear
//! interpolation between the LEDs' centre angles at the pixel is always
//! scored beside the estimator.
use crate::calibration::estimators::interpolation;
use crate::calibration::estimators::pairs_wiener;
use crate::calibration::estimators::scale_free::{self, ScaleFreeOptions, peak_error};
use crate::forward::pairs::{Criterion, Pairs, PixelOptics};
use anyhow::Context;
use brdf_meter::blob::EstimatorKind;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// How the held-out errors are drawn.
#[derive(Clone, Debug)]
pub struct HeldOutSpec {
    /// Estimator kind: Wiener, scale-free or scale-free piecewise.
    pub kind: EstimatorKind,
    /// Training criterion.
    pub criterion: Criterion,
    /// Folds over the prior's samples (its size: leave one out).
    pub folds: usize,
    /// Noisy draws per sample.
    pub draws: usize,
    /// Seed of the fold split and the draws.
    pub seed: u64,
}

impl Default for HeldOutSpec {
    fn default() -> Self {
        Self { kind: EstimatorKind::Wiener, criterion: Criterion::PeakRelative, folds: 10, draws: 4, seed: 11 }
    }
}

/// Per prior sample: its held-out error and linear interpolation's.
#[derive(Clone, Debug, PartialEq)]
pub struct SampleErrors {
    /// The estimator's peak-relative RMS error, per sample.
    pub estimator: Vec<f64>,
    /// Linear interpolation's, per sample.
    pub interpolation: Vec<f64>,
}

/// A trained estimator of one fold, as a function of the readings.
enum FoldEstimator {
    Linear(DMatrix<f64>),
    ScaleFree(Box<scale_free::ScaleFreeZone>),
}

impl FoldEstimator {
    fn estimate(&self, v: &DVector<f64>) -> DVector<f64> {
        match self {
            Self::Linear(w) => w * v,
            Self::ScaleFree(z) => {
                let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
                let (e, _, _, _) = z.estimate_f32(&v32);
                DVector::from_iterator(e.len(), e.iter().map(|x| f64::from(*x)))
            }
        }
    }
}

fn train_fold(pairs: &Pairs, spec: &HeldOutSpec) -> anyhow::Result<FoldEstimator> {
    let weighted = pairs.weighted(spec.criterion);
    Ok(match spec.kind {
        EstimatorKind::Wiener => FoldEstimator::Linear(pairs_wiener::linear_map(&weighted, &weighted.truth)?.g),
        EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise => {
            let opts = ScaleFreeOptions {
                piecewise: spec.kind == EstimatorKind::ScaleFreePiecewise,
                seed: spec.seed,
                ..Default::default()
            };
            FoldEstimator::ScaleFree(Box::new(scale_free::train_pairs(&weighted, &opts)?))
        }
        k => anyhow::bail!("{k:?}: the held-out error is drawn for the Wiener and scale-free kinds"),
    })
}

/// The held-out errors at pixel `px` of every sample of `pairs` (the raw
/// pairs of a prior at that one pixel; one column per prior sample).
pub fn held_out_errors(px: &PixelOptics, pairs: &Pairs, spec: &HeldOutSpec) -> anyhow::Result<SampleErrors> {
    let k = pairs.len();
    let folds = spec.folds.clamp(2, k);
    let mut order: Vec<usize> = (0..k).collect();
    {
        use rand::seq::SliceRandom;
        order.shuffle(&mut ChaCha8Rng::seed_from_u64(spec.seed));
    }
    let mut fold_of = vec![0; k];
    for (pos, &s) in order.iter().enumerate() {
        fold_of[s] = pos % folds;
    }
    let w_interp = interpolation::weights(px.bins(), &px.centres_deg).context("interpolation at the pixel")?;
    let mut out = SampleErrors { estimator: vec![0.0; k], interpolation: vec![0.0; k] };
    let nd = Normal::new(0.0, 1.0).expect("unit normal");
    for f in 0..folds {
        let train: Vec<usize> = (0..k).filter(|s| fold_of[*s] != f).collect();
        let est = train_fold(&pairs.columns(&train), spec).with_context(|| format!("fold {f}"))?;
        let mut rng = ChaCha8Rng::seed_from_u64(spec.seed ^ (f as u64).wrapping_mul(0x9E37_79B9));
        for s in (0..k).filter(|s| fold_of[*s] == f) {
            let truth = pairs.truth.column(s).into_owned();
            let (mut e2, mut i2) = (0.0, 0.0);
            for _ in 0..spec.draws.max(1) {
                let v = DVector::from_fn(pairs.m(), |i, _| {
                    pairs.readings[(i, s)] + pairs.noise_var[(i, s)].max(0.0).sqrt() * nd.sample(&mut rng)
                });
                e2 += peak_error(&est.estimate(&v), &truth).powi(2);
                i2 += peak_error(&(&w_interp * &v), &truth).powi(2);
            }
            out.estimator[s] = (e2 / spec.draws.max(1) as f64).sqrt();
            out.interpolation[s] = (i2 / spec.draws.max(1) as f64).sqrt();
        }
    }
    Ok(out)
}

/// Median, 90th percentile and largest of `x` (NaN-free).
pub fn quantiles(x: &[f64]) -> [f64; 3] {
    let mut v: Vec<f64> = x.iter().copied().filter(|e| e.is_finite()).collect();
    if v.is_empty() {
        return [f64::NAN; 3];
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((q * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)];
    [at(0.5), at(0.9), *v.last().expect("not empty")]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::{Brdf, Ward};
    use crate::forward::optics::{Instrument, Optics, RayModel};
    use crate::forward::prior_models::PriorModels;
    use crate::forward::reading_noise::ReadingNoise;
    use std::sync::Arc;

    #[test]
    fn held_out_wiener_beats_interpolation_on_a_smooth_family() {
        let inst = Instrument::patent_profile();
        let grid = inst.grid().unwrap();
        let optics = Optics::new(&inst, RayModel::legacy(false));
        let px = PixelOptics::new(
            &optics,
            &grid,
            0.0,
            &nalgebra::Vector3::zeros(),
            inst.view_dir(),
            inst.centre_angles_deg(),
            ReadingNoise::relative(0.02, 7),
        )
        .unwrap();
        let mut brdfs: Vec<(String, Arc<dyn Brdf>)> = Vec::new();
        for d in [0.1, 0.3, 0.5, 0.7] {
            for a in [0.04, 0.06, 0.08, 0.1, 0.12] {
                brdfs.push((format!("{d},{a}"), Arc::new(Ward::patent(d, a))));
            }
        }
        let prior = PriorModels::from_brdfs("ward", brdfs);
        let pairs = Pairs::build(std::slice::from_ref(&px), &prior);
        let e = held_out_errors(&px, &pairs, &HeldOutSpec::default()).unwrap();
        let [em, _, _] = quantiles(&e.estimator);
        let [im, _, _] = quantiles(&e.interpolation);
        assert!(em < 0.5 * im, "estimator {em} vs interpolation {im}");
        assert_eq!(quantiles(&[3.0, 1.0, 2.0]), [2.0, 3.0, 3.0]);
    }
}
