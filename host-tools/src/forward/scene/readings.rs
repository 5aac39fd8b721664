//! A scene's readings for people: raw, dark, white and white-calibrated
//! readings per point and LED, the same without noise, and the truth beside
//! them (what `host-tools simulate` writes as CSV and JSON).
use super::pipeline::{Mode, pixel_view};
use super::{EffectSpec, Scene, Simulator};
use anyhow::{Context, bail};
use serde::Serialize;

/// Seeds the scene's noise draw with `seed`; an error if the scene lists no
/// `noise` effect (there is nothing to seed).
pub fn set_noise_seed(scene: &mut Scene, seed: u64) -> anyhow::Result<()> {
    let mut found = false;
    for e in &mut scene.effects {
        if let EffectSpec::Noise { seed: s, .. } = e {
            *s = seed;
            found = true;
        }
    }
    if !found {
        bail!("--seed {seed}: scene `{}` lists no `noise` effect, so there is nothing to seed", scene.name);
    }
    Ok(())
}

/// One reading in the CSV.
#[derive(Debug, Serialize)]
pub struct ReadingRow {
    pub line: u64,
    pub pixel: usize,
    pub led: usize,
    pub led_name: String,
    pub centre_deg: f64,
    pub incidence_deg: f64,
    pub x_cm: f64,
    pub y_cm: f64,
    pub raw: f64,
    pub dark: f64,
    pub white: f64,
    pub corrected: f64,
    pub noise_free: f64,
    pub truth_at_centre: f64,
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
    /// view; a mirror spike projected onto its bins), per pixel (n each).
    pub rho: Vec<Vec<f64>>,
    /// Each pixel's view: its polar angle, degrees (the specular incidence
    /// its gloss readings are defined about).
    pub view_deg: Vec<f64>,
    /// Each pixel's gloss readings by their definitions at its own view
    /// (`forward::gloss`, in three dimensions): specular gloss GU, haze HU,
    /// distinctness % (null: the distinctness of a pixel that reflects
    /// nothing at its specular peak).
    pub readings: Vec<[Option<f64>; 3]>,
}

/// One point in `points.csv`: what the device would correct a pixel's frames
/// to, in the form `host-tools estimate` reads (line, pixel, then the m
/// corrected readings in LED order).
pub fn points_csv(out: &Output) -> anyhow::Result<Vec<u8>> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["line".to_string(), "pixel".to_string()];
    header.extend(out.leds.iter().cloned());
    w.write_record(&header)?;
    for l in &out.lines {
        for (px, v) in l.corrected.iter().enumerate() {
            let mut rec = vec![l.line.to_string(), px.to_string()];
            rec.extend(v.iter().map(|x| format!("{}", *x as f32)));
            w.write_record(&rec)?;
        }
    }
    w.into_inner().map_err(|e| anyhow::anyhow!("CSV: {e}"))
}

/// Simulates lines `first..first + lines` of `scene`: the JSON document and
/// the CSV rows (one per line, pixel and LED).
pub fn simulate_lines(scene: &Scene, first: u64, lines: u64) -> anyhow::Result<(Output, Vec<ReadingRow>)> {
    let sim = Simulator::new(scene)?;
    let inst = &scene.instrument;
    let (p, m) = (sim.pixels(), sim.m());
    let grid = inst.grid().context("instrument.grid")?;
    let (brdfs, of_pixel) = scene.surface_brdfs()?;
    let names: Vec<String> =
        inst.leds.iter().enumerate().map(|(k, l)| l.name.clone().unwrap_or_else(|| format!("LED{k}"))).collect();
    let centres = inst.centre_angles_deg();
    let pi = std::f64::consts::PI;
    let mut at_centre = Vec::with_capacity(p);
    let mut rho = Vec::with_capacity(p);
    let mut view_deg = Vec::with_capacity(p);
    let mut readings = Vec::with_capacity(p);
    for px in 0..p {
        let wo = pixel_view(scene, px);
        let b = brdfs[of_pixel[px]].as_ref();
        at_centre
            .push(centres.iter().map(|c| pi * b.f_r(&crate::forward::brdf::light_dir(*c), &wo)).collect::<Vec<_>>());
        let r: Vec<f64> = grid
            .bins_deg()
            .iter()
            .map(|t| crate::forward::brdf::binned_reflectance_at(b, *t, &wo, grid.step_deg()))
            .collect();
        let theta_o = wo.z.clamp(-1.0, 1.0).acos().to_degrees();
        readings.push(crate::forward::gloss::model_readings(b, &wo).map(|x| x.is_finite().then_some(x)));
        view_deg.push(theta_o);
        rho.push(r);
    }
    let incidence: Vec<Vec<f64>> =
        (0..p).map(|px| (0..m).map(|k| scene.led_incidence_deg(k, px as f64)).collect()).collect();
    let white = sim.white();
    let mut rows = Vec::new();
    let mut outs = Vec::new();
    for line in first..first + lines {
        let r = sim.simulate_line(line, Mode::Full);
        let clean = sim.simulate_line(line, Mode::NoNoise);
        for px in 0..p {
            let pt = scene.pixel_point(px as f64);
            for k in 0..m {
                rows.push(ReadingRow {
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
        truth: Truth { at_led_centre: at_centre, rho, view_deg, readings },
    };
    Ok((out, rows))
}
