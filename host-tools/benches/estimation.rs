//! Batch estimation throughput, n = 81 bins from m = 7 readings (the patent
//! profile's Wiener matrix), in points per second.
//!
//! `cargo bench -p host-tools --bench estimation`
use brdf_meter::blob::EstimatorKind;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use host_tools::calibration::estimators::{self, BatchEstimator, EstimatorInputs, NoiseModel};
use host_tools::forward::optics::{Instrument, system_matrix};
use host_tools::forward::prior::PriorSpec;
use nalgebra::DMatrix;
use std::hint::black_box;
use std::path::Path;

fn patent_wiener() -> estimators::LinearEstimator {
    let inst = Instrument::patent_profile();
    let grid = inst.grid().unwrap();
    let h = system_matrix(&inst, &grid, false).unwrap();
    let prior = PriorSpec::patent().build(&grid, inst.view_deg, Path::new(".")).unwrap();
    let centres = inst.centre_angles_deg();
    estimators::build(
        EstimatorKind::Wiener,
        &EstimatorInputs {
            h: &h,
            r_pp: &prior.r_pp,
            prior_samples: prior.samples.ncols(),
            noise: NoiseModel::Relative(0.02),
            bins_deg: grid.bins_deg(),
            centres_deg: &centres,
        },
    )
    .unwrap()
}

fn readings(points: usize, m: usize) -> Vec<f32> {
    // Deterministic, plausible readings (diffuse level plus a peak).
    (0..points * m).map(|k| 0.3 + ((k * 7919) % 1000) as f32 * 0.05).collect()
}

fn bench(c: &mut Criterion) {
    let est = patent_wiener();
    let (n, m) = (est.n(), est.m());
    let batch = BatchEstimator::from_estimator(&est);
    let w32 = est.w_f32_row_major();
    let mut g = c.benchmark_group("estimate_n81_m7");
    for &points in &[120usize, 10_000, 1_000_000] {
        let v = readings(points, m);
        let mut out = vec![0.0f32; points * n];
        g.throughput(Throughput::Elements(points as u64));
        g.bench_with_input(BenchmarkId::new("batch_f32", points), &points, |b, _| {
            b.iter(|| batch.estimate_into(black_box(&v), black_box(&mut out)))
        });
        if points <= 10_000 {
            g.bench_with_input(BenchmarkId::new("kernel_f32_per_point", points), &points, |b, _| {
                b.iter(|| {
                    for (vp, op) in v.chunks_exact(m).zip(out.chunks_exact_mut(n)) {
                        brdf_meter::kernel::mat_vec_f32_slice(black_box(&w32), vp, op);
                    }
                })
            });
            let v64 = DMatrix::from_fn(m, points, |i, p| v[p * m + i] as f64);
            g.bench_with_input(BenchmarkId::new("nalgebra_f64_matmul", points), &points, |b, _| {
                b.iter(|| black_box(&est.w * black_box(&v64)))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
