//! The hard cases stay numerically stable.
//!
//! - Property tests (proptest, fixed seed, [`CASES`] cases per family) over
//!   every family of `host_tools::evaluation::stability`: all invariants hold for the
//!   product's solver and the device kernel.
//! - Every invariant is shown to fail for a deliberately broken solver or
//!   kernel on hard cases (so none of them is vacuous).
//! - The sigma -> 0 limit is the minimum-norm `R^1/2 (H R^1/2)^+`.
//! - Training's f32 gate: the pass path, the power-of-two rescaling path and
//!   the refusal (with the zone, the measured error, the tolerance and advice).
//! - No explicit inverse in production code.
//!
//! The long run (>= 10,000 cases) is `cargo run --release -p host-tools --
//! stability --cases 10000 --json out/stability.json`.
use brdf_meter::blob::{BlobView, EstimatorKind};
use host_tools::calibration::estimators::{self, EstimatorInputs, NoiseModel};
use host_tools::calibration::train::{F32_TOLERANCE, TrainSpec, f32_gate, train};
use host_tools::evaluation::stability::solvers::{
    ExplicitInverse, F32Only, FixedFloor, IgnoresNoise, Solver, TruncateThenWhiten, bf16_kernel,
};
use host_tools::evaluation::stability::{CaseReport, Family, Production, check_case, device_kernel, generate};
use host_tools::forward::grid::AngleGrid;
use host_tools::forward::optics::Instrument;
use host_tools::forward::prior::{Prior, PriorSpec};
use host_tools::forward::prior_models::{PriorModels, PriorSample, SampleModel};
use host_tools::forward::reading_noise::ReadingNoise;
use host_tools::forward::zone_optics::{ZoneOptics, uniform_zones};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed};
use std::path::Path;

/// Cases per family in the normal test run (9 families).
const CASES: u32 = 40;

fn config(seed: u64) -> Config {
    Config {
        cases: CASES,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        max_shrink_iters: 0,
        ..Config::default()
    }
}

fn assert_holds(r: &CaseReport) -> Result<(), TestCaseError> {
    prop_assert!(r.failures.is_empty(), "{} seed {} [{}]: {:#?}", r.family, r.seed, r.label, r.failures);
    Ok(())
}

macro_rules! family_property {
    ($name:ident, $family:expr, $seed:expr) => {
        proptest! {
            #![proptest_config(config($seed))]
            #[test]
            fn $name(seed in any::<u64>()) {
                assert_holds(&check_case(&generate($family, seed), &Production, device_kernel))?;
            }
        }
    };
}

family_property!(noise_1e_12_to_0_2_stays_stable, Family::Noise, 1);
family_property!(condition_up_to_1e14_stays_stable, Family::Conditioning, 2);
family_property!(duplicate_and_coincident_leds_stay_stable, Family::DuplicateLeds, 3);
family_property!(leds_bunched_on_one_side_stay_stable, Family::OneSided, 4);
family_property!(fewer_samples_than_leds_stay_stable, Family::FewSamples, 5);
family_property!(rank_deficient_priors_stay_stable, Family::RankDeficientPrior, 6);
family_property!(roughness_down_to_0_005_stays_stable, Family::SharpLobe, 7);
family_property!(grazing_incidence_to_89_deg_stays_stable, Family::Grazing, 8);
family_property!(sensor_gains_1e_6_to_1e6_stay_stable, Family::Gain, 9);

/// How many of `seeds` cases of `family` fail the invariant tagged `tag`
/// (e.g. "I5") for `solver` and `kernel`.
fn failures(
    solver: &dyn Solver,
    kernel: host_tools::evaluation::stability::DeviceKernel,
    family: Family,
    seeds: std::ops::Range<u64>,
    tag: &str,
) -> usize {
    seeds
        .map(|s| check_case(&generate(family, s), solver, kernel))
        .filter(|r| r.failures.iter().any(|f| f.starts_with(tag)))
        .count()
}

#[test]
fn production_passes_where_the_broken_solvers_are_caught() {
    // The same cases for all: the product passes them (else the comparisons mean nothing).
    for fam in [Family::Noise, Family::Conditioning, Family::DuplicateLeds, Family::Gain] {
        for s in 0..24 {
            let r = check_case(&generate(fam, s), &Production, device_kernel);
            assert!(r.failures.is_empty(), "{} seed {s}: {:?}", fam.name(), r.failures);
        }
    }
}

#[test]
fn explicit_inverse_is_caught_by_the_backward_error_and_the_error_bound() {
    // cond(H R_pp H^T) up to 1e14: the explicit inverse loses up to 14 digits.
    let i5 = failures(&ExplicitInverse, device_kernel, Family::Conditioning, 0..24, "I5");
    assert!(i5 >= 3, "I5 flagged only {i5} of 24 explicit-inverse cases");
    // Duplicate LEDs: H R_pp H^T singular, the inverse is garbage or NaN.
    let bad = (0..24)
        .map(|s| check_case(&generate(Family::DuplicateLeds, s), &ExplicitInverse, device_kernel))
        .filter(|r| r.failures.iter().any(|f| f.starts_with("I1") || f.starts_with("I2") || f.starts_with("I5")))
        .count();
    assert!(bad >= 3, "only {bad} of 24 duplicate-LED cases flagged for the explicit inverse");
}

#[test]
fn f32_only_solver_is_caught() {
    let n = failures(&F32Only, device_kernel, Family::Conditioning, 0..24, "I5")
        + failures(&F32Only, device_kernel, Family::Conditioning, 0..24, "I2");
    assert!(n >= 6, "the f32-only solver was flagged only {n} times");
}

#[test]
fn a_fixed_floor_is_caught_by_continuity() {
    let n = failures(&FixedFloor, device_kernel, Family::Noise, 0..16, "I3");
    assert!(n >= 8, "a fixed Tikhonov floor passed continuity in {} of 16 cases", 16 - n);
}

#[test]
fn ignoring_the_noise_is_caught_by_the_error_bound() {
    let n = failures(&IgnoresNoise, device_kernel, Family::Noise, 0..24, "I2");
    assert!(n >= 6, "eq. 20 under noise was flagged only {n} times");
}

#[test]
fn a_bf16_kernel_is_caught_by_the_f32_bound() {
    let n = failures(&Production, bf16_kernel, Family::Noise, 0..8, "I4");
    assert_eq!(n, 8, "bf16 weights passed the f32 rounding bound");
}

#[test]
fn rank_decided_before_whitening_is_caught_by_gain_covariance() {
    let n = failures(&TruncateThenWhiten, device_kernel, Family::Gain, 0..24, "I6")
        + failures(&TruncateThenWhiten, device_kernel, Family::Gain, 0..24, "I2");
    assert!(n >= 3, "the old truncate-then-whiten algorithm was flagged only {n} times on gains 1e-6..1e6");
}

/// `R^1/2` by the symmetric eigendecomposition (eigenvalues below the
/// documented floor `n eps lambda_max` dropped, as the product does).
fn sqrt_psd(r: &DMatrix<f64>) -> DMatrix<f64> {
    let n = r.nrows();
    let e = r.clone().symmetric_eigen();
    let lmax = e.eigenvalues.amax();
    let d = e.eigenvalues.map(|x| if x > n as f64 * f64::EPSILON * lmax { x.sqrt() } else { 0.0 });
    &e.eigenvectors * DMatrix::from_diagonal(&d) * e.eigenvectors.transpose()
}

fn wiener(h: &DMatrix<f64>, r: &DMatrix<f64>, noise: NoiseModel) -> DMatrix<f64> {
    let kind = if matches!(noise, NoiseModel::None) { EstimatorKind::WienerNoiseFree } else { EstimatorKind::Wiener };
    let inputs = EstimatorInputs { h, r_pp: r, prior_samples: 0, noise, bins_deg: &[], centres_deg: &[] };
    estimators::build(kind, &inputs).unwrap().w
}

#[test]
fn noise_free_wiener_is_the_minimum_norm_limit_on_singular_systems() {
    // The patent profile's H (cond(H R_pp H^T) ~ 1e10) made singular two ways:
    // LED 4 duplicated exactly (8 readings), and a prior of 5 samples (< 8).
    let grid = AngleGrid::patent();
    let h7 = host_tools::forward::optics::system_matrix(&Instrument::patent_profile(), &grid, false).unwrap();
    let mut h = DMatrix::zeros(8, 81);
    h.rows_mut(0, 7).copy_from(&h7);
    h.set_row(7, &h7.row(3));
    let full = patent_prior(&grid);
    let few = Prior::from_samples(full.samples.columns(0, 5).into_owned() + full.samples.columns(9, 5)).unwrap();
    for (name, r) in [("16 samples", &full.r_pp), ("5 samples", &few.r_pp)] {
        let m = h.nrows();
        let rh = sqrt_psd(r);
        let b = &h * &rh;
        let sv = b.clone().svd(false, false).singular_values;
        let tol = estimators::rank_tolerance(m, 81) * sv.amax();
        let w_mn = &rh * b.clone().pseudo_inverse(tol).unwrap(); // R^1/2 (H R^1/2)^+
        let w0 = wiener(&h, r, NoiseModel::None);
        let d0 = (&w0 - &w_mn).norm() / w_mn.norm();
        // Rounding: c max(m, n) u kappa with kappa = s_max / s_min(kept) of H R^1/2.
        let kept_min = sv.iter().copied().filter(|x| *x > tol).fold(f64::INFINITY, f64::min);
        let bound = 64.0 * 81.0 * f64::EPSILON / 2.0 * sv.amax() / kept_min;
        assert!(d0 <= bound, "{name}: eq. 20 vs R^1/2 (H R^1/2)^+: {d0:e} > {bound:e}");
        // Isotropic noise sigma^2 mean(diag(H R H^T)) I: W(sigma) -> W_mn, and
        // the distance shrinks monotonically (exact for isotropic noise:
        // |W(sigma) - W_mn|_F^2 = sum_i (sigma^2 / (s_i (s_i^2 + sigma^2)))^2 |L v_i|^2).
        let scale = (&h * r * h.transpose()).diagonal().mean();
        let mut last = f64::INFINITY;
        for k in 1..=7 {
            let sg = 10f64.powi(-2 * k);
            let w = wiener(&h, r, NoiseModel::Covariance(DMatrix::identity(m, m) * (sg * sg * scale)));
            assert!(w.iter().all(|x| x.is_finite()));
            let d = (&w - &w_mn).norm() / w_mn.norm();
            assert!(d <= last * (1.0 + 1e-9) + bound, "{name}: sigma {sg:e}: {d:e} after {last:e}");
            last = d;
        }
        assert!(last <= bound, "{name}: W(sigma = 1e-14) is {last:e} from the minimum-norm solution (bound {bound:e})");
    }
}

fn patent_prior(grid: &AngleGrid) -> Prior {
    PriorSpec::patent().build(grid, 45.0, Path::new(".")).unwrap()
}

/// The patent prior's samples as training takes them (their grid vectors:
/// in-plane pairs `H rho` whatever H a case gives).
fn profiles(prior: &Prior) -> &'static PriorModels {
    let samples = prior
        .samples
        .column_iter()
        .enumerate()
        .map(|(k, c)| PriorSample {
            name: format!("patent:{k}"),
            family: "patent".into(),
            weight: 1.0 / prior.samples.ncols() as f64,
            model: SampleModel::Profile(c.into_owned()),
        })
        .collect();
    Box::leak(Box::new(PriorModels { samples, ..Default::default() }))
}

/// A zone of in-plane optics `h` with relative noise `noise`.
fn zone(h: DMatrix<f64>, centres: &[f64], noise: f64) -> ZoneOptics {
    ZoneOptics::from_h(0, h, centres.to_vec(), 45.0, &AngleGrid::patent(), ReadingNoise::relative(noise, centres.len()))
}

fn spec<'a>(
    prior: &'a Prior,
    bins: &'a [f64],
    zones: Vec<ZoneOptics>,
    noise: f64,
    kind: EstimatorKind,
) -> TrainSpec<'a> {
    TrainSpec::new(bins, zones, 16, 45.0, profiles(prior), noise, kind)
}

#[test]
fn f32_gate_passes_the_patent_profile_unscaled() {
    let grid = AngleGrid::patent();
    let prior = patent_prior(&grid);
    let inst = Instrument::patent_profile();
    let zones = uniform_zones(&inst, &grid, 2, 16, false, 0.02).unwrap();
    let t = train(&spec(&prior, grid.bins_deg(), zones, 0.02, EstimatorKind::Wiener)).unwrap();
    assert!(t.f32_rel_error <= F32_TOLERANCE, "{}", t.f32_rel_error);
    assert!(t.f32_exponents.iter().flatten().all(|e| *e == 0));
    // The blob's matrices are exactly W rounded to f32.
    let v = BlobView::parse(&t.blob).unwrap();
    let mut w = vec![0.0; 81 * 7];
    v.copy_matrix(1, &mut w);
    assert_eq!(w, t.zones[1].linear().unwrap().w_f32_row_major());
    assert_eq!(v.summary().f32_rel_error, t.f32_rel_error as f32);
}

#[test]
fn f32_gate_refuses_an_ill_conditioned_matrix_with_the_reason() {
    // LEDs bunched within 1.2 deg on one side, trained for noise 1e-10: W
    // cancels ~1e6-fold, which f32 cannot evaluate to 1e-3.
    let grid = AngleGrid::patent();
    let prior = patent_prior(&grid);
    let centres = [55.0, 55.2, 55.4, 55.6, 55.8, 56.0, 56.2];
    let h = host_tools::evaluation::stability::families::optics_h(&centres, 0.17, 5, &grid_spec(), 45.0);
    let zones = vec![zone(h, &centres, 1e-10)];
    let e = train(&spec(&prior, grid.bins_deg(), zones, 1e-10, EstimatorKind::Wiener)).unwrap_err();
    let msg = format!("{e:#}");
    assert!(msg.contains("zone 0"), "{msg}");
    assert!(msg.contains("tolerance 1e-3"), "{msg}");
    assert!(msg.contains("cancels"), "{msg}");
    assert!(msg.contains("--noise"), "{msg}");
    // The advice is right: at the advised noise the gate passes.
    let advised: f64 = msg.split("--noise ").nth(1).unwrap().split_whitespace().next().unwrap().parse().unwrap();
    let h = host_tools::evaluation::stability::families::optics_h(&centres, 0.17, 5, &grid_spec(), 45.0);
    let zones = vec![zone(h, &centres, advised)];
    let t = train(&spec(&prior, grid.bins_deg(), zones, advised, EstimatorKind::Wiener)).unwrap();
    assert!(t.f32_rel_error <= F32_TOLERANCE);
}

fn grid_spec() -> host_tools::forward::grid::GridSpec {
    host_tools::forward::grid::GridSpec::patent()
}

#[test]
fn f32_gate_rescales_by_powers_of_two_when_w_leaves_the_f32_range() {
    // H in units 2^-128 of the white reference: W ~ 2^128 |W_0| overflows f32
    // and the readings are subnormal.
    let grid = AngleGrid::patent();
    let prior = patent_prior(&grid);
    let inst = Instrument::patent_profile();
    let k = 2f64.powi(-128);
    let h = uniform_zones(&inst, &grid, 1, 16, false, 0.02).unwrap()[0].h() * k;
    let zones = vec![zone(h.clone(), &inst.centre_angles_deg(), 0.02)];
    let w0 = wiener(&h, &prior.r_pp, NoiseModel::Relative(0.02));
    assert!(w0.amax() > f32::MAX as f64, "the case must overflow f32 unscaled");
    // The device's white reference is correspondingly large.
    let mut s = spec(&prior, grid.bins_deg(), zones, 0.02, EstimatorKind::Wiener);
    s.white = Some(vec![1e30; 16 * 7]);
    let t = train(&s).unwrap();
    let exps = &t.f32_exponents[0];
    assert!(exps.iter().all(|e| *e < -100), "{exps:?}");
    assert!(t.f32_rel_error <= F32_TOLERANCE);
    // Device emulation from the blob alone: raw signal = v * white, the device
    // divides by the blob's white and multiplies by the blob's W.
    let view = BlobView::parse(&t.blob).unwrap();
    let mut w = vec![0.0f32; 81 * 7];
    view.copy_matrix(0, &mut w);
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    for c in 0..prior.samples.ncols() {
        let v: DVector<f64> = &h * prior.samples.column(c);
        let vdev: Vec<f32> = (0..7).map(|i| ((v[i] * 1e30) as f32) / view.white(3, i)).collect();
        let mut out = vec![0.0f32; 81];
        brdf_meter::kernel::mat_vec_f32_slice(&w, &vdev, &mut out);
        let e64 = &w0 * &v;
        for j in 0..81 {
            assert!(out[j].is_finite());
            worst = worst.max((out[j] as f64 - e64[j]).abs());
            scale = scale.max(e64[j].abs());
        }
    }
    assert!(worst / scale <= F32_TOLERANCE, "device error {:.2e} of scale", worst / scale);
    // Without the rescaling the gate would have had nothing finite to offer.
    assert!(f32_gate(&w0, &(&h * &prior.samples)).unwrap().exponents.iter().any(|e| *e != 0));
}

/// The scene library's hard cases (`scenes/hard/*.toml`, the scene engineer's
/// files): H from each scene's optics and effects, the patent prior on the
/// scene's grid, the scene's proportional noise. Every invariant holds, and
/// training either writes a blob within the f32 tolerance or refuses with the
/// zone, the measured error and the tolerance - never NaN, never a panic.
#[test]
fn scene_library_hard_cases_stay_stable() {
    use host_tools::forward::scene::{EffectSpec, Scene, training_optics, zone_system_matrices};
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/hard");
    let Ok(entries) = std::fs::read_dir(&dir) else {
        eprintln!("no {} yet: skipped", dir.display());
        return;
    };
    let mut paths: Vec<_> =
        entries.map(|e| e.unwrap().path()).filter(|p| p.extension().is_some_and(|x| x == "toml")).collect();
    paths.sort();
    assert!(!paths.is_empty());
    for path in paths {
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let inst = &scene.instrument;
        let grid = inst.grid().unwrap();
        let prior = PriorSpec::patent().build(&grid, inst.view_deg, Path::new(".")).unwrap();
        let noise = match scene.noise() {
            Some(EffectSpec::Noise { sigma: Some(s), .. }) => *s,
            _ => 0.02,
        };
        let h = zone_system_matrices(&scene, 1).unwrap().remove(0).h;
        let case = host_tools::evaluation::stability::Case {
            family: Family::Noise,
            seed: 0,
            label: scene.name.clone(),
            h,
            r_pp: prior.r_pp.clone(),
            samples: prior.samples.clone(),
            noise,
            gains: None,
        };
        let r = check_case(&case, &Production, device_kernel);
        assert!(r.failures.is_empty(), "{}: {:?}", scene.name, r.failures);
        let optics = training_optics(&scene, 2.min(inst.pixels()), Some(noise)).unwrap();
        let spec = TrainSpec {
            white: Some(optics.white),
            root: false,
            ..TrainSpec::new(
                grid.bins_deg(),
                optics.zones,
                optics.pixels,
                inst.view_deg,
                profiles(&prior),
                noise,
                EstimatorKind::Wiener,
            )
        };
        match train(&spec) {
            Ok(t) => {
                assert!(t.f32_rel_error <= F32_TOLERANCE, "{}: {}", scene.name, t.f32_rel_error);
                BlobView::parse(&t.blob).unwrap();
            }
            Err(e) => {
                let msg = format!("{e:#}");
                assert!(msg.contains("zone ") && msg.contains("tolerance 1e-3"), "{}: {msg}", scene.name);
                eprintln!("{}: refused: {msg}", scene.name);
            }
        }
    }
}

/// The three cases of the long run where nalgebra's SVD returned factors
/// whose product missed the whitened system by up to 6e-7 relative, which
/// left W(sigma = 1e-16) up to 3e-2 from the limit: the checked SVD keeps
/// them within the continuity tolerance.
#[test]
fn inaccurate_svd_cases_of_the_long_run_stay_continuous() {
    for (family, seed) in
        [(Family::Conditioning, 1_000_410), (Family::OneSided, 1_000_680), (Family::SharpLobe, 1_001_031)]
    {
        let r = check_case(&generate(family, seed), &Production, device_kernel);
        assert!(r.failures.is_empty(), "{} seed {seed}: {:?}", family.name(), r.failures);
        assert!(
            r.continuity_resolved && r.continuity_ratio <= 1e-2,
            "{} seed {seed}: ratio {}",
            family.name(),
            r.continuity_ratio
        );
    }
}

/// The command as a user runs it: one row per family, and with stderr not a
/// terminal (here a pipe) no progress bar is drawn on it.
#[test]
fn the_command_prints_its_table_and_no_progress_on_a_pipe() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_host-tools"))
        .args(["stability", "--cases", "9", "--threads", "1"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("total: 9 cases, 0 failing"), "{stdout}");
    assert!(out.stderr.is_empty(), "stderr: {:?}", String::from_utf8_lossy(&out.stderr));
}
