//! Training cost on the patent profile (n = 81, m = 7, 16 prior samples).
//!
//! `cargo bench -p host-tools --bench training`
use brdf_meter::blob::EstimatorKind;
use criterion::{Criterion, criterion_group, criterion_main};
use host_tools::calibration::estimators::{self, EstimatorInputs, NoiseModel};
use host_tools::calibration::train::{TrainSpec, train};
use host_tools::forward::optics::{Instrument, system_matrix};
use host_tools::forward::prior::PriorSpec;
use host_tools::forward::zone_optics::uniform_zones;
use std::hint::black_box;
use std::path::Path;

fn bench(c: &mut Criterion) {
    let inst = Instrument::patent_profile();
    let grid = inst.grid().unwrap();
    let h = system_matrix(&inst, &grid, false).unwrap();
    let prior = PriorSpec::patent().build(&grid, inst.view_deg, Path::new(".")).unwrap();
    let centres = inst.centre_angles_deg();
    let models = host_tools::forward::prior_measured::PriorMix::parse("patent")
        .unwrap()
        .models(&grid, inst.view_deg, inst.spectral_weights)
        .unwrap();
    let mut g = c.benchmark_group("train_patent_profile");
    for (name, kind) in [
        ("wiener", EstimatorKind::Wiener),
        ("wiener_noise_free", EstimatorKind::WienerNoiseFree),
        ("pseudo_inverse", EstimatorKind::PseudoInverse),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| {
                estimators::build(
                    kind,
                    &EstimatorInputs {
                        h: black_box(&h),
                        r_pp: &prior.r_pp,
                        prior_samples: 16,
                        noise: NoiseModel::Relative(0.02),
                        bins_deg: grid.bins_deg(),
                        centres_deg: &centres,
                    },
                )
                .unwrap()
            })
        });
    }
    // Whole pipeline: optics -> sample pairs -> W per zone -> f32 check -> gloss rows -> blob, 8 zones of 128 pixels.
    g.bench_function("blob_8_zones", |b| {
        b.iter(|| {
            let zones = uniform_zones(&inst, &grid, 8, 128, false, 0.02).unwrap();
            train(&TrainSpec::new(grid.bins_deg(), zones, 128, inst.view_deg, &models, 0.02, EstimatorKind::Wiener))
                .unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
