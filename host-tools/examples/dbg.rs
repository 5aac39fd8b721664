use host_tools::forward::prior_models::SampleModel;
use host_tools::forward::scene::{Scene, training_optics};
use std::sync::Arc;
fn main() {
    let scene = Scene::load(std::path::Path::new("scenes/handheld.toml")).unwrap();
    let px: usize = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(18);
    let prior = host_tools::calibration::demo::scene_prior(&scene, "merl").unwrap();
    let optics = training_optics(&scene, 128, None).unwrap();
    let po = &optics.zones[px].centre;
    // rows fitted on prior+standards at this pixel
    let std = host_tools::calibration::gloss_rows::standards();
    let a = host_tools::forward::pairs::Pairs::build_with_gloss(std::slice::from_ref(po), &prior);
    let b = host_tools::forward::pairs::Pairs::build_with_gloss(std::slice::from_ref(po), &std);
    let aug = a.joined(&b, 0.5);
    let t = aug.gloss.clone().unwrap();
    let aug = host_tools::calibration::gloss_rows::reading_weighted(&aug, &t);
    let map = host_tools::calibration::estimators::pairs_wiener::linear_map(&aug, &t).unwrap();
    println!("G row0 {:?}", map.g.row(0).iter().map(|x| format!("{x:.2}")).collect::<Vec<_>>());
    for (n, bb) in host_tools::evaluation::pixel_map::gloss_tiles() {
        let m = SampleModel::Brdf(bb.clone());
        let tr = po.truth(&m);
        let v = po.readings(&m, &tr);
        let g = po.gloss_target(&m, &tr).unwrap();
        let est = (&map.g * &v)[0];
        println!(
            "{n:30} truth {:7.2} est {:7.2} v {:?}",
            g[0],
            est,
            v.iter().map(|x| format!("{x:.2}")).collect::<Vec<_>>()
        );
    }
    let bgm = SampleModel::Brdf(Arc::new(host_tools::forward::brdf::SmoothDielectric::black_glass()));
    let v = po.readings(&bgm, &po.truth(&bgm));
    println!("black glass v {:?} est {:.2}", v.iter().map(|x| format!("{x:.2}")).collect::<Vec<_>>(), (&map.g * &v)[0]);
}
