//! The predicted gloss error of a layout at one pixel, every prior sample
//! held out of the rows that read it: what `design` ranks layouts by for
//! the instrument's first reading, beside the BRDF error.
//!
//! The rows are fitted as training fits the calibration's
//! (`calibration::gloss_rows`): the prior's pairs at the pixel mixed with
//! the gloss standards' ([`gloss_rows::STANDARDS_WEIGHT`]), each pair
//! weighted by its reading's size ([`gloss_rows::reading_weighted`]), the
//! black glass holding half the criterion ([`gloss_rows::anchored`]),
//! fitted by the pairs' Wiener map (`pairs_wiener::linear_map`, the
//! readings' noise included, as training fits the linear kinds' rows);
//! then scaled so the black glass as the pixel measures it reads its
//! assigned 100 GU, as the device's per-pixel reference does. One linear row per pixel, where the product
//! has one per zone and cluster in the root form: a predictor that ranks
//! layouts by what their readings can say about gloss, not the product's
//! figure (`pixel-map` measures that).
//!
//! A sample's error is its RMS relative error over noisy draws of its
//! readings, `|G_est - G| / G` against its gloss by the definitions in
//! three dimensions at the pixel's view; linear interpolation's profile
//! read by the in-plane definitions (as `pixel-map` reads it) beside it.
use crate::calibration::estimators::{interpolation, pairs_wiener};
use crate::calibration::gloss_rows;
use crate::forward::gloss::{ASSIGNED_GU, profile_scaled_readings};
use crate::forward::pairs::{Pairs, PixelOptics};
use crate::forward::prior_models::PriorModels;
use anyhow::Context;
use nalgebra::DVector;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Per prior sample (its position in the prior): the rows' relative gloss
/// error and interpolation's (NaN where the sample has no gloss).
#[derive(Clone, Debug, PartialEq)]
pub struct GlossSampleErrors {
    /// The held-out rows'.
    pub estimator: Vec<f64>,
    /// Linear interpolation's.
    pub interpolation: Vec<f64>,
}

/// The held-out gloss errors at pixel `px` of every sample of `prior`
/// (`folds` folds over it, `draws` noisy draws each, seeded by `seed`);
/// `None` when the pixel has no gloss reading: its grid does not cover the
/// gloss window, or the black glass reads nothing there (no LED in its
/// mirror direction).
pub fn held_out_gloss(
    px: &PixelOptics,
    prior: &PriorModels,
    folds: usize,
    draws: usize,
    seed: u64,
) -> anyhow::Result<Option<GlossSampleErrors>> {
    let pairs = Pairs::build_with_gloss(std::slice::from_ref(px), prior);
    let standards = Pairs::build_with_gloss(std::slice::from_ref(px), &gloss_rows::standards());
    let (Some(target), Some(_)) = (&pairs.gloss, &standards.gloss) else { return Ok(None) };
    let k = pairs.len();
    let folds = folds.clamp(2, k.max(2));
    let mut order: Vec<usize> = (0..k).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let mut fold_of = vec![0; k];
    for (pos, &s) in order.iter().enumerate() {
        fold_of[s] = pos % folds;
    }
    let w_interp = interpolation::weights(px.bins(), &px.centres_deg).context("interpolation at the pixel")?;
    let glass = gloss_rows::black_glass_readings(px);
    let nd = Normal::new(0.0, 1.0).expect("unit normal");
    let mut out = GlossSampleErrors { estimator: vec![f64::NAN; k], interpolation: vec![f64::NAN; k] };
    for f in 0..folds {
        let train: Vec<usize> = (0..k).filter(|s| fold_of[*s] != f).collect();
        let aug = pairs.columns(&train).joined(&standards, gloss_rows::STANDARDS_WEIGHT);
        let t = aug.gloss.clone().context("the standards carry gloss targets")?;
        let weighted = gloss_rows::reading_weighted(&aug, &t);
        // The standards' samples are numbered after the training folds' (`joined`).
        let first_standard = aug.sample[..train.len()].iter().copied().max().map_or(0, |x| x + 1);
        let fitted = gloss_rows::anchored(&weighted, first_standard + gloss_rows::BLACK_GLASS_STANDARD);
        // The calibration's own fit of a linear row (training's for the linear kinds).
        let row: DVector<f64> = pairs_wiener::linear_map(&fitted, &t.rows(0, 1).into_owned())?.g.row(0).transpose();
        let glass_reading = row.dot(&glass);
        if glass_reading.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            // No LED in the pixel's mirror direction: the standard reads
            // nothing, no gloss scale can be set, as on the device.
            return Ok(None);
        }
        let q = ASSIGNED_GU / glass_reading;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (f as u64).wrapping_mul(0x9E37_79B9));
        for s in (0..k).filter(|s| fold_of[*s] == f) {
            let g = target[(0, s)];
            if g.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                continue;
            }
            let (mut e2, mut i2) = (0.0, 0.0);
            for _ in 0..draws.max(1) {
                let v = DVector::from_fn(pairs.m(), |i, _| {
                    pairs.readings[(i, s)] + pairs.noise_var[(i, s)].max(0.0).sqrt() * nd.sample(&mut rng)
                });
                e2 += ((q * row.dot(&v) - g) / g).powi(2);
                let gi =
                    profile_scaled_readings(&(&w_interp * &v), px.bins(), px.theta_o_deg).map_or(f64::NAN, |l| l[0]);
                i2 += ((gi - g) / g).powi(2);
            }
            out.estimator[s] = (e2 / draws.max(1) as f64).sqrt();
            out.interpolation[s] = (i2 / draws.max(1) as f64).sqrt();
        }
    }
    Ok(Some(out))
}
