//! Hard-case generators: one [`Family`] per way a real instrument makes the
//! Wiener problem hard. Every case is a deterministic function of
//! `(family, seed)`, so any failure is reproduced by its seed alone.
use crate::forward::brdf::{Brdf, Ward};
use crate::forward::grid::{AngleGrid, GridSpec};
use crate::forward::optics::{ClusterSpec, Instrument, LedSpec, system_matrix};
use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// The hard-case families.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Family {
    /// Patent-like optics, relative noise log-uniform in [1e-12, 0.2].
    Noise,
    /// Synthetic H and prior with cond(H R_pp H^T) log-uniform in [1e2, 1e14].
    Conditioning,
    /// A duplicated LED (exact copy, or 1e-9..1e-2 deg away).
    DuplicateLeds,
    /// All LEDs bunched within 0.5..6 deg on one side of the grid.
    OneSided,
    /// Fewer prior samples than LEDs (K < m).
    FewSamples,
    /// Many samples spanning only 1..3 directions (rank-deficient R_pp).
    RankDeficientPrior,
    /// Ward roughness down to alpha = 0.005 (lobes spanning 1e4 in value).
    SharpLobe,
    /// Centre rays up to 85..89 deg, grid to 89.5 deg.
    Grazing,
    /// Per-reading sensor gains log-uniform in [1e-6, 1e6] folded into H.
    Gain,
}

impl Family {
    /// Every family, in report order.
    pub const ALL: [Family; 9] = [
        Family::Noise,
        Family::Conditioning,
        Family::DuplicateLeds,
        Family::OneSided,
        Family::FewSamples,
        Family::RankDeficientPrior,
        Family::SharpLobe,
        Family::Grazing,
        Family::Gain,
    ];

    /// Kebab-case name (reports, JSON).
    pub fn name(self) -> &'static str {
        match self {
            Family::Noise => "noise",
            Family::Conditioning => "conditioning",
            Family::DuplicateLeds => "duplicate-leds",
            Family::OneSided => "one-sided",
            Family::FewSamples => "few-samples",
            Family::RankDeficientPrior => "rank-deficient-prior",
            Family::SharpLobe => "sharp-lobe",
            Family::Grazing => "grazing",
            Family::Gain => "gain",
        }
    }
}

/// One hard case: what a solver is given, and the BRDFs it is judged on.
#[derive(Clone, Debug)]
pub struct Case {
    /// Family.
    pub family: Family,
    /// Seed (with the family, reproduces the case).
    pub seed: u64,
    /// The generating parameters, for reports.
    pub label: String,
    /// System matrix as the solver sees it, m x n (gains included).
    pub h: DMatrix<f64>,
    /// The prior's samples, n x K (also the test BRDFs: in-sample, the
    /// covariance's prediction is exact in expectation).
    pub samples: DMatrix<f64>,
    /// `R_pp = samples samples^T / K`.
    pub r_pp: DMatrix<f64>,
    /// Relative noise level s (`R_nn = s^2 diag(H R_pp H^T)`).
    pub noise: f64,
    /// Gain family: the per-reading gains G with `h = G h0`, and h0.
    pub gains: Option<(DVector<f64>, DMatrix<f64>)>,
}

impl Case {
    /// Readings m.
    pub fn m(&self) -> usize {
        self.h.nrows()
    }
    /// Bins n.
    pub fn n(&self) -> usize {
        self.h.ncols()
    }
    /// Prior samples K.
    pub fn k(&self) -> usize {
        self.samples.ncols()
    }
}

/// Builds the case of `family` for `seed`.
pub fn generate(family: Family, seed: u64) -> Case {
    // Mix the family into the stream so equal seeds differ across families.
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ ((family as u64 + 1) << 56));
    let noise = log_uniform(&mut rng, 1e-12, 0.2);
    match family {
        Family::Noise => {
            let (h, grid, label) = regular_optics(&mut rng);
            let k = rng.random_range(8..=40);
            let s = ward_samples(&mut rng, &grid, 45.0, k, 0.02, 0.1);
            finish(family, seed, format!("{label}, K={k}, s={noise:.2e}"), h, s, noise, None)
        }
        Family::Conditioning => conditioning(&mut rng, family, seed, noise),
        Family::DuplicateLeds => {
            let m0 = rng.random_range(4..=8);
            let (mut centres, pitch) = regular_centres(&mut rng, m0);
            let j = rng.random_range(0..m0);
            let exact = rng.random_range(0..3) == 0;
            let delta = if exact { 0.0 } else { log_uniform(&mut rng, 1e-9, 1e-2) };
            centres.insert(j + 1, centres[j] + delta);
            if rng.random_range(0..2) == 0 {
                // A third LED at the same place.
                centres.insert(j + 1, centres[j]);
            }
            let grid = GridSpec::patent();
            let h = optics_h(&centres, pitch, 5, &grid, 45.0);
            let k = rng.random_range(8..=40);
            let g = AngleGrid::new(&grid).expect("valid grid");
            let s = ward_samples(&mut rng, &g, 45.0, k, 0.02, 0.1);
            let label = format!("m={}, LED {j} repeated {} deg away, K={k}, s={noise:.2e}", centres.len(), delta);
            finish(family, seed, label, h, s, noise, None)
        }
        Family::OneSided => {
            let m = rng.random_range(4..=9);
            let span: f64 = rng.random_range(0.5..6.0);
            let c0 = rng.random_range(50.0..(58.0 - span).max(50.5));
            let centres: Vec<f64> = (0..m).map(|i| c0 + span * i as f64 / (m - 1) as f64).collect();
            let grid = GridSpec::patent();
            let h = optics_h(&centres, 0.17, 5, &grid, 45.0);
            let k = rng.random_range(8..=40);
            let g = AngleGrid::new(&grid).expect("valid grid");
            let s = ward_samples(&mut rng, &g, 45.0, k, 0.02, 0.1);
            finish(
                family,
                seed,
                format!("m={m} LEDs in {c0:.2}..{:.2} deg, K={k}, s={noise:.2e}", c0 + span),
                h,
                s,
                noise,
                None,
            )
        }
        Family::FewSamples => {
            let m = rng.random_range(5..=12);
            let (centres, pitch) = regular_centres(&mut rng, m);
            let grid = GridSpec::patent();
            let h = optics_h(&centres, pitch, 5, &grid, 45.0);
            let k = rng.random_range(1..m);
            let g = AngleGrid::new(&grid).expect("valid grid");
            let s = ward_samples(&mut rng, &g, 45.0, k, 0.02, 0.1);
            finish(family, seed, format!("m={m}, K={k} < m, s={noise:.2e}"), h, s, noise, None)
        }
        Family::RankDeficientPrior => {
            let (h, grid, label) = regular_optics(&mut rng);
            let rank = rng.random_range(1..=3);
            let base = ward_samples(&mut rng, &grid, 45.0, rank, 0.02, 0.1);
            let k = rng.random_range(2 * h.nrows()..=3 * h.nrows() + 4);
            let c = DMatrix::from_fn(rank, k, |_, _| rng.random_range(0.0..1.0));
            let s = &base * c;
            finish(family, seed, format!("{label}, K={k} samples of rank {rank}, s={noise:.2e}"), h, s, noise, None)
        }
        Family::SharpLobe => {
            let (h, grid, label) = regular_optics(&mut rng);
            let k = rng.random_range(8..=40);
            let s = ward_samples(&mut rng, &grid, 45.0, k, 0.005, 0.05);
            let span = s.max() / s.iter().copied().filter(|x| *x > 0.0).fold(f64::INFINITY, f64::min);
            finish(
                family,
                seed,
                format!("{label}, K={k}, alpha 0.005..0.05, value span {span:.1e}, s={noise:.2e}"),
                h,
                s,
                noise,
                None,
            )
        }
        Family::Grazing => {
            let m = rng.random_range(4..=8);
            let last = rng.random_range(85.0..89.0);
            let first = rng.random_range(55.0..65.0);
            let centres: Vec<f64> = (0..m).map(|i| first + (last - first) * i as f64 / (m - 1) as f64).collect();
            // Keep the outer sources of the 5-source row below 89.4 deg.
            let room = (89.4 - last).to_radians() * 10.0 / 2.0;
            let pitch = (0.9 * room).min(0.17);
            let grid = GridSpec { start_deg: 40.0, stop_deg: 89.5, step_deg: 0.5 };
            let h = optics_h(&centres, pitch, 5, &grid, 45.0);
            let k = rng.random_range(8..=40);
            let g = AngleGrid::new(&grid).expect("valid grid");
            let s = ward_samples(&mut rng, &g, 45.0, k, 0.02, 0.1);
            let label = format!("m={m}, centres {first:.1}..{last:.2} deg, pitch {pitch:.3} cm, K={k}, s={noise:.2e}");
            finish(family, seed, label, h, s, noise, None)
        }
        Family::Gain => {
            let (h0, grid, label) = regular_optics(&mut rng);
            let k = rng.random_range(8..=40);
            let s = ward_samples(&mut rng, &grid, 45.0, k, 0.02, 0.1);
            let common = log_uniform(&mut rng, 1e-6, 1e6);
            let spread = rng.random_range(0..2) == 0;
            let g = DVector::from_fn(h0.nrows(), |_, _| if spread { log_uniform(&mut rng, 1e-6, 1e6) } else { common });
            let h = DMatrix::from_fn(h0.nrows(), h0.ncols(), |i, j| g[i] * h0[(i, j)]);
            let label = format!("{label}, gains {:.1e}..{:.1e}, K={k}, s={noise:.2e}", g.min(), g.max());
            finish(family, seed, label, h, s, noise, Some((g, h0)))
        }
    }
}

fn finish(
    family: Family,
    seed: u64,
    label: String,
    h: DMatrix<f64>,
    samples: DMatrix<f64>,
    noise: f64,
    gains: Option<(DVector<f64>, DMatrix<f64>)>,
) -> Case {
    let r_pp = &samples * samples.transpose() / samples.ncols() as f64;
    Case { family, seed, label, h, samples, r_pp, noise, gains }
}

/// `lo * (hi/lo)^U(0,1)`.
pub fn log_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    (lo.ln() + rng.random_range(0.0..1.0) * (hi.ln() - lo.ln())).exp()
}

/// m evenly spaced centre angles within the patent grid, and a cluster pitch.
fn regular_centres(rng: &mut ChaCha8Rng, m: usize) -> (Vec<f64>, f64) {
    let step = rng.random_range(2.0..(26.0 / (m - 1) as f64).min(5.0));
    let c0 = rng.random_range(29.0..(61.0 - step * (m - 1) as f64).max(29.5));
    let pitch = rng.random_range(0.05..0.2);
    ((0..m).map(|i| c0 + step * i as f64).collect(), pitch)
}

fn regular_optics(rng: &mut ChaCha8Rng) -> (DMatrix<f64>, AngleGrid, String) {
    let m = rng.random_range(4..=9);
    let (centres, pitch) = regular_centres(rng, m);
    let grid = GridSpec::patent();
    let h = optics_h(&centres, pitch, 5, &grid, 45.0);
    let label = format!("m={m}, centres {:.1}..{:.1} deg, pitch {pitch:.3} cm", centres[0], centres[m - 1]);
    (h, AngleGrid::new(&grid).expect("valid grid"), label)
}

/// H of LEDs at `centres` (each a row of `count` sources `pitch` cm apart,
/// 10 cm away) through the product's optics model.
///
/// # Panics
/// If the optics refuse the geometry (a generator bug, not a solver failure).
pub fn optics_h(centres: &[f64], pitch: f64, count: usize, grid: &GridSpec, view_deg: f64) -> DMatrix<f64> {
    let mut inst = Instrument::patent_profile();
    inst.name = "stability".into();
    inst.view_deg = view_deg;
    inst.grid = grid.clone();
    inst.leds = centres
        .iter()
        .enumerate()
        .map(|(i, c)| LedSpec {
            name: Some(format!("L{i}")),
            centre_deg: *c,
            distance_cm: 10.0,
            azimuth_deg: 0.0,
            cluster: Some(ClusterSpec { count, pitch_cm: pitch }),
            sources: None,
            extended: None,
            intensity: 1.0,
            emission: None,
        })
        .collect();
    let g = AngleGrid::new(grid).expect("valid grid");
    system_matrix(&inst, &g, false).unwrap_or_else(|e| panic!("generator geometry refused by the optics: {e}"))
}

/// K Ward samples (rho_s = 1 - rho_d) with rho_d in [0.05, 0.95] and alpha
/// log-uniform in [alpha_lo, alpha_hi], as reflectance factors on the grid: n x K.
pub fn ward_samples(
    rng: &mut ChaCha8Rng,
    grid: &AngleGrid,
    view_deg: f64,
    k: usize,
    alpha_lo: f64,
    alpha_hi: f64,
) -> DMatrix<f64> {
    let brdfs: Vec<Ward> =
        (0..k).map(|_| Ward::patent(rng.random_range(0.05..0.95), log_uniform(rng, alpha_lo, alpha_hi))).collect();
    DMatrix::from_fn(grid.n(), k, |j, c| brdfs[c].reflectance(grid.bins_deg()[j], view_deg))
}

/// Synthetic H = U diag(sh) V^T (m x n) and a prior with eigenvalues
/// log-spaced over two decades, scaled so cond(H R_pp H^T) lands near a target
/// log-uniform in [1e2, 1e14].
fn conditioning(rng: &mut ChaCha8Rng, family: Family, seed: u64, noise: f64) -> Case {
    let n = rng.random_range(20..=81);
    let m = rng.random_range(3..=12);
    let target = log_uniform(rng, 1e2, 1e14);
    // cond(H R H^T) ~ cond(H)^2 * (prior spread seen through H, up to 1e2).
    let cond_h = (target / 10.0).sqrt().max(1.0);
    let u = orthonormal(rng, m, m);
    let v = orthonormal(rng, n, m);
    let sh = DVector::from_fn(m, |i, _| cond_h.powf(-(i as f64) / (m - 1) as f64));
    let h = &u * DMatrix::from_diagonal(&sh) * v.transpose();
    let q = orthonormal(rng, n, n);
    let lam = DVector::from_fn(n, |i, _| 10f64.powf(-2.0 * i as f64 / (n - 1) as f64));
    let k = n + 10;
    let z = DMatrix::from_fn(n, k, |_, _| gauss(rng));
    let s = q * DMatrix::from_diagonal(&lam.map(f64::sqrt)) * z;
    finish(family, seed, format!("n={n}, m={m}, target cond {target:.1e}, K={k}, s={noise:.2e}"), h, s, noise, None)
}

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    // Box-Muller; rand_distr would do, this keeps the stream explicit.
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// An r x c matrix with orthonormal columns (QR of a Gaussian matrix).
fn orthonormal(rng: &mut ChaCha8Rng, r: usize, c: usize) -> DMatrix<f64> {
    let g = DMatrix::from_fn(r, c, |_, _| gauss(rng));
    g.qr().q().columns(0, c).into_owned()
}
