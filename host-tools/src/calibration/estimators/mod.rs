//! Linear BRDF estimators `rho_hat = W v` (W is n x m) and what they predict
//! about their own accuracy.
//!
//! Every estimator the product can put in a calibration blob is linear in the
//! readings, so all of them are trained into one type, [`LinearEstimator`]:
//! the f64 matrix W, its [`EstimatorKind`], the predicted standard
//! uncertainty per bin and an [`EstimatorSummary`] (condition numbers,
//! effective rank, regularisation applied, tolerances).
//!
//! | kind | module | W |
//! |---|---|---|
//! | Wiener, noise term (eq. 22) | [`wiener`] | `R_pp H^T (H R_pp H^T + R_nn)^-1` |
//! | Wiener, noise-free (eq. 20) | [`wiener`] | `R_pp H^T (H R_pp H^T)^+` |
//! | inverse (claim 3) | [`inverse`] | `H^-1`, H square and non-singular |
//! | pseudo-inverse (claim 4) | [`pseudo_inverse`] | `H^+` by SVD |
//! | interpolation (\[0004\]) | [`interpolation`] | linear interpolation between the LEDs' centre angles |
//!
//! The scale-free kinds ([`scale_free`]) carry an out-of-prior flag, trained
//! in [`out_of_prior`].
//!
//! # Predicted uncertainty
//! For any linear W, prior correlation `R_pp = <rho rho^T>` and noise
//! covariance `R_nn` (noise uncorrelated with rho), the error `e = rho - W v`
//! has the second-moment matrix
//!
//! ```text
//! E = (I - W H) R_pp (I - W H)^T + W R_nn W^T
//! ```
//!
//! which for the Wiener W reduces to the patent's `R_pp - W H R_pp`
//! (tested). The predicted standard uncertainty of bin j is `sqrt(E_jj)` and
//! the predicted RMSE is `sqrt(mean_j E_jj)`. Both are computed from square-root
//! factors (`E = A A^T + B B^T`), so they are never negative from rounding.
//! They assume the BRDFs come from the prior's ensemble and that H is exact;
//! the reproduction compares them with the achieved error on the test set.
//!
//! # Noise model
//! The patent's noise is 2 % of the measured value: `v_i + N(0, (s v_i)^2)`.
//! Averaged over the prior that is exactly `R_nn = s^2 diag(H R_pp H^T)`
//! (and the noise is uncorrelated with rho), see [`NoiseModel::Relative`].
//! Estimators that ignore noise when they are built (eq. 20, inverse,
//! pseudo-inverse, interpolation) still report the uncertainty the noise
//! model predicts for them.
//!
//! # Numerics
//! No explicit inverse of an ill-conditioned matrix is formed anywhere. The
//! Wiener matrix is computed in square-root form from an SVD of the whitened
//! `H L` (`R_pp = L L^T`), which has the square root of the condition number
//! of `H R_pp H^T` (1e5 instead of 1e10 on the patent profile); see
//! [`wiener`] for the derivation and the fallbacks.
use brdf_meter::blob::EstimatorKind;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

pub mod batch;
pub(crate) mod checked_svd;
pub mod clustered;
pub mod fixed_point;
pub mod interpolation;
pub mod inverse;
pub mod log_wiener;
pub mod out_of_prior;
pub mod pairs_wiener;
pub mod pseudo_inverse;
pub mod scale_free;
pub mod wiener;

pub use batch::BatchEstimator;

/// Why an estimator could not be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EstimatorError {
    /// An input has the wrong shape.
    #[error("{what} is {got_rows} x {got_cols}, expected {rows} x {cols}")]
    Shape {
        /// Which input.
        what: &'static str,
        /// Expected rows.
        rows: usize,
        /// Expected columns.
        cols: usize,
        /// Rows given.
        got_rows: usize,
        /// Columns given.
        got_cols: usize,
    },
    /// An input holds NaN or infinity.
    #[error("{what} has a non-finite value at ({row}, {col})")]
    NonFinite {
        /// Which input.
        what: &'static str,
        /// Row.
        row: usize,
        /// Column.
        col: usize,
    },
    /// A matrix that must be symmetric positive semi-definite is not.
    #[error("{what} is not symmetric positive semi-definite ({detail})")]
    NotPsd {
        /// Which input.
        what: &'static str,
        /// What was found.
        detail: String,
    },
    /// The prior carries no signal (R_pp = 0).
    #[error("the prior correlation matrix R_pp is zero: train from at least one non-zero sample BRDF")]
    ZeroPrior,
    /// The system matrix is all zero.
    #[error("the system matrix H is zero: no LED illuminates any angle bin")]
    ZeroSystem,
    /// The inverse estimator needs a square H.
    #[error(
        "the inverse estimator (claim 3) needs a square H, got {m} readings x {n} bins; use the pseudo-inverse or Wiener estimator"
    )]
    NotSquare {
        /// Readings.
        m: usize,
        /// Bins.
        n: usize,
    },
    /// H is numerically singular.
    #[error("H is numerically singular (condition number {condition:.3e}); use the pseudo-inverse or Wiener estimator")]
    Singular {
        /// sigma_max / sigma_min.
        condition: f64,
    },
    /// The noise level is negative or not finite.
    #[error("relative noise level must be finite and >= 0, got {0}")]
    BadNoise(f64),
    /// Angles for interpolation are unusable.
    #[error("interpolation: {0}")]
    BadAngles(String),
    /// The kind is not a linear estimator this crate trains.
    #[error(
        "the {0} estimator is not trained by this crate; choose wiener, wiener-noise-free, inverse, pseudo-inverse or interpolation"
    )]
    Unsupported(&'static str),
}

/// The measurement noise the estimators are built for and judged against.
#[derive(Clone, Debug, PartialEq)]
pub enum NoiseModel {
    /// No noise: `R_nn = 0`.
    None,
    /// Noise proportional to the value, standard deviation `s * v_i`:
    /// `R_nn = s^2 diag(H R_pp H^T)` (the patent's 2 % is `Relative(0.02)`).
    Relative(f64),
    /// An explicit m x m covariance (symmetric positive semi-definite).
    Covariance(DMatrix<f64>),
}

impl NoiseModel {
    /// The m x m noise covariance `R_nn` for system `h` and prior `r_pp`.
    pub fn covariance(&self, h: &DMatrix<f64>, r_pp: &DMatrix<f64>) -> Result<DMatrix<f64>, EstimatorError> {
        let m = h.nrows();
        match self {
            Self::None => Ok(DMatrix::zeros(m, m)),
            Self::Relative(s) => {
                if !s.is_finite() || *s < 0.0 {
                    return Err(EstimatorError::BadNoise(*s));
                }
                let hr = h * r_pp;
                let mut r = DMatrix::zeros(m, m);
                for i in 0..m {
                    r[(i, i)] = s * s * hr.row(i).dot(&h.row(i)).max(0.0);
                }
                Ok(r)
            }
            Self::Covariance(c) => {
                check_shape("R_nn", c, m, m)?;
                check_finite("R_nn", c)?;
                check_symmetric("R_nn", c)?;
                Ok(c.clone())
            }
        }
    }

    /// The relative level recorded in a blob (0 for none, NaN-free).
    pub fn relative_level(&self) -> f64 {
        match self {
            Self::Relative(s) => *s,
            _ => 0.0,
        }
    }
}

/// What an estimator is trained from.
#[derive(Clone, Debug)]
pub struct EstimatorInputs<'a> {
    /// System matrix H, m x n (readings x bins).
    pub h: &'a DMatrix<f64>,
    /// Prior correlation `R_pp = <rho rho^T>`, n x n.
    pub r_pp: &'a DMatrix<f64>,
    /// Number of sample BRDFs behind `r_pp` (for the summary only).
    pub prior_samples: usize,
    /// The instrument's noise model: used to build the Wiener (eq. 22) matrix
    /// and, for every kind, to predict the uncertainty.
    pub noise: NoiseModel,
    /// Bin centres in degrees, n (for interpolation).
    pub bins_deg: &'a [f64],
    /// Incidence angle of each LED's centre ray in degrees, m (for interpolation).
    pub centres_deg: &'a [f64],
}

/// How an estimator was computed and how well-posed it was.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EstimatorSummary {
    /// Estimator kind, kebab-case (`wiener`, `pseudo-inverse`, ...).
    pub kind: String,
    /// Bins n.
    pub n: usize,
    /// Readings m.
    pub m: usize,
    /// Sample BRDFs behind the prior.
    pub prior_samples: usize,
    /// Numerical rank of R_pp (eigenvalues above `n eps lambda_max`).
    pub prior_rank: usize,
    /// sigma_max / sigma_min of H over its min(m, n) singular values (inf if singular).
    pub condition_h: f64,
    /// Numerical rank of H (singular values above `max(m,n) eps sigma_max`).
    pub rank_h: usize,
    /// Condition number of the matrix the estimator effectively inverts:
    /// `H R_pp H^T + R_nn` for Wiener (noise-free: `H R_pp H^T`), H for the
    /// inverse and pseudo-inverse, 1 for interpolation (nothing inverted).
    pub condition_system: f64,
    /// Effective rank of the estimator: directions kept (pseudo-inverse,
    /// noise-free Wiener), or the degrees of freedom `sum s^2/(s^2+1)` of the
    /// whitened problem (Wiener with noise).
    pub effective_rank: f64,
    /// Relative truncation or floor actually applied (0 when none was needed).
    pub regularisation: f64,
    /// Relative tolerance used to decide numerical rank.
    pub tolerance: f64,
    /// Relative noise level the uncertainty assumes.
    pub noise_rel: f64,
    /// Predicted RMSE over the prior's ensemble, `sqrt(mean_j E_jj)`.
    pub predicted_rmse: f64,
    /// How W was computed (algorithm and fallback taken).
    pub method: String,
}

/// A trained linear estimator.
#[derive(Clone, Debug)]
pub struct LinearEstimator {
    /// Which estimator.
    pub kind: EstimatorKind,
    /// W, n x m.
    pub w: DMatrix<f64>,
    /// Predicted standard uncertainty per bin (n).
    pub uncertainty: DVector<f64>,
    /// How it was computed.
    pub summary: EstimatorSummary,
}

/// Kebab-case name of an estimator kind (as on the command line and in JSON).
pub fn kind_name(kind: EstimatorKind) -> &'static str {
    match kind {
        EstimatorKind::Wiener => "wiener",
        EstimatorKind::WienerNoiseFree => "wiener-noise-free",
        EstimatorKind::Inverse => "inverse",
        EstimatorKind::PseudoInverse => "pseudo-inverse",
        EstimatorKind::Interpolation => "interpolation",
        EstimatorKind::LogWiener => "log-wiener",
        EstimatorKind::ScaleFree => "scale-free",
        EstimatorKind::ScaleFreePiecewise => "scale-free-piecewise",
    }
}

/// What a kind-specific builder returns before the uncertainty is attached.
pub(crate) struct Built {
    pub w: DMatrix<f64>,
    pub condition_system: f64,
    pub effective_rank: f64,
    pub regularisation: f64,
    pub tolerance: f64,
    pub method: String,
}

/// Trains an estimator of `kind` from `inputs`.
pub fn build(kind: EstimatorKind, inputs: &EstimatorInputs<'_>) -> Result<LinearEstimator, EstimatorError> {
    let h = inputs.h;
    let (m, n) = h.shape();
    check_shape("R_pp", inputs.r_pp, n, n)?;
    check_finite("H", h)?;
    check_finite("R_pp", inputs.r_pp)?;
    check_symmetric("R_pp", inputs.r_pp)?;
    if h.iter().all(|x| *x == 0.0) {
        return Err(EstimatorError::ZeroSystem);
    }
    let r_nn = inputs.noise.covariance(h, inputs.r_pp)?;
    let prior = PsdFactor::new("R_pp", inputs.r_pp)?;
    if prior.rank == 0 {
        return Err(EstimatorError::ZeroPrior);
    }
    let noise_f = PsdFactor::new("R_nn", &r_nn)?;
    let sv_h = h.clone().svd(false, false).singular_values;
    let smax = sv_h.max();
    let tol_h = rank_tolerance(m, n);
    let rank_h = sv_h.iter().filter(|s| **s > tol_h * smax).count();
    let smin = sv_h.min();
    let condition_h = if smin > 0.0 { smax / smin } else { f64::INFINITY };

    let built = match kind {
        EstimatorKind::Wiener => wiener::build(h, &prior, &r_nn, &noise_f)?,
        EstimatorKind::WienerNoiseFree => {
            let zero = DMatrix::zeros(m, m);
            let zf = PsdFactor::new("R_nn", &zero)?;
            wiener::build(h, &prior, &zero, &zf)?
        }
        EstimatorKind::Inverse => inverse::build(h)?,
        EstimatorKind::PseudoInverse => pseudo_inverse::build(h),
        EstimatorKind::Interpolation => interpolation::build(inputs.bins_deg, inputs.centres_deg, m)?,
        // Not one linear W: trained by `scale_free::train_zone`.
        EstimatorKind::LogWiener | EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise => {
            return Err(EstimatorError::Unsupported(kind_name(kind)));
        }
    };
    let var = error_variance(&built.w, h, &prior, &noise_f);
    let predicted_rmse = (var.sum() / n as f64).sqrt();
    let uncertainty = var.map(f64::sqrt);
    Ok(LinearEstimator {
        kind,
        w: built.w,
        uncertainty,
        summary: EstimatorSummary {
            kind: kind_name(kind).to_string(),
            n,
            m,
            prior_samples: inputs.prior_samples,
            prior_rank: prior.rank,
            condition_h,
            rank_h,
            condition_system: built.condition_system,
            effective_rank: built.effective_rank,
            regularisation: built.regularisation,
            tolerance: built.tolerance,
            noise_rel: inputs.noise.relative_level(),
            predicted_rmse,
            method: built.method,
        },
    })
}

impl LinearEstimator {
    /// Bins n.
    pub fn n(&self) -> usize {
        self.w.nrows()
    }
    /// Readings m.
    pub fn m(&self) -> usize {
        self.w.ncols()
    }
    /// `W v` in f64.
    pub fn estimate(&self, v: &DVector<f64>) -> DVector<f64> {
        &self.w * v
    }
    /// W as f32, row-major n x m: the layout of the blob and of
    /// `brdf_meter::kernel::mat_vec_f32_slice`.
    pub fn w_f32_row_major(&self) -> Vec<f32> {
        let (n, m) = self.w.shape();
        let mut out = Vec::with_capacity(n * m);
        for j in 0..n {
            for i in 0..m {
                out.push(self.w[(j, i)] as f32);
            }
        }
        out
    }
}

/// Second moment of the error of any linear W per bin: the diagonal of
/// `(I - W H) R_pp (I - W H)^T + W R_nn W^T`, from square-root factors.
pub(crate) fn error_variance(w: &DMatrix<f64>, h: &DMatrix<f64>, prior: &PsdFactor, noise: &PsdFactor) -> DVector<f64> {
    let n = w.nrows();
    // (I - W H) L = L - W (H L)
    let a = &prior.l - w * (h * &prior.l);
    let b = w * &noise.l;
    DVector::from_fn(n, |j, _| a.row(j).norm_squared() + b.row(j).norm_squared())
}

/// Full error second-moment matrix of a linear W (tests and diagnostics).
pub fn error_covariance(w: &DMatrix<f64>, h: &DMatrix<f64>, r_pp: &DMatrix<f64>, r_nn: &DMatrix<f64>) -> DMatrix<f64> {
    let n = w.nrows();
    let iwh = DMatrix::identity(n, n) - w * h;
    &iwh * r_pp * iwh.transpose() + w * r_nn * w.transpose()
}

/// Relative tolerance for the numerical rank of an r x c matrix:
/// singular values at or below `max(r, c) * eps * sigma_max` are treated as
/// zero (the LAPACK / NumPy `matrix_rank` and `pinv` convention: below it a
/// singular value is indistinguishable from rounding of the largest one).
pub fn rank_tolerance(rows: usize, cols: usize) -> f64 {
    rows.max(cols).max(1) as f64 * f64::EPSILON
}

/// A square-root factor `A = L L^T` of a symmetric positive semi-definite
/// matrix, from its symmetric eigendecomposition. Eigenvalues at or below
/// `k eps lambda_max` (k the order) are rounding noise and are dropped, as are
/// slightly negative ones; clearly negative eigenvalues are an error.
pub(crate) struct PsdFactor {
    /// k x rank.
    pub l: DMatrix<f64>,
    pub rank: usize,
}

impl PsdFactor {
    pub fn new(what: &'static str, a: &DMatrix<f64>) -> Result<Self, EstimatorError> {
        let k = a.nrows();
        if a.iter().all(|x| *x == 0.0) {
            return Ok(Self { l: DMatrix::zeros(k, 0), rank: 0 });
        }
        // Exactly diagonal (the usual noise covariance): no decomposition needed.
        let diagonal = (0..k).all(|i| (0..k).all(|j| i == j || a[(i, j)] == 0.0));
        let (vals, vecs) = if diagonal {
            (DVector::from_fn(k, |i, _| a[(i, i)]), DMatrix::identity(k, k))
        } else {
            let sym = (a + a.transpose()) * 0.5;
            let e = sym.symmetric_eigen();
            (e.eigenvalues, e.eigenvectors)
        };
        let lmax = vals.iter().fold(0.0f64, |acc, v| acc.max(v.abs()));
        let floor = k as f64 * f64::EPSILON * lmax;
        // A clearly negative eigenvalue is not rounding: refuse.
        if let Some(neg) = vals.iter().find(|v| **v < -1e3 * floor.max(f64::MIN_POSITIVE)) {
            return Err(EstimatorError::NotPsd {
                what,
                detail: format!("eigenvalue {neg:.3e} with largest {lmax:.3e}"),
            });
        }
        // The floor applies to computed eigenvalues. A diagonal matrix's
        // eigenvalues are its entries, exact: every positive one is kept, so
        // readings whose noise variance is tiny next to another's (per-LED
        // gains 1e-6 vs 1e6 make the ratio 1e24) stay noisy readings instead
        // of being treated as noise-free (stability family `gain`).
        let cut = if diagonal { 0.0 } else { floor };
        let keep: Vec<usize> = (0..k).filter(|&i| vals[i] > cut).collect();
        let mut l = DMatrix::zeros(k, keep.len());
        for (c, &i) in keep.iter().enumerate() {
            let s = vals[i].sqrt();
            l.set_column(c, &(vecs.column(i) * s));
        }
        Ok(Self { l, rank: keep.len() })
    }
}

fn check_shape(what: &'static str, a: &DMatrix<f64>, rows: usize, cols: usize) -> Result<(), EstimatorError> {
    if a.shape() != (rows, cols) {
        return Err(EstimatorError::Shape { what, rows, cols, got_rows: a.nrows(), got_cols: a.ncols() });
    }
    Ok(())
}

fn check_finite(what: &'static str, a: &DMatrix<f64>) -> Result<(), EstimatorError> {
    for c in 0..a.ncols() {
        for r in 0..a.nrows() {
            if !a[(r, c)].is_finite() {
                return Err(EstimatorError::NonFinite { what, row: r, col: c });
            }
        }
    }
    Ok(())
}

fn check_symmetric(what: &'static str, a: &DMatrix<f64>) -> Result<(), EstimatorError> {
    let scale = a.amax();
    let k = a.nrows();
    for i in 0..k {
        for j in 0..i {
            if (a[(i, j)] - a[(j, i)]).abs() > 1e-10 * scale {
                return Err(EstimatorError::NotPsd { what, detail: format!("not symmetric at ({i}, {j})") });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod test_support {
    //! Small synthetic problems shared by the estimator tests.
    use nalgebra::DMatrix;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A smooth, peaked family of "BRDFs" on n bins: diffuse + Gaussian lobe,
    /// with random amplitude, centre and width; columns are samples.
    pub fn lobes(n: usize, k: usize, seed: u64) -> DMatrix<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut s = DMatrix::zeros(n, k);
        for c in 0..k {
            let d: f64 = rng.random_range(0.1..1.0);
            let a: f64 = rng.random_range(0.5..20.0);
            let mu: f64 = rng.random_range(0.3..0.7) * n as f64;
            let w: f64 = rng.random_range(0.02..0.15) * n as f64;
            for j in 0..n {
                let x = (j as f64 - mu) / w;
                s[(j, c)] = d + a * (-0.5 * x * x).exp();
            }
        }
        s
    }

    /// A smooth blur: each of m rows a normalised Gaussian window around an
    /// evenly spaced centre, width `w` bins.
    pub fn blur(m: usize, n: usize, w: f64) -> DMatrix<f64> {
        let mut h = DMatrix::zeros(m, n);
        for i in 0..m {
            let c = (i as f64 + 0.5) * n as f64 / m as f64;
            for j in 0..n {
                let x = (j as f64 - c) / w;
                h[(i, j)] = (-0.5 * x * x).exp();
            }
            let s = h.row(i).sum();
            h.row_mut(i).scale_mut(1.0 / s);
        }
        h
    }

    /// `<rho rho^T>` of sample columns.
    pub fn correlation(s: &DMatrix<f64>) -> DMatrix<f64> {
        s * s.transpose() / s.ncols() as f64
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::*;
    use super::*;

    fn inputs<'a>(
        h: &'a DMatrix<f64>,
        r: &'a DMatrix<f64>,
        noise: NoiseModel,
        bins: &'a [f64],
        c: &'a [f64],
    ) -> EstimatorInputs<'a> {
        EstimatorInputs { h, r_pp: r, prior_samples: 0, noise, bins_deg: bins, centres_deg: c }
    }

    #[test]
    fn relative_noise_covariance_is_diagonal_of_h_rpp_ht() {
        let h = blur(5, 30, 2.0);
        let r = correlation(&lobes(30, 40, 1));
        let rnn = NoiseModel::Relative(0.02).covariance(&h, &r).unwrap();
        let full = &h * &r * h.transpose();
        for i in 0..5 {
            for j in 0..5 {
                let want = if i == j { 0.0004 * full[(i, i)] } else { 0.0 };
                assert!((rnn[(i, j)] - want).abs() <= 1e-12 * full.amax());
            }
        }
    }

    #[test]
    fn predicted_uncertainty_matches_the_full_covariance_for_every_kind() {
        let (m, n) = (6, 40);
        let h = blur(m, n, 3.0);
        let r = correlation(&lobes(n, 30, 2));
        let bins: Vec<f64> = (0..n).map(|j| j as f64).collect();
        let c: Vec<f64> = (0..m).map(|i| (i as f64 + 0.5) * n as f64 / m as f64).collect();
        let noise = NoiseModel::Relative(0.03);
        let rnn = noise.covariance(&h, &r).unwrap();
        for kind in [
            EstimatorKind::Wiener,
            EstimatorKind::WienerNoiseFree,
            EstimatorKind::PseudoInverse,
            EstimatorKind::Interpolation,
        ] {
            let est = build(kind, &inputs(&h, &r, noise.clone(), &bins, &c)).unwrap();
            let e = error_covariance(&est.w, &h, &r, &rnn);
            for j in 0..n {
                let want = e[(j, j)].max(0.0).sqrt();
                assert!(
                    (est.uncertainty[j] - want).abs() <= 1e-6 * want.max(1e-3),
                    "{kind:?} bin {j}: {} vs {want}",
                    est.uncertainty[j]
                );
            }
        }
    }

    #[test]
    fn bad_inputs_are_refused_with_the_reason() {
        let h = blur(3, 10, 1.0);
        let r = correlation(&lobes(10, 5, 3));
        let bins: Vec<f64> = (0..10).map(|j| j as f64).collect();
        let c = [1.0, 5.0, 8.0];
        let mut bad = h.clone();
        bad[(1, 4)] = f64::NAN;
        let e = build(EstimatorKind::Wiener, &inputs(&bad, &r, NoiseModel::None, &bins, &c)).unwrap_err();
        assert_eq!(e, EstimatorError::NonFinite { what: "H", row: 1, col: 4 });
        let small = DMatrix::zeros(9, 9);
        let e = build(EstimatorKind::Wiener, &inputs(&h, &small, NoiseModel::None, &bins, &c)).unwrap_err();
        assert!(matches!(e, EstimatorError::Shape { what: "R_pp", .. }));
        let e = build(EstimatorKind::Wiener, &inputs(&h, &r, NoiseModel::Relative(-0.1), &bins, &c)).unwrap_err();
        assert_eq!(e, EstimatorError::BadNoise(-0.1));
        let mut neg = r.clone();
        neg[(0, 0)] = -neg.amax();
        let e = build(EstimatorKind::Wiener, &inputs(&h, &neg, NoiseModel::None, &bins, &c)).unwrap_err();
        assert!(matches!(e, EstimatorError::NotPsd { what: "R_pp", .. }), "{e:?}");
        let e = build(EstimatorKind::Inverse, &inputs(&h, &r, NoiseModel::None, &bins, &c)).unwrap_err();
        assert_eq!(e, EstimatorError::NotSquare { m: 3, n: 10 });
        let z = DMatrix::zeros(10, 10);
        let e = build(EstimatorKind::Wiener, &inputs(&h, &z, NoiseModel::None, &bins, &c)).unwrap_err();
        assert_eq!(e, EstimatorError::ZeroPrior);
    }
}
