use brdf_meter::blob::EstimatorKind;
use host_tools::evaluation::pixel_error::{HeldOutSpec, held_out_errors, quantiles};
use host_tools::forward::pairs::Pairs;
use host_tools::forward::prior_measured::PriorMix;
use host_tools::forward::scene::{Scene, training_optics};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scene = Scene::load(std::path::Path::new(&args[1])).unwrap();
    let kind = match args.get(2).map(|s| s.as_str()) {
        Some("sf") => EstimatorKind::ScaleFree,
        Some("pw") => EstimatorKind::ScaleFreePiecewise,
        _ => EstimatorKind::Wiener,
    };
    let crit = match args.get(3).map(|s| s.as_str()) {
        Some("plain") => host_tools::forward::pairs::Criterion::Plain,
        Some("scale") => host_tools::forward::pairs::Criterion::ScaleRelative,
        _ => host_tools::forward::pairs::Criterion::PeakRelative,
    };
    let inst = &scene.instrument;
    let grid = inst.grid().unwrap();
    let prior = PriorMix::parse("merl").unwrap().models(&grid, inst.view_deg, inst.spectral_weights).unwrap();
    let p = inst.pixels();
    let t = std::time::Instant::now();
    let optics = training_optics(&scene, p, std::env::var("NOISE").ok().map(|s| s.parse().unwrap())).unwrap();
    eprintln!("optics {:?}", t.elapsed());
    let mut all_e = Vec::new();
    let mut all_i = Vec::new();
    for px in [0usize, 16, 32, 48, 64, 80, 96, 112, 127] {
        if px >= p {
            continue;
        }
        let po = &optics.zones[px].centre;
        let pairs = Pairs::build(std::slice::from_ref(po), &prior);
        let e = held_out_errors(po, &pairs, &HeldOutSpec { kind, criterion: crit, folds: 20, ..Default::default() })
            .unwrap();
        if px == 64 && std::env::var("DETAIL").is_ok() {
            let mut v: Vec<(f64, f64, String, f64)> = (0..prior.len())
                .map(|k| {
                    (e.estimator[k], e.interpolation[k], prior.samples[k].name.clone(), pairs.truth.column(k).amax())
                })
                .collect();
            v.sort_by(|a, b| a.0.total_cmp(&b.0));
            for x in &v {
                println!("  {:.3} {:.3} {:8.2} {}", x.0, x.1, x.3, x.2);
            }
        }
        let q = quantiles(&e.estimator);
        let qi = quantiles(&e.interpolation);
        println!(
            "px {px:3} view {:.2}: est {:.3}/{:.3}/{:.3}  interp {:.3}/{:.3}/{:.3}",
            po.theta_o_deg, q[0], q[1], q[2], qi[0], qi[1], qi[2]
        );
        all_e.extend(e.estimator);
        all_i.extend(e.interpolation);
    }
    let q = quantiles(&all_e);
    let qi = quantiles(&all_i);
    println!(
        "all: est {:.3}/{:.3}/{:.3} interp {:.3}/{:.3}/{:.3}  ({:?})",
        q[0],
        q[1],
        q[2],
        qi[0],
        qi[1],
        qi[2],
        t.elapsed()
    );
}
#[allow(dead_code)]
fn detail() {}
