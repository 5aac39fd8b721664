//! Scenes: an instrument, a surface and the effects to simulate, from a TOML
//! file. Only the effects a scene lists are built into its pipeline; an
//! effect it does not list is not there at all (not computed and multiplied
//! by zero), so a result can be traced to the effects that made it.
//!
//! ```toml
//! name = "example"
//! effects = [
//!   { kind = "near-field" },
//!   { kind = "inverse-square" },
//!   { kind = "noise", model = "proportional", sigma = 0.02 },
//! ]
//! [instrument]            # optics::Instrument: LEDs, sensor, view, grid
//! view_deg = 45.0
//! grid = { start_deg = 25.0, stop_deg = 65.0, step_deg = 0.5 }
//! [[instrument.leds]]
//! centre_deg = 33.0
//! distance_cm = 10.0
//! cluster = { count = 5, pitch_cm = 0.17 }
//! [surface]
//! brdf = { model = "ward", rho_d = 0.3, alpha = 0.05 }
//! ```
//!
//! See [`effects`] for the effects table and the stage order, [`pipeline`]
//! for the simulation, and the functions below for what training, the blob
//! and the simulated sensor take from a scene:
//! - [`zone_system_matrices`] / [`pixel_system_matrix`]: H per zone or pixel
//!   (the optics the scene says it has; no noise draw, no surface, no truth);
//! - [`white_reference`]: the blob's white reference per pixel and LED;
//! - [`sensor_linearity`]: the factory's measurement of a nonlinear sensor,
//!   the correction the blob carries;
//! - [`raw_frames`]: one line's raw u16 frames (dark first, then the LEDs in
//!   physical order) for the simulated line sensor; [`frames`] for whole
//!   lines and the synthetic analytic pattern.
pub mod defects;
pub mod effects;
pub mod frames;
pub mod noise_level;
pub mod pipeline;
pub mod readings;
pub mod sensor_linearity;

use crate::forward::brdf::{Brdf, BrdfSpec};
use crate::forward::optics::{Instrument, Optics, OpticsError, RayModel, system_matrix_at};
use crate::output::config::{ConfigError, FieldError, Validate};
use anyhow::Context;
pub use effects::{DriftRate, EffectSpec, NoiseModel, STAGE_ORDER};
use nalgebra::{DMatrix, Vector3};
pub use pipeline::{LineReadings, Pipeline, Simulator};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Name for reports.
    pub name: String,
    /// What the scene is for.
    #[serde(default)]
    pub description: String,
    /// The effects to simulate; anything not listed is not simulated.
    #[serde(default)]
    pub effects: Vec<EffectSpec>,
    /// LEDs, sensor, view, grid.
    pub instrument: Instrument,
    /// What the instrument looks at.
    pub surface: SurfaceSpec,
}

/// The surface along the line.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceSpec {
    /// The BRDF everywhere no segment covers.
    pub brdf: BrdfSpec,
    /// Stretches of the line with another BRDF.
    #[serde(default)]
    pub segments: Vec<SegmentSpec>,
}

/// A stretch of pixels with its own BRDF.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SegmentSpec {
    /// First pixel (0-based).
    pub first_pixel: usize,
    /// Last pixel, included.
    pub last_pixel: usize,
    /// The BRDF there.
    pub brdf: BrdfSpec,
}

impl Validate for Scene {
    fn validate(&self) -> Result<(), FieldError> {
        if self.name.trim().is_empty() {
            return Err(FieldError::new("name", "must not be empty"));
        }
        self.instrument.validate().map_err(|e| e.within("instrument"))?;
        let mut seen = [false; STAGE_ORDER.len()];
        for (i, e) in self.effects.iter().enumerate() {
            let at = |x: FieldError| x.within(&format!("effects[{i}]"));
            e.validate().map_err(at)?;
            if let EffectSpec::LedDrift { rate: DriftRate::PerLed(rates) } = e
                && rates.len() != self.instrument.leds.len()
            {
                return Err(at(FieldError::new(
                    "rates_per_frame",
                    format!(
                        "lists {} rate(s) for {} LED(s); list one per LED, in `instrument.leds` order (or one \
                         `rate_per_frame` for all)",
                        rates.len(),
                        self.instrument.leds.len()
                    ),
                )));
            }
            if std::mem::replace(&mut seen[e.order()], true) {
                return Err(at(FieldError::new(
                    "kind",
                    format!("effect `{}` is listed twice; list each effect once", e.name()),
                )));
            }
        }
        if self.has("per-pixel-geometry")
            && !self.has("3d-geometry")
            && self.instrument.sensor.line_axis == crate::forward::optics::LineAxis::Y
        {
            return Err(FieldError::new(
                "instrument.sensor.line_axis",
                "a line across the plane of incidence (\"y\") collapses onto the centre point in-plane: list `3d-geometry` too, or use \"x\"",
            ));
        }
        self.surface.brdf.build().map_err(|e| FieldError::new("surface.brdf", e.to_string()))?;
        let p = self.instrument.sensor.pixels;
        let mut covered = vec![false; p];
        for (k, s) in self.surface.segments.iter().enumerate() {
            let at = |x: FieldError| x.within(&format!("surface.segments[{k}]"));
            s.brdf.build().map_err(|e| at(FieldError::new("brdf", e.to_string())))?;
            if s.last_pixel >= p || s.first_pixel > s.last_pixel {
                return Err(at(FieldError::new(
                    "last_pixel",
                    format!(
                        "pixels {}..={} are impossible; need first_pixel <= last_pixel < {p} (instrument.sensor.pixels)",
                        s.first_pixel, s.last_pixel
                    ),
                )));
            }
            for c in &mut covered[s.first_pixel..=s.last_pixel] {
                if std::mem::replace(c, true) {
                    return Err(at(FieldError::new("first_pixel", "overlaps an earlier segment")));
                }
            }
        }
        Ok(())
    }
}

/// A scene file as read, before its effect tables are checked one by one
/// (so that an error names the effect's own line and field).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    name: String,
    #[serde(default)]
    description: String,
    #[serde(default)]
    effects: Vec<effects::EffectEntry>,
    instrument: Instrument,
    surface: SurfaceSpec,
}

impl RawScene {
    fn scene(&self) -> Result<Scene, FieldError> {
        let effects = self
            .effects
            .iter()
            .enumerate()
            .map(|(i, e)| EffectSpec::from_entry(e.clone()).map_err(|x| x.within(&format!("effects[{i}]"))))
            .collect::<Result<_, _>>()?;
        Ok(Scene {
            name: self.name.clone(),
            description: self.description.clone(),
            effects,
            instrument: self.instrument.clone(),
            surface: self.surface.clone(),
        })
    }
}

impl Validate for RawScene {
    fn validate(&self) -> Result<(), FieldError> {
        self.scene()?.validate()
    }
}

impl Scene {
    /// Reads, parses and validates a scene file; errors name the file, the
    /// line and the field.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let raw: RawScene = crate::output::config::load_toml(path)?;
        Ok(raw.scene().expect("checked by validate"))
    }

    /// Parses and validates scene text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, ConfigError> {
        let raw: RawScene = crate::output::config::parse_toml(text, origin)?;
        Ok(raw.scene().expect("checked by validate"))
    }

    /// The built-in default: the patent profile (method.md) as a scene. One
    /// pixel at the measured point, near-field clusters of 5 sources with the
    /// inverse square, 2 % proportional noise, a Ward surface from the test set.
    pub fn patent_profile() -> Self {
        Self {
            name: "patent-profile".into(),
            description: "The patent's experiment (method.md): 7 illuminations of 5 point sources 0.17 cm apart, centre 10 cm away, centre rays 33..57 deg, view 45 deg, 2 % noise.".into(),
            effects: vec![
                EffectSpec::NearField {},
                EffectSpec::InverseSquare {},
                EffectSpec::Noise { model: NoiseModel::Proportional, sigma: Some(0.02), sigma_counts: None, electrons_per_count: None, read_sigma_counts: None, seed: 1 },
            ],
            instrument: Instrument::patent_profile(),
            surface: SurfaceSpec { brdf: BrdfSpec::Ward { rho_d: 0.3075, rho_s: None, alpha: 0.0599 }, segments: Vec::new() },
        }
    }

    /// The scene read through a window of `pixels` of its sensor's pixels
    /// from `first` (a device with fewer pixels reading a cut of the line:
    /// every pixel keeps the point and view it has in the whole line).
    pub fn window(&self, first: usize, pixels: usize) -> anyhow::Result<Self> {
        let p = self.instrument.sensor.pixels;
        anyhow::ensure!(
            pixels >= 1 && first + pixels <= p,
            "scene `{}`: pixels {first}..{} are not within its {p} pixels",
            self.name,
            first + pixels
        );
        let mut s = self.clone();
        s.name = format!("{} (pixels {first}..={})", self.name, first + pixels - 1);
        s.instrument.sensor = self.instrument.sensor.window(first, pixels);
        s.surface.segments = self
            .surface
            .segments
            .iter()
            .filter(|g| g.last_pixel >= first && g.first_pixel < first + pixels)
            .map(|g| SegmentSpec {
                first_pixel: g.first_pixel.saturating_sub(first),
                last_pixel: (g.last_pixel - first).min(pixels - 1),
                brdf: g.brdf.clone(),
            })
            .collect();
        Ok(s)
    }

    /// The scene for a simulated device of `pixels` pixels: as it is when
    /// they agree, else the window of them centred on the line (a device
    /// with more pixels than the scene is an error).
    pub fn for_device(&self, pixels: usize) -> anyhow::Result<Self> {
        let p = self.instrument.sensor.pixels;
        if p == pixels {
            return Ok(self.clone());
        }
        anyhow::ensure!(
            pixels < p,
            "scene `{}` has {p} pixels; the device reads {pixels}: give a scene with at least as many",
            self.name
        );
        self.window((p - pixels) / 2, pixels)
    }

    /// Whether the scene lists effect `name`.
    pub fn has(&self, name: &str) -> bool {
        self.effects.iter().any(|e| e.name() == name)
    }

    /// The ray model the scene's geometric effects call for.
    pub fn ray_model(&self) -> RayModel {
        RayModel {
            near_field: self.has("near-field"),
            three_d: self.has("3d-geometry"),
            inverse_square: self.has("inverse-square"),
            emission_profile: self.has("emission-profile"),
        }
    }

    /// The scene's noise effect, if listed (its statistics, for R_nn; never a draw).
    pub fn noise(&self) -> Option<&EffectSpec> {
        self.effects.iter().find(|e| matches!(e, EffectSpec::Noise { .. }))
    }

    /// The BRDF of each pixel: (distinct models, model index per pixel).
    pub fn surface_brdfs(&self) -> anyhow::Result<SurfaceModels> {
        let spectral = self.instrument.spectral_weights;
        let mut models = vec![self.surface.brdf.build_for(spectral).context("surface.brdf")?];
        let mut of_pixel = vec![0; self.instrument.sensor.pixels];
        for (k, s) in self.surface.segments.iter().enumerate() {
            models.push(s.brdf.build_for(spectral).with_context(|| format!("surface.segments[{k}].brdf"))?);
            for p in &mut of_pixel[s.first_pixel..=s.last_pixel] {
                *p = k + 1;
            }
        }
        Ok((models, of_pixel))
    }

    /// The surface point (cm, instrument frame) that (fractional) pixel `p`
    /// sees under this scene's geometry: the centre point unless the scene
    /// lists `per-pixel-geometry`; on the plane of incidence unless it lists
    /// `3d-geometry`.
    pub fn pixel_point(&self, p: f64) -> Vector3<f64> {
        geometry_point(&self.instrument, p, self.has("per-pixel-geometry"), self.has("3d-geometry"))
    }
}

impl Scene {
    /// Incidence angle (degrees) of LED `led`'s centre ray at the point pixel
    /// `px` sees: the nominal centre angle in far field (parallel light),
    /// the direction to the LED's centre in near field.
    pub fn led_incidence_deg(&self, led: usize, px: f64) -> f64 {
        let inst = &self.instrument;
        let three_d = self.has("3d-geometry");
        let dir = if self.has("near-field") {
            (inst.led_centre(led, three_d) - self.pixel_point(px)).normalize()
        } else {
            inst.led_direction(led, three_d)
        };
        (crate::forward::optics::surface_frame(&inst.normal()) * dir).z.clamp(-1.0, 1.0).acos().to_degrees()
    }
}

/// The distinct BRDFs of a surface and the index of each pixel's.
pub type SurfaceModels = (Vec<Box<dyn Brdf>>, Vec<usize>);

/// Point seen by pixel `p` (see [`Scene::pixel_point`]).
pub(crate) fn geometry_point(inst: &Instrument, p: f64, per_pixel: bool, three_d: bool) -> Vector3<f64> {
    let c = Vector3::from(inst.point.position_cm);
    if !per_pixel {
        return c;
    }
    let off = inst.sensor.offset_cm(p);
    // The line runs along the surface: the axis projected onto the tangent plane.
    let n = inst.normal();
    let axis = match inst.sensor.line_axis {
        crate::forward::optics::LineAxis::X => Vector3::x(),
        crate::forward::optics::LineAxis::Y => Vector3::y(),
    };
    let mut t = axis - n * n.dot(&axis);
    if t.norm() < 1e-9 {
        t = Vector3::z() - n * n.dot(&Vector3::z());
    }
    let mut q = c + t.normalize() * off;
    if !three_d {
        q.y = c.y;
    }
    q
}

/// One zone's system matrix.
#[derive(Clone, Debug)]
pub struct ZoneMatrix {
    /// First pixel of the zone.
    pub first_pixel: usize,
    /// Last pixel of the zone, included.
    pub last_pixel: usize,
    /// The (fractional) pixel whose point H is computed at: the zone's centre.
    pub centre_pixel: f64,
    /// H (m x n), rows summing to 1.
    pub h: DMatrix<f64>,
}

/// First pixel of each of `zones` zones of `pixels` pixels, as the blob
/// stores them: `z * P / Z`.
pub fn zone_starts(pixels: usize, zones: usize) -> Vec<usize> {
    (0..zones).map(|z| z * pixels / zones).collect()
}

/// H (m x n) at (fractional) pixel `pixel` with the optics the scene lists
/// (near/far field, 3-D, per-pixel geometry, inverse square, emission
/// profile). It reads only the instrument and the effect list: never the
/// surface, the noise draw or the truth.
pub fn pixel_system_matrix(scene: &Scene, pixel: f64) -> Result<DMatrix<f64>, OpticsError> {
    let optics = Optics::new(&scene.instrument, scene.ray_model());
    let grid = scene.instrument.grid().expect("validated scene has a valid grid");
    system_matrix_at(&optics, &grid, &scene.pixel_point(pixel))
}

/// H for each of `zones` zones of the scene's pixels, at each zone's centre.
/// `1 <= zones <= pixels`.
pub fn zone_system_matrices(scene: &Scene, zones: usize) -> anyhow::Result<Vec<ZoneMatrix>> {
    let p = scene.instrument.sensor.pixels;
    anyhow::ensure!(zones >= 1 && zones <= p, "{zones} zones are impossible for a sensor of {p} pixels; use 1..={p}");
    let optics = Optics::new(&scene.instrument, scene.ray_model());
    let grid = scene.instrument.grid().context("instrument.grid")?;
    let starts = zone_starts(p, zones);
    let mut out = Vec::with_capacity(zones);
    for (z, &first) in starts.iter().enumerate() {
        let last = starts.get(z + 1).map_or(p - 1, |s| s - 1);
        let centre = (first + last) as f64 / 2.0;
        let h = system_matrix_at(&optics, &grid, &scene.pixel_point(centre))
            .with_context(|| format!("scene `{}`, zone {z} (pixels {first}..={last})", scene.name))?;
        out.push(ZoneMatrix { first_pixel: first, last_pixel: last, centre_pixel: centre, h });
    }
    Ok(out)
}

/// What training takes from a scene: the optics per zone, the sensor's
/// pixel count, the white reference for the blob and the noise level it records.
#[derive(Clone, Debug)]
pub struct TrainingOptics {
    /// One entry per zone: first pixel, the optics at its centre and at the
    /// pixels its sample pairs are taken at.
    pub zones: Vec<crate::forward::zone_optics::ZoneOptics>,
    /// Pixels P.
    pub pixels: usize,
    /// White reference, `p * m + i` (see [`white_reference`]).
    pub white: Vec<f32>,
    /// The relative noise of a perfect diffuser's readings
    /// ([`noise_level::relative_noise_level`]).
    pub noise_level: f64,
    /// The factory's measurement of the sensor, when the scene makes it
    /// nonlinear: its correction goes into the blob (the white above
    /// already took it).
    pub linearity: Option<sensor_linearity::SensorLinearity>,
}

/// The optics of `zones` zones of the scene, for `train` (no noise draw, no
/// surface, no truth): each zone's centre and training pixels with their
/// own rays, view and readings' noise (the scene's sensor effects, or
/// relative noise `noise_override` when given).
pub fn training_optics(scene: &Scene, zones: usize, noise_override: Option<f64>) -> anyhow::Result<TrainingOptics> {
    use crate::forward::pairs::PixelOptics;
    use crate::forward::reading_noise::ReadingNoise;
    let p = scene.instrument.sensor.pixels;
    anyhow::ensure!(zones >= 1 && zones <= p, "{zones} zones are impossible for a sensor of {p} pixels; use 1..={p}");
    let m = scene.instrument.m();
    let sim = Simulator::new(scene)?;
    let noise = noise_level::reading_noise(scene, &sim);
    let noise_of = |px: f64| match noise_override {
        Some(s) => ReadingNoise::relative(s, m),
        None => noise[(px.round() as usize).min(p - 1)].clone(),
    };
    let optics = Optics::new(&scene.instrument, scene.ray_model());
    let grid = scene.instrument.grid().context("instrument.grid")?;
    let pixel = |px: f64| {
        PixelOptics::new(
            &optics,
            &grid,
            px,
            &scene.pixel_point(px),
            pipeline::pixel_view_at(scene, px),
            (0..m).map(|k| scene.led_incidence_deg(k, px)).collect(),
            noise_of(px),
        )
    };
    // The black-glass standard as the instrument measures it, every pixel:
    // what calibrating the gloss readings on the standard reads.
    let standard =
        Simulator::with_surface(scene, std::sync::Arc::new(crate::forward::brdf::SmoothDielectric::black_glass()))?
            .simulate_line(0, pipeline::Mode::Reference)
            .corrected;
    let starts = zone_starts(p, zones);
    let mut out = Vec::with_capacity(zones);
    for (z, &first) in starts.iter().enumerate() {
        let last = starts.get(z + 1).map_or(p - 1, |s| s - 1);
        let at = || format!("scene `{}`, zone {z} (pixels {first}..={last})", scene.name);
        let centre = pixel((first + last) as f64 / 2.0).with_context(at)?;
        let mut every = (first..=last).map(|px| pixel(px as f64)).collect::<Result<Vec<_>, _>>().with_context(at)?;
        for (i, po) in every.iter_mut().enumerate() {
            let px = first + i;
            po.standard = Some(nalgebra::DVector::from_column_slice(&standard[px * m..(px + 1) * m]));
        }
        let pixels = crate::forward::zone_optics::training_pixels(first, last)
            .into_iter()
            .map(|px| every[px - first].clone())
            .collect();
        out.push(crate::forward::zone_optics::ZoneOptics { first_pixel: first, centre, pixels, every });
    }
    let noise_level = match noise_override {
        Some(s) => s,
        None => noise_level::relative_noise_level(scene)?,
    };
    Ok(TrainingOptics {
        zones: out,
        pixels: p,
        white: sim.white().iter().map(|w| *w as f32).collect(),
        noise_level,
        linearity: sim.linearity().cloned(),
    })
}

impl Scene {
    /// The scene with its surface replaced by `spec`, written as a scene's
    /// `surface.brdf` (e.g. `{ model = "lambertian", rho = 0.99 }`, a white
    /// tile): the whole line, its segments dropped; the instrument and the
    /// effects unchanged. For `--surface` on the command line.
    pub fn with_surface(mut self, spec: &str) -> anyhow::Result<Self> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Surface {
            brdf: BrdfSpec,
        }
        let s: Surface = toml::from_str(&format!("brdf = {spec}")).map_err(|e| {
            anyhow::anyhow!(
                "surface {spec}: not a surface as a scene's `surface.brdf` writes it, e.g. '{{ model = \"lambertian\", \
                 rho = 0.99 }}': {}",
                e.message()
            )
        })?;
        s.brdf.build().map_err(|e| anyhow::anyhow!("surface {spec}: {e}"))?;
        self.surface = SurfaceSpec { brdf: s.brdf, segments: Vec::new() };
        Ok(self)
    }
}

/// The blob's white reference: for every pixel p and LED i (physical order),
/// the dark-corrected, noise-free, drift-free reading of a perfect diffuser
/// through the scene's whole pipeline, at index `p * m + i`.
pub fn white_reference(scene: &Scene) -> anyhow::Result<Vec<f32>> {
    let sim = Simulator::new(scene)?;
    Ok(sim.white().iter().map(|w| *w as f32).collect())
}

/// Raw frames of scene line `line` for the simulated line sensor: `m + 1`
/// frames of P u16 counts, the dark frame first, then one per LED in physical
/// order. Counts are rounded to the nearest integer, negative ones read as
/// 0; a count above 65535 is an error (the link carries u16). List
/// `quantisation` and `saturation` in the scene to model the converter
/// itself.
pub fn raw_frames(scene: &Scene, line: u64) -> anyhow::Result<Vec<Vec<u16>>> {
    Simulator::new(scene)?.raw_frames(line)
}

/// Time to simulate one line of `scene` from scratch (preparing the rays and
/// the white reference included), the fastest of repeated runs over about
/// `seconds` of wall time (the minimum is the least disturbed by the machine).
pub fn time_simulation(scene: &Scene, seconds: f64) -> anyhow::Result<std::time::Duration> {
    use std::time::{Duration, Instant};
    let start = Instant::now();
    let mut best = Duration::MAX;
    let mut runs = 0u32;
    while runs < 3 || (start.elapsed().as_secs_f64() < seconds && runs < 1_000_000) {
        let t = Instant::now();
        let sim = Simulator::new(scene)?;
        std::hint::black_box(sim.simulate_line(0, pipeline::Mode::Full));
        best = best.min(t.elapsed());
        runs += 1;
    }
    Ok(best)
}

#[cfg(test)]
mod tests;
