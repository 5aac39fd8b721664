//! The conventional baseline: fit a Ward model to each point's m readings by
//! bounded Levenberg-Marquardt, then evaluate the fitted model on the grid.
//!
//! Two forward models, as in the patent's Table 1:
//! - **condition 1** ([`ForwardModel::far_field`]): the model ignores the
//!   light distribution; each reading is the BRDF at its LED's centre angle.
//! - **condition 2** ([`ForwardModel::near_field`]): the model integrates the
//!   distribution; each reading is the weighted sum of the BRDF over the
//!   LED's rays (the same rays the simulation uses).
//!
//! # The fit (meant to be a competent baseline, not a strawman)
//! - **Model**: `R(theta_i) = rho_d + rho_s exp(-tan^2 d / a^2) / (4 a^2 sqrt(cos_i cos_o))`
//!   with all three parameters free (the fit does not know the profile's
//!   `rho_s = 1 - rho_d`).
//! - **Bounds** ([`Bounds::physical`]): `rho_d, rho_s in [0, 1]`,
//!   `alpha in [0.005, 0.5]`, enforced by the MINUIT/lmfit sine
//!   reparametrisation `p = lo + (hi - lo)(1 + sin u)/2`.
//! - **Weights**: the noise is 2 % of the value, so residuals are relative,
//!   `(model_i - v_i) / v_i` (maximum likelihood under that noise).
//! - **Start values**: the model is linear in `(rho_d, rho_s)` for fixed
//!   alpha (variable projection), so a cheap scan over [`FitOptions::alpha_grid`]
//!   log-spaced alphas solves the bounded 2-parameter linear problem exactly
//!   at each and keeps the best [`FitOptions::starts`] local minima as starts.
//! - **Solver**: the `levenberg-marquardt` crate (a port of MINPACK's
//!   `lmder`, the algorithm behind `scipy.optimize.least_squares(method="lm")`
//!   and `leastsq`) with the analytic Jacobian and SciPy's default
//!   tolerances `ftol = xtol = gtol = 1e-8`.
//! - **Reported cost**: residual and Jacobian evaluations per fit
//!   ([`FitResult`]), so the speed comparison can be judged.
use crate::forward::brdf::Ward;
use crate::forward::optics::{Instrument, rays, surface_frame};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, TerminationReason};
use nalgebra::Vector3;
use nalgebra034 as na;
use std::cell::Cell;

/// Ward parameters.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct WardParams {
    /// Diffuse albedo.
    pub rho_d: f64,
    /// Specular albedo.
    pub rho_s: f64,
    /// Roughness.
    pub alpha: f64,
}

impl WardParams {
    /// As an array `[rho_d, rho_s, alpha]`.
    pub fn to_array(self) -> [f64; 3] {
        [self.rho_d, self.rho_s, self.alpha]
    }
    /// From `[rho_d, rho_s, alpha]`.
    pub fn from_array(p: [f64; 3]) -> Self {
        Self { rho_d: p[0], rho_s: p[1], alpha: p[2] }
    }
    /// The model as a BRDF (no range check: fitted values are within bounds).
    pub fn brdf(self) -> Ward {
        Ward { rho_d: self.rho_d, rho_s: self.rho_s, alpha: self.alpha }
    }
}

/// Box bounds on `[rho_d, rho_s, alpha]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Lower bounds.
    pub lo: [f64; 3],
    /// Upper bounds.
    pub hi: [f64; 3],
}

impl Bounds {
    /// Physical ranges: albedos in [0, 1], roughness 0.005..0.5 (from a
    /// near-mirror to a very rough surface).
    pub fn physical() -> Self {
        Self { lo: [0.0, 0.0, 0.005], hi: [1.0, 1.0, 0.5] }
    }
}

/// How residuals are weighted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Weighting {
    /// `(model - v) / v`: maximum likelihood for noise proportional to the value.
    Relative,
    /// `model - v`: ordinary least squares.
    Uniform,
}

/// Fit settings.
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Parameter bounds.
    pub bounds: Bounds,
    /// Number of log-spaced alphas in the start scan.
    pub alpha_grid: usize,
    /// Number of starts (best local minima of the scan) refined by LM.
    pub starts: usize,
    /// Relative reduction of the cost below which LM stops.
    pub ftol: f64,
    /// Relative step size below which LM stops.
    pub xtol: f64,
    /// Gradient orthogonality below which LM stops.
    pub gtol: f64,
    /// LM gives up after `patience * (3 + 1)` residual evaluations.
    pub patience: usize,
    /// Residual weighting.
    pub weighting: Weighting,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            bounds: Bounds::physical(),
            alpha_grid: 24,
            starts: 2,
            ftol: 1e-8,
            xtol: 1e-8,
            gtol: 1e-8,
            patience: 100,
            weighting: Weighting::Relative,
        }
    }
}

/// One fit's outcome and cost.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FitResult {
    /// Best parameters.
    pub params: WardParams,
    /// `0.5 * sum r_i^2` at the best parameters.
    pub cost: f64,
    /// Residual evaluations by LM, summed over starts.
    pub residual_evals: usize,
    /// Jacobian evaluations by LM (one per LM iteration), summed over starts.
    pub jacobian_evals: usize,
    /// Forward-model evaluations of the start scan.
    pub scan_evals: usize,
    /// Starts refined.
    pub starts: usize,
    /// Whether the best start's LM reported convergence.
    pub converged: bool,
    /// LM's termination reason for the best start.
    pub termination: String,
}

/// One ray, reduced to what the Ward model needs.
#[derive(Clone, Copy, Debug, PartialEq)]
struct RayTerm {
    /// Weight (sums to 1 per reading).
    weight: f64,
    /// `weight / (4 sqrt(cos_i cos_o))`.
    wc: f64,
    /// `tan^2` of the half-vector angle.
    tan2: f64,
}

/// The readings a Ward model predicts for an instrument.
#[derive(Clone, Debug, PartialEq)]
pub struct ForwardModel {
    readings: Vec<Vec<RayTerm>>,
}

impl ForwardModel {
    /// Condition 1: every reading is the BRDF at its LED's centre direction.
    pub fn far_field(inst: &Instrument) -> Self {
        Self::from_instrument(inst, true)
    }

    /// Condition 2: every reading integrates its LED's rays.
    pub fn near_field(inst: &Instrument) -> Self {
        Self::from_instrument(inst, false)
    }

    fn from_instrument(inst: &Instrument, far_field: bool) -> Self {
        let wo = surface_frame(&inst.normal()) * inst.view_dir();
        let readings = (0..inst.m())
            .map(|led| {
                rays(inst, led, far_field)
                    .iter()
                    .map(|r| ray_term(&r.dir, &wo, r.weight))
                    .filter(|t| t.weight > 0.0)
                    .collect()
            })
            .collect();
        Self { readings }
    }

    /// From explicit rays: for each reading, `(direction to the light, weight)`
    /// in the surface frame, and the direction to the viewer.
    pub fn from_rays(readings: &[Vec<(Vector3<f64>, f64)>], wo: &Vector3<f64>) -> Self {
        Self { readings: readings.iter().map(|r| r.iter().map(|(d, w)| ray_term(d, wo, *w)).collect()).collect() }
    }

    /// The rays of each reading as `[weight, weight / (4 sqrt(cos_i cos_o)), tan^2 delta]`
    /// (for external fitters and inspection).
    pub fn terms(&self) -> Vec<Vec<[f64; 3]>> {
        self.readings.iter().map(|rs| rs.iter().map(|t| [t.weight, t.wc, t.tan2]).collect()).collect()
    }

    /// Number of readings m.
    pub fn m(&self) -> usize {
        self.readings.len()
    }

    /// Predicted readings for `p`.
    pub fn readings(&self, p: &WardParams) -> Vec<f64> {
        let ia2 = 1.0 / (p.alpha * p.alpha);
        self.readings
            .iter()
            .map(|rs| rs.iter().map(|t| t.weight * p.rho_d + p.rho_s * t.wc * ia2 * (-t.tan2 * ia2).exp()).sum())
            .collect()
    }

    /// For a fixed alpha, the two basis values of reading i:
    /// `(sum weight, sum wc exp(-tan2/a^2)/a^2)`, so `v_i = rho_d a_i + rho_s b_i`.
    fn basis(&self, alpha: f64, out: &mut [(f64, f64)]) {
        let ia2 = 1.0 / (alpha * alpha);
        for (o, rs) in out.iter_mut().zip(&self.readings) {
            *o = rs.iter().fold((0.0, 0.0), |(a, b), t| (a + t.weight, b + t.wc * ia2 * (-t.tan2 * ia2).exp()));
        }
    }
}

fn ray_term(wi: &Vector3<f64>, wo: &Vector3<f64>, weight: f64) -> RayTerm {
    let (ci, co) = (wi.z, wo.z);
    if ci <= 0.0 || co <= 0.0 {
        return RayTerm { weight: 0.0, wc: 0.0, tan2: 0.0 };
    }
    let h = wi + wo;
    RayTerm { weight, wc: weight / (4.0 * (ci * co).sqrt()), tan2: (h.x * h.x + h.y * h.y) / (h.z * h.z) }
}

/// Maps unbounded internal `u` to bounded `p` and back (MINUIT's sine transform).
#[derive(Clone, Copy, Debug)]
struct Transform {
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Transform {
    fn external(&self, u: &[f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| self.lo[k] + (self.hi[k] - self.lo[k]) * 0.5 * (1.0 + u[k].sin()))
    }
    fn derivative(&self, u: &[f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| (self.hi[k] - self.lo[k]) * 0.5 * u[k].cos())
    }
    fn internal(&self, p: &[f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| {
            let span = self.hi[k] - self.lo[k];
            // Keep starts off the bounds, where the transform's slope is zero.
            let x = ((p[k] - self.lo[k]) / span).clamp(1e-4, 1.0 - 1e-4);
            (2.0 * x - 1.0).asin()
        })
    }
}

struct Problem<'a> {
    model: &'a ForwardModel,
    v: &'a [f64],
    inv_sigma: &'a [f64],
    tf: Transform,
    u: [f64; 3],
    residual_evals: Cell<usize>,
    jacobian_evals: Cell<usize>,
}

type Vec3 = na::Vector3<f64>;
type ResVec = na::DVector<f64>;
type JacMat = na::OMatrix<f64, na::Dyn, na::U3>;

impl LeastSquaresProblem<f64, na::Dyn, na::U3> for Problem<'_> {
    type ResidualStorage = na::VecStorage<f64, na::Dyn, na::U1>;
    type JacobianStorage = na::VecStorage<f64, na::Dyn, na::U3>;
    type ParameterStorage = na::ArrayStorage<f64, 3, 1>;

    fn set_params(&mut self, x: &Vec3) {
        self.u = [x[0], x[1], x[2]];
    }

    fn params(&self) -> Vec3 {
        Vec3::new(self.u[0], self.u[1], self.u[2])
    }

    fn residuals(&self) -> Option<ResVec> {
        self.residual_evals.set(self.residual_evals.get() + 1);
        let p = WardParams::from_array(self.tf.external(&self.u));
        let pred = self.model.readings(&p);
        let r = ResVec::from_iterator(
            pred.len(),
            pred.iter().zip(self.v).zip(self.inv_sigma).map(|((m, v), s)| (m - v) * s),
        );
        r.iter().all(|x| x.is_finite()).then_some(r)
    }

    fn jacobian(&self) -> Option<JacMat> {
        self.jacobian_evals.set(self.jacobian_evals.get() + 1);
        let [d, s, a] = self.tf.external(&self.u);
        let dp = self.tf.derivative(&self.u);
        let _ = d;
        let ia2 = 1.0 / (a * a);
        let m = self.model.m();
        let mut j = JacMat::zeros(m);
        for (i, rs) in self.model.readings.iter().enumerate() {
            let (mut dd, mut ds, mut da) = (0.0, 0.0, 0.0);
            for t in rs {
                let g = t.wc * ia2 * (-t.tan2 * ia2).exp();
                dd += t.weight;
                ds += g;
                // d/da [exp(-t/a^2)/a^2] = exp(-t/a^2)/a^2 * (2t/a^3 - 2/a)
                da += s * g * (2.0 * t.tan2 * ia2 / a - 2.0 / a);
            }
            let w = self.inv_sigma[i];
            j[(i, 0)] = w * dd * dp[0];
            j[(i, 1)] = w * ds * dp[1];
            j[(i, 2)] = w * da * dp[2];
        }
        j.iter().all(|x| x.is_finite()).then_some(j)
    }
}

/// Why a fit was not attempted.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FitError {
    /// Wrong number of readings.
    #[error("{got} readings given for a model with {want}")]
    Readings {
        /// Model's m.
        want: usize,
        /// Given.
        got: usize,
    },
    /// A reading is NaN, infinite or negative.
    #[error("reading {index} is {value}: readings must be finite and non-negative")]
    BadReading {
        /// Index.
        index: usize,
        /// Value.
        value: f64,
    },
}

/// Fits Ward parameters to readings `v` under `model`.
pub fn fit_ward(model: &ForwardModel, v: &[f64], opts: &FitOptions) -> Result<FitResult, FitError> {
    let m = model.m();
    if v.len() != m {
        return Err(FitError::Readings { want: m, got: v.len() });
    }
    if let Some((index, value)) = v.iter().enumerate().find(|(_, x)| !x.is_finite() || **x < 0.0) {
        return Err(FitError::BadReading { index, value: *value });
    }
    let vmax = v.iter().fold(0.0f64, |a, x| a.max(*x));
    let inv_sigma: Vec<f64> = match opts.weighting {
        Weighting::Relative => v.iter().map(|x| 1.0 / x.max(1e-6 * vmax).max(f64::MIN_POSITIVE)).collect(),
        Weighting::Uniform => vec![1.0; m],
    };
    let b = opts.bounds;

    // Start scan: exact bounded linear solve for (rho_d, rho_s) per alpha.
    let k = opts.alpha_grid.max(1);
    let (alo, ahi) = (b.lo[2].max(1e-6), b.hi[2]);
    let mut basis = vec![(0.0, 0.0); m];
    let mut scan: Vec<([f64; 3], f64)> = Vec::with_capacity(k);
    for q in 0..k {
        let a = if k == 1 { (alo * ahi).sqrt() } else { alo * (ahi / alo).powf(q as f64 / (k - 1) as f64) };
        model.basis(a, &mut basis);
        let (d, s, cost) = bounded_linear_2(&basis, v, &inv_sigma, [b.lo[0], b.hi[0]], [b.lo[1], b.hi[1]]);
        scan.push(([d, s, a], cost));
    }
    // Local minima of the scan over alpha, best first.
    let mut minima: Vec<usize> = (0..k)
        .filter(|&q| (q == 0 || scan[q].1 <= scan[q - 1].1) && (q + 1 == k || scan[q].1 <= scan[q + 1].1))
        .collect();
    minima.sort_by(|x, y| scan[*x].1.total_cmp(&scan[*y].1));
    minima.truncate(opts.starts.max(1));

    let tf = Transform { lo: b.lo, hi: b.hi };
    let lm = LevenbergMarquardt::new()
        .with_ftol(opts.ftol)
        .with_xtol(opts.xtol)
        .with_gtol(opts.gtol)
        .with_patience(opts.patience);
    let mut best: Option<(f64, [f64; 3], TerminationReason)> = None;
    let (mut re, mut je) = (0, 0);
    for &q in &minima {
        let problem = Problem {
            model,
            v,
            inv_sigma: &inv_sigma,
            tf,
            u: tf.internal(&scan[q].0),
            residual_evals: Cell::new(0),
            jacobian_evals: Cell::new(0),
        };
        let (problem, report) = lm.minimize(problem);
        re += problem.residual_evals.get();
        je += problem.jacobian_evals.get();
        let p = tf.external(&problem.u);
        // Re-evaluate the cost at the returned point (LM reports the last one it computed).
        let cost = 0.5 * problem.residuals().map_or(f64::INFINITY, |r| r.norm_squared());
        if best.as_ref().is_none_or(|(c, _, _)| cost < *c) {
            best = Some((cost, p, report.termination));
        }
    }
    let (cost, p, term) = best.expect("at least one start");
    Ok(FitResult {
        params: WardParams::from_array(p),
        cost,
        residual_evals: re,
        jacobian_evals: je,
        scan_evals: k,
        starts: minima.len(),
        converged: term.was_successful(),
        termination: format!("{term:?}"),
    })
}

/// Minimises `sum w_i^2 (d a_i + s b_i - v_i)^2` over the box, exactly:
/// the unconstrained solution if feasible, else the best of the edge and
/// corner solutions. Returns `(d, s, 0.5 * cost)`.
fn bounded_linear_2(ab: &[(f64, f64)], v: &[f64], w: &[f64], dr: [f64; 2], sr: [f64; 2]) -> (f64, f64, f64) {
    let (mut saa, mut sab, mut sbb, mut sav, mut sbv) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for ((&(a, b), &vi), &wi) in ab.iter().zip(v).zip(w) {
        let (a, b, vi) = (a * wi, b * wi, vi * wi);
        saa += a * a;
        sab += a * b;
        sbb += b * b;
        sav += a * vi;
        sbv += b * vi;
    }
    let cost = |d: f64, s: f64| -> f64 {
        ab.iter().zip(v).zip(w).map(|((&(a, b), &vi), &wi)| (wi * (d * a + s * b - vi)).powi(2)).sum::<f64>() * 0.5
    };
    let inside = |x: f64, r: [f64; 2]| x >= r[0] && x <= r[1];
    let det = saa * sbb - sab * sab;
    if det > 1e-12 * saa * sbb {
        let d = (sav * sbb - sbv * sab) / det;
        let s = (sbv * saa - sav * sab) / det;
        if inside(d, dr) && inside(s, sr) {
            return (d, s, cost(d, s));
        }
    }
    let mut best = (dr[0], sr[0], f64::INFINITY);
    let mut consider = |d: f64, s: f64| {
        let (d, s) = (d.clamp(dr[0], dr[1]), s.clamp(sr[0], sr[1]));
        let c = cost(d, s);
        if c < best.2 {
            best = (d, s, c);
        }
    };
    for d in dr {
        consider(d, if sbb > 0.0 { (sbv - d * sab) / sbb } else { sr[0] });
    }
    for s in sr {
        consider(if saa > 0.0 { (sav - s * sab) / saa } else { dr[0] }, s);
    }
    for d in dr {
        for s in sr {
            consider(d, s);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::Brdf;
    use crate::forward::optics::simulate_readings;

    #[test]
    fn forward_models_match_the_optics_simulation() {
        let inst = Instrument::patent_profile();
        let w = Ward::patent(0.35, 0.06);
        let p = WardParams { rho_d: 0.35, rho_s: 0.65, alpha: 0.06 };
        for far in [true, false] {
            let fm = if far { ForwardModel::far_field(&inst) } else { ForwardModel::near_field(&inst) };
            let mine = fm.readings(&p);
            let sim = simulate_readings(&inst, &w, far);
            for i in 0..inst.m() {
                assert!((mine[i] - sim[i]).abs() < 1e-10 * sim[i], "far={far} reading {i}: {} vs {}", mine[i], sim[i]);
            }
        }
    }

    #[test]
    fn fit_model_matches_simulated_readings_on_a_tilted_point() {
        let mut inst = Instrument::patent_profile();
        let t = 3f64.to_radians();
        inst.point.normal = [-t.sin(), 0.01, t.cos()];
        inst.point.position_cm = [0.4, 0.1, 0.0];
        let w = Ward::patent(0.5, 0.08);
        let fm = ForwardModel::near_field(&inst);
        let mine = fm.readings(&WardParams { rho_d: 0.5, rho_s: 0.5, alpha: 0.08 });
        let sim = simulate_readings(&inst, &w, false);
        for i in 0..inst.m() {
            assert!((mine[i] - sim[i]).abs() < 1e-10 * sim[i]);
        }
    }

    #[test]
    fn analytic_jacobian_matches_finite_differences() {
        let inst = Instrument::patent_profile();
        let fm = ForwardModel::near_field(&inst);
        let v = fm.readings(&WardParams { rho_d: 0.3, rho_s: 0.6, alpha: 0.05 });
        let inv: Vec<f64> = v.iter().map(|x| 1.0 / x).collect();
        let tf = Transform { lo: Bounds::physical().lo, hi: Bounds::physical().hi };
        let mut pr = Problem {
            model: &fm,
            v: &v,
            inv_sigma: &inv,
            tf,
            u: tf.internal(&[0.4, 0.5, 0.07]),
            residual_evals: Cell::new(0),
            jacobian_evals: Cell::new(0),
        };
        let j = pr.jacobian().unwrap();
        let u0 = pr.u;
        for k in 0..3 {
            let h = 1e-6;
            let mut up = u0;
            up[k] += h;
            pr.set_params(&Vec3::from(up));
            let rp = pr.residuals().unwrap();
            let mut dn = u0;
            dn[k] -= h;
            pr.set_params(&Vec3::from(dn));
            let rm = pr.residuals().unwrap();
            for i in 0..fm.m() {
                let fd = (rp[i] - rm[i]) / (2.0 * h);
                assert!((fd - j[(i, k)]).abs() <= 1e-5 * fd.abs().max(1e-3), "d r{i}/d u{k}: {fd} vs {}", j[(i, k)]);
            }
        }
    }

    #[test]
    fn recovers_known_parameters_from_noise_free_readings_in_both_conditions() {
        let inst = Instrument::patent_profile();
        for (far, fm) in [(true, ForwardModel::far_field(&inst)), (false, ForwardModel::near_field(&inst))] {
            for &(d, a) in &[(0.2477, 0.0305), (0.4067, 0.0743), (0.9391, 0.0991), (0.3098, 0.0518)] {
                let w = Ward::patent(d, a);
                let v: Vec<f64> = simulate_readings(&inst, &w, far).iter().copied().collect();
                let r = fit_ward(&fm, &v, &FitOptions::default()).unwrap();
                let p = r.params;
                assert!((p.rho_d - d).abs() < 1e-5, "far={far} {d},{a}: rho_d {}", p.rho_d);
                assert!((p.rho_s - (1.0 - d)).abs() < 1e-4, "far={far} {d},{a}: rho_s {}", p.rho_s);
                assert!((p.alpha - a).abs() < 1e-6, "far={far} {d},{a}: alpha {}", p.alpha);
                assert!(r.converged, "{}", r.termination);
                // The fitted model reproduces the BRDF.
                assert!(
                    (p.brdf().reflectance(45.0, 45.0) - w.reflectance(45.0, 45.0)).abs()
                        < 1e-3 * w.reflectance(45.0, 45.0)
                );
            }
        }
    }

    #[test]
    fn bounds_hold_and_bad_readings_are_refused() {
        let inst = Instrument::patent_profile();
        let fm = ForwardModel::near_field(&inst);
        // Readings no Ward model in the bounds can produce (rising with angle).
        let v: Vec<f64> = (0..7).map(|i| 5.0 + i as f64).collect();
        let r = fit_ward(&fm, &v, &FitOptions::default()).unwrap();
        let b = Bounds::physical();
        for (k, x) in r.params.to_array().iter().enumerate() {
            assert!(*x >= b.lo[k] && *x <= b.hi[k], "parameter {k} = {x}");
        }
        assert_eq!(fit_ward(&fm, &[1.0; 3], &FitOptions::default()), Err(FitError::Readings { want: 7, got: 3 }));
        let mut bad = v.clone();
        bad[2] = f64::NAN;
        assert!(matches!(fit_ward(&fm, &bad, &FitOptions::default()), Err(FitError::BadReading { index: 2, .. })));
    }

    #[test]
    fn bounded_linear_solve_is_exact_inside_and_clamped_outside() {
        let ab = [(1.0, 0.5), (1.0, 2.0), (1.0, 8.0)];
        let v: Vec<f64> = ab.iter().map(|(a, b)| 0.3 * a + 0.6 * b).collect();
        let w = [1.0; 3];
        let (d, s, c) = bounded_linear_2(&ab, &v, &w, [0.0, 1.0], [0.0, 1.0]);
        assert!((d - 0.3).abs() < 1e-12 && (s - 0.6).abs() < 1e-12 && c < 1e-20);
        let v: Vec<f64> = ab.iter().map(|(a, b)| -0.2 * a + 0.6 * b).collect();
        let (d, s, _) = bounded_linear_2(&ab, &v, &w, [0.0, 1.0], [0.0, 1.0]);
        assert_eq!(d, 0.0);
        assert!(s > 0.5 && s < 0.6);
    }
}
