//! The sensor's linearity correction: what the factory measured of how the
//! sensor's counts bend away from the light that made them, undone on every
//! reading before it is white-calibrated.
//!
//! A line sensor's output is not quite proportional to its light (a
//! photodiode's charge-to-voltage conversion, the amplifier): a response
//! `c = FS (x / FS)^1.01` reads 3.7 % low at 100 counts and 0.7 % low at
//! 2,000. White calibration divides a sample's counts by the white tile's,
//! read at other counts, so a dark sample comes out bent against the white
//! (`(S/W)^gamma` for that response), and the shorter exposures of a
//! mirror-like sample against the long one. The correction is a factor per
//! octave of counts, the linear reading of `s` counts (dark-corrected) being
//! `s f(s)`:
//!
//! - knot `k` is at `2^k` counts, `k = 0..LINEARITY_KNOTS` (1 to 65,536
//!   counts: any converter up to 16 bits);
//! - between knots the factor is interpolated linearly in the float's
//!   mantissa, `f = f_k + t (f_{k+1} - f_k)` with `s = 2^k (1 + t)`, which
//!   needs no logarithm: the octave is the float's exponent, `t` its
//!   mantissa (a smooth response, one whose factor is linear in `log s`,
//!   is followed within 0.1 of its change over an octave);
//! - below one count the factor is the first knot's, above the last the
//!   last knot's.
//!
//! The host measures the factors (`host_tools::forward::scene::sensor_linearity`)
//! and writes them into the calibration blob (`crate::blob`, flag bit 11);
//! the device and the host apply this one function, so their readings agree
//! bit for bit. Its overall scale is arbitrary (white calibration divides it
//! out); the host's measurement sets it to 1 at the top of the range.

/// Knots of the correction: one per octave, `2^0 .. 2^16` counts.
pub const LINEARITY_KNOTS: usize = 17;

/// Smallest and largest factor a valid correction holds: a sensor whose
/// response bends by more than a factor 8 over its range is broken, not
/// nonlinear (a response `c = FS (x / FS)^1.3` needs 7 at one count).
pub const FACTOR_RANGE: (f32, f32) = (0.125, 8.0);

/// A sensor's linearity correction (the factor at each knot).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Linearity {
    factors: [f32; LINEARITY_KNOTS],
}

/// Why a set of factors is no linearity correction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinearityError {
    /// Factor `index` is NaN, infinite or outside [`FACTOR_RANGE`].
    OutOfRange {
        /// The knot.
        index: usize,
    },
    /// The corrected response falls between knots `index` and `index + 1`
    /// (more counts would read as less light).
    NotMonotone {
        /// The lower knot.
        index: usize,
    },
}

impl Linearity {
    /// The correction of `factors`, when it is one: every factor finite and
    /// within [`FACTOR_RANGE`], and the corrected response `s f(s)`
    /// increasing in `s`. Within an octave `s f(s)` is a parabola in `t`,
    /// increasing on `0..=1` when `3 f_{k+1} >= 2 f_k` (and `f_{k+1} >= 0`).
    pub fn new(factors: [f32; LINEARITY_KNOTS]) -> Result<Self, LinearityError> {
        let mut last = f32::NAN;
        for (index, &f) in factors.iter().enumerate() {
            if let Some(e) = fault(index, f, last) {
                return Err(e);
            }
            last = f;
        }
        Ok(Self { factors })
    }

    /// The correction of factors a validated blob holds (`crate::blob`
    /// checked them with [`Self::new`]'s rules when it parsed).
    pub(crate) fn validated(factors: [f32; LINEARITY_KNOTS]) -> Self {
        Self { factors }
    }

    /// The correction that changes nothing: every factor 1. Applying it
    /// gives back every signal bit for bit (`s (1 + t 0) = s`).
    pub const IDENTITY: Self = Self { factors: [1.0; LINEARITY_KNOTS] };

    /// The factors, knot by knot.
    pub fn factors(&self) -> &[f32; LINEARITY_KNOTS] {
        &self.factors
    }

    /// The linear reading of a dark-corrected signal of `s` counts, `s f(s)`.
    /// Inlined: the device calls it once a reading, from the correction's
    /// inner loop (`correct_reading`, its one call site there); the call
    /// cost 7 % of a shorter exposure's frame (275 against 255 us).
    #[inline(always)]
    pub fn linear(&self, s: f32) -> f32 {
        // Also NaN and negative signals (a reading below its dark frame):
        // the first knot's factor keeps their sign and their NaN.
        if s.is_nan() || s < 1.0 {
            return s * self.factors[0];
        }
        let bits = s.to_bits();
        let octave = ((bits >> 23) - 127) as usize;
        if octave >= LINEARITY_KNOTS - 1 {
            return s * self.factors[LINEARITY_KNOTS - 1];
        }
        let t = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000) - 1.0;
        let (a, b) = (self.factors[octave], self.factors[octave + 1]);
        s * (a + t * (b - a))
    }
}

/// What is wrong with factor `f` at knot `index`, the knot before holding
/// `last` (NaN for the first): [`Linearity::new`]'s rules, one knot at a
/// time, so the blob's parser runs them over the section in place.
#[inline]
pub fn fault(index: usize, f: f32, last: f32) -> Option<LinearityError> {
    if !(FACTOR_RANGE.0..=FACTOR_RANGE.1).contains(&f) {
        Some(LinearityError::OutOfRange { index })
    } else if 3.0 * f < 2.0 * last {
        Some(LinearityError::NotMonotone { index: index - 1 })
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn power_law(gamma: f64) -> [f32; LINEARITY_KNOTS] {
        // The factor that undoes c = FS (x / FS)^gamma, 1 at 4096 counts.
        core::array::from_fn(|k| (2f64.powi(k as i32) / 4096.0).powf(1.0 / gamma - 1.0) as f32)
    }

    #[test]
    fn a_unit_correction_changes_no_bit() {
        let one = Linearity::new([1.0; LINEARITY_KNOTS]).unwrap();
        for s in [-3.5f32, 0.0, 0.25, 1.0, 7.0, 100.5, 4095.0, 70_000.0, f32::MAX] {
            assert_eq!(one.linear(s).to_bits(), s.to_bits());
        }
        assert!(one.linear(f32::NAN).is_nan());
    }

    #[test]
    fn the_factor_is_exact_at_the_knots_and_interpolated_in_the_mantissa_between() {
        let lin = Linearity::new(power_law(1.01)).unwrap();
        for k in 0..LINEARITY_KNOTS {
            let s = 2f32.powi(k as i32);
            assert_eq!(lin.linear(s), s * lin.factors()[k]);
        }
        // Half way through octave 9 (768 counts = 512 x 1.5).
        let f = lin.factors();
        assert_eq!(lin.linear(768.0), 768.0 * (f[9] + 0.5 * (f[10] - f[9])));
        // Below one count and above the last knot: the end factors.
        assert_eq!(lin.linear(0.5), 0.5 * f[0]);
        assert_eq!(lin.linear(-20.0), -20.0 * f[0]);
        assert_eq!(lin.linear(1.0e6), 1.0e6 * f[LINEARITY_KNOTS - 1]);
    }

    #[test]
    fn a_power_law_response_is_undone_within_its_interpolation_error() {
        // The sensor reads c = FS (x / FS)^1.01; the correction gives x back.
        let gamma = 1.01;
        let lin = Linearity::new(power_law(gamma)).unwrap();
        let mut worst = 0.0f64;
        for x in [10.0f64, 37.0, 100.0, 333.0, 1000.0, 2500.0, 4000.0] {
            let c = 4096.0 * (x / 4096.0).powf(gamma);
            let back = f64::from(lin.linear(c as f32));
            worst = worst.max((back / x - 1.0).abs());
        }
        // Uncorrected, 100 counts read 3.7 % low; corrected, within 0.1 %.
        assert!(worst < 1e-3, "worst relative error {worst}");
    }

    #[test]
    fn factors_out_of_range_or_a_falling_response_are_refused() {
        let mut f = [1.0; LINEARITY_KNOTS];
        f[3] = f32::NAN;
        assert_eq!(Linearity::new(f), Err(LinearityError::OutOfRange { index: 3 }));
        f[3] = 9.0;
        assert_eq!(Linearity::new(f), Err(LinearityError::OutOfRange { index: 3 }));
        f[3] = 1.0;
        f[8] = 0.6;
        // 3 x 0.6 < 2 x 1: counts just above 128 read less light than 128.
        assert_eq!(Linearity::new(f), Err(LinearityError::NotMonotone { index: 7 }));
        f[8] = 0.7;
        assert!(Linearity::new(f).is_ok());
    }
}
