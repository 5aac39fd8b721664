//! The readings pipeline of a scene, built from its effect list.
//!
//! Per pixel and LED: geometry (the rays [`Optics`] makes for the scene's
//! [`RayModel`]) -> irradiance weights -> BRDF -> light stages (drift) ->
//! sensor stages (ambient, nonlinearity, dark offset, noise, saturation,
//! quantisation) -> raw counts; plus a dark frame through the same stages.
//! The host then white-calibrates: `corrected = (raw - dark) / white`, where
//! `white` is the same pipeline's noise-free, drift-free reading of a perfect
//! diffuser, dark-corrected (so a perfect diffuser reads 1 in every geometry).
//! A sensor the scene makes nonlinear (`nonlinearity`) is measured as a
//! factory would ([`super::sensor_linearity`]) and every signal, the white's
//! too, is made linear with that correction first, as the device does.
//!
//! Geometric effects configure the optics (a flag that is off is a
//! computation that never runs); the others are boxed [`Stage`]s, one per
//! listed effect and none for an unlisted one.
use super::Scene;
use super::effects::{DriftRate, EffectSpec, NoiseModel, STAGE_ORDER};
use crate::forward::brdf::{Brdf, ray_reflectance};
use crate::forward::optics::{Optics, RayModel};
use anyhow::{Context, bail};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Where a frame sits in time and what lights it.
#[derive(Clone, Copy, Debug)]
pub struct FrameCtx {
    /// Scene line (0 = the first line after calibration).
    pub line: u64,
    /// 0 = dark frame, 1 + k = LED k.
    pub frame: usize,
    /// LEDs per line.
    pub m: usize,
    /// The frame's exposure relative to the long one (1; `1 / ratio` for
    /// the `short-exposure` effect's frames).
    pub exposure: f64,
}

impl FrameCtx {
    /// Frames elapsed since calibration (dark frame of line 0 = 0).
    pub fn time(&self) -> u64 {
        self.line * (self.m as u64 + 1) + self.frame as u64
    }

    /// The noise stream of this frame: the long frames 0..=m, each shorter
    /// exposure's after them (its level from the exposure).
    fn stream(&self) -> u64 {
        let level = if self.exposure < 1.0 { (1.0 / self.exposure).round() as u64 } else { 0 };
        self.frame as u64 + level * (self.m as u64 + 1)
    }
}

/// Which stages run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Every listed stage.
    Full,
    /// Every listed stage but noise (the "noise-free" readings beside the truth).
    NoNoise,
    /// The calibration: no noise, no drift (the white reference).
    Reference,
}

/// A light or sensor stage acting on one frame of counts (P pixels).
pub trait Stage: Send + Sync + std::fmt::Debug {
    /// The effect's name.
    fn name(&self) -> &'static str;
    /// Applies the stage.
    fn apply(&self, frame: &mut [f64], ctx: &FrameCtx);
    /// Whether the stage runs in `mode`.
    fn runs_in(&self, _mode: Mode) -> bool {
        true
    }
}

#[derive(Debug)]
struct Drift {
    rate: DriftRate,
}
impl Stage for Drift {
    fn name(&self) -> &'static str {
        "led-drift"
    }
    fn apply(&self, frame: &mut [f64], ctx: &FrameCtx) {
        if ctx.frame > 0 {
            // Frame 1 + k is LED k's (at any exposure).
            let f = 1.0 + self.rate.of_led(ctx.frame - 1) * ctx.time() as f64;
            frame.iter_mut().for_each(|x| *x *= f);
        }
    }
    fn runs_in(&self, mode: Mode) -> bool {
        mode != Mode::Reference
    }
}

#[derive(Debug)]
struct Ambient {
    counts: f64,
}
impl Stage for Ambient {
    fn name(&self) -> &'static str {
        "ambient-light"
    }
    fn apply(&self, frame: &mut [f64], ctx: &FrameCtx) {
        // Ambient light integrates over the exposure like the LEDs' light.
        frame.iter_mut().for_each(|x| *x += self.counts * ctx.exposure);
    }
}

#[derive(Debug)]
struct Nonlinearity {
    gamma: f64,
    full_scale: f64,
}
impl Stage for Nonlinearity {
    fn name(&self) -> &'static str {
        "nonlinearity"
    }
    fn apply(&self, frame: &mut [f64], _: &FrameCtx) {
        for x in frame.iter_mut().filter(|x| **x > 0.0) {
            *x = self.full_scale * (*x / self.full_scale).powf(self.gamma);
        }
    }
}

#[derive(Debug)]
struct DarkOffset {
    counts: f64,
    /// Per-pixel pattern; empty when the scene gives none.
    pattern: Vec<f64>,
}
impl Stage for DarkOffset {
    fn name(&self) -> &'static str {
        "dark-offset"
    }
    fn apply(&self, frame: &mut [f64], _: &FrameCtx) {
        frame.iter_mut().for_each(|x| *x += self.counts);
        for (x, p) in frame.iter_mut().zip(&self.pattern) {
            *x += p;
        }
    }
}

#[derive(Debug)]
struct Noise {
    model: NoiseModel,
    /// sigma (proportional), sigma_counts (additive) or e-/count (shot-read).
    a: f64,
    /// read sigma (shot-read).
    b: f64,
    seed: u64,
}
impl Stage for Noise {
    fn name(&self) -> &'static str {
        "noise"
    }
    fn apply(&self, frame: &mut [f64], ctx: &FrameCtx) {
        // One stream per (seed, line, frame): a frame's draw does not depend
        // on which other frames were simulated.
        let mut rng = ChaCha8Rng::seed_from_u64(mix(self.seed, ctx.line, ctx.stream()));
        for x in frame.iter_mut() {
            let sd = match self.model {
                NoiseModel::Additive => self.a,
                NoiseModel::Proportional => self.a * x.abs(),
                NoiseModel::ShotRead => (x.max(0.0) / self.a + self.b * self.b).sqrt(),
            };
            let z: f64 = StandardNormal.sample(&mut rng);
            *x += sd * z;
        }
    }
    fn runs_in(&self, mode: Mode) -> bool {
        mode == Mode::Full
    }
}

#[derive(Debug)]
struct Saturation {
    full_scale: f64,
}
impl Stage for Saturation {
    fn name(&self) -> &'static str {
        "saturation"
    }
    fn apply(&self, frame: &mut [f64], _: &FrameCtx) {
        frame.iter_mut().for_each(|x| *x = x.clamp(0.0, self.full_scale));
    }
}

#[derive(Debug)]
struct Quantisation {
    step: f64,
}
impl Stage for Quantisation {
    fn name(&self) -> &'static str {
        "quantisation"
    }
    fn apply(&self, frame: &mut [f64], _: &FrameCtx) {
        frame.iter_mut().for_each(|x| *x = (*x / self.step).round() * self.step);
    }
}

fn mix(seed: u64, line: u64, frame: u64) -> u64 {
    // SplitMix64 finaliser over the three inputs.
    let mut z = seed ^ line.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ frame.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The stages a scene's effect list builds, in stage order.
#[derive(Debug)]
pub struct Pipeline {
    model: RayModel,
    per_pixel: bool,
    geometry: Vec<&'static str>,
    stages: Vec<Box<dyn Stage>>,
    /// The `short-exposure` effect's ratios (empty when not listed).
    short_ratios: Vec<f64>,
    /// Counts at which a pixel saturates.
    full_scale: f64,
}

impl Pipeline {
    /// Builds the pipeline of `scene`: exactly one stage per listed effect.
    pub fn new(scene: &Scene) -> Self {
        let mut effects: Vec<&EffectSpec> = scene.effects.iter().collect();
        effects.sort_by_key(|e| e.order());
        let s = &scene.instrument.sensor;
        let mut geometry = Vec::new();
        let mut stages: Vec<Box<dyn Stage>> = Vec::new();
        let mut short_ratios = Vec::new();
        for e in effects {
            match e {
                EffectSpec::NearField {}
                | EffectSpec::ThreeDGeometry {}
                | EffectSpec::PerPixelGeometry {}
                | EffectSpec::InverseSquare {}
                | EffectSpec::EmissionProfile {} => geometry.push(e.name()),
                EffectSpec::LedDrift { rate } => stages.push(Box::new(Drift { rate: rate.clone() })),
                EffectSpec::AmbientLight { counts } => stages.push(Box::new(Ambient { counts: *counts })),
                EffectSpec::Nonlinearity { gamma } => {
                    stages.push(Box::new(Nonlinearity { gamma: *gamma, full_scale: s.full_scale }))
                }
                EffectSpec::DarkOffset { counts, fixed_pattern_rms, seed } => {
                    let pattern = if *fixed_pattern_rms > 0.0 {
                        let mut rng = ChaCha8Rng::seed_from_u64(mix(*seed, u64::MAX, u64::MAX));
                        (0..s.pixels)
                            .map(|_| {
                                let z: f64 = StandardNormal.sample(&mut rng);
                                fixed_pattern_rms * z
                            })
                            .collect()
                    } else {
                        Vec::new()
                    };
                    stages.push(Box::new(DarkOffset { counts: *counts, pattern }))
                }
                EffectSpec::Noise { model, sigma, sigma_counts, electrons_per_count, read_sigma_counts, seed } => {
                    let (a, b) = match model {
                        NoiseModel::Additive => (sigma_counts.unwrap_or(0.0), 0.0),
                        NoiseModel::Proportional => (sigma.unwrap_or(0.0), 0.0),
                        NoiseModel::ShotRead => (electrons_per_count.unwrap_or(1.0), read_sigma_counts.unwrap_or(0.0)),
                    };
                    stages.push(Box::new(Noise { model: *model, a, b, seed: *seed }))
                }
                EffectSpec::Saturation {} => stages.push(Box::new(Saturation { full_scale: s.full_scale })),
                EffectSpec::Quantisation { step_counts } => stages.push(Box::new(Quantisation { step: *step_counts })),
                EffectSpec::ShortExposure { ratios } => short_ratios = ratios.clone(),
            }
        }
        Self {
            model: scene.ray_model(),
            per_pixel: scene.has("per-pixel-geometry"),
            geometry,
            stages,
            short_ratios,
            full_scale: s.full_scale,
        }
    }

    /// Names of the stages, in the order they run.
    pub fn names(&self) -> Vec<&'static str> {
        let acquisition = (!self.short_ratios.is_empty()).then_some("short-exposure");
        self.geometry.iter().copied().chain(self.stages.iter().map(|s| s.name())).chain(acquisition).collect()
    }

    /// The `short-exposure` effect's ratios (empty when the scene does not list it).
    pub fn short_ratios(&self) -> &[f64] {
        &self.short_ratios
    }

    /// The ray model of the geometric stages.
    pub fn ray_model(&self) -> RayModel {
        self.model
    }

    /// Runs the light and sensor stages on one frame.
    pub fn run(&self, frame: &mut [f64], ctx: &FrameCtx, mode: Mode) {
        for s in self.stages.iter().filter(|s| s.runs_in(mode)) {
            s.apply(frame, ctx);
        }
    }
}

/// One simulated line.
#[derive(Clone, Debug)]
pub struct LineReadings {
    /// Scene line.
    pub line: u64,
    /// Raw counts: frame 0 is dark, frame 1 + k is LED k; P values each.
    pub raw: Vec<Vec<f64>>,
    /// White-calibrated readings `(raw - dark) / white`, index `p * m + k`.
    pub corrected: Vec<f64>,
}

/// A scene prepared for simulation: the pipeline, the light reaching each
/// pixel under each LED (computed once) and the white reference.
#[derive(Debug)]
pub struct Simulator {
    pipeline: Pipeline,
    m: usize,
    p: usize,
    /// Counts of light before the light and sensor stages, `p * m + k`.
    signal: Vec<f64>,
    /// White reference, `p * m + k`.
    white: Vec<f64>,
    /// The dark frame's noise-free counts (P).
    dark: Vec<f64>,
    /// The factory's measurement of a nonlinear sensor (scenes that list
    /// `nonlinearity`), whose correction the readings and the white take.
    linearity: Option<super::sensor_linearity::SensorLinearity>,
}

impl Simulator {
    /// Prepares `scene` (validated). Fails, naming the pixel and the LED,
    /// when a pixel gets no light from an LED (a white reference of 0).
    pub fn new(scene: &Scene) -> anyhow::Result<Self> {
        let (brdfs, of_pixel) = scene.surface_brdfs()?;
        let brdfs: Vec<std::sync::Arc<dyn Brdf>> = brdfs.into_iter().map(std::sync::Arc::from).collect();
        Self::with_models(scene, &brdfs, &of_pixel)
    }

    /// Prepares `scene` with `brdf` as its surface at every pixel (a
    /// reflection model no scene file names: a prior's sample, a test tile).
    pub fn with_surface(scene: &Scene, brdf: std::sync::Arc<dyn Brdf>) -> anyhow::Result<Self> {
        Self::with_models(scene, &[brdf], &vec![0; scene.instrument.pixels()])
    }

    fn with_models(scene: &Scene, brdfs: &[std::sync::Arc<dyn Brdf>], of_pixel: &[usize]) -> anyhow::Result<Self> {
        let pipeline = Pipeline::new(scene);
        let inst = &scene.instrument;
        let (m, p) = (inst.m(), inst.pixels());
        let optics = Optics::new(inst, pipeline.model);
        let gain = inst.sensor.gain;
        let step = inst.grid().context("the scene's angle grid")?.step_deg();
        // Light per (point, model): computed once per distinct pair. Without
        // per-pixel geometry there is one point, so one evaluation per LED
        // and model serves every pixel.
        let npoints = if pipeline.per_pixel { p } else { 1 };
        let mut memo: Vec<Option<Vec<f64>>> = vec![None; npoints * brdfs.len()];
        let mut white_memo: Vec<Option<Vec<f64>>> = vec![None; npoints];
        let mut signal = vec![0.0; p * m];
        let mut white_signal = vec![0.0; p * m];
        for px in 0..p {
            let pt = if pipeline.per_pixel { px } else { 0 };
            let b = of_pixel[px];
            let key = pt * brdfs.len() + b;
            if memo[key].is_none() || white_memo[pt].is_none() {
                // One pass over the rays gives the surface's light and the white tile's.
                let (l, w) = light(
                    &optics,
                    &scene.pixel_point(px as f64),
                    &pixel_view(scene, px),
                    brdfs[b].as_ref(),
                    gain,
                    step,
                );
                memo[key].get_or_insert(l);
                white_memo[pt].get_or_insert(w);
            }
            signal[px * m..(px + 1) * m].copy_from_slice(memo[key].as_deref().unwrap());
            white_signal[px * m..(px + 1) * m].copy_from_slice(white_memo[pt].as_deref().unwrap());
        }
        let linearity = if scene.has("nonlinearity") {
            Some(super::sensor_linearity::measure_once(&pipeline, m, p, inst.sensor.full_scale)?)
        } else {
            None
        };
        let (mut white, dark) = reference(&pipeline, &white_signal, m, p);
        if let Some(l) = &linearity {
            white.iter_mut().for_each(|w| *w = linear(&l.correction, *w));
        }
        for px in 0..p {
            for k in 0..m {
                let w = white[px * m + k];
                if w.is_nan() || w <= 0.0 || !w.is_finite() {
                    bail!(
                        "scene `{}`: pixel {px} gets no usable light from instrument.leds[{k}] (white reference {w}); \
                         check the LED's position, emission profile and the sensor's gain and saturation",
                        scene.name
                    );
                }
            }
        }
        Ok(Self { pipeline, m, p, signal, white, dark, linearity })
    }

    /// The pipeline.
    pub fn pipeline(&self) -> &Pipeline {
        &self.pipeline
    }

    /// LEDs m.
    pub fn m(&self) -> usize {
        self.m
    }

    /// Pixels P.
    pub fn pixels(&self) -> usize {
        self.p
    }

    /// Light reaching the sensor before drift and the sensor stages, counts,
    /// `p * m + k`.
    pub fn signal(&self) -> &[f64] {
        &self.signal
    }

    /// White reference, `p * m + k`.
    pub fn white(&self) -> &[f64] {
        &self.white
    }

    /// The sensor's linearity as the factory measured it, when the scene
    /// makes the sensor nonlinear (the correction is the blob's).
    pub fn linearity(&self) -> Option<&super::sensor_linearity::SensorLinearity> {
        self.linearity.as_ref()
    }

    /// The dark frame's noise-free, drift-free counts per pixel (what the
    /// dark-offset and ambient-light effects add; 0 without them).
    pub fn dark(&self) -> &[f64] {
        &self.dark
    }

    /// The raw frames of `line` in `mode`: dark, then one per LED.
    pub fn frames(&self, line: u64, mode: Mode) -> Vec<Vec<f64>> {
        self.frames_at(line, mode, 1.0, &self.signal)
    }

    /// The same frames at exposure `exposure` (relative to the long one),
    /// of the light `signal` (`p * m + k`).
    fn frames_at(&self, line: u64, mode: Mode, exposure: f64, signal: &[f64]) -> Vec<Vec<f64>> {
        (0..=self.m)
            .map(|f| {
                let mut frame = if f == 0 {
                    vec![0.0; self.p]
                } else {
                    (0..self.p).map(|px| signal[px * self.m + f - 1] * exposure).collect()
                };
                self.pipeline.run(&mut frame, &FrameCtx { line, frame: f, m: self.m, exposure }, mode);
                frame
            })
            .collect()
    }

    /// The `short-exposure` effect's frames of `line`: per ratio, the dark
    /// frame and one per LED at the exposure 1 / ratio (none when the scene
    /// does not list the effect).
    pub fn short_frames(&self, line: u64, mode: Mode) -> Vec<Vec<Vec<f64>>> {
        self.pipeline.short_ratios.iter().map(|r| self.frames_at(line, mode, 1.0 / r, &self.signal)).collect()
    }

    /// Simulates line `line`: raw frames and white-calibrated readings.
    pub fn simulate_line(&self, line: u64, mode: Mode) -> LineReadings {
        let mut raw = self.frames(line, mode);
        raw.extend(self.short_frames(line, mode).into_iter().flatten());
        let corrected = self.correct(&raw);
        raw.truncate(self.m + 1);
        LineReadings { line, raw, corrected }
    }

    /// `(raw - dark) / white` for frames laid out as [`Self::frames`] gives;
    /// with the short frames after them ([`Self::short_frames`], each level's
    /// dark frame and LED frames), a pixel whose long frame saturated is read
    /// from its longest unsaturated exposure, `(short - its dark) ratio /
    /// white` (the shortest's when every one saturates), each exposure's
    /// signal made linear first when the sensor is measured nonlinear: the
    /// device's rule (`brdf_meter::acquire::correct_point_into`).
    pub fn correct(&self, raw: &[Vec<f64>]) -> Vec<f64> {
        let (m, fs) = (self.m, self.pipeline.full_scale);
        let lin = |s: f64| self.linearity.as_ref().map_or(s, |l| linear(&l.correction, s));
        let levels = (raw.len() / (m + 1)).saturating_sub(1).min(self.pipeline.short_ratios.len());
        let mut out = vec![0.0; self.p * m];
        for px in 0..self.p {
            for k in 0..m {
                let mut s = lin(raw[1 + k][px] - raw[0][px]);
                if raw[1 + k][px] >= fs {
                    for (l, r) in self.pipeline.short_ratios[..levels].iter().enumerate() {
                        let base = (l + 1) * (m + 1);
                        s = lin(raw[base + 1 + k][px] - raw[base][px]) * r;
                        if raw[base + 1 + k][px] < fs {
                            break;
                        }
                    }
                }
                out[px * m + k] = s / self.white[px * m + k];
            }
        }
        out
    }

    /// Raw frames of `line` as the simulated sensor serves them: u16,
    /// rounded, negative counts read as 0; dark first, then LEDs in order.
    /// A count above 65535 cannot cross the link: that is an error naming
    /// the pixel and LED (lower `instrument.sensor.gain` or list `saturation`).
    pub fn raw_frames(&self, line: u64) -> anyhow::Result<Vec<Vec<u16>>> {
        self.raw_frames_of(line, &self.signal)
    }

    /// [`Self::raw_frames`] of another light `signal` (`p * m + k`) through
    /// the same pipeline: a defect scene mixes other surfaces' light in
    /// (`forward::scene::defects`).
    pub fn raw_frames_of(&self, line: u64, signal: &[f64]) -> anyhow::Result<Vec<Vec<u16>>> {
        let mut frames = self.frames_at(line, Mode::Full, 1.0, signal);
        frames
            .extend(self.pipeline.short_ratios.iter().flat_map(|r| self.frames_at(line, Mode::Full, 1.0 / r, signal)));
        let mut out = Vec::with_capacity(frames.len());
        for (f, frame) in frames.into_iter().enumerate() {
            let mut px_out = Vec::with_capacity(frame.len());
            for (px, x) in frame.into_iter().enumerate() {
                let r = x.round();
                if r.is_nan() || r > 65535.0 {
                    let (g, short) = if f > self.m { (f % (self.m + 1), "short-exposure ") } else { (f, "") };
                    let what = if g == 0 {
                        format!("the {short}dark frame")
                    } else {
                        format!("the {short}frame of instrument.leds[{}]", g - 1)
                    };
                    bail!(
                        "line {line}, pixel {px}, {what}: {x} counts do not fit the u16 link; lower instrument.sensor.gain or list the `saturation` effect"
                    );
                }
                px_out.push(r.max(0.0) as u16);
            }
            out.push(px_out);
        }
        Ok(out)
    }
}

/// Per LED: gain x sum over rays of weight x R(ray, view), and the same for
/// a perfect diffuser (R = 1 wherever the viewer sees the surface).
/// A mirror spike is spread over the angle grid's bin kernel (`step_deg`)
/// about the view's mirror incidence (`crate::forward::brdf::ray_reflectance`).
fn light(
    optics: &Optics,
    point: &Vector3<f64>,
    wo: &Vector3<f64>,
    brdf: &dyn Brdf,
    gain: f64,
    step_deg: f64,
) -> (Vec<f64>, Vec<f64>) {
    let seen = if wo.z > 0.0 { 1.0 } else { 0.0 };
    let theta_o = wo.z.clamp(-1.0, 1.0).acos().to_degrees();
    (0..optics.m())
        .map(|led| {
            let (mut s, mut w) = (0.0, 0.0);
            optics.for_each_ray(led, point, |r| {
                s += r.weight * ray_reflectance(brdf, &r.dir, wo, r.theta_deg, theta_o, step_deg);
                w += r.weight;
            });
            (gain * s, gain * w * seen)
        })
        .unzip()
}

/// `s` counts made linear by `correction`: the device's function (in f32,
/// which is all the sensor's counts need).
fn linear(correction: &brdf_meter::acquire::Linearity, s: f64) -> f64 {
    f64::from(correction.linear(s as f32))
}

/// Dark-corrected reference readings of the white signal (`p * m + k`) and
/// the reference dark frame (P).
fn reference(pipeline: &Pipeline, white_signal: &[f64], m: usize, p: usize) -> (Vec<f64>, Vec<f64>) {
    let mut dark = vec![0.0; p];
    pipeline.run(&mut dark, &FrameCtx { line: 0, frame: 0, m, exposure: 1.0 }, Mode::Reference);
    let mut out = vec![0.0; p * m];
    for k in 0..m {
        let mut f: Vec<f64> = (0..p).map(|px| white_signal[px * m + k]).collect();
        pipeline.run(&mut f, &FrameCtx { line: 0, frame: 1 + k, m, exposure: 1.0 }, Mode::Reference);
        for px in 0..p {
            out[px * m + k] = f[px] - dark[px];
        }
    }
    (out, dark)
}

/// The view direction (surface frame) of pixel `px` under the scene's geometry.
pub fn pixel_view(scene: &Scene, px: usize) -> Vector3<f64> {
    pixel_view_at(scene, px as f64)
}

/// The view direction (surface frame) of (fractional) pixel `p`: towards
/// the lens (`instrument.view_distance_cm`) from the pixel's own point with
/// `per-pixel-geometry`, else along the nominal view.
pub fn pixel_view_at(scene: &Scene, p: f64) -> Vector3<f64> {
    let optics_frame = crate::forward::optics::surface_frame(&scene.instrument.normal());
    let inst = &scene.instrument;
    match (scene.has("per-pixel-geometry"), inst.view_distance_cm) {
        (true, Some(d)) => {
            let c = Vector3::from(inst.point.position_cm) + inst.view_dir() * d;
            optics_frame * (c - scene.pixel_point(p)).normalize()
        }
        _ => optics_frame * inst.view_dir(),
    }
}

/// Every effect name, for messages.
pub fn effect_names() -> String {
    STAGE_ORDER.join(", ")
}
