//! Piecewise (clustered) estimation: which of K matrices a point uses.

/// The clustered estimator's selection rule: the index of the centroid
/// nearest (squared Euclidean distance, first one on ties) to the readings
/// normalised by their sum, `u = v / sum_i |v_i|` (all-zero readings stay 0).
/// `centroids` is K x m row-major, in the same normalised space. Cost: m adds,
/// one division, m multiplies, K*m subtract/multiply-adds and K compares.
///
/// # Panics
/// If `centroids.len()` is not a non-zero multiple of `v.len()`.
#[inline]
pub fn select_cluster(centroids: &[f32], v: &[f32]) -> usize {
    let m = v.len();
    assert!(m > 0 && !centroids.is_empty() && centroids.len().is_multiple_of(m), "centroids must be K x m");
    let mut sum = 0.0f32;
    for x in v {
        sum += x.abs();
    }
    let inv = if sum > 0.0 { 1.0 / sum } else { 0.0 };
    // Normalise once (same products as inside the loop, so the same bits).
    let mut ubuf = [0.0f32; 16];
    let u: &[f32] = if m <= ubuf.len() {
        for (o, x) in ubuf.iter_mut().zip(v) {
            *o = *x * inv;
        }
        &ubuf[..m]
    } else {
        &[]
    };
    let (mut best, mut best_d) = (0usize, f32::INFINITY);
    for (c, row) in centroids.chunks_exact(m).enumerate() {
        let mut d = 0.0f32;
        if u.is_empty() {
            for (x, cx) in v.iter().zip(row) {
                let e = *x * inv - *cx;
                d += e * e;
            }
        } else {
            for (x, cx) in u.iter().zip(row) {
                let e = *x - *cx;
                d += e * e;
            }
        }
        if d < best_d {
            best_d = d;
            best = c;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selection_picks_the_nearest_normalised_centroid() {
        // Three centroids in the normalised space of m = 3 readings.
        let c = [1.0f32, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0];
        assert_eq!(select_cluster(&c, &[5.0, 0.1, 0.2]), 0);
        assert_eq!(select_cluster(&c, &[0.0, 900.0, 1.0]), 1);
        // Scale does not matter: only the shape of the readings.
        assert_eq!(select_cluster(&c, &[2.0, 2.1, 1.9]), 2);
        assert_eq!(select_cluster(&c, &[2e-6, 2.1e-6, 1.9e-6]), 2);
        // Ties go to the first centroid; zero readings are the origin.
        assert_eq!(select_cluster(&[0.5, 0.5, 0.5, 0.5], &[1.0, 1.0]), 0);
        assert_eq!(select_cluster(&c, &[0.0, 0.0, 0.0]), 2);
    }
}
