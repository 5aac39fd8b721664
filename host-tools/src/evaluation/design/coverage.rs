//! Per pixel, what a layout lets the instrument see of a mirror: how far
//! inside an LED's die the pixel's specular direction falls (negative: in a
//! gap between LEDs, where a mirror reflects no LED into the pixel), and the
//! raw counts the black-glass standard and polished metals give under each
//! LED (whether the long exposure, and the short one, saturate).
use crate::forward::brdf::{Brdf, NbrdfSet, SmoothDielectric};
use crate::forward::optics::Optics;
use crate::forward::pairs::PixelOptics;
use crate::forward::prior_models::SampleModel;
use crate::forward::scene::Scene;
use crate::forward::scene::pipeline::Simulator;
use nalgebra::Vector3;
use serde::Serialize;
use std::sync::Arc;

/// The MERL materials the saturation check takes as polished metals.
pub const POLISHED_METALS: [&str; 8] =
    ["chrome", "chrome-steel", "aluminium", "nickel", "brass", "ss440", "steel", "tungsten-carbide"];

/// One pixel's coverage.
#[derive(Clone, Debug, Serialize)]
pub struct PixelCoverage {
    /// Pixel.
    pub pixel: usize,
    /// Specular incidence (the view's polar angle), degrees.
    pub specular_deg: f64,
    /// How far inside the nearest die (in the plane of incidence) the
    /// specular direction falls, degrees; negative in a gap.
    pub margin_deg: f64,
    /// The LED whose die holds (or is nearest to) it.
    pub led: usize,
    /// The black glass's largest raw count over the LEDs, long exposure.
    pub black_glass_counts: f64,
    /// The polished metals' largest raw count, long exposure.
    pub metal_counts: f64,
}

/// In-plane elevation of a ray towards the light, degrees from the normal
/// (positive on the LEDs' side).
fn in_plane_deg(d: &Vector3<f64>) -> f64 {
    (-d.x).atan2(d.z).to_degrees()
}

/// The coverage of every pixel of `scene` (its optics, the sensor's white
/// counts and dark level from `sim`).
pub fn coverage(scene: &Scene, optics: &Optics, sim: &Simulator, pixels: &[PixelOptics]) -> Vec<PixelCoverage> {
    let m = optics.m();
    let metals: Vec<SampleModel> = POLISHED_METALS
        .iter()
        .filter_map(|n| NbrdfSet::merl().by_name(n, scene.instrument.spectral_weights).ok())
        .map(|b| SampleModel::Brdf(Arc::new(b) as Arc<dyn Brdf>))
        .collect();
    let bg = SampleModel::Brdf(Arc::new(SmoothDielectric::black_glass()));
    pixels
        .iter()
        .map(|px| {
            let p = px.pixel.round() as usize;
            let point = scene.pixel_point(px.pixel);
            let spec = px.theta_o_deg;
            // Each die's span in the plane of incidence, extended by half a
            // sample pitch at each end (the samples are the pitch's centres).
            let mut best = (f64::NEG_INFINITY, 0);
            for led in 0..m {
                let mut a: Vec<f64> = Vec::new();
                optics.for_each_ray(led, &point, |r| a.push(in_plane_deg(&r.dir)));
                a.sort_by(f64::total_cmp);
                a.dedup_by(|x, y| (*x - *y).abs() < 1e-9);
                let half = if a.len() > 1 { 0.5 * (a[a.len() - 1] - a[0]) / (a.len() - 1) as f64 } else { 0.0 };
                let (lo, hi) = (a[0] - half, a[a.len() - 1] + half);
                let margin = (spec - lo).min(hi - spec);
                if margin > best.0 {
                    best = (margin, led);
                }
            }
            let counts = |model: &SampleModel| {
                let v = px.readings(model, &px.truth(model));
                (0..m).map(|k| sim.white()[p * m + k] * v[k] + sim.dark()[p]).fold(0.0, f64::max)
            };
            PixelCoverage {
                pixel: p,
                specular_deg: spec,
                margin_deg: best.0,
                led: best.1,
                black_glass_counts: counts(&bg),
                metal_counts: metals.iter().map(counts).fold(0.0, f64::max),
            }
        })
        .collect()
}
