//! Which of a calibration's per-bin uncertainty tables a point's bins take.
//!
//! A calibration's per-bin uncertainty is set, per zone and cluster, from
//! the errors of held-out training readings (host-tools'
//! `calibration::estimators::scale_free`). The readings a cluster selects
//! can be read as a broad lobe or as a sharp peak, and the two err
//! differently: where a sharp estimate's peak may be far off (a mirror
//! spike read as the prior's idea of one), a broad estimate's is not, and
//! one table for both states the polished materials' errors on every
//! smooth lobe (in a one-zone calibration of the handheld, 4 to 6 times
//! the broad lobes' own at the specular bins) while the few sharp readings
//! of a mostly broad cluster are covered less often than the rest. A blob may
//! therefore carry a second table ([`crate::blob`], flag bit 8): the first
//! for points whose estimate is sharp, the second for those whose estimate
//! is broad ([`is_broad`]), each set from held-out readings of its own
//! kind.
//!
//! The device does not use the tables (it streams each point's scale,
//! and the host states the per-bin uncertainty from it); the host decides
//! from the values a frame carries, so a frame of a subset of the bins is
//! judged on those.

/// A point's estimate is broad when its half-maximum width about its
/// highest value is at least this (deg): over twice the widest peak
/// resolution of the product's calibrations (1.16 deg on the handheld,
/// 0.76 on the patent profile), so a broad estimate is a lobe the
/// calibration resolves by a margin, never its response to a spike.
pub const BROAD_WIDTH_DEG: f32 = 3.0;

/// Which table a point takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BandTable {
    /// The first table: a sharp estimate's, or every point's when the
    /// blob carries one table.
    Sharp,
    /// The second table: a broad estimate's.
    Broad,
}

/// The full width (deg) at half of the highest of `rho` (on the ascending
/// angles `bins_deg`) about it, the half-maximum crossings interpolated
/// between bins; a side that stays above half to the end of the grid
/// counts to the end. 0 when there is no positive value (or the lengths
/// differ, or a value is not a number).
pub fn half_maximum_width(bins_deg: &[f32], rho: &[f32]) -> f32 {
    if bins_deg.len() != rho.len() || rho.iter().any(|x| x.is_nan()) {
        return 0.0;
    }
    let Some((k, top)) = rho.iter().copied().enumerate().fold(None, |best: Option<(usize, f32)>, (j, x)| match best {
        Some((_, b)) if b >= x => best,
        _ => Some((j, x)),
    }) else {
        return 0.0;
    };
    if top <= 0.0 {
        return 0.0;
    }
    let half = 0.5 * top;
    // The crossing between bins a (above half) and b (below) on one side.
    let cross = |a: usize, b: usize| {
        let (ya, yb) = (rho[a], rho[b]);
        bins_deg[a] + (bins_deg[b] - bins_deg[a]) * ((ya - half) / (ya - yb))
    };
    let mut lo = k;
    while lo > 0 && rho[lo - 1] >= half {
        lo -= 1;
    }
    let left = if lo > 0 { cross(lo, lo - 1) } else { bins_deg[0] };
    let mut hi = k;
    while hi + 1 < rho.len() && rho[hi + 1] >= half {
        hi += 1;
    }
    let right = if hi + 1 < rho.len() { cross(hi, hi + 1) } else { bins_deg[rho.len() - 1] };
    right - left
}

/// Whether the estimate `rho` on `bins_deg` is broad ([`BROAD_WIDTH_DEG`]).
pub fn is_broad(bins_deg: &[f32], rho: &[f32]) -> bool {
    half_maximum_width(bins_deg, rho) >= BROAD_WIDTH_DEG
}

/// The table a point of estimate `rho` takes, from a blob that carries
/// the second table (`two_tables`) or not.
pub fn table_of(two_tables: bool, bins_deg: &[f32], rho: &[f32]) -> BandTable {
    if two_tables && is_broad(bins_deg, rho) { BandTable::Broad } else { BandTable::Sharp }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> [f32; 41] {
        core::array::from_fn(|i| 40.0 + 0.5 * i as f32)
    }

    /// A triangle of half-maximum width `w` centred at 50 deg on a level `base`.
    fn triangle(w: f32, base: f32) -> [f32; 41] {
        let g = grid();
        core::array::from_fn(|i| base + (1.0 - (g[i] - 50.0).abs() / w).max(0.0))
    }

    #[test]
    fn the_width_is_the_half_maximum_crossings_apart() {
        let g = grid();
        for w in [0.5f32, 1.0, 2.9, 3.0, 7.25] {
            let width = half_maximum_width(&g, &triangle(w, 0.0));
            assert!((width - w).abs() < 1e-5, "{w}: {width}");
        }
        // On a level the half maximum is of the whole height.
        let width = half_maximum_width(&g, &triangle(4.0, 0.5));
        assert!((width - 8.0 * 0.75).abs() < 1e-5, "{width}");
        // A flat estimate spans the grid; nothing positive has no width.
        assert_eq!(half_maximum_width(&g, &[0.3; 41]), 20.0);
        assert_eq!(half_maximum_width(&g, &[0.0; 41]), 0.0);
        assert_eq!(half_maximum_width(&g, &[-1.0; 41]), 0.0);
        let mut nan = [0.3; 41];
        nan[3] = f32::NAN;
        assert_eq!(half_maximum_width(&g, &nan), 0.0);
        assert_eq!(half_maximum_width(&g[..40], &[0.3; 41]), 0.0);
    }

    #[test]
    fn a_point_takes_the_broad_table_only_from_a_blob_that_has_one() {
        let g = grid();
        let (sharp, broad) = (triangle(2.0, 0.0), triangle(3.5, 0.0));
        assert_eq!(table_of(true, &g, &sharp), BandTable::Sharp);
        assert_eq!(table_of(true, &g, &broad), BandTable::Broad);
        assert_eq!(table_of(false, &g, &broad), BandTable::Sharp);
    }
}
