//! `host-tools simulate`: a scene -> raw and white-calibrated readings per
//! point and per LED, with the truth beside them (CSV and JSON), and a plot
//! (SVG and PNG).
//!
//! Everything is computed and rendered in memory first; files are written
//! (atomically) only once all of it succeeded, so a bad scene writes nothing.
use crate::forward::scene::Scene;
use crate::forward::scene::readings::{set_noise_seed, simulate_lines};
use anyhow::{Context, bail};
use std::path::{Path, PathBuf};

/// Simulate a scene's readings (CSV, JSON, SVG and PNG plot).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scene file (TOML); default: the built-in patent profile
    /// (scenes/patent-profile.toml).
    #[arg(value_name = "SCENE")]
    pub scene: Option<PathBuf>,
    /// Output directory: readings.csv, readings.json, plot.svg, plot.png.
    #[arg(long, value_name = "DIR", default_value = "out/simulate")]
    pub out: PathBuf,
    /// First scene line to simulate (time since calibration, for drift and the noise draw).
    #[arg(long, default_value_t = 0)]
    pub line: u64,
    /// Number of lines to simulate.
    #[arg(long, default_value_t = 1)]
    pub lines: u64,
    /// Seed of the noise draw (overrides the scene's `noise.seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Another surface under the same instrument and effects, written as a
    /// scene's `surface.brdf`, e.g. '{ model = "lambertian", rho = 0.99 }'
    /// (a white tile): the whole line, the scene's segments dropped.
    #[arg(long, value_name = "BRDF")]
    pub surface: Option<String>,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let mut scene = match &a.scene {
        Some(p) => Scene::load(p)?,
        None => Scene::patent_profile(),
    };
    if a.lines == 0 || a.lines > 10_000 {
        bail!("--lines {}: simulate 1..=10000 lines", a.lines);
    }
    if let Some(seed) = a.seed {
        set_noise_seed(&mut scene, seed)?;
    }
    if let Some(spec) = &a.surface {
        scene = scene.with_surface(spec)?;
    }
    let origin = a.scene.as_ref().map_or("the built-in patent profile".to_string(), |p| p.display().to_string());
    let (out, rows) = simulate_lines(&scene, a.line, a.lines).with_context(|| format!("simulating {origin}"))?;
    let csv = crate::output::io::csv_bytes(&rows)?;
    let points = crate::forward::scene::readings::points_csv(&out)?;
    let (svg, png) = crate::output::plot::simulate::plots(&out).context("drawing the plot")?;
    let dir = &a.out;
    let files = [("readings.csv", csv), ("points.csv", points), ("plot.svg", svg.into_bytes()), ("plot.png", png)];
    for (name, bytes) in &files {
        crate::output::io::write_atomic(&dir.join(name), bytes)
            .with_context(|| format!("writing {}", dir.join(name).display()))?;
    }
    crate::output::io::write_json(&dir.join("readings.json"), &out)?;
    println!(
        "simulated `{}` ({} pixels x {} LEDs, {} line(s)); stages: {}",
        out.scene,
        out.pixels,
        out.leds.len(),
        out.lines.len(),
        if out.stages.is_empty() { "none (far field, ideal sensor)".to_string() } else { out.stages.join(", ") }
    );
    println!("wrote {}/{{readings.csv, points.csv, readings.json, plot.svg, plot.png}}", dir.display());
    Ok(())
}

/// For tests: simulate into `dir` as the command would.
#[doc(hidden)]
pub fn run_to(scene: Option<&Path>, dir: &Path) -> anyhow::Result<()> {
    run(Args {
        scene: scene.map(Path::to_path_buf),
        out: dir.to_path_buf(),
        line: 0,
        lines: 1,
        seed: None,
        surface: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scenes() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
    }

    #[test]
    fn writes_csv_json_svg_and_png_with_the_truth_beside_the_readings() {
        let dir = tempfile::tempdir().unwrap();
        run_to(Some(&scenes().join("handheld.toml")), dir.path()).unwrap();
        let csv = std::fs::read_to_string(dir.path().join("readings.csv")).unwrap();
        let mut lines = csv.lines();
        assert_eq!(
            lines.next().unwrap(),
            "line,pixel,led,led_name,centre_deg,incidence_deg,x_cm,y_cm,raw,dark,white,corrected,noise_free,truth_at_centre"
        );
        assert_eq!(lines.count(), 128 * 7);
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("readings.json")).unwrap()).unwrap();
        assert_eq!(j["pixels"], 128);
        assert_eq!(j["stages"].as_array().unwrap().len(), 13);
        assert_eq!(j["truth"]["view_deg"].as_array().unwrap().len(), 128);
        assert_eq!(j["truth"]["readings"][0].as_array().unwrap().len(), 3);
        // points.csv: line, pixel, then the m corrected readings, as `estimate` reads it.
        let points = std::fs::read_to_string(dir.path().join("points.csv")).unwrap();
        let mut rows = points.lines();
        assert_eq!(rows.next().unwrap(), "line,pixel,L1,L2,L3,L4,L5,L6,L7");
        let first: Vec<&str> = rows.next().unwrap().split(',').collect();
        assert_eq!((first[0], first[1], first.len()), ("0", "0", 9));
        let want = j["lines"][0]["corrected"][0][3].as_f64().unwrap() as f32;
        assert_eq!(first[5].parse::<f32>().unwrap(), want);
        assert_eq!(j["truth"]["rho"].as_array().unwrap().len(), 128);
        assert_eq!(j["truth"]["rho"][0].as_array().unwrap().len(), 81);
        assert_eq!(j["lines"][0]["raw"].as_array().unwrap().len(), 7);
        let svg = std::fs::read_to_string(dir.path().join("plot.svg")).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("Reflectance factor") && svg.contains("handheld"));
        let png = std::fs::read(dir.path().join("plot.png")).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        assert!(png.len() > 10_000);
    }

    fn json(dir: &Path) -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join("readings.json")).unwrap()).unwrap()
    }

    fn pairs(j: &serde_json::Value, a: &str, px: usize) -> Vec<(f64, f64)> {
        let x = j["lines"][0][a][px].as_array().unwrap();
        let t = j["truth"]["at_led_centre"][px].as_array().unwrap();
        x.iter().zip(t).map(|(a, b)| (a.as_f64().unwrap(), b.as_f64().unwrap())).collect()
    }

    #[test]
    fn the_default_is_the_patent_profile_and_far_field_reads_the_truth() {
        let dir = tempfile::tempdir().unwrap();
        run_to(None, dir.path()).unwrap();
        let j = json(dir.path());
        assert_eq!(j["scene"], "patent-profile");
        assert_eq!(j["stages"], serde_json::json!(["near-field", "inverse-square", "noise"]));
        // Near field: readings mix rays from several angles, so they are not
        // the centre-angle truth (the effect the method corrects).
        assert!(pairs(&j, "noise_free", 0).iter().any(|(a, b)| (a - b).abs() > 0.05 * b));
        // The far-field idealisation reads exactly the truth at the centre angles.
        run_to(Some(&scenes().join("far-field.toml")), dir.path()).unwrap();
        let j = json(dir.path());
        assert_eq!(j["stages"], serde_json::json!([]));
        for px in [0, 64, 127] {
            for (a, b) in pairs(&j, "corrected", px) {
                assert!((a - b).abs() < 1e-12 * b, "{a} vs {b}");
            }
        }
    }

    #[test]
    fn another_surface_under_the_same_instrument_and_effects() {
        let dir = tempfile::tempdir().unwrap();
        let args = |surface: &str| Args {
            scene: Some(scenes().join("handheld.toml")),
            out: dir.path().to_path_buf(),
            line: 3,
            lines: 1,
            seed: None,
            surface: Some(surface.into()),
        };
        run(args(r#"{ model = "lambertian", rho = 0.99 }"#)).unwrap();
        let j = json(dir.path());
        assert_eq!(j["stages"].as_array().unwrap().len(), 13);
        // A white tile reads 0.99 at every pixel and LED, within the noise.
        let truth = j["truth"]["rho"][64].as_array().unwrap();
        assert!(truth.iter().all(|r| (r.as_f64().unwrap() - 0.99).abs() < 1e-9));
        for px in [0, 64, 127] {
            for x in j["lines"][0]["corrected"][px].as_array().unwrap() {
                assert!((x.as_f64().unwrap() - 0.99).abs() < 0.03, "pixel {px}: {x}");
            }
        }
        for (bad, why) in [
            ("lambertian", "not a surface as a scene's `surface.brdf` writes it"),
            (r#"{ model = "lambertian", rho = 2 }"#, "must be in [0, 1]"),
            (r#"{ model = "chalk" }"#, "chalk"),
        ] {
            let e = run(args(bad)).unwrap_err().to_string();
            assert!(e.contains(why), "{bad}: {e}");
        }
    }

    #[test]
    fn a_bad_scene_writes_nothing_and_names_file_line_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("bad.toml");
        let text = std::fs::read_to_string(scenes().join("handheld.toml"))
            .unwrap()
            .replace("kind = \"saturation\"", "kind = \"saturaton\"");
        std::fs::write(&bad, text).unwrap();
        let out = dir.path().join("out");
        let e = format!("{:#}", run_to(Some(&bad), &out).unwrap_err());
        assert!(e.contains("bad.toml:") && e.contains("saturaton") && e.contains("saturation"), "{e}");
        assert!(!out.exists());
        let e = run(Args {
            scene: Some(scenes().join("far-field.toml")),
            out: out.clone(),
            line: 0,
            lines: 1,
            seed: Some(3),
            surface: None,
        })
        .unwrap_err();
        assert!(e.to_string().contains("no `noise` effect"), "{e}");
        assert!(!out.exists());
    }
}
