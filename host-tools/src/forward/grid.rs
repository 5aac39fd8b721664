//! The incidence-angle grid: the n bins of the BRDF vector rho.
use serde::{Deserialize, Serialize};

/// How a grid is described in instrument and scene files.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// First bin, degrees.
    pub start_deg: f64,
    /// Last bin, degrees (included when it falls on a step).
    pub stop_deg: f64,
    /// Spacing, degrees.
    pub step_deg: f64,
}

impl GridSpec {
    /// The patent profile: 25..65 deg in 0.5 deg steps (n = 81).
    pub fn patent() -> Self {
        Self { start_deg: 25.0, stop_deg: 65.0, step_deg: 0.5 }
    }
}

/// Why a grid description was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GridError {
    /// A field is not finite.
    #[error("grid field `{0}` is not a finite number")]
    NotFinite(&'static str),
    /// Step not positive or stop before start.
    #[error("grid needs step_deg > 0 and stop_deg > start_deg (got start {start}, stop {stop}, step {step})")]
    Empty {
        /// start_deg
        start: f64,
        /// stop_deg
        stop: f64,
        /// step_deg
        step: f64,
    },
    /// Angles outside [0, 90).
    #[error("grid angles must lie in [0, 90) degrees (got {start}..{stop})")]
    OutOfRange {
        /// start_deg
        start: f64,
        /// stop_deg
        stop: f64,
    },
    /// More bins than the calibration blob can hold.
    #[error("grid has {0} bins; at most {max} are supported", max = brdf_meter::blob::MAX_BINS)]
    TooMany(usize),
}

/// A uniform grid of incidence angles.
#[derive(Clone, Debug, PartialEq)]
pub struct AngleGrid {
    start: f64,
    step: f64,
    bins: Vec<f64>,
}

impl AngleGrid {
    /// Builds the grid a spec describes.
    pub fn new(spec: &GridSpec) -> Result<Self, GridError> {
        for (name, v) in [("start_deg", spec.start_deg), ("stop_deg", spec.stop_deg), ("step_deg", spec.step_deg)] {
            if !v.is_finite() {
                return Err(GridError::NotFinite(name));
            }
        }
        let (start, stop, step) = (spec.start_deg, spec.stop_deg, spec.step_deg);
        if step <= 0.0 || stop <= start {
            return Err(GridError::Empty { start, stop, step });
        }
        if start < 0.0 || stop >= 90.0 {
            return Err(GridError::OutOfRange { start, stop });
        }
        // Tolerate rounding in (stop - start) / step.
        let count = ((stop - start) / step + 1e-9).floor() as usize + 1;
        if count > brdf_meter::blob::MAX_BINS {
            return Err(GridError::TooMany(count));
        }
        let bins = (0..count).map(|i| start + step * i as f64).collect();
        Ok(Self { start, step, bins })
    }

    /// The patent profile's grid, n = 81.
    pub fn patent() -> Self {
        Self::new(&GridSpec::patent()).expect("patent grid is valid")
    }

    /// Number of bins n.
    pub fn n(&self) -> usize {
        self.bins.len()
    }

    /// Bin angles in degrees.
    pub fn bins_deg(&self) -> &[f64] {
        &self.bins
    }

    /// Spacing in degrees.
    pub fn step_deg(&self) -> f64 {
        self.step
    }

    /// Whether `theta_deg` lies within the grid's span.
    pub fn contains(&self, theta_deg: f64) -> bool {
        let last = *self.bins.last().expect("grid is never empty");
        theta_deg >= self.start - 1e-9 && theta_deg <= last + 1e-9
    }

    /// Splits `theta_deg` between its two neighbouring bins by linear
    /// interpolation: returns `(j, 1 - f)` for bin j and `(j + 1, f)`, or `None`
    /// when the angle is outside the grid.
    pub fn split(&self, theta_deg: f64) -> Option<[(usize, f64); 2]> {
        if !theta_deg.is_finite() || !self.contains(theta_deg) {
            return None;
        }
        let mut t = ((theta_deg - self.start) / self.step).max(0.0);
        // An angle that is a bin centre up to rounding (e.g. acos(cos(33 deg)))
        // belongs wholly to that bin, so far-field rows stay one-hot.
        if (t - t.round()).abs() < 1e-9 {
            t = t.round();
        }
        let n = self.n();
        if n == 1 {
            return Some([(0, 1.0), (0, 0.0)]);
        }
        let j = (t.floor() as usize).min(n - 2);
        let f = (t - j as f64).clamp(0.0, 1.0);
        Some([(j, 1.0 - f), (j + 1, f)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patent_grid_has_81_bins_from_25_to_65() {
        let g = AngleGrid::patent();
        assert_eq!(g.n(), 81);
        assert_eq!(g.bins_deg()[0], 25.0);
        assert_eq!(*g.bins_deg().last().unwrap(), 65.0);
    }

    #[test]
    fn split_is_linear_interpolation_and_conserves_weight() {
        let g = AngleGrid::patent();
        let [(j0, a), (j1, b)] = g.split(33.2).unwrap();
        assert_eq!((j0, j1), (16, 17));
        assert!((a - 0.6).abs() < 1e-12 && (b - 0.4).abs() < 1e-12);
        let [(j, w), _] = g.split(65.0).unwrap();
        assert_eq!(g.bins_deg()[j] + g.step_deg() * (1.0 - w), 65.0);
        assert!(g.split(24.9).is_none() && g.split(65.1).is_none() && g.split(f64::NAN).is_none());
    }

    #[test]
    fn bad_specs_are_refused_with_the_reason() {
        let bad = |s, e, st| AngleGrid::new(&GridSpec { start_deg: s, stop_deg: e, step_deg: st }).unwrap_err();
        assert!(matches!(bad(30.0, 20.0, 1.0), GridError::Empty { .. }));
        assert!(matches!(bad(30.0, 40.0, 0.0), GridError::Empty { .. }));
        assert!(matches!(bad(30.0, 95.0, 1.0), GridError::OutOfRange { .. }));
        assert!(matches!(bad(f64::NAN, 40.0, 1.0), GridError::NotFinite("start_deg")));
        assert!(matches!(bad(0.0, 89.0, 0.01), GridError::TooMany(_)));
    }
}
