//! Gloss readings end to end on the host: calibrations trained by the
//! production path, points estimated by the device's own rule
//! (`device::reference::PointEstimator`, bit for bit the firmware's), truth
//! from the true BRDF by the same definition (`forward::gloss`).
//!
//! Prints the readings table of the scene library and the coverage of the
//! stated uncertainties: `cargo test --release -p host-tools --test
//! gloss_readings -- --nocapture`.
use brdf_meter::blob::BlobView;
use brdf_meter::gloss::{DISTINCTNESS, HAZE_HU, SPECULAR_GU};
use host_tools::calibration::demo::{train_for_scene, train_scale_free_for_scene};
use host_tools::device::reference::PointEstimator;
use host_tools::forward::brdf::{Brdf, NbrdfSet};
use host_tools::forward::gloss::{true_readings, true_rho};
use host_tools::forward::optics::simulate_readings;
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

struct Tally {
    inside: [usize; 3],
    total: [usize; 3],
}

impl Tally {
    fn add(&mut self, dev: &[f32; 3], u: &[f32; 3], truth: &[f64; 3]) {
        for r in 0..3 {
            if !truth[r].is_finite() {
                continue;
            }
            self.total[r] += 1;
            let ok = dev[r].is_finite() && (f64::from(dev[r]) - truth[r]).abs() <= K * f64::from(u[r]);
            self.inside[r] += usize::from(ok);
        }
    }
    fn coverage(&self, r: usize) -> f64 {
        self.inside[r] as f64 / self.total[r].max(1) as f64
    }
}

fn blobs() -> Vec<(&'static str, Vec<u8>)> {
    let s = scene("patent-profile.toml");
    vec![
        ("wiener", train_for_scene(&s, 1, 0.02).unwrap().blob),
        ("scale-free", train_scale_free_for_scene(&s, 1, 0.02, false).unwrap().blob),
        ("scale-free-piecewise", train_scale_free_for_scene(&s, 1, 0.02, true).unwrap().blob),
    ]
}

#[test]
fn readings_of_the_library_and_of_measured_materials_against_the_truth() {
    let lib = ["patent-profile.toml", "black-glass.toml", "matte-white.toml"];
    for (kind, blob) in blobs() {
        let view = BlobView::parse(&blob).unwrap();
        assert_eq!(view.version(), 3, "{kind}: training writes the gloss section");
        let est = PointEstimator::new(view, 0).unwrap();
        // The calibration's scale against the definition's: how the estimator
        // misreads the black glass (the standard's L_0 by the definition over
        // the zone's reading of it).
        let mut block = vec![0.0f32; brdf_meter::gloss::block_len(view.dims().m)];
        let (_, _, s_ref) = view.copy_gloss(0, 0, &mut block).unwrap();
        let scale_bias = host_tools::forward::gloss::black_glass_specular(45.0) / f64::from(s_ref);
        println!("\n{kind}: black glass L_0 by definition / as the zone reads it = {scale_bias:.3}");
        let bins: Vec<f64> = (0..view.dims().n).map(|j| f64::from(view.grid_deg(j))).collect();
        let step = bins[1] - bins[0];
        println!("\n{kind}: scene | truth G H D | device mean G H D | stated u G H D");
        for name in lib {
            let sc = scene(name);
            let sim = Simulator::new(&sc).unwrap();
            let (brdfs, _) = sc.surface_brdfs().unwrap();
            let truth = true_readings(&true_rho(brdfs[0].as_ref(), &bins, 45.0, step), &bins, 45.0).unwrap();
            let mut tally = Tally { inside: [0; 3], total: [0; 3] };
            let (mut mean, mut u) = ([0.0f64; 3], [0.0f64; 3]);
            let lines = 200;
            for line in 0..lines {
                let c = sim.simulate_line(line, Mode::Full).corrected;
                let v: Vec<f32> = c.iter().map(|x| *x as f32).collect();
                let e = est.apply(&v);
                tally.add(&e.readings, &e.reading_sigma, &truth);
                for r in 0..3 {
                    mean[r] += f64::from(e.readings[r]) / lines as f64;
                    u[r] += f64::from(e.reading_sigma[r]) / lines as f64;
                }
            }
            println!(
                "{name:20} | {:7.2} {:6.2} {:6.1} | {:7.2} {:6.2} {:6.1} | {:6.2} {:6.2} {:6.1} | coverage {:.2} {:.2} {:.2}",
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
                assert!((g - 100.0).abs() < 0.5, "{kind}: the noise-free black glass reads {g} GU");
                assert!((mean[SPECULAR_GU] - 100.0).abs() < 0.5, "{kind}: black glass reads {} GU", mean[0]);
            }
        }
        // Measured materials: MERL, 4 noise draws each (2 % proportional).
        let set = NbrdfSet::merl();
        let inst = host_tools::forward::optics::Instrument::patent_profile();
        let mut tally = Tally { inside: [0; 3], total: [0; 3] };
        // The same with the definition's scale instead of the black-glass calibration.
        let mut uncal = Tally { inside: [0; 3], total: [0; 3] };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let names: Vec<String> = set.names().map(str::to_string).collect();
        for name in &names {
            let mat = set.by_name(name, inst.spectral_weights).unwrap();
            let truth = true_readings(&true_rho(&mat as &dyn Brdf, &bins, 45.0, step), &bins, 45.0).unwrap();
            let clean = simulate_readings(&inst, &mat, false);
            for _ in 0..4 {
                let v: Vec<f32> = clean
                    .iter()
                    .map(|x| (x + Normal::new(0.0, 0.02 * x.abs()).unwrap().sample(&mut rng)) as f32)
                    .collect();
                let e = est.apply(&v);
                tally.add(&e.readings, &e.reading_sigma, &truth);
                let f = |x: [f32; 3]| [x[0] / scale_bias as f32, x[1] / scale_bias as f32, x[2]];
                uncal.add(&f(e.readings), &f(e.reading_sigma), &truth);
            }
        }
        println!(
            "MERL ({} materials x 4 draws): coverage at k = {K}: gloss {:.3}, haze {:.3}, distinctness {:.3}",
            names.len(),
            tally.coverage(SPECULAR_GU),
            tally.coverage(HAZE_HU),
            tally.coverage(DISTINCTNESS)
        );
        println!(
            "  same on the definition's scale (no black-glass calibration): gloss {:.3}, haze {:.3}",
            uncal.coverage(SPECULAR_GU),
            uncal.coverage(HAZE_HU)
        );
    }
}
