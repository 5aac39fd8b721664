//! Zones along the line sensor: flash bytes against accuracy along the line.
//!
//! The instrument is the handheld of `scenes/handheld.toml` (m = 7 extended
//! LEDs at 6 cm, P = 128 pixels over 8.1 mm), with its geometric effects only
//! (near field, 3-D geometry, per-pixel geometry, inverse square, emission
//! profile) and a telecentric view at 45 deg, so that every pixel's truth is
//! the same in-plane reflectance factor on the grid. Each pixel's readings are
//! simulated from the continuous BRDF over that pixel's own rays (the LEDs
//! seen from its point), plus 2 % proportional noise.
//!
//! With Z zones, zone z's matrix is the Wiener matrix (dense Ward prior) of the
//! system matrix at the zone's centre pixel, and every pixel of the zone uses
//! it; Z = P is one matrix per pixel. Flash: Z n m f32 (4 bytes) or Q15
//! (2 bytes, padded pairs, plus a scale per row).
use crate::calibration::estimators::BatchEstimator;
use crate::forward::brdf::Brdf;
use crate::forward::optics::Optics;
use crate::forward::prior::{Prior, SampleSet};
use crate::forward::scene::{Scene, zone_system_matrices};
use anyhow::Context;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

/// One zone count.
#[derive(Clone, Debug, Serialize)]
pub struct ZoneRow {
    /// Zones Z.
    pub zones: usize,
    /// RMSE over all test points along the line.
    pub rmse: f64,
    /// RMSE of the worst pixel.
    pub worst_pixel_rmse: f64,
    /// Pixel with the worst RMSE.
    pub worst_pixel: usize,
    /// Flash bytes of the matrices in f32.
    pub flash_bytes_f32: usize,
    /// Flash bytes in Q15 (packed pairs + one f32 scale per row).
    pub flash_bytes_q15: usize,
    /// RMSE per pixel tested, (pixel, rmse).
    pub along_line: Vec<(usize, f64)>,
}

/// The line-sensor scene used here.
pub fn line_scene(root: &std::path::Path) -> anyhow::Result<Scene> {
    let path = root.join("scenes/handheld.toml");
    let mut s = Scene::load(&path).with_context(|| format!("loading {}", path.display()))?;
    let keep = ["near-field", "3d-geometry", "per-pixel-geometry", "inverse-square", "emission-profile"];
    s.effects.retain(|e| keep.contains(&e.name()));
    s.instrument.view_distance_cm = None;
    Ok(s)
}

/// Runs the zone sweep with the given prior.
pub fn run(cfg: &super::Config, prior: &Prior) -> anyhow::Result<Vec<ZoneRow>> {
    let scene = line_scene(&cfg.root)?;
    let inst = &scene.instrument;
    let grid = inst.grid().context("grid")?;
    let (n, m, p) = (grid.n(), inst.m(), inst.sensor.pixels);
    let optics = Optics::new(inst, scene.ray_model());
    let wo = optics.frame() * inst.view_dir();
    let test = SampleSet::patent_test();
    let stride_b = if cfg.quick { 10 } else { 1 };
    let brdfs: Vec<&dyn Brdf> = test.brdfs.iter().step_by(stride_b).map(|b| b.as_ref()).collect();
    let pixels: Vec<usize> = (0..p).step_by(cfg.zone_pixel_stride.max(1)).collect();
    let truth: Vec<Vec<f64>> =
        brdfs.iter().map(|b| grid.bins_deg().iter().map(|t| b.reflectance(*t, inst.view_deg)).collect()).collect();
    // Readings per (pixel, BRDF), noisy, f32.
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let mut readings: Vec<Vec<f32>> = Vec::with_capacity(pixels.len());
    for &px in &pixels {
        let point = scene.pixel_point(px as f64);
        let mut rows = Vec::with_capacity(brdfs.len() * m);
        for b in &brdfs {
            for led in 0..m {
                let (mut s, mut wsum) = (0.0, 0.0);
                optics.for_each_ray(led, &point, |r| {
                    if r.weight > 0.0 {
                        s += r.weight * std::f64::consts::PI * b.f_r(&r.dir, &wo);
                        wsum += r.weight;
                    }
                });
                let v = s / wsum;
                let sd = cfg.noise_rel * v.abs();
                let e = if sd > 0.0 { Normal::new(0.0, sd)?.sample(&mut rng) } else { 0.0 };
                rows.push((v + e).max(0.0) as f32);
            }
        }
        readings.push(rows);
    }
    let mut out = Vec::new();
    for &z in &cfg.zones {
        let z = z.min(p);
        let zm = zone_system_matrices(&scene, z)?;
        let batches: Vec<BatchEstimator> = zm
            .iter()
            .map(|zone| super::wiener(&zone.h, prior, cfg.noise_rel).map(|e| BatchEstimator::from_estimator(&e)))
            .collect::<anyhow::Result<_>>()?;
        let (mut tot, mut cnt) = (0.0, 0usize);
        let mut along = Vec::new();
        for (pi, &px) in pixels.iter().enumerate() {
            let zi = zm.iter().rposition(|zz| zz.first_pixel <= px).unwrap_or(0);
            let mut est = vec![0.0f32; brdfs.len() * n];
            batches[zi].estimate_into(&readings[pi], &mut est);
            let mut s = 0.0;
            for (k, t) in truth.iter().enumerate() {
                for j in 0..n {
                    let e = est[k * n + j] as f64 - t[j];
                    s += e * e;
                }
            }
            tot += s;
            cnt += brdfs.len() * n;
            along.push((px, (s / (brdfs.len() * n) as f64).sqrt()));
        }
        let (worst_pixel, worst) = along.iter().fold((0, 0.0f64), |a, &(px, r)| if r > a.1 { (px, r) } else { a });
        out.push(ZoneRow {
            zones: z,
            rmse: (tot / cnt as f64).sqrt(),
            worst_pixel_rmse: worst,
            worst_pixel,
            flash_bytes_f32: 4 * z * n * m,
            flash_bytes_q15: z * (4 * brdf_meter::kernel::q15_w_words(n, m) + 4 * n),
            along_line: along,
        });
    }
    Ok(out)
}
