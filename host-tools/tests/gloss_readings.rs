//! Gloss readings end to end on the host: calibrations trained by the
//! production path, points estimated by the device's own rule
//! (`device::reference::PointEstimator`, bit for bit the firmware's), truth
//! from the true BRDF by the same definition (`forward::gloss`).
//!
//! Two surface sets, each with the calibrations made for it:
//! - the scene library (patent profile, black glass, matt white) with the
//!   calibrations trained for the patent-profile scene (Wiener on the
//!   Table 5 Ward prior, the scale-free kinds on the MERL prior);
//! - the MERL materials, held out: 5 folds, every material read by
//!   calibrations trained on the other four folds only (Wiener on their
//!   R_pp, scale-free, scale-free piecewise).
//!
//! Coverage is the fraction of readings whose error is within k = 2 stated
//! standard uncertainties; for the scale-free kinds it is also given on
//! the points the out-of-prior flag leaves trusted. Prints the readings
//! table and the coverage: `cargo test --release -p host-tools --test
//! gloss_readings -- --nocapture`.
use brdf_meter::blob::{BlobView, EstimatorKind};
use brdf_meter::gloss::{DISTINCTNESS, HAZE_HU, SPECULAR_GU};
use host_tools::calibration::demo::{train_for_scene, train_measured_for_scene, train_scale_free_for_scene};
use host_tools::device::reference::PointEstimator;
use host_tools::forward::brdf::{Brdf, NbrdfSet};
use host_tools::forward::gloss::model_readings;
use host_tools::forward::optics::simulate_readings;
use host_tools::forward::prior_measured::PriorMix;
use host_tools::forward::scene::Scene;
use host_tools::forward::scene::pipeline::{Mode, Simulator};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::path::Path;

fn scene(name: &str) -> Scene {
    Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name)).unwrap()
}

/// Coverage factor: expanded uncertainty U = K u (the GUM's ~95 % convention).
const K: f64 = 2.0;
/// The coverage the stated uncertainties must reach.
const REQUIRED: f64 = 0.95;
/// Held-out folds of the MERL set.
const FOLDS: usize = 5;
/// The out-of-prior flag bit of a point.
const OUT_OF_PRIOR: u8 = 1 << 3;

#[derive(Default)]
struct Tally {
    inside: [usize; 3],
    total: [usize; 3],
    /// Points where the truth has a value and the device gives none (the
    /// linear form's distinctness where its estimated peak is not positive).
    undefined: [usize; 3],
}

impl Tally {
    fn add(&mut self, dev: &[f32; 3], u: &[f32; 3], truth: &[f64; 3]) {
        for r in 0..3 {
            if !truth[r].is_finite() {
                continue;
            }
            self.total[r] += 1;
            self.undefined[r] += usize::from(!dev[r].is_finite());
            let ok = dev[r].is_finite() && (f64::from(dev[r]) - truth[r]).abs() <= K * f64::from(u[r]);
            self.inside[r] += usize::from(ok);
        }
    }
    fn coverage(&self, r: usize) -> f64 {
        self.inside[r] as f64 / self.total[r].max(1) as f64
    }
    /// Coverage of the points the device gives a value for.
    fn coverage_defined(&self, r: usize) -> f64 {
        self.inside[r] as f64 / (self.total[r] - self.undefined[r]).max(1) as f64
    }
    fn line(&self) -> String {
        format!(
            "gloss {:.3}, haze {:.3}, distinctness {:.3} (of {})",
            self.coverage(SPECULAR_GU),
            self.coverage(HAZE_HU),
            self.coverage(DISTINCTNESS),
            self.total[SPECULAR_GU]
        )
    }
}

fn kind_label(kind: EstimatorKind) -> &'static str {
    host_tools::calibration::estimators::kind_name(kind)
}

/// The library's scenes through `blob`; returns the coverage over all of them.
fn library(kind: EstimatorKind, blob: &[u8]) -> Tally {
    let view = BlobView::parse(blob).unwrap();
    assert_eq!(view.version(), 4, "{kind:?}: training writes the gloss section");
    let est = PointEstimator::new(view, 0).unwrap();
    // The rows' reading of the standard on its own scale: 100 when they
    // read the black glass right.
    let s_ref = view.gloss_reference(0).unwrap();
    println!(
        "\n{}: the black glass as the rows read it, on its own scale: {s_ref:.2} (100 when right)",
        kind_label(kind)
    );
    let wo = host_tools::forward::brdf::view_dir(45.0);
    println!("scene | truth G H D | device mean G H D | stated u G H D | coverage at k = {K}");
    let mut all = Tally::default();
    for name in ["patent-profile.toml", "black-glass.toml", "matte-white.toml"] {
        let sc = scene(name);
        let sim = Simulator::new(&sc).unwrap();
        let (brdfs, _) = sc.surface_brdfs().unwrap();
        let truth = model_readings(brdfs[0].as_ref(), &wo);
        let mut tally = Tally::default();
        let (mut mean, mut u) = ([0.0f64; 3], [0.0f64; 3]);
        let lines = 200;
        for line in 0..lines {
            let c = sim.simulate_line(line, Mode::Full).corrected;
            let v: Vec<f32> = c.iter().map(|x| *x as f32).collect();
            let e = est.apply(&v);
            tally.add(&e.readings, &e.reading_sigma, &truth);
            all.add(&e.readings, &e.reading_sigma, &truth);
            for r in 0..3 {
                mean[r] += f64::from(e.readings[r]) / lines as f64;
                u[r] += f64::from(e.reading_sigma[r]) / lines as f64;
            }
        }
        println!(
            "{name:20} | {:7.2} {:6.2} {:6.1} | {:7.2} {:6.2} {:6.1} | {:6.2} {:6.2} {:6.1} | {:.2} {:.2} {:.2}",
            truth[0],
            truth[1],
            truth[2],
            mean[0],
            mean[1],
            mean[2],
            u[0],
            u[1],
            u[2],
            tally.coverage(0),
            tally.coverage(1),
            tally.coverage(2)
        );
        if name == "black-glass.toml" {
            // Calibrated on it: the noise-free tile reads 100 GU through the
            // scene simulator's full pipeline, and so does the mean of noisy lines.
            let c = sim.simulate_line(0, Mode::NoNoise).corrected;
            let v: Vec<f32> = c.iter().map(|x| *x as f32).collect();
            let g = est.apply(&v).readings[SPECULAR_GU];
            assert!((g - 100.0).abs() < 0.5, "{kind:?}: the noise-free black glass reads {g} GU");
            assert!((mean[SPECULAR_GU] - 100.0).abs() < 0.5, "{kind:?}: black glass reads {} GU", mean[0]);
        }
    }
    println!("library, all points: {}", all.line());
    all
}

/// The MERL materials held out in folds; returns the coverage on every
/// point and on the points not flagged out of prior, and the flagged count.
fn merl_held_out(kind: EstimatorKind) -> (Tally, Tally, usize) {
    let sc = scene("patent-profile.toml");
    let inst = host_tools::forward::optics::Instrument::patent_profile();
    let grid = sc.instrument.grid().unwrap();
    let models = PriorMix::parse("merl").unwrap().models(&grid, 45.0, inst.spectral_weights).unwrap();
    let names = models.names();
    let set = NbrdfSet::merl();
    let wo = host_tools::forward::brdf::view_dir(45.0);
    let (mut all, mut trusted, mut flagged) = (Tally::default(), Tally::default(), 0);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    for fold in 0..FOLDS {
        let train: Vec<usize> = (0..names.len()).filter(|i| i % FOLDS != fold).collect();
        let blob = train_measured_for_scene(&sc, 1, 0.02, kind, &models.subset(&train)).unwrap();
        let est = PointEstimator::new(BlobView::parse(&blob).unwrap(), 0).unwrap();
        for name in names.iter().enumerate().filter(|(i, _)| i % FOLDS == fold).map(|(_, n)| n) {
            let mat = set.by_name(name.trim_start_matches("merl:"), inst.spectral_weights).unwrap();
            let truth = model_readings(&mat as &dyn Brdf, &wo);
            let clean = simulate_readings(&inst, &mat, false);
            for _ in 0..4 {
                let v: Vec<f32> = clean
                    .iter()
                    .map(|x| (x + Normal::new(0.0, 0.02 * x.abs()).unwrap().sample(&mut rng)) as f32)
                    .collect();
                let e = est.apply(&v);
                all.add(&e.readings, &e.reading_sigma, &truth);
                if e.flag_bits & OUT_OF_PRIOR != 0 {
                    flagged += 1;
                } else {
                    trusted.add(&e.readings, &e.reading_sigma, &truth);
                }
            }
        }
    }
    println!(
        "\n{}: MERL held out ({} materials in {FOLDS} folds x 4 draws), coverage at k = {K}: {}",
        kind_label(kind),
        names.len(),
        all.line()
    );
    if matches!(kind, EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise) {
        println!("  {flagged} points flagged out of prior; on the others: {}", trusted.line());
    }
    (all, trusted, flagged)
}

#[test]
fn readings_of_the_library_and_of_measured_materials_against_the_truth() {
    let s = scene("patent-profile.toml");
    let lib = [
        (EstimatorKind::Wiener, train_for_scene(&s, 1, 0.02).unwrap().blob),
        (EstimatorKind::ScaleFree, train_scale_free_for_scene(&s, 1, 0.02, false).unwrap().blob),
        (EstimatorKind::ScaleFreePiecewise, train_scale_free_for_scene(&s, 1, 0.02, true).unwrap().blob),
    ];
    // The library: Wiener (Table 5 prior) and the piecewise kind (MERL
    // prior) read every reading of the three scenes with at least 95 %
    // within k = 2. The linear form (Wiener) has no distinctness where its
    // estimate of the peak is not positive (the matte tile in about half
    // its lines): its distinctness coverage is over the points it reads;
    // the root form reads every point. One scale-free map trained on the
    // MERL materials cannot read both their mirror-like metals and the
    // library's matt tile (it reads the tile at about 40 GU for 8): its
    // gloss and haze are asserted only as a floor against regression;
    // the piecewise kind, whose clusters separate them, is the one the
    // tools default to.
    for (kind, blob) in &lib {
        let t = library(*kind, blob);
        for (r, what) in [(SPECULAR_GU, "gloss"), (HAZE_HU, "haze"), (DISTINCTNESS, "distinctness")] {
            let c = if *kind == EstimatorKind::Wiener { t.coverage_defined(r) } else { t.coverage(r) };
            let floor = if *kind == EstimatorKind::ScaleFree { 0.5 } else { REQUIRED };
            assert!(c >= floor, "{kind:?}: library {what} coverage {c:.3}");
            if *kind != EstimatorKind::Wiener {
                assert_eq!(t.undefined[r], 0, "{kind:?}: the root form reads {what} at every point");
            }
        }
    }
    // MERL held out. Met: gloss, haze and distinctness within 0.95 +- 0.03
    // for the piecewise kind (the default), both ways: a stated uncertainty
    // that over-covers is as wrong as one that under-covers (distinctness
    // was 0.80-0.83 until the maps trained on the rays and each cluster's
    // readings had their own scale factors). Not met, printed and asserted
    // only as a floor against regression: one scale-free map's gloss (over,
    // 0.998) and Wiener's gloss and distinctness.
    for kind in [EstimatorKind::Wiener, EstimatorKind::ScaleFree, EstimatorKind::ScaleFreePiecewise] {
        let (all, _, _) = merl_held_out(kind);
        for r in [SPECULAR_GU, HAZE_HU] {
            let c = all.coverage(r);
            if kind == EstimatorKind::ScaleFreePiecewise {
                assert!((c - REQUIRED).abs() <= 0.03, "{kind:?}: MERL coverage of reading {r}: {c:.3}");
            } else {
                assert!(c >= 0.9, "{kind:?}: MERL coverage of reading {r}: {c:.3}");
            }
        }
        // The linear form's distinctness over the points it gives one for.
        let d =
            if kind == EstimatorKind::Wiener { all.coverage_defined(DISTINCTNESS) } else { all.coverage(DISTINCTNESS) };
        if kind == EstimatorKind::ScaleFreePiecewise {
            assert!((d - REQUIRED).abs() <= 0.03, "{kind:?}: MERL distinctness {d:.3}");
        }
        assert!(d >= 0.65, "{kind:?}: MERL distinctness {d:.3}");
    }
}
