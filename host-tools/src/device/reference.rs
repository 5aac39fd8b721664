//! The host's reference computation of the device: what the device must
//! answer for a line of raw frames, computed with the library's own
//! correction and kernel, so a link test can demand equality bit for bit.
use brdf_meter::acquire::correct_point_into;
use brdf_meter::blob::BlobView;
use brdf_meter::kernel::mat_vec_f32_slice;

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
