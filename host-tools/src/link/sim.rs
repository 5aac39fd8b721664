//! Simulated scenes for a simulated instrument (QEMU firmware, host
//! simulation), and the host's reference computation of what the device must
//! answer for them.
//!
//! The scene here is a simple analytic one (a diffuse base plus a specular
//! lobe that moves along the line); it exercises every pixel, zone and LED
//! with distinct values, which is what the link and bit-exactness checks need.
use brdf_meter::acquire::correct_point_into;
use brdf_meter::blob::BlobView;
use brdf_meter::kernel::mat_vec_f32_slice;

/// Raw frames of a scene: `[line][frame][pixel]`, frame 0 dark, 1 + k under LED k.
pub type SceneFrames = Vec<Vec<Vec<u16>>>;

/// A scene of `lines` lines for the instrument `blob` describes: raw counts
/// are `dark + white * reflectance`, with the blob's white reference (so a
/// perfect diffuser reads its white value), clamped to `full_scale`.
#[allow(clippy::needless_range_loop)] // p indexes every frame of the line
pub fn analytic_scene(blob: &BlobView<'_>, lines: usize, full_scale: u16) -> SceneFrames {
    let d = blob.dims();
    let order = blob.led_order();
    (0..lines)
        .map(|l| {
            let mut frames = vec![vec![0u16; d.pixels]; d.m + 1];
            for p in 0..d.pixels {
                let dark = 40 + ((p * 7 + l * 3) % 23) as u16;
                frames[0][p] = dark;
                for (i, &led) in order.iter().enumerate() {
                    let x = p as f32 / d.pixels.max(2) as f32;
                    let lobe_at = (l as f32 * 0.37 + x) * (d.m as f32 - 1.0) % d.m as f32;
                    let diff = 0.15 + 0.5 * x;
                    let spec = 0.6 * (-((i as f32 - lobe_at).powi(2)) / 0.8).exp();
                    let counts = dark as f32 + blob.white(p, i) * (diff + spec);
                    frames[led as usize + 1][p] = counts.round().clamp(0.0, full_scale as f32) as u16;
                }
            }
            frames
        })
        .collect()
}

/// What the device must send for one scene line, point by point: zone, flags
/// and the n values, computed with the library's own correction and kernel
/// (so equality is bit for bit).
pub fn expected_line(blob: &BlobView<'_>, frames: &[Vec<u16>], full_scale: u16) -> Vec<(u16, u8, Vec<f32>)> {
    let d = blob.dims();
    let order = blob.led_order();
    let mut w = vec![0.0f32; d.n * d.m];
    (0..d.pixels)
        .map(|p| {
            let lit: Vec<u16> = order.iter().map(|&led| frames[led as usize + 1][p]).collect();
            let white: Vec<f32> = (0..d.m).map(|i| blob.white(p, i)).collect();
            let mut v = vec![0.0f32; d.m];
            let mut flags = correct_point_into(frames[0][p], &lit, &white, full_scale, &mut v);
            let z = blob.zone_of_pixel(p);
            blob.copy_matrix(z, &mut w);
            let mut rho = vec![0.0f32; d.n];
            mat_vec_f32_slice(&w, &v, &mut rho);
            flags |= brdf_meter::estimate::guard_estimate(&mut rho);
            (z as u16, flags, rho)
        })
        .collect()
}

/// The patent-profile scene (host-tools' scene simulator) with a line sensor
/// of `pixels` pixels: what the QEMU instrument simulates by default.
pub fn patent_scene(pixels: usize) -> crate::scene::Scene {
    let mut s = crate::scene::Scene::patent_profile();
    s.instrument.sensor.pixels = pixels;
    s
}

/// Trains a calibration for `scene` with host-tools' training: `zones` zones,
/// each with the system matrix at its centre pixel, the scene's white
/// reference, the patent prior and `noise_rel` relative noise (Wiener, eq. 22).
pub fn train_for_scene(scene: &crate::scene::Scene, zones: usize, noise_rel: f64) -> anyhow::Result<crate::train::Trained> {
    use anyhow::Context;
    let inst = &scene.instrument;
    let grid = inst.grid().context("the scene's angle grid")?;
    let prior = crate::prior::PriorSpec::patent()
        .build(&grid, inst.view_deg, std::path::Path::new("."))
        .context("building the patent prior")?;
    let centres = inst.centre_angles_deg();
    let zones: Vec<crate::train::ZoneOptics> = crate::scene::zone_system_matrices(scene, zones)?
        .into_iter()
        .map(|z| crate::train::ZoneOptics { first_pixel: z.first_pixel, h: z.h, centres_deg: centres.clone() })
        .collect();
    let white = crate::scene::white_reference(scene).context("the scene's white reference")?;
    crate::train::train(&crate::train::TrainSpec {
        bins_deg: grid.bins_deg(),
        zones,
        pixels: inst.sensor.pixels,
        prior: &prior,
        noise_rel,
        estimator: brdf_meter::blob::EstimatorKind::Wiener,
        far_field: false,
        led_order: None,
        white: Some(white),
    })
}

/// Raw frames of `lines` lines of `scene` from host-tools' scene simulator.
pub fn scene_frames(scene: &crate::scene::Scene, lines: usize) -> anyhow::Result<SceneFrames> {
    (0..lines as u64).map(|l| crate::scene::raw_frames(scene, l)).collect()
}
