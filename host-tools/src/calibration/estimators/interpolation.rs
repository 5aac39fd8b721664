//! Linear interpolation between the measured angles (the patent's \[0004\]
//! baseline).
//!
//! Reading i is taken as the reflectance factor at the incidence angle of
//! LED i's centre ray, and bins between two such angles are linearly
//! interpolated; bins outside the measured range take the nearest end value
//! (the `numpy.interp` convention: extrapolating a peaked BRDF linearly is
//! worse). LEDs that share a centre angle are averaged. W is a fixed n x m
//! matrix, so this baseline runs through the same kernel as the others.
use super::{Built, EstimatorError};
use nalgebra::DMatrix;

/// Interpolation weights, n x m, for bins `bins_deg` and LED centre angles `centres_deg`.
pub fn weights(bins_deg: &[f64], centres_deg: &[f64]) -> Result<DMatrix<f64>, EstimatorError> {
    let m = centres_deg.len();
    if m == 0 {
        return Err(EstimatorError::BadAngles("no LED centre angles given".into()));
    }
    if bins_deg.is_empty() {
        return Err(EstimatorError::BadAngles("no angle bins given".into()));
    }
    if let Some(i) = centres_deg.iter().position(|x| !x.is_finite()) {
        return Err(EstimatorError::BadAngles(format!("centre angle of LED {i} is not finite")));
    }
    if let Some(j) = bins_deg.iter().position(|x| !x.is_finite()) {
        return Err(EstimatorError::BadAngles(format!("bin {j} is not finite")));
    }
    // Distinct angles (ascending), each with the LEDs at it.
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|a, b| centres_deg[*a].total_cmp(&centres_deg[*b]));
    let mut knots: Vec<(f64, Vec<usize>)> = Vec::new();
    for i in order {
        let a = centres_deg[i];
        match knots.last_mut() {
            Some((x, leds)) if (a - *x).abs() <= 1e-9 * a.abs().max(1.0) => leds.push(i),
            _ => knots.push((a, vec![i])),
        }
    }
    let n = bins_deg.len();
    let mut w = DMatrix::zeros(n, m);
    let mut put = |j: usize, knot: &(f64, Vec<usize>), weight: f64| {
        for &i in &knot.1 {
            w[(j, i)] += weight / knot.1.len() as f64;
        }
    };
    for (j, &b) in bins_deg.iter().enumerate() {
        let first = &knots[0];
        let last = &knots[knots.len() - 1];
        if b <= first.0 {
            put(j, first, 1.0);
        } else if b >= last.0 {
            put(j, last, 1.0);
        } else {
            let k = knots.partition_point(|(x, _)| *x <= b) - 1; // knots[k].0 <= b < knots[k+1].0
            let (x0, x1) = (knots[k].0, knots[k + 1].0);
            let t = (b - x0) / (x1 - x0);
            put(j, &knots[k], 1.0 - t);
            put(j, &knots[k + 1], t);
        }
    }
    Ok(w)
}

pub(crate) fn build(bins_deg: &[f64], centres_deg: &[f64], m: usize) -> Result<Built, EstimatorError> {
    if centres_deg.len() != m {
        return Err(EstimatorError::BadAngles(format!("{} centre angles given for {m} readings", centres_deg.len())));
    }
    let w = weights(bins_deg, centres_deg)?;
    Ok(Built {
        w,
        condition_system: 1.0,
        effective_rank: m as f64,
        regularisation: 0.0,
        tolerance: 0.0,
        method: "[0004] baseline: linear interpolation between the LEDs' centre angles, nearest value outside".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reproduces_a_function_linear_in_angle_inside_the_measured_range() {
        let centres = [57.0, 33.0, 41.0, 37.0, 45.0, 53.0, 49.0]; // any order
        let bins: Vec<f64> = (0..81).map(|j| 25.0 + 0.5 * j as f64).collect();
        let w = weights(&bins, &centres).unwrap();
        let f = |a: f64| 0.3 + 0.021 * a;
        let v = nalgebra::DVector::from_iterator(7, centres.iter().map(|a| f(*a)));
        let est = &w * v;
        for (j, &b) in bins.iter().enumerate() {
            let want = f(b.clamp(33.0, 57.0));
            assert!((est[j] - want).abs() < 1e-12, "bin {b}: {} vs {want}", est[j]);
        }
        // Rows are convex combinations.
        for j in 0..81 {
            assert!((w.row(j).sum() - 1.0).abs() < 1e-12);
            assert!(w.row(j).iter().all(|x| *x >= 0.0));
        }
    }

    #[test]
    fn duplicate_leds_are_averaged_and_bad_angles_refused() {
        let w = weights(&[1.0, 1.5, 2.0], &[1.0, 2.0, 2.0]).unwrap();
        assert_eq!(w.row(1).iter().copied().collect::<Vec<_>>(), vec![0.5, 0.25, 0.25]);
        assert!(weights(&[1.0], &[f64::NAN]).is_err());
        assert!(weights(&[1.0], &[]).is_err());
    }
}
