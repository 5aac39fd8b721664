//! SPC figures of an inspection run: the line means of the gloss change
//! (each verdict's `mean_gloss`) against the recipe's gloss window as the
//! specification limits.
use serde::Serialize;

/// Mean, sd, Cp and Cpk of a run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Spc {
    /// Lines with a mean.
    pub lines: usize,
    /// Mean of the line means, GU (change from the reference).
    pub mean: f64,
    /// Their sample standard deviation, GU.
    pub sd: f64,
    /// `(USL - LSL) / 6 sd` (NaN without both limits).
    pub cp: f64,
    /// `min(USL - mean, mean - LSL) / 3 sd` (over the limits there are).
    pub cpk: f64,
}

/// The figures of `values` against the window `[lsl, usl]` (either may be infinite: none).
pub fn spc(values: &[f32], lsl: f32, usl: f32) -> Spc {
    let v: Vec<f64> = values.iter().filter(|x| x.is_finite()).map(|x| *x as f64).collect();
    let n = v.len();
    let mean = if n > 0 { v.iter().sum::<f64>() / n as f64 } else { f64::NAN };
    let sd = if n > 1 { (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt() } else { f64::NAN };
    let (lsl, usl) = (lsl as f64, usl as f64);
    let cp = if lsl.is_finite() && usl.is_finite() { (usl - lsl) / (6.0 * sd) } else { f64::NAN };
    let sides = [usl.is_finite().then_some(usl - mean), lsl.is_finite().then_some(mean - lsl)];
    let cpk = sides.iter().flatten().map(|d| d / (3.0 * sd)).fold(f64::NAN, f64::min);
    Spc { lines: n, mean, sd, cp, cpk }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cp_and_cpk_of_a_known_sample() {
        // Mean 0.5, sd 1 (sample), window -3..3: Cp = 1, Cpk = 2.5 / 3.
        let s = spc(&[-0.5, 1.5, -0.5, 1.5, f32::NAN], -3.0, 3.0);
        assert_eq!(s.lines, 4);
        assert!((s.mean - 0.5).abs() < 1e-12);
        let sd = (4.0f64 / 3.0).sqrt();
        assert!((s.sd - sd).abs() < 1e-12);
        assert!((s.cp - 6.0 / (6.0 * sd)).abs() < 1e-12);
        assert!((s.cpk - 2.5 / (3.0 * sd)).abs() < 1e-12);
        // One-sided: only the upper limit counts (USL - mean = 2.5, sd = sqrt 2).
        assert!((spc(&[-0.5, 1.5], f32::NEG_INFINITY, 3.0).cpk - 2.5 / (3.0 * 2f64.sqrt())).abs() < 1e-12);
    }
}
