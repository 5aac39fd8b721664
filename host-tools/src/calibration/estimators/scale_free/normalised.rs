//! The pairs over their scale (readings `u = v / s`, targets `y`, noise
//! and weights) and the affine map fitted to their moments.

use super::*;

/// Per-pair quantities: normalised readings `u = v / s`, the target over
/// the scale, the noise's standard deviations over the scale, the weight
/// of the pair in the fit (the criterion's weight times `s^2`, since an
/// error of `y` is `s` times smaller than the same error of the target).
pub(super) struct Normalised {
    pub(super) u: Vec<DVector<f64>>,
    pub(super) y: Vec<DVector<f64>>,
    pub(super) sn: Vec<DVector<f64>>,
    pub(super) w: Vec<f64>,
}

/// How a target is fitted: as it is, or in the root form with each pair's
/// level (its truth's peak; a gloss row's reading) for the weight.
#[derive(Clone, Copy, Debug)]
pub(super) enum Form<'a> {
    Linear,
    Root(&'a [f64]),
}

pub(super) fn normalise(pairs: &Pairs, target: &DMatrix<f64>, form: Form<'_>) -> anyhow::Result<Normalised> {
    let mut out = Normalised { u: Vec::new(), y: Vec::new(), sn: Vec::new(), w: Vec::new() };
    for k in 0..pairs.len() {
        let v = pairs.readings.column(k);
        let s: f64 = v.iter().sum();
        ensure!(
            s > 0.0 && s.is_finite(),
            "prior sample {}: its readings sum to {s}; a sample must reflect some light",
            pairs.sample[k]
        );
        out.u.push(v / s);
        out.sn.push(pairs.noise_var.column(k).map(|x| x.max(0.0).sqrt() / s));
        match form {
            Form::Linear => {
                out.y.push(target.column(k) / s);
                out.w.push(pairs.weights[k] * s * s);
            }
            Form::Root(level) => {
                out.y.push(target.column(k).map(|x| (x.max(0.0) / s).sqrt()));
                out.w.push(pairs.weights[k] * s * level[k].max(f64::MIN_POSITIVE));
            }
        }
    }
    Ok(out)
}

/// Each pair's truth's peak: the root form's level of the BRDF target.
pub(super) fn peaks(pairs: &Pairs) -> Vec<f64> {
    pairs.truth.column_iter().map(|c| c.amax()).collect()
}

/// A pair's level for a gloss target (its gloss row plus one GU, so a matt
/// sample's rows still count).
pub fn gloss_levels(target: &DMatrix<f64>) -> Vec<f64> {
    target.row(0).iter().map(|g| g.max(0.0) + 1.0).collect()
}

/// Mean, centred factor (columns scaled by sqrt(w)) and noise covariance of
/// `u'`, plus the target's mean and factor.
pub(super) struct Moments {
    pub(super) mu_u: DVector<f64>,
    pub(super) mu_y: DVector<f64>,
    pub(super) su: DMatrix<f64>,
    pub(super) sy: DMatrix<f64>,
    pub(super) r_noise: DMatrix<f64>,
}

pub(super) fn moments(nz: &Normalised, idx: &[usize]) -> Moments {
    moments_scaled(nz, idx, &vec![1.0; idx.len()])
}

pub(super) fn moments_scaled(nz: &Normalised, idx: &[usize], mult: &[f64]) -> Moments {
    let m1 = nz.u[0].len() - 1;
    let n = nz.y[0].len();
    let wk = |c: usize| nz.w[idx[c]] * mult[c];
    let total: f64 = (0..idx.len()).map(wk).sum();
    let mut mu_u = DVector::zeros(m1);
    let mut mu_y = DVector::zeros(n);
    for (c, &k) in idx.iter().enumerate() {
        let w = wk(c) / total;
        mu_u += nz.u[k].rows(0, m1) * w;
        mu_y += &nz.y[k] * w;
    }
    let mut su = DMatrix::zeros(m1, idx.len());
    let mut sy = DMatrix::zeros(n, idx.len());
    let mut r_noise = DMatrix::zeros(m1, m1);
    for (c, &k) in idx.iter().enumerate() {
        let w = wk(c) / total;
        let sw = w.sqrt();
        su.set_column(c, &((nz.u[k].rows(0, m1) - &mu_u) * sw));
        sy.set_column(c, &((&nz.y[k] - &mu_y) * sw));
        // du = (I - u 1^T) diag(sigma / s) e, e ~ N(0, I); keep rows < m-1.
        let (u, sn) = (&nz.u[k], &nz.sn[k]);
        let mm = u.len();
        let a = DMatrix::from_fn(m1, mm, |i, j| (if i == j { 1.0 } else { 0.0 } - u[i]) * sn[j]);
        r_noise += (&a * a.transpose()) * w;
    }
    Moments { mu_u, mu_y, su, sy, r_noise }
}

pub(super) fn fit_map(mo: &Moments, ridge: f64) -> anyhow::Result<ScaleFreeMap> {
    let m1 = mo.mu_u.len();
    let cuu = &mo.su * mo.su.transpose() + &mo.r_noise;
    let lam = ridge * (cuu.trace() / m1 as f64).max(f64::MIN_POSITIVE);
    let reg = &cuu + DMatrix::identity(m1, m1) * lam;
    let chol =
        reg.cholesky().context("the normalised readings' covariance is not positive definite; add samples or noise")?;
    let cyu = &mo.sy * mo.su.transpose();
    // W' = C_yu C^-1  <=>  C W'^T = C_yu^T.
    let wp = chol.solve(&cyu.transpose()).transpose();
    let b = &mo.mu_y - &wp * &mo.mu_u;
    let n = mo.mu_y.len();
    let mut w = DMatrix::zeros(n, m1 + 1);
    w.view_mut((0, 0), (n, m1)).copy_from(&wp);
    w.set_column(m1, &b);
    let err = &mo.sy * mo.sy.transpose() - &wp * &cyu.transpose();
    let sigma_unit = DVector::from_fn(n, |j, _| err[(j, j)].max(0.0).sqrt());
    Ok(ScaleFreeMap { w, sigma_unit, err_unit: err, sigma_broad: None })
}

/// Packed `chol(C')^-1` (lower triangular) of the predictive covariance of
/// `u'` (the linear out-of-prior form's model).
pub(super) fn whitening(mo: &Moments) -> anyhow::Result<Vec<f32>> {
    let m1 = mo.mu_u.len();
    let c = &mo.su * mo.su.transpose() + &mo.r_noise;
    let jitter = 1e-12 * (c.trace() / m1 as f64).max(f64::MIN_POSITIVE);
    let l = (c + DMatrix::identity(m1, m1) * jitter).cholesky().context("the predictive covariance is singular")?.l();
    let g = l.solve_lower_triangular(&DMatrix::identity(m1, m1)).context("whitening")?;
    let mut packed = Vec::with_capacity(whitening_len(m1 + 1));
    for k in 0..m1 {
        for i in 0..=k {
            packed.push(g[(k, i)] as f32);
        }
    }
    Ok(packed)
}
