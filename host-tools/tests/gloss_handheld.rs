//! Gloss readings on the handheld instrument (`scenes/handheld.toml`, 16
//! zones), trained by the production path (the linear and the scale-free
//! kinds): zones that see the black-glass standard's mirror reflection read
//! the black glass through their optics as its assigned value, the others
//! stream NaN
//! ("no reading", the blob's per-zone marker) instead of the whole
//! calibration losing its readings. Points are estimated by the device's
//! own rule (`device::reference::PointEstimator`). Prints the zones and
//! their mean readings: `cargo test --release -p host-tools --test
//! gloss_handheld -- --nocapture`.
use brdf_meter::blob::BlobView;
use brdf_meter::gloss::SPECULAR_GU;
use host_tools::calibration::demo::{train_for_scene, train_scale_free_for_scene};
use host_tools::calibration::gloss_rows::black_glass_readings;
use host_tools::device::reference::PointEstimator;
use host_tools::forward::scene::pipeline::{Mode, Simulator};
use host_tools::forward::scene::{Scene, training_optics};
use std::path::Path;

const ZONES: usize = 16;
/// Lines of the black glass simulated pixel by pixel.
const LINES: u64 = 20;
/// How far a zone's mean reading of the black glass may be from 100 GU.
const TOLERANCE_GU: f64 = 0.5;

fn scene(name: &str) -> Scene {
    Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name)).unwrap()
}

/// Per zone, the gloss reading of the black glass through the zone's
/// optics (the optics training gives the zone, at its centre pixel): the
/// readings `H_z rho` of the standard, estimated by the device's rule.
fn black_glass_gu(blob: &[u8]) -> Vec<f64> {
    let view = BlobView::parse(blob).unwrap();
    assert_eq!(view.version(), 3, "the handheld calibration carries the gloss section");
    let sc = scene("handheld.toml");
    let optics = training_optics(&sc, ZONES, None).unwrap();
    (0..ZONES)
        .map(|z| {
            let v = black_glass_readings(&optics.zones[z].centre);
            let v: Vec<f32> = v.iter().map(|x| *x as f32).collect();
            f64::from(PointEstimator::new(view, z).unwrap().apply(&v).readings[SPECULAR_GU])
        })
        .collect()
}

/// Per zone, the mean gloss reading of a black glass simulated with every
/// effect of the handheld scene, pixel by pixel (printed: the mirror
/// reflection moves across a zone's pixels, which the zone's one
/// calibration at its centre does not follow).
fn simulated_black_glass_gu(blob: &[u8]) -> Vec<f64> {
    let view = BlobView::parse(blob).unwrap();
    let (p, m) = (view.dims().pixels, view.dims().m);
    let mut sc = scene("handheld.toml");
    sc.surface = scene("black-glass.toml").surface;
    let sim = Simulator::new(&sc).unwrap();
    let ests: Vec<PointEstimator> = (0..ZONES).map(|z| PointEstimator::new(view, z).unwrap()).collect();
    let (mut sum, mut count) = (vec![0.0f64; ZONES], vec![0usize; ZONES]);
    for line in 0..LINES {
        let c = sim.simulate_line(line, Mode::Full).corrected;
        for px in 0..p {
            let z = (0..ZONES).rev().find(|z| px >= usize::from(view.zone_start(*z))).unwrap();
            let v: Vec<f32> = c[px * m..(px + 1) * m].iter().map(|x| *x as f32).collect();
            sum[z] += f64::from(ests[z].apply(&v).readings[SPECULAR_GU]);
            count[z] += 1;
        }
    }
    sum.iter().zip(&count).map(|(s, n)| s / *n as f64).collect()
}

/// The zones the blob marks as without a reading (NaN reference).
fn zones_without_reading(blob: &[u8]) -> Vec<usize> {
    let view = BlobView::parse(blob).unwrap();
    let mut block = vec![0.0f32; brdf_meter::gloss::block_len(view.dims().m)];
    (0..ZONES).filter(|z| view.copy_gloss(*z, 0, &mut block).unwrap().2.is_nan()).collect()
}

fn check(label: &str, blob: &[u8]) -> Vec<usize> {
    let none = zones_without_reading(blob);
    let gu = black_glass_gu(blob);
    let sim = simulated_black_glass_gu(blob);
    println!("{label}: zones without a gloss reading {none:?}");
    println!("  zone | black glass through the zone's optics, GU | simulated pixel by pixel, every effect, mean GU");
    for (z, (g, s)) in gu.iter().zip(&sim).enumerate() {
        println!("  {z:4} | {g:8.3} | {s:8.3}");
        // A zone without a reading streams NaN for every point.
        assert_eq!(none.contains(&z), s.is_nan(), "{label} zone {z}");
    }
    for (z, g) in gu.iter().enumerate() {
        if none.contains(&z) {
            assert!(g.is_nan(), "{label} zone {z}: marked without a reading, reads {g}");
        } else {
            assert!((g - 100.0).abs() <= TOLERANCE_GU, "{label} zone {z}: black glass reads {g} GU");
        }
    }
    assert!(none.len() < ZONES, "{label}: some zone has readings");
    none
}

#[test]
fn handheld_zones_that_see_the_standard_read_it_and_the_others_stream_nan() {
    let sc = scene("handheld.toml");
    let linear = train_for_scene(&sc, ZONES, 0.02).unwrap();
    let none_linear = check("Wiener", &linear.blob);
    let sf = train_scale_free_for_scene(&sc, ZONES, 0.02, false).unwrap();
    let none_sf = check("scale-free", &sf.blob);
    // Whether a zone sees the standard is the optics', not the estimator's.
    assert_eq!(none_linear, none_sf);
    assert!(!none_linear.is_empty(), "the handheld has zones that do not see the standard");
}
