//! Simulated scenes for a simulated instrument (QEMU firmware, host
//! simulation), and the host's reference computation of what the device must
//! answer for them.
//!
//! The scene here is a simple analytic one (a diffuse base plus a specular
//! lobe that moves along the line); it exercises every pixel, zone and LED
//! with distinct values, which is what the link and bit-exactness checks need.
use brdf_meter::acquire::correct_point_into;
use brdf_meter::blob::BlobView;
use brdf_meter::kernel::estimate_into;

/// Raw frames of a scene: `[line][frame][pixel]`, frame 0 dark, 1 + k under LED k.
pub type SceneFrames = Vec<Vec<Vec<u16>>>;

/// A scene of `lines` lines for the instrument `blob` describes: raw counts
/// are `dark + white * reflectance`, with the blob's white reference (so a
/// perfect diffuser reads its white value), clamped to `full_scale`.
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
            estimate_into(&w, &v, &mut rho);
            if rho.iter().any(|x| !x.is_finite()) {
                flags |= brdf_meter::protocol::flags::NON_FINITE;
            }
            (z as u16, flags, rho)
        })
        .collect()
}
