//! Gloss readings: what the meter tells its user about a point besides its
//! BRDF vector, computed on the device from the point's estimate and
//! defined once here for the device and the host (which calls these same
//! functions, so both give the same bits).
//!
//! Each point frame carries [`crate::shape::READINGS`] readings, in this
//! order, and a standard uncertainty (k = 1) for each:
//! - [`SPECULAR_GU`]: specular gloss in gloss units (GU), the black-glass
//!   standard (n = 1.567) reading its assigned value (100);
//! - [`HAZE_HU`]: haze in haze units (HU): reflection just off the specular
//!   direction, on the same black-glass scale;
//! - [`DISTINCTNESS`]: distinctness of the specular peak in %: 100 for a
//!   peak narrower than the instrument resolves, 0 for a flat one.
//!
//! # How they are computed
//! Every reading is built from [`LINEAR`] *linear* readings of the estimate,
//! `L_r = a_r^T rho` (the weights `a_r` over the angle grid are the
//! definitions; host-tools' `forward::gloss` has them). Since `rho = W x`
//! (x the kernel's input: the readings, or for the scale-free kinds the
//! readings with the last replaced by their scale), `L = (A W) x`: training
//! stores the rows `A W` per zone and cluster, so the device spends
//! [`LINEAR`] x m multiply-adds, not n x [`LINEAR`]. Then
//!
//! - gloss `G = q L_0`, haze `H = q L_1`, with `q = assigned / S_z` (the
//!   standard's assigned value over zone z's reading of it: the calibration
//!   on the gloss standard);
//! - distinctness `D = 100 (L_2 - L_3) / L_2`, computed as `100 - 100 r`
//!   with `r = L_3 / L_2` (peak against its shoulders;
//!   NaN when `L_2 <= 0`, no peak to compare). The root form reads the
//!   peak's deficit over its shoulders as a root of its own
//!   ([`RootReadings`], [`readings_root`]).
//!
//! # Uncertainties
//! Training stores the covariance `C = A E A^T` of the linear readings'
//! errors (E the estimator's error covariance, per unit scale for the
//! scale-free kinds), packed, per zone and cluster, each reading's rows and
//! columns scaled by the factor training calibrated on held-out samples
//! (host-tools' `calibration::gloss_rows`). With `s` the point's
//! `sigma_scale` (1 for the linear kinds):
//! `u(G) = q s sqrt(C_00)`, `u(H) = q s sqrt(C_11)` (both square roots
//! stored beside C, [`SD_LEN`]), and to first order in
//! `(L_2, L_3)`, with `r = L_3 / L_2`,
//! `u(D) = 100 s sqrt(r^2 C_22 - 2 r C_23 + C_33) / |L_2|`.
//!
//! A reading of NaN means "no reading": the calibration carries no gloss
//! section (blob format 1 or 2), the point's zone cannot read the standard
//! (its `S_z` and rows NaN, `crate::blob`'s per-zone marker: `q` and the
//! linear readings are NaN, so every reading and uncertainty is, with no
//! branch of its own), the point's estimate was not finite, or
//! (distinctness only) there is no peak.

/// Index of the specular gloss (GU) in a point's readings.
pub const SPECULAR_GU: usize = 0;
/// Index of the haze (HU) in a point's readings.
pub const HAZE_HU: usize = 1;
/// Index of the distinctness (%) in a point's readings.
pub const DISTINCTNESS: usize = 2;
/// Names of the readings in order, as the host's outputs label them.
pub const NAMES: [&str; crate::shape::READINGS] = ["gloss_gu", "haze_hu", "distinctness_pct"];
/// Each reading's range by its definition, `(lowest, highest)`, in
/// [`NAMES`] order: gloss and haze are reflected flux on the black glass's
/// scale, never below 0 and unbounded above (a metal reads thousands of
/// GU); distinctness is a share of the peak, 0 to 100 %. A stated
/// coverage interval lies within it (the truth does), which is how the
/// host states a result's.
pub const DOMAINS: [(f32, f32); crate::shape::READINGS] = [(0.0, f32::INFINITY), (0.0, f32::INFINITY), (0.0, 100.0)];
/// What a point without readings streams.
pub const NO_READINGS: [f32; crate::shape::READINGS] = [f32::NAN; crate::shape::READINGS];

/// Linear readings per point: specular aperture, haze windows, peak,
/// shoulders.
pub const LINEAR: usize = 4;
/// Packed upper-triangular covariance of the linear readings: (0,0), (0,1),
/// (0,2), (0,3), (1,1), (1,2), (1,3), (2,2), (2,3), (3,3).
pub const COV_LEN: usize = LINEAR * (LINEAR + 1) / 2;

/// Standard deviations stored beside the covariance: `sqrt(C_00)` and
/// `sqrt(C_11)`, the per-zone constants of the gloss's and the haze's
/// uncertainty (so the device takes no square root for them per point).
pub const SD_LEN: usize = 2;

/// Values per zone and cluster in the blob's gloss section for m readings:
/// the rows (LINEAR x m, row-major), the packed covariance, then
/// `sqrt(C_00)`, `sqrt(C_11)`.
pub const fn block_len(m: usize) -> usize {
    LINEAR * m + COV_LEN + SD_LEN
}

/// The gloss rows' cluster of a point whose corrected readings are `v`
/// (m values) and whose BRDF cluster is `brdf_cluster`: with rows that have
/// clusters of their own (`crate::blob`, flag bit 9; `centroids` the
/// zone's K_g x m) the nearest ([`crate::kernel::select_cluster`]), else
/// the BRDF's. The device, the host's reference and training all choose
/// with it.
pub fn cluster_of(centroids: &[f32], brdf_cluster: usize, v: &[f32]) -> usize {
    if centroids.is_empty() { brdf_cluster } else { crate::kernel::select_cluster(centroids, v) }
}

/// Index of `(i, j)`, `i <= j`, in the packed covariance.
pub const fn cov_index(i: usize, j: usize) -> usize {
    // Row i starts after rows 0..i, row k holding LINEAR - k entries.
    i * LINEAR - i * (i + 1) / 2 + j
}

/// One point's readings and their standard uncertainties.
///
/// `block` is the zone and cluster's [`block_len`]`(m)` values, `x` the
/// estimator kernel's input (the corrected readings; for the scale-free
/// kinds the readings with the last replaced by their scale), `q` the
/// zone's `assigned / S_z` and `s` the point's `sigma_scale`. The linear
/// readings are accumulated in index order, unfused, like the kernel.
///
/// # Panics
/// If `block.len() != block_len(x.len())`.
#[inline]
pub fn readings(
    block: &[f32],
    x: &[f32],
    q: f32,
    s: f32,
) -> ([f32; crate::shape::READINGS], [f32; crate::shape::READINGS]) {
    let m = x.len();
    assert!(block.len() == block_len(m), "a gloss block is LINEAR x m rows and the covariance");
    let mut l = [0.0f32; LINEAR];
    // The estimator's own kernel (its accumulation order; VLDM/VMLA on the M4).
    crate::kernel::mat_vec_f32_4(&block[..LINEAR * m], x, &mut l);
    let c = &block[LINEAR * m..];
    let sd = &c[COV_LEN..];
    let qs = q * s.abs();
    let r = l[3] / l[2];
    // 100 (L_2 - L_3) / L_2, as 100 - 100 r (one multiply-subtract).
    let d = if l[2] > 0.0 { 100.0 - 100.0 * r } else { f32::NAN };
    let var_d = (r * r) * c[7] - 2.0 * r * c[8] + c[9];
    let u_d = if l[2] > 0.0 { 100.0 * s.abs() * (crate::kernel::sqrt0(var_d) / l[2]) } else { f32::NAN };
    ([q * l[0], q * l[1], d], [qs * sd[0], qs * sd[1], u_d])
}

/// How a root-form calibration's gloss rows are read (`crate::blob`'s
/// flag bit 10 says [`RootReadings::Deficit`]).
///
/// Distinctness compares the peak with its shoulders 0.5-1.5 deg off; a
/// broad lobe's two are nearly equal. Read as two roots, `D = 100 (1 -
/// (t_3 / t_2)^2)` turns a 5 % error of their ratio into 10 % points of
/// distinctness on a surface whose truth is near 0, and the rows of a
/// cluster that mixes broad and sharp lobes make such errors. Reading the
/// peak's deficit over its shoulders, `max(L_2 - L_3, 0)`, as a root of
/// its own makes a broad lobe's distinctness the square of a small root:
/// its error is second order where the truth is near 0, and the rows
/// learn "no deficit" directly from the broad samples.
///
/// Gloss and haze are squares of roots too, and the first-order
/// uncertainty of a square, `2 |t| e`, says a reading near 0 is exact:
/// the second form states the standard deviation of the square of a
/// normal root, `sqrt(4 t^2 e^2 + 2 e^4)`, for them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RootReadings {
    /// The fourth row gives the root of the shoulders' reading `L_3`; every
    /// uncertainty to first order (calibrations trained before flag bit 10).
    Shoulders,
    /// The fourth row gives the root of the peak's deficit over its
    /// shoulders, `max(L_2 - L_3, 0)`; gloss and haze state the square's
    /// standard deviation.
    Deficit,
}

/// One point's readings and their standard uncertainties in the root form
/// (`crate::blob`'s flag bit 3). `x` is the kernel's input already scaled
/// by `1 / sqrt(s)` (`crate::kernel::root_scales`, `s` the readings'
/// scale) and `sqrt_s` is `sqrt(s)`: the rows give `t' = t / sqrt(s)` with
/// `t` the roots of `L s`, so every linear reading `L_r = t'_r^2` is
/// non-negative by construction and every reading lies within its
/// definition: gloss and haze >= 0, distinctness
/// `D = 100 max(L_2 - L_3, 0) / L_2` in 0..=100 (0 for no peak, `t'_2 = 0`).
/// The covariance is of `t / s` (per unit scale): `e_0 = sqrt(s C_00)` is
/// the standard error of `t'_0`. How the rows are read is `form`
/// ([`RootReadings`]), with `r = t'_3 / t'_2`:
/// - [`RootReadings::Shoulders`]: to first order `u(G) = 2 q |t'_0| e_0`,
///   likewise haze; `D = 100 (1 - r^2)` (0 when `r^2 >= 1`),
///   `u(D) = 200 sqrt(s) |t'_3| sqrt(v) / t'_2^2`, `v = r^2 C_22 - 2 r
///   C_23 + C_33`;
/// - [`RootReadings::Deficit`]: `u(G) = q e_0 sqrt(4 t'_0^2 + 2 e_0^2)`,
///   likewise haze; `D = 100 r^2` (100 when `r^2 >= 1`), `u(D)` the
///   expression above, to first order (the square's standard deviation
///   was tried for it too and over-covered the held-out measured
///   materials, 99.8 % of their distinctness within k = 2 against 97.8 %:
///   the factor training sets per cluster is set by the sharp lobes'
///   errors, and the second-order term then widened every broad lobe's
///   band).
///
/// `u(D)` is NaN with no peak. Readings of no light (`sqrt_s` not
/// positive) give NaN.
///
/// # Panics
/// If `block.len() != block_len(x.len())`.
#[inline]
pub fn readings_root(
    block: &[f32],
    x: &[f32],
    q: f32,
    sqrt_s: f32,
    form: RootReadings,
) -> ([f32; crate::shape::READINGS], [f32; crate::shape::READINGS]) {
    let m = x.len();
    assert!(block.len() == block_len(m), "a gloss block is LINEAR x m rows and the covariance");
    if sqrt_s.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
        return (NO_READINGS, NO_READINGS);
    }
    let mut t = [0.0f32; LINEAR];
    crate::kernel::mat_vec_f32_4(&block[..LINEAR * m], x, &mut t);
    let c = &block[LINEAR * m..];
    let sd = &c[COV_LEN..];
    let (t2, t3) = (t[2], t[3]);
    let (d, u_d) = if t2 != 0.0 {
        let r = t3 / t2;
        let r2 = r * r;
        let d = match form {
            RootReadings::Shoulders if r2 < 1.0 => 100.0 - 100.0 * r2,
            RootReadings::Shoulders => 0.0,
            RootReadings::Deficit if r2 < 1.0 => 100.0 * r2,
            RootReadings::Deficit => 100.0,
        };
        let var = r2 * c[7] - 2.0 * r * c[8] + c[9];
        (d, 200.0 * sqrt_s * (t3.abs() * crate::kernel::sqrt0(var)) / (t2 * t2))
    } else {
        (0.0, f32::NAN)
    };
    let (u_g, u_h) = match form {
        RootReadings::Shoulders => {
            let qs = 2.0 * q * sqrt_s;
            (qs * t[0].abs() * sd[0], qs * t[1].abs() * sd[1])
        }
        RootReadings::Deficit => {
            let (e0, e1) = (sqrt_s * sd[0], sqrt_s * sd[1]);
            (
                q * e0 * crate::kernel::sqrt0(4.0 * (t[0] * t[0]) + 2.0 * (e0 * e0)),
                q * e1 * crate::kernel::sqrt0(4.0 * (t[1] * t[1]) + 2.0 * (e1 * e1)),
            )
        }
    };
    ([q * (t[0] * t[0]), q * (t[1] * t[1]), d], [u_g, u_h, u_d])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A root-form block for m = 2 whose rows give, for x' = (1, 1)
    /// (already over sqrt(s) = 2), t' = (3, 1, 2, 1): L = t'^2.
    fn root_block() -> [f32; 4 * 2 + COV_LEN + SD_LEN] {
        let mut block = [0.0f32; 4 * 2 + COV_LEN + SD_LEN];
        block[..8].copy_from_slice(&[1.5, 1.5, 0.5, 0.5, 1.0, 1.0, 0.5, 0.5]);
        block[8 + cov_index(2, 2)] = 0.01;
        block[8 + cov_index(3, 3)] = 0.01;
        block[8 + COV_LEN] = 0.1;
        block[8 + COV_LEN + 1] = 0.2;
        block
    }

    #[test]
    fn the_root_form_reads_within_the_definitions() {
        let block = root_block();
        let (r, u) = readings_root(&block, &[1.0, 1.0], 2.0, 2.0, RootReadings::Shoulders);
        assert_eq!(r, [2.0 * 9.0, 2.0 * 1.0, 75.0]);
        assert_eq!([u[0], u[1]], [8.0 * 3.0 * 0.1, 8.0 * 1.0 * 0.2]);
        assert!(u[2] > 0.0);
        // Negative roots still give non-negative readings; shoulders above
        // the peak give no distinctness, not a negative one.
        let mut neg = block;
        for x in &mut neg[..8] {
            *x = -*x;
        }
        neg[6] = -1.5;
        neg[7] = -1.5;
        let (r, _) = readings_root(&neg, &[1.0, 1.0], 2.0, 2.0, RootReadings::Shoulders);
        assert!(r[0] > 0.0 && r[1] > 0.0 && r[2] == 0.0, "{r:?}");
        // Readings of no light: no reading.
        for row in [RootReadings::Shoulders, RootReadings::Deficit] {
            assert!(readings_root(&block, &[0.0, 0.0], 2.0, 0.0, row).0.iter().all(|x| x.is_nan()));
        }
    }

    #[test]
    fn the_deficit_row_reads_distinctness_as_the_square_of_its_ratio() {
        // t' = (3, 1, 2, t_d).
        let mut block = root_block();
        let deficit = RootReadings::Deficit;
        // t_d = 1 against a peak of 2: a quarter of the peak is deficit.
        let (r, u) = readings_root(&block, &[1.0, 1.0], 2.0, 2.0, deficit);
        assert_eq!(r[DISTINCTNESS], 25.0);
        // r = 1/2: u = 200 sqrt(s) |t_d| sqrt(r^2 C_22 - 2 r C_23 + C_33) / t_2^2.
        let want = 200.0 * 2.0 * (0.25f64 * 0.01 + 0.01).sqrt() / 4.0;
        assert!((f64::from(u[DISTINCTNESS]) - want).abs() < 1e-4 * want, "{} {want}", u[DISTINCTNESS]);
        // No deficit (a broad lobe): no distinctness.
        block[6] = 0.0;
        block[7] = 0.0;
        assert_eq!(readings_root(&block, &[1.0, 1.0], 2.0, 2.0, deficit).0[DISTINCTNESS], 0.0);
        // A deficit larger than the peak (the rows overshoot): 100, not more.
        block[6] = -3.0;
        block[7] = -3.0;
        assert_eq!(readings_root(&block, &[1.0, 1.0], 2.0, 2.0, deficit).0[DISTINCTNESS], 100.0);
        // Gloss and haze read the same; their uncertainty is the square's
        // standard deviation: q e sqrt(4 t^2 + 2 e^2), e = sqrt(s) sd.
        let shoulders = readings_root(&block, &[1.0, 1.0], 2.0, 2.0, RootReadings::Shoulders);
        let with_deficit = readings_root(&block, &[1.0, 1.0], 2.0, 2.0, deficit);
        assert_eq!(shoulders.0[..2], with_deficit.0[..2]);
        let (e0, e1) = (2.0 * 0.1f64, 2.0 * 0.2f64);
        let want = [2.0 * e0 * (4.0 * 9.0 + 2.0 * e0 * e0).sqrt(), 2.0 * e1 * (4.0 * 1.0 + 2.0 * e1 * e1).sqrt()];
        for (k, w) in want.iter().enumerate() {
            assert!((f64::from(with_deficit.1[k]) - w).abs() < 1e-5 * w, "{k}: {} {w}", with_deficit.1[k]);
            assert!(with_deficit.1[k] > shoulders.1[k], "{k}: above the first order");
        }
        // A reading near 0 is not stated exact.
        let mut dark = block;
        dark[..4].fill(0.0);
        assert!(readings_root(&dark, &[1.0, 1.0], 2.0, 2.0, deficit).1[0] > 0.0);
        assert_eq!(readings_root(&dark, &[1.0, 1.0], 2.0, 2.0, RootReadings::Shoulders).1[0], 0.0);
    }

    #[test]
    fn packed_covariance_indices_run_row_by_row() {
        let mut k = 0;
        for i in 0..LINEAR {
            for j in i..LINEAR {
                assert_eq!(cov_index(i, j), k, "({i}, {j})");
                k += 1;
            }
        }
        assert_eq!(k, COV_LEN);
    }

    #[test]
    fn readings_follow_their_definitions() {
        // m = 2; rows pick x_0, x_1, x_0 + x_1, x_0 - x_1.
        let mut block = [0.0f32; 20];
        block[..8].copy_from_slice(&[1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, -1.0]);
        block[18..].copy_from_slice(&[2.0, 3.0]);
        // Covariance: diag 4, 9, 1, 0.25; cov(2,3) = 0.1.
        block[8 + cov_index(0, 0)] = 4.0;
        block[8 + cov_index(1, 1)] = 9.0;
        block[8 + cov_index(2, 2)] = 1.0;
        block[8 + cov_index(2, 3)] = 0.1;
        block[8 + cov_index(3, 3)] = 0.25;
        let (r, u) = readings(&block, &[3.0, 1.0], 2.0, 0.5);
        assert_eq!(r[SPECULAR_GU], 6.0);
        assert_eq!(r[HAZE_HU], 2.0);
        assert_eq!(r[DISTINCTNESS], 100.0 - 100.0 * (2.0 / 4.0));
        assert_eq!(u[SPECULAR_GU], 2.0 * 0.5 * 2.0);
        assert_eq!(u[HAZE_HU], 2.0 * 0.5 * 3.0);
        let rr = 2.0f64 / 4.0;
        let want = 100.0 * 0.5 * (rr * rr * 1.0 - 2.0 * rr * 0.1 + 0.25f64).sqrt() / 4.0;
        assert!((f64::from(u[DISTINCTNESS]) - want).abs() < 1e-5 * want, "{} {want}", u[DISTINCTNESS]);
        // No peak: no distinctness.
        let (r, u) = readings(&block, &[-3.0, 1.0], 2.0, 1.0);
        assert!(r[DISTINCTNESS].is_nan() && u[DISTINCTNESS].is_nan());
        assert!(r[SPECULAR_GU].is_finite());
    }
}
