//! Reading a surface: seeded noisy draws of its readings, each read by the
//! calibration exactly as the device reads it (`device::reference::
//! PointEstimator`, bit for bit the firmware's arithmetic: estimate, per-bin
//! uncertainty, gloss readings with theirs, flags) and by linear
//! interpolation between the LEDs' centre angles (the patent's \[0004\]
//! baseline), whose gloss readings are the definitions applied to its
//! profile (`forward::gloss::profile_scaled_readings`).
use crate::calibration::estimators::interpolation;
use crate::device::reference::PointEstimator;
use crate::forward::gloss::{ASSIGNED_GU, profile_scaled_readings, readings_of};
use crate::forward::grid::AngleGrid;
use crate::output::peak::{Peak, specular_peak};
use anyhow::Context;
use brdf_meter::blob::BlobView;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// One estimate of a surface, by either method.
#[derive(Clone, Debug)]
pub struct Reading {
    /// The bins (n).
    pub rho: Vec<f64>,
    /// Their standard uncertainties, when the method states them.
    pub sigma: Option<Vec<f64>>,
    /// Gloss GU, haze HU, distinctness % (NaN: no reading).
    pub gloss: [f64; 3],
    /// Their standard uncertainties, when the method states them.
    pub gloss_u: Option<[f64; 3]>,
    /// Whether any flag was raised (`None`: the method has no flags).
    pub flagged: Option<bool>,
    /// The specular peak of the estimate.
    pub specular: Peak,
    /// The out-of-prior statistic (NaN: the method has none).
    pub stat: f64,
    /// The largest reading over the readings' sum: near 1 when one LED
    /// carries all the light, a peak narrower than the LEDs' spacing.
    pub brightest_share: f64,
}

/// The largest of the readings `v` over their sum (NaN when they sum to nothing).
fn brightest_share(v: &[f32]) -> f64 {
    let sum: f64 = v.iter().map(|x| f64::from(*x)).sum();
    let max = v.iter().map(|x| f64::from(*x)).fold(f64::NEG_INFINITY, f64::max);
    if sum > 0.0 { max / sum } else { f64::NAN }
}

/// `draws` noisy draws of the readings `clean`: each reading times `1 +
/// noise_rel N(0, 1)`, clipped at 0 (a sensor reads no negative light),
/// from a stream seeded by `seed` alone (the same draws whichever
/// calibration reads them).
pub fn noisy_draws(clean: &DVector<f64>, noise_rel: f64, draws: usize, seed: u64) -> Vec<Vec<f32>> {
    let nd = Normal::new(0.0, 1.0).expect("unit normal");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..draws)
        .map(|_| clean.iter().map(|x| (x * (1.0 + noise_rel * nd.sample(&mut rng))).max(0.0) as f32).collect())
        .collect()
}

/// The two methods, ready to read points of the calibration's zone 0.
pub struct Readers<'a> {
    estimator: PointEstimator<'a>,
    /// The blob's white reference of the zone's first pixel (the f32 gate
    /// may have folded a power of two into it).
    white: Vec<f32>,
    interpolation: DMatrix<f64>,
    bins: Vec<f64>,
    bins32: Vec<f32>,
    view_deg: f64,
    /// The peak resolution (`output::peak`) of the pixel read (the zone's
    /// first), if the calibration records one.
    resolution_deg: Option<f64>,
    /// The calibration's factors on a resolved peak's uncertainties.
    peak_factors: Option<crate::output::peak::PeakFactors>,
}

impl<'a> Readers<'a> {
    /// Readers for `blob` on `grid` (LED centre angles `centres_deg`, view `view_deg`).
    pub fn new(blob: &'a [u8], grid: &AngleGrid, centres_deg: &[f64], view_deg: f64) -> anyhow::Result<Self> {
        let view = BlobView::parse(blob).map_err(|e| anyhow::anyhow!("the calibration: {e}"))?;
        let estimator = PointEstimator::new(view, 0)?;
        let white = (0..view.dims().m).map(|i| view.white(view.zone_start(0) as usize, i)).collect();
        let interpolation = interpolation::weights(grid.bins_deg(), centres_deg).context("interpolation weights")?;
        Ok(Self {
            estimator,
            white,
            interpolation,
            bins: grid.bins_deg().to_vec(),
            bins32: grid.bins_deg().iter().map(|x| *x as f32).collect(),
            view_deg,
            resolution_deg: view.peak_resolution_at(view.zone_start(0) as usize).map(f64::from),
            peak_factors: view.peak_factors(),
        })
    }

    /// The name of the statistic the calibration's out-of-prior flag is
    /// raised on (`none` without one).
    pub fn flag_statistic(&self) -> &'static str {
        crate::calibration::estimators::out_of_prior::statistic_name(self.estimator.view())
    }

    /// The calibration's estimate of white-normalised readings `v`, as the device computes it.
    pub fn estimator(&self, v: &[f32]) -> Reading {
        let corrected: Vec<f32> = v.iter().zip(&self.white).map(|(x, w)| x / w).collect();
        let p = self.estimator.apply(&corrected);
        let f = |x: &[f32]| x.iter().map(|y| f64::from(*y)).collect::<Vec<f64>>();
        Reading {
            rho: f(&p.rho),
            sigma: Some(f(&p.sigma)),
            gloss: p.readings.map(f64::from),
            gloss_u: Some(p.reading_sigma.map(f64::from)),
            flagged: Some(p.flag_bits != 0),
            specular: specular_peak(&self.bins32, &p.rho, &p.sigma, self.view_deg)
                .stated(self.resolution_deg, self.peak_factors),
            stat: f64::from(p.stat),
            brightest_share: brightest_share(v),
        }
    }

    /// Linear interpolation's estimate of the same readings.
    pub fn interpolation(&self, v: &[f32]) -> Reading {
        let share = brightest_share(v);
        let v = DVector::from_iterator(v.len(), v.iter().map(|x| f64::from(*x)));
        let rho = &self.interpolation * v;
        let gloss = profile_scaled_readings(&rho, &self.bins, self.view_deg)
            .map_or([f64::NAN; 3], |l| readings_of(&l, ASSIGNED_GU));
        let rho32: Vec<f32> = rho.iter().map(|x| *x as f32).collect();
        Reading {
            specular: specular_peak(&self.bins32, &rho32, &vec![0.0; rho32.len()], self.view_deg),
            rho: rho.iter().copied().collect(),
            sigma: None,
            gloss,
            gloss_u: None,
            flagged: None,
            stat: f64::NAN,
            brightest_share: share,
        }
    }
}
