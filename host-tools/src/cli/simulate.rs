//! `host-tools simulate`: a scene -> raw and white-calibrated readings per
//! point and per LED, with the truth beside them (CSV and JSON), and a plot
//! (SVG and PNG).
//!
//! Everything is computed and rendered in memory first; files are written
//! (atomically) only once all of it succeeded, so a bad scene writes nothing.
use crate::scene::pipeline::{Mode, pixel_view};
use crate::scene::{Scene, Simulator};
use anyhow::{Context, anyhow, bail};
use plotters::coord::Shift;
use plotters::prelude::*;
use serde::Serialize;
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
}

/// One reading in the CSV.
#[derive(Debug, Serialize)]
struct Row {
    line: u64,
    pixel: usize,
    led: usize,
    led_name: String,
    centre_deg: f64,
    incidence_deg: f64,
    x_cm: f64,
    y_cm: f64,
    raw: f64,
    dark: f64,
    white: f64,
    corrected: f64,
    noise_free: f64,
    truth_at_centre: f64,
}

/// The JSON document.
#[derive(Debug, Serialize)]
pub struct Output {
    /// Scene name.
    pub scene: String,
    /// Scene description.
    pub description: String,
    /// Stages of the pipeline, in order.
    pub stages: Vec<&'static str>,
    /// Pixels P.
    pub pixels: usize,
    /// LED names (physical order).
    pub leds: Vec<String>,
    /// LED centre angles, degrees.
    pub centre_deg: Vec<f64>,
    /// Incidence of each LED's centre ray at each pixel's point, degrees (m per pixel).
    pub incidence_deg: Vec<Vec<f64>>,
    /// The angle grid of the truth, degrees.
    pub bins_deg: Vec<f64>,
    /// White reference per pixel: m values each.
    pub white: Vec<Vec<f64>>,
    /// The simulated lines.
    pub lines: Vec<LineOut>,
    /// The truth.
    pub truth: Truth,
}

/// One simulated line in the JSON.
#[derive(Debug, Serialize)]
pub struct LineOut {
    /// Scene line.
    pub line: u64,
    /// Dark frame, P counts.
    pub dark: Vec<f64>,
    /// Raw frame per LED, P counts each.
    pub raw: Vec<Vec<f64>>,
    /// White-calibrated readings per pixel (m each).
    pub corrected: Vec<Vec<f64>>,
    /// The same without the noise stage (m each).
    pub noise_free: Vec<Vec<f64>>,
}

/// What the readings should be.
#[derive(Debug, Serialize)]
pub struct Truth {
    /// Reflectance factor at each LED's centre angle (in-plane light, the
    /// pixel's view), per pixel (m each).
    pub at_led_centre: Vec<Vec<f64>>,
    /// The BRDF vector on the grid (in-plane light at each bin, the pixel's
    /// view), per pixel (n each).
    pub rho: Vec<Vec<f64>>,
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
        let mut found = false;
        for e in &mut scene.effects {
            if let crate::scene::EffectSpec::Noise { seed: s, .. } = e {
                *s = seed;
                found = true;
            }
        }
        if !found {
            bail!("--seed {seed}: scene `{}` lists no `noise` effect, so there is nothing to seed", scene.name);
        }
    }
    let origin = a.scene.as_ref().map_or("the built-in patent profile".to_string(), |p| p.display().to_string());
    let (out, rows) = simulate(&scene, a.line, a.lines).with_context(|| format!("simulating {origin}"))?;
    let mut csv = csv::Writer::from_writer(Vec::new());
    for r in &rows {
        csv.serialize(r)?;
    }
    let csv = csv.into_inner().map_err(|e| anyhow!("{e}"))?;
    let (svg, png) = plots(&out).context("drawing the plot")?;
    let dir = &a.out;
    let files = [("readings.csv", csv), ("plot.svg", svg.into_bytes()), ("plot.png", png)];
    for (name, bytes) in &files {
        crate::io::write_atomic(&dir.join(name), bytes).with_context(|| format!("writing {}", dir.join(name).display()))?;
    }
    crate::io::write_json(&dir.join("readings.json"), &out)?;
    println!(
        "simulated `{}` ({} pixels x {} LEDs, {} line(s)); stages: {}",
        out.scene,
        out.pixels,
        out.leds.len(),
        out.lines.len(),
        if out.stages.is_empty() { "none (far field, ideal sensor)".to_string() } else { out.stages.join(", ") }
    );
    println!("wrote {}/{{readings.csv, readings.json, plot.svg, plot.png}}", dir.display());
    Ok(())
}

fn simulate(scene: &Scene, first: u64, lines: u64) -> anyhow::Result<(Output, Vec<Row>)> {
    let sim = Simulator::new(scene)?;
    let inst = &scene.instrument;
    let (p, m) = (sim.pixels(), sim.m());
    let grid = inst.grid().context("instrument.grid")?;
    let (brdfs, of_pixel) = scene.surface_brdfs()?;
    let names: Vec<String> = inst.leds.iter().enumerate().map(|(k, l)| l.name.clone().unwrap_or_else(|| format!("LED{k}"))).collect();
    let centres = inst.centre_angles_deg();
    let pi = std::f64::consts::PI;
    let mut at_centre = Vec::with_capacity(p);
    let mut rho = Vec::with_capacity(p);
    for px in 0..p {
        let wo = pixel_view(scene, px);
        let b = brdfs[of_pixel[px]].as_ref();
        at_centre.push(centres.iter().map(|c| pi * b.f_r(&crate::brdf::light_dir(*c), &wo)).collect::<Vec<_>>());
        rho.push(grid.bins_deg().iter().map(|t| pi * b.f_r(&crate::brdf::light_dir(*t), &wo)).collect::<Vec<_>>());
    }
    let incidence: Vec<Vec<f64>> = (0..p).map(|px| (0..m).map(|k| scene.led_incidence_deg(k, px as f64)).collect()).collect();
    let white = sim.white();
    let mut rows = Vec::new();
    let mut outs = Vec::new();
    for line in first..first + lines {
        let r = sim.simulate_line(line, Mode::Full);
        let clean = sim.simulate_line(line, Mode::NoNoise);
        for px in 0..p {
            let pt = scene.pixel_point(px as f64);
            for k in 0..m {
                rows.push(Row {
                    line,
                    pixel: px,
                    led: k,
                    led_name: names[k].clone(),
                    centre_deg: centres[k],
                    incidence_deg: incidence[px][k],
                    x_cm: pt.x,
                    y_cm: pt.y,
                    raw: r.raw[1 + k][px],
                    dark: r.raw[0][px],
                    white: white[px * m + k],
                    corrected: r.corrected[px * m + k],
                    noise_free: clean.corrected[px * m + k],
                    truth_at_centre: at_centre[px][k],
                });
            }
        }
        outs.push(LineOut {
            line,
            dark: r.raw[0].clone(),
            raw: r.raw[1..].to_vec(),
            corrected: r.corrected.chunks(m).map(<[f64]>::to_vec).collect(),
            noise_free: clean.corrected.chunks(m).map(<[f64]>::to_vec).collect(),
        });
    }
    let out = Output {
        scene: scene.name.clone(),
        description: scene.description.clone(),
        stages: sim.pipeline().names(),
        pixels: p,
        leds: names,
        centre_deg: centres,
        incidence_deg: incidence,
        bins_deg: grid.bins_deg().to_vec(),
        white: white.chunks(m).map(<[f64]>::to_vec).collect(),
        lines: outs,
        truth: Truth { at_led_centre: at_centre, rho },
    };
    Ok((out, rows))
}

const SIZE: (u32, u32) = (1400, 560);

/// The plot as SVG text and PNG bytes.
fn plots(out: &Output) -> anyhow::Result<(String, Vec<u8>)> {
    struct Fig<'a>(&'a Output);
    impl crate::plot::Figure for Fig<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
        where
            DB::ErrorType: 'static,
        {
            draw(root, self.0)
        }
    }
    crate::plot::render(&Fig(out), SIZE)
}

fn colour(i: usize) -> RGBColor {
    const C: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
    ];
    C[i % C.len()]
}

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.filter(|x| x.is_finite()).fold((f64::MAX, f64::MIN), |(l, h), x| (l.min(x), h.max(x)));
    if lo > hi {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.08).max(hi.abs() * 1e-3).max(1e-12);
    (lo - pad, hi + pad)
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, out: &Output) -> anyhow::Result<()> {
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{x:?}");
    root.fill(&WHITE).map_err(e)?;
    let (top, root) = root.split_vertically(56);
    top.draw_text(&format!("scene `{}`: {} pixel(s) x {} LED(s)", out.scene, out.pixels, out.leds.len()), &("sans-serif", 20).into_font().color(&BLACK), (12, 6))
        .map_err(e)?;
    top.draw_text(&format!("stages: {}", stage_list(out)), &("sans-serif", 14).into_font().color(&BLACK), (12, 32)).map_err(e)?;
    let (left, right) = root.split_horizontally(SIZE.0 / 2);
    let line0 = &out.lines[0];
    let p = out.pixels;
    let shown: Vec<usize> = if p == 1 { vec![0] } else { vec![0, p / 2, p - 1] };

    // Left: reflectance factor against incidence: the truth on the grid and
    // the white-calibrated readings at each LED's centre angle.
    let (x0, x1) = range(out.bins_deg.iter().copied());
    let (y0, y1) = range(
        shown
            .iter()
            .flat_map(|&px| out.truth.rho[px].iter().chain(&line0.corrected[px]).copied().collect::<Vec<_>>())
            .chain(std::iter::once(0.0)),
    );
    let mut c = ChartBuilder::on(&left)
        .caption("Reflectance factor: truth (lines) and corrected readings (dots)", ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(e)?;
    c.configure_mesh()
        .x_desc("incidence of the LED's centre ray at the pixel's point (deg)")
        .y_desc("reflectance factor R")
        .y_label_formatter(&|v| tick(*v))
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    for (i, &px) in shown.iter().enumerate() {
        let col = colour(i);
        c.draw_series(LineSeries::new(out.bins_deg.iter().copied().zip(out.truth.rho[px].iter().copied()), col.stroke_width(2)))
            .map_err(e)?
            .label(format!("pixel {px}"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], col.stroke_width(2)));
        c.draw_series(out.incidence_deg[px].iter().zip(&line0.corrected[px]).map(|(x, y)| Circle::new((*x, *y), 5, col.filled())))
            .map_err(e)?;
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(e)?;

    // Right: raw counts along the line, one curve per LED, and the dark frame.
    let (r0, r1) = range(line0.raw.iter().flatten().chain(&line0.dark).copied().chain(std::iter::once(0.0)));
    let (xa, xb) = if p == 1 { (-1.0, 1.0) } else { (-0.5, p as f64 - 0.5) };
    let mut c = ChartBuilder::on(&right)
        .caption(format!("Raw counts along the line (line {})", line0.line), ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(xa..xb, r0..r1)
        .map_err(e)?;
    c.configure_mesh()
        .x_desc("pixel")
        .y_desc("counts")
        .y_label_formatter(&|v| tick(*v))
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    let mut series: Vec<(String, &Vec<f64>, RGBColor)> = vec![("dark".to_string(), &line0.dark, BLACK)];
    for (k, f) in line0.raw.iter().enumerate() {
        series.push((format!("{} ({:.0} deg)", out.leds[k], out.centre_deg[k]), f, colour(k)));
    }
    for (name, f, col) in series {
        let pts: Vec<(f64, f64)> = f.iter().enumerate().map(|(i, y)| (i as f64, *y)).collect();
        if p == 1 {
            c.draw_series(pts.iter().map(|pt| Circle::new(*pt, 5, col.filled())))
                .map_err(e)?
                .label(name)
                .legend(move |(x, y)| Circle::new((x + 9, y), 4, col.filled()));
        } else {
            c.draw_series(LineSeries::new(pts, col.stroke_width(2)))
                .map_err(e)?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], col.stroke_width(2)));
        }
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 12))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(e)?;
    Ok(())
}

/// A compact tick label: plain below 1e5, scientific above or for tiny values.
fn tick(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 {
        "0".into()
    } else if !(1e-2..1e5).contains(&a) {
        format!("{v:.2e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}

fn stage_list(out: &Output) -> String {
    if out.stages.is_empty() { "no effects (far field, ideal sensor)".into() } else { out.stages.join(", ") }
}

/// For tests: simulate into `dir` as the command would.
#[doc(hidden)]
pub fn run_to(scene: Option<&Path>, dir: &Path) -> anyhow::Result<()> {
    run(Args { scene: scene.map(Path::to_path_buf), out: dir.to_path_buf(), line: 0, lines: 1, seed: None })
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
        let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("readings.json")).unwrap()).unwrap();
        assert_eq!(j["pixels"], 128);
        assert_eq!(j["stages"].as_array().unwrap().len(), 12);
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
    fn a_bad_scene_writes_nothing_and_names_file_line_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("bad.toml");
        let text = std::fs::read_to_string(scenes().join("handheld.toml")).unwrap().replace("kind = \"saturation\"", "kind = \"saturaton\"");
        std::fs::write(&bad, text).unwrap();
        let out = dir.path().join("out");
        let e = format!("{:#}", run_to(Some(&bad), &out).unwrap_err());
        assert!(e.contains("bad.toml:") && e.contains("saturaton") && e.contains("saturation"), "{e}");
        assert!(!out.exists());
        let e = run(Args { scene: Some(scenes().join("far-field.toml")), out: out.clone(), line: 0, lines: 1, seed: Some(3) }).unwrap_err();
        assert!(e.to_string().contains("no `noise` effect"), "{e}");
        assert!(!out.exists());
    }
}
