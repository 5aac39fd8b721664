//! Prints how much faster the far-field, noise-free scene simulates than the
//! full near-field handheld scene with extended LEDs (issue: at least 10x).
//!
//! `cargo run --release -p host-tools --example scene_speed [FAST.toml FULL.toml]`
use host_tools::forward::scene::{Scene, time_simulation};
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let (fast, full) = match args.as_slice() {
        [] => (dir.join("far-field.toml"), dir.join("handheld.toml")),
        [a, b] => (a.clone(), b.clone()),
        _ => anyhow::bail!("usage: scene_speed [FAST.toml FULL.toml]"),
    };
    let (a, b) = (Scene::load(&fast)?, Scene::load(&full)?);
    let ta = time_simulation(&a, 1.0)?;
    let tb = time_simulation(&b, 1.0)?;
    println!("{:<16} {:>12.3} us per line  (stages: {})", a.name, ta.as_secs_f64() * 1e6, stages(&a));
    println!("{:<16} {:>12.3} us per line  (stages: {})", b.name, tb.as_secs_f64() * 1e6, stages(&b));
    println!("ratio {}/{} = {:.0}x", b.name, a.name, tb.as_secs_f64() / ta.as_secs_f64());
    Ok(())
}

fn stages(s: &Scene) -> String {
    let n = host_tools::forward::scene::Pipeline::new(s).names();
    if n.is_empty() { "none".into() } else { n.join(", ") }
}
