//! Scene simulation cost: the far-field, noise-free idealisation against the
//! full handheld scene (near field with extended LEDs and every effect), one
//! line of 128 pixels x 7 LEDs each, preparation (rays, white reference)
//! included.
//!
//! `cargo bench -p host-tools --bench scene`; the ratio in one run:
//! `cargo run --release -p host-tools --example scene_speed`.
use criterion::{Criterion, criterion_group, criterion_main};
use host_tools::forward::scene::pipeline::Mode;
use host_tools::forward::scene::{Scene, Simulator};
use std::hint::black_box;
use std::path::Path;

fn load(name: &str) -> Scene {
    Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name)).unwrap()
}

fn simulate(c: &mut Criterion) {
    let mut g = c.benchmark_group("simulate one line");
    for name in ["far-field.toml", "handheld.toml", "patent-profile.toml"] {
        let scene = load(name);
        g.bench_function(name.trim_end_matches(".toml"), |b| {
            b.iter(|| {
                let sim = Simulator::new(black_box(&scene)).unwrap();
                black_box(sim.simulate_line(0, Mode::Full))
            })
        });
    }
    g.finish();
}

criterion_group!(benches, simulate);
criterion_main!(benches);
