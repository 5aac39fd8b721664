//! A measured in-plane BRDF: reflectance factor sampled at incidence angles
//! (for the instrument's fixed view), linearly interpolated between samples.
use super::Brdf;
use nalgebra::Vector3;

/// Why measured samples were refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TabulatedError {
    /// Fewer than two samples.
    #[error("a measured BRDF needs at least two samples, got {0}")]
    TooFew(usize),
    /// A sample is NaN or infinite.
    #[error("sample {index}: {what} is not a finite number")]
    NotFinite {
        /// Sample index (0-based).
        index: usize,
        /// `angle` or `value`.
        what: &'static str,
    },
    /// A reflectance factor below zero.
    #[error("sample {index}: value {value} is negative; a reflectance factor is >= 0")]
    Negative {
        /// Sample index.
        index: usize,
        /// Value.
        value: f64,
    },
    /// An angle outside [0, 90).
    #[error("sample {index}: angle {angle} deg is outside [0, 90)")]
    AngleOutOfRange {
        /// Sample index.
        index: usize,
        /// Angle.
        angle: f64,
    },
    /// Angles not strictly increasing.
    #[error("sample {index}: angle {angle} deg is not above the previous one; sort the samples and remove duplicates")]
    NotAscending {
        /// Sample index.
        index: usize,
        /// Angle.
        angle: f64,
    },
    /// A requested angle outside the measured span.
    #[error("angle {angle} deg is outside the measured span {lo}..{hi} deg")]
    OutsideSpan {
        /// Requested.
        angle: f64,
        /// First measured angle.
        lo: f64,
        /// Last measured angle.
        hi: f64,
    },
}

/// Measured reflectance factors R(theta_i) at the instrument's view.
#[derive(Clone, Debug, PartialEq)]
pub struct Tabulated {
    angles_deg: Vec<f64>,
    values: Vec<f64>,
}

impl Tabulated {
    /// Validates samples: finite, non-negative, angles strictly ascending in [0, 90).
    pub fn new(angles_deg: Vec<f64>, values: Vec<f64>) -> Result<Self, TabulatedError> {
        assert_eq!(angles_deg.len(), values.len());
        if angles_deg.len() < 2 {
            return Err(TabulatedError::TooFew(angles_deg.len()));
        }
        for (index, (&a, &v)) in angles_deg.iter().zip(&values).enumerate() {
            if !a.is_finite() {
                return Err(TabulatedError::NotFinite { index, what: "angle" });
            }
            if !v.is_finite() {
                return Err(TabulatedError::NotFinite { index, what: "value" });
            }
            if v < 0.0 {
                return Err(TabulatedError::Negative { index, value: v });
            }
            if !(0.0..90.0).contains(&a) {
                return Err(TabulatedError::AngleOutOfRange { index, angle: a });
            }
            if index > 0 && a <= angles_deg[index - 1] {
                return Err(TabulatedError::NotAscending { index, angle: a });
            }
        }
        Ok(Self { angles_deg, values })
    }

    /// Reflectance factor at `theta_deg`, linearly interpolated.
    pub fn at(&self, theta_deg: f64) -> Result<f64, TabulatedError> {
        let (lo, hi) = (self.angles_deg[0], *self.angles_deg.last().unwrap());
        if !(theta_deg >= lo - 1e-9 && theta_deg <= hi + 1e-9) {
            return Err(TabulatedError::OutsideSpan { angle: theta_deg, lo, hi });
        }
        let k = self.angles_deg.partition_point(|&a| a <= theta_deg).clamp(1, self.angles_deg.len() - 1);
        let (a0, a1) = (self.angles_deg[k - 1], self.angles_deg[k]);
        let t = ((theta_deg - a0) / (a1 - a0)).clamp(0.0, 1.0);
        Ok(self.values[k - 1] * (1.0 - t) + self.values[k] * t)
    }
}

impl Brdf for Tabulated {
    /// Only meaningful in-plane at the view it was measured for: the incidence
    /// angle is read from `wi`; outside the measured span it is 0.
    fn f_r(&self, wi: &Vector3<f64>, _wo: &Vector3<f64>) -> f64 {
        let theta = wi.z.clamp(-1.0, 1.0).acos().to_degrees();
        self.at(theta).unwrap_or(0.0) / std::f64::consts::PI
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_and_refuses_bad_samples_with_the_reason() {
        let t = Tabulated::new(vec![20.0, 40.0, 60.0], vec![1.0, 3.0, 2.0]).unwrap();
        assert_eq!(t.at(30.0).unwrap(), 2.0);
        assert_eq!(t.at(60.0).unwrap(), 2.0);
        assert!((t.reflectance(50.0, 45.0) - 2.5).abs() < 1e-9);
        assert!(matches!(t.at(61.0), Err(TabulatedError::OutsideSpan { .. })));
        assert_eq!(
            Tabulated::new(vec![1.0, 2.0], vec![1.0, -0.5]),
            Err(TabulatedError::Negative { index: 1, value: -0.5 })
        );
        assert_eq!(
            Tabulated::new(vec![1.0, 1.0], vec![1.0, 1.0]),
            Err(TabulatedError::NotAscending { index: 1, angle: 1.0 })
        );
        assert_eq!(
            Tabulated::new(vec![1.0, 2.0], vec![f64::NAN, 1.0]),
            Err(TabulatedError::NotFinite { index: 0, what: "value" })
        );
    }
}
