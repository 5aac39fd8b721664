//! The noise of one point's white-calibrated readings, as training models
//! it: for LED i, the variance of `v_i = (lit - dark) / white_i` as a
//! function of its noise-free value,
//!
//! ```text
//! var(v_i) = a v_i^2 + b_i v_i + c_i
//! ```
//!
//! `a` is the relative part (the patent's 2 % is `a = 0.02^2`), `b_i` the
//! photon shot noise of the signal and `c_i` what does not depend on it
//! (read noise, the dark level's shot noise, quantisation: twice, since the
//! dark frame is subtracted), each divided by the white count of the LED at
//! the point, which is why a dim LED or a dark pixel is noisier.
//! `crate::forward::scene::noise_level::reading_noise` derives it from a
//! scene's sensor effects; [`ReadingNoise::relative`] is the patent's model.

/// The variance model of one point's readings (m LEDs).
#[derive(Clone, Debug, PartialEq)]
pub struct ReadingNoise {
    /// Relative variance (per squared reading).
    pub a: f64,
    /// Per LED, variance per unit reading.
    pub b: Vec<f64>,
    /// Per LED, constant variance.
    pub c: Vec<f64>,
    /// Per LED, the reading above which the long exposure saturates (empty:
    /// never), and the shorter exposures' ratios it is then read at: a
    /// reading from an exposure `r` times shorter has `r` times the shot
    /// variance and `r^2` times the constant one.
    pub saturates_above: Vec<f64>,
    /// The shorter exposures' ratios, ascending.
    pub ratios: Vec<f64>,
}

impl ReadingNoise {
    /// Noise proportional to the reading, standard deviation `s v` (m LEDs).
    pub fn relative(s: f64, m: usize) -> Self {
        Self { a: s * s, b: vec![0.0; m], c: vec![0.0; m], saturates_above: Vec::new(), ratios: Vec::new() }
    }

    /// The exposure ratio reading `i` of value `v` is read at: 1, or the
    /// first shorter exposure it does not saturate (the last when all do).
    pub fn ratio(&self, i: usize, v: f64) -> f64 {
        let Some(&limit) = self.saturates_above.get(i) else { return 1.0 };
        if v <= limit {
            return 1.0;
        }
        self.ratios.iter().copied().find(|r| v / r <= limit).or(self.ratios.last().copied()).unwrap_or(1.0)
    }

    /// LEDs m.
    pub fn m(&self) -> usize {
        self.b.len()
    }

    /// Variance of reading `i` whose noise-free value is `v` (a negative
    /// noise-free value, which no real reading has, counts as 0 for the
    /// signal-dependent parts).
    pub fn variance(&self, i: usize, v: f64) -> f64 {
        let s = v.max(0.0);
        let r = self.ratio(i, s);
        self.a * v * v + r * self.b[i] * s + r * r * self.c[i]
    }

    /// The standard deviation of every reading of `v`.
    pub fn sigma(&self, v: &[f64]) -> Vec<f64> {
        v.iter().enumerate().map(|(i, x)| self.variance(i, *x).sqrt()).collect()
    }

    /// The relative level of a perfect diffuser's readings (v = 1), the
    /// worst LED: what a blob records as its noise level.
    pub fn diffuser_level(&self) -> f64 {
        (0..self.m()).map(|i| self.variance(i, 1.0).sqrt()).fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_noise_is_proportional_and_the_parts_add() {
        let r = ReadingNoise::relative(0.02, 3);
        assert!((r.variance(1, 2.0) - 0.0016).abs() < 1e-15);
        for (got, want) in r.sigma(&[0.0, 1.0, 3.0]).iter().zip([0.0, 0.02, 0.06]) {
            assert!((got - want).abs() < 1e-15, "{got} {want}");
        }
        let s = ReadingNoise {
            a: 0.0,
            b: vec![0.01, 0.02],
            c: vec![1e-4, 0.0],
            saturates_above: Vec::new(),
            ratios: Vec::new(),
        };
        assert_eq!(s.variance(0, 4.0), 0.04 + 1e-4);
        assert_eq!(s.variance(1, -1.0), 0.0);
        assert!((s.diffuser_level() - 0.02f64.sqrt()).abs() < 1e-15);
        // A reading above saturation comes from a shorter exposure: r times
        // the shot variance, r^2 times the constant.
        let h = ReadingNoise { saturates_above: vec![2.0, 2.0], ratios: vec![16.0, 80.0], ..s };
        assert_eq!(h.ratio(0, 1.0), 1.0);
        assert_eq!(h.ratio(0, 20.0), 16.0);
        assert_eq!(h.ratio(0, 100.0), 80.0);
        assert_eq!(h.ratio(0, 1e6), 80.0);
        assert_eq!(h.variance(0, 20.0), 16.0 * 0.01 * 20.0 + 256.0 * 1e-4);
    }
}
