//! Defect scenes: a scene (the instrument and a defect-free surface with
//! its effects) plus defects over pixels and lines, for inspection: what an
//! instrument over a production line sees line after line.
//!
//! ```toml
//! name = "gloss-step"
//! scene = "../handheld.toml"      # relative to this file
//! [[defects]]
//! kind = "gloss-step"
//! first_pixel = 60
//! pixels = 8
//! first_line = 0
//! lines = 1000000
//! delta_gu = 2.0
//! ```
//!
//! | `kind` | parameters | the surface there |
//! |---|---|---|
//! | `scratch` | `brdf` | another BRDF (a few pixels wide) |
//! | `matt-patch` | `alpha` | the surface's Ward lobe with roughness `alpha` |
//! | `gloss-step` | `delta_gu` | the surface with its specular part scaled so that its specular gloss (`forward::gloss`, at the centre pixel's view) is `delta_gu` higher |
//! | `film` | `albedo`, `coverage` | a contamination film: a diffuse layer over the surface, the mixture `(1 - coverage) f + coverage albedo / pi` |
//! | `gloss-drift` | `gu_per_line` | every pixel, line l: the gloss step of `l x gu_per_line` GU (slow drift of the product) |
//! | `motion` | `shift_per_frame` | the surface moves between LED frames: frame k (0 = the first lit) of line l sees line `l + k x shift_per_frame` (in lines); without it every frame of a line sees the same strip |
//!
//! Every kind but `gloss-drift` and `motion` covers `pixels` pixels from
//! `first_pixel` and `lines` lines from `first_line`. Light is linear in
//! the BRDF, so every defect is simulated exactly as a mixture of the light
//! of two surfaces (computed once each by the scene's own optics); the
//! scene's effects (noise, saturation, ...) then act on the line as always.
//! Only the listed defects are simulated.
use super::{Scene, Simulator};
use crate::forward::brdf::{Brdf, BrdfSpec};
use crate::output::config::{FieldError, Validate};
use anyhow::{Context, bail};
use serde::Deserialize;
use std::path::Path;
use std::sync::Arc;

/// A defect scene file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DefectSceneFile {
    /// Name for reports.
    pub name: String,
    /// What it shows.
    #[serde(default)]
    pub description: String,
    /// The base scene, relative to this file.
    pub scene: String,
    /// The defects.
    #[serde(default)]
    pub defects: Vec<DefectSpec>,
}

/// One defect.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum DefectSpec {
    /// A few pixels of another BRDF.
    Scratch {
        /// Where.
        #[serde(flatten)]
        at: Extent,
        /// The BRDF there.
        brdf: BrdfSpec,
    },
    /// A rougher (matt) patch of the same Ward surface.
    MattPatch {
        /// Where.
        #[serde(flatten)]
        at: Extent,
        /// Its roughness.
        alpha: f64,
    },
    /// A step of specular gloss.
    GlossStep {
        /// Where.
        #[serde(flatten)]
        at: Extent,
        /// The gloss change, GU.
        delta_gu: f64,
    },
    /// A diffuse film over the surface.
    Film {
        /// Where.
        #[serde(flatten)]
        at: Extent,
        /// The film's albedo.
        albedo: f64,
        /// Its share of the reflection, 0..=1.
        coverage: f64,
    },
    /// Slow gloss drift of the whole line.
    GlossDrift {
        /// GU per line.
        gu_per_line: f64,
    },
    /// The surface moving between LED frames.
    Motion {
        /// Lines the surface moves between two LED frames.
        shift_per_frame: f64,
    },
}

impl DefectSpec {
    /// The pixels and lines it covers (`None`: the whole line, drift and
    /// motion).
    fn extent_mut(&mut self) -> Option<&mut Extent> {
        match self {
            Self::Scratch { at, .. }
            | Self::MattPatch { at, .. }
            | Self::GlossStep { at, .. }
            | Self::Film { at, .. } => Some(at),
            Self::GlossDrift { .. } | Self::Motion { .. } => None,
        }
    }
}

/// Pixels and lines a defect covers.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Extent {
    /// First pixel.
    pub first_pixel: usize,
    /// Pixels.
    pub pixels: usize,
    /// First line.
    #[serde(default)]
    pub first_line: u64,
    /// Lines (default: every line from the first).
    #[serde(default = "every_line")]
    pub lines: u64,
}

fn every_line() -> u64 {
    u64::MAX / 4
}

impl Validate for DefectSceneFile {
    fn validate(&self) -> Result<(), FieldError> {
        for (i, d) in self.defects.iter().enumerate() {
            let at = |e: FieldError| e.within(&format!("defects[{i}]"));
            let extent = match d {
                DefectSpec::Scratch { at, .. } => Some(at),
                DefectSpec::MattPatch { at, alpha } => {
                    if !(*alpha > 0.0 && alpha.is_finite()) {
                        return Err(at_err(i, "alpha", format!("{alpha} is impossible; must be > 0")));
                    }
                    Some(at)
                }
                DefectSpec::GlossStep { at, delta_gu } => {
                    if !delta_gu.is_finite() {
                        return Err(at_err(i, "delta_gu", "must be a finite number of GU".into()));
                    }
                    Some(at)
                }
                DefectSpec::Film { at, albedo, coverage } => {
                    if !(0.0..=1.0).contains(albedo) || !(0.0..=1.0).contains(coverage) {
                        return Err(at_err(i, "coverage", "albedo and coverage must be within 0..=1".into()));
                    }
                    Some(at)
                }
                DefectSpec::GlossDrift { gu_per_line } if !gu_per_line.is_finite() => {
                    return Err(at_err(i, "gu_per_line", "must be finite".into()));
                }
                DefectSpec::Motion { shift_per_frame } if !(0.0..=1.0).contains(shift_per_frame) => {
                    return Err(at_err(
                        i,
                        "shift_per_frame",
                        format!("{shift_per_frame} is outside 0..=1 line per frame (the surface would skip lines)"),
                    ));
                }
                _ => None,
            };
            if let Some(e) = extent
                && (e.pixels == 0 || e.lines == 0)
            {
                return Err(at(FieldError::new("pixels", "a defect covers at least one pixel and one line")));
            }
        }
        Ok(())
    }
}

fn at_err(i: usize, field: &str, msg: String) -> FieldError {
    FieldError::new(field, msg).within(&format!("defects[{i}]"))
}

/// A defect scene, ready to simulate.
pub struct DefectScene {
    /// Its name.
    pub name: String,
    /// The base scene.
    pub scene: Scene,
    sim: Simulator,
    base: Vec<f64>,
    /// Per area defect: its extent and its light (`p * m + k`).
    areas: Vec<(Extent, Vec<f64>)>,
    /// Light added per GU of specular gloss (`p * m + k`), for drift.
    per_gu: Vec<f64>,
    drift_gu_per_line: f64,
    shift_per_frame: f64,
}

impl DefectScene {
    /// Reads a defect scene file and its base scene.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let (name, scene, defects) = Self::read_file(path)?;
        Self::new(&name, scene, &defects)
    }

    /// A defect scene file's name, base scene and defects.
    fn read_file(path: &Path) -> anyhow::Result<(String, Scene, Vec<DefectSpec>)> {
        let file: DefectSceneFile = crate::output::config::load_toml(path)?;
        let base = path.parent().unwrap_or(Path::new(".")).join(&file.scene);
        let scene = Scene::load(&base).with_context(|| format!("{}: field `scene`", path.display()))?;
        Ok((file.name, scene, file.defects))
    }

    /// A defect scene file, or a plain scene (no defects; told apart by the
    /// defect scene's `scene` field), for a device of `pixels` pixels: a
    /// scene of more is cut to its centre pixels, as `measure --scene` cuts it
    /// ([`Scene::for_device`]), each defect moved with the window (and cut
    /// to it; one wholly outside is an error). Also returns the note to
    /// print when the scene was cut.
    pub fn load_any_for_device(path: &Path, pixels: usize) -> anyhow::Result<(Self, Option<String>)> {
        let (name, whole, defects) = Self::read_any(path)?;
        let p = whole.instrument.sensor.pixels;
        if p == pixels {
            return Ok((Self::new(&name, whole, &defects)?, None));
        }
        let scene = whole.for_device(pixels).with_context(|| format!("{}", path.display()))?;
        let first = (p - pixels) / 2;
        let moved = defects
            .iter()
            .enumerate()
            .map(|(i, d)| {
                let mut d = d.clone();
                if let Some(at) = d.extent_mut() {
                    let (a, b) = (at.first_pixel.max(first), (at.first_pixel + at.pixels).min(first + pixels));
                    anyhow::ensure!(
                        a < b,
                        "{}: defect {i} covers pixels {}..={} of the scene's {p}, none of the {pixels} the device reads \
                         ({first}..={}): move it, or give a scene of the device's {pixels} pixels",
                        path.display(),
                        at.first_pixel,
                        at.first_pixel + at.pixels - 1,
                        first + pixels - 1
                    );
                    (at.first_pixel, at.pixels) = (a - first, b - a);
                }
                Ok(d)
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        let note = format!(
            "note: scene {} has {p} pixels; the device reads its pixels {first}..={}{}",
            path.display(),
            first + pixels - 1,
            if defects.is_empty() { "" } else { " (the defects moved with them)" }
        );
        Ok((Self::new(&name, scene, &moved)?, Some(note)))
    }

    /// A defect scene file's or a plain scene's name, scene and defects.
    fn read_any(path: &Path) -> anyhow::Result<(String, Scene, Vec<DefectSpec>)> {
        let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        if text.lines().any(|l| l.trim_start().starts_with("scene ") || l.trim_start().starts_with("scene=")) {
            Self::read_file(path)
        } else {
            Ok(("defect-free".into(), Scene::load(path)?, Vec::new()))
        }
    }

    /// `scene` with `defects`.
    pub fn new(name: &str, scene: Scene, defects: &[DefectSpec]) -> anyhow::Result<Self> {
        let sim = Simulator::new(&scene)?;
        let p = sim.pixels();
        let base = sim.signal().to_vec();
        let light = |brdf: Arc<dyn Brdf>| -> anyhow::Result<Vec<f64>> {
            Ok(Simulator::with_surface(&scene, brdf)?.signal().to_vec())
        };
        let spectral = scene.instrument.spectral_weights;
        // Per GU of gloss: the surface's specular part over the gloss it gives.
        let per_gu = || -> anyhow::Result<Vec<f64>> {
            let BrdfSpec::Ward { rho_d, alpha, .. } = scene.surface.brdf else {
                bail!(
                    "a gloss step or drift needs a Ward surface (surface.brdf.model = \"ward\"), to scale its specular part"
                );
            };
            let diffuse = BrdfSpec::Ward { rho_d, rho_s: Some(0.0), alpha }.build_for(spectral)?;
            let wo = super::pipeline::pixel_view(&scene, p / 2);
            let full = scene.surface.brdf.build_for(spectral)?;
            let g = crate::forward::gloss::model_readings(full.as_ref(), &wo)[0]
                - crate::forward::gloss::model_readings(diffuse.as_ref(), &wo)[0];
            anyhow::ensure!(g.abs() > 1e-9, "the surface has no specular gloss to step");
            let d = light(Arc::from(diffuse))?;
            Ok(base.iter().zip(&d).map(|(b, d)| (b - d) / g).collect())
        };
        let mut areas = Vec::new();
        let (mut gain, mut drift, mut shift) = (None, 0.0, 0.0);
        for (i, d) in defects.iter().enumerate() {
            let ctx = || format!("defects[{i}]");
            let (at, signal) = match d {
                DefectSpec::Scratch { at, brdf } => {
                    (*at, light(Arc::from(brdf.build_for(spectral).with_context(ctx)?))?)
                }
                DefectSpec::MattPatch { at, alpha } => {
                    let BrdfSpec::Ward { rho_d, rho_s, .. } = scene.surface.brdf else {
                        bail!("{}: a matt patch needs a Ward surface", ctx());
                    };
                    (*at, light(Arc::from(BrdfSpec::Ward { rho_d, rho_s, alpha: *alpha }.build_for(spectral)?))?)
                }
                DefectSpec::GlossStep { at, delta_gu } => {
                    let g = gain.get_or_insert(per_gu().with_context(ctx)?);
                    (*at, base.iter().zip(g.iter()).map(|(b, x)| b + delta_gu * x).collect())
                }
                DefectSpec::Film { at, albedo, coverage } => {
                    let film = light(Arc::from(BrdfSpec::Lambertian { rho: *albedo }.build_for(spectral)?))?;
                    (*at, base.iter().zip(&film).map(|(b, f)| (1.0 - coverage) * b + coverage * f).collect())
                }
                DefectSpec::GlossDrift { gu_per_line } => {
                    gain.get_or_insert(per_gu().with_context(ctx)?);
                    drift = *gu_per_line;
                    continue;
                }
                DefectSpec::Motion { shift_per_frame } => {
                    shift = *shift_per_frame;
                    continue;
                }
            };
            anyhow::ensure!(
                at.first_pixel + at.pixels <= p,
                "{}: pixels {}..{} run past the sensor's {p}",
                ctx(),
                at.first_pixel,
                at.first_pixel + at.pixels
            );
            areas.push((at, signal));
        }
        Ok(Self {
            name: name.into(),
            scene,
            sim,
            base,
            areas,
            per_gu: gain.unwrap_or_default(),
            drift_gu_per_line: drift,
            shift_per_frame: shift,
        })
    }

    /// Pixels P.
    pub fn pixels(&self) -> usize {
        self.sim.pixels()
    }

    /// Whether line `line` (any of its frames) shows an area defect, and
    /// which pixels: `(first, last)` over every defect it shows.
    pub fn defect_pixels(&self, line: u64) -> Option<(usize, usize)> {
        let span = (self.sim.m() as f64 - 1.0) * self.shift_per_frame;
        self.areas
            .iter()
            .filter(|(at, _)| overlap(line as f64, line as f64 + 1.0 + span, at) > 0.0)
            .map(|(at, _)| (at.first_pixel, at.first_pixel + at.pixels - 1))
            .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
    }

    /// The raw frames of `line` as the simulated sensor serves them
    /// (`Simulator::raw_frames`), with the defects.
    pub fn raw_frames_at(&self, line: u64) -> anyhow::Result<Vec<Vec<u16>>> {
        let m = self.sim.m();
        let mut signal = self.base.clone();
        for k in 0..m {
            let from = line as f64 + k as f64 * self.shift_per_frame;
            let gu = self.drift_gu_per_line * from;
            if gu != 0.0 {
                for px in 0..signal.len() / m {
                    signal[px * m + k] += gu * self.per_gu[px * m + k];
                }
            }
            for (at, light) in &self.areas {
                let c = overlap(from, from + 1.0, at);
                if c > 0.0 {
                    for px in at.first_pixel..at.first_pixel + at.pixels {
                        let i = px * m + k;
                        signal[i] += c * (light[i] - self.base[i]);
                    }
                }
            }
        }
        self.sim.raw_frames_of(line, &signal)
    }
}

/// The share of the strip `[a, b)` (in lines) inside the defect's lines.
fn overlap(a: f64, b: f64, at: &Extent) -> f64 {
    let (lo, hi) = (at.first_line as f64, at.first_line as f64 + at.lines as f64);
    ((b.min(hi) - a.max(lo)) / (b - a)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn library(name: &str) -> DefectScene {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/inspect").join(name);
        DefectScene::load(&path).unwrap_or_else(|e| panic!("{name}: {e:#}"))
    }

    fn light(ds: &DefectScene, line: u64) -> Vec<Vec<u16>> {
        ds.raw_frames_at(line).unwrap()
    }

    #[test]
    fn each_library_defect_changes_its_pixels_and_lines_only() {
        let clean = DefectScene::new("clean", library("scratch.toml").scene.clone(), &[]).unwrap();
        for (file, pixels, line) in [
            ("scratch.toml", 62..66, 12),
            ("matt-patch.toml", 40..56, 12),
            ("gloss-step.toml", 80..88, 12),
            ("film.toml", 20..36, 12),
        ] {
            let ds = library(file);
            // Before the defect's lines: the defect-free frames, noise draw and all.
            assert_eq!(light(&ds, 3), light(&clean, 3), "{file}: line 3");
            let (got, want) = (light(&ds, line), light(&clean, line));
            let differs: Vec<usize> =
                (0..ds.pixels()).filter(|&p| got.iter().zip(&want).any(|(g, w)| g[p] != w[p])).collect();
            assert!(!differs.is_empty() && differs.iter().all(|p| pixels.contains(p)), "{file}: pixels {differs:?}");
            assert_eq!(ds.defect_pixels(line), Some((pixels.start, pixels.end - 1)), "{file}");
        }
        // Drift: nothing at line 0, the whole line later.
        let drift = library("gloss-drift.toml");
        assert_eq!(light(&drift, 0), light(&clean, 0));
        let (got, want) = (light(&drift, 200), light(&clean, 200));
        assert!((0..drift.pixels()).filter(|&p| got.iter().zip(&want).any(|(g, w)| g[p] != w[p])).count() > 100);
        // Motion: line 9's later LED frames already see the step of line 10, its first frame not.
        let moving = library("motion.toml");
        let still = library("gloss-step.toml");
        assert_eq!(light(&still, 9), light(&clean, 9));
        let (got, want) = (light(&moving, 9), light(&clean, 9));
        let m = moving.scene.instrument.m();
        for level in 0..got.len() / (m + 1) {
            let first_led = level * (m + 1) + 1;
            assert_eq!(got[first_led], want[first_led], "the first LED's frames of line 9 see line 9");
        }
        assert_ne!(got, want, "the later LEDs' frames see part of line 10");
    }

    #[test]
    fn a_scene_cut_to_the_devices_pixels_keeps_its_defects_where_they_were_on_the_surface() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/inspect");
        let (whole, note) = DefectScene::load_any_for_device(&dir.join("scratch.toml"), 128).unwrap();
        assert!(note.is_none());
        assert_eq!(whole.defect_pixels(12), Some((62, 65)));
        // 32 of 128 pixels: 48..=79; the scratch at 62..=65 is at 14..=17.
        let (cut, note) = DefectScene::load_any_for_device(&dir.join("scratch.toml"), 32).unwrap();
        assert!(note.unwrap().contains("48..=79"));
        assert_eq!((cut.pixels(), cut.defect_pixels(12)), (32, Some((14, 17))));
        let clean = DefectScene::new("clean", cut.scene.clone(), &[]).unwrap();
        let (got, want) = (light(&cut, 12), light(&clean, 12));
        let differs: Vec<usize> = (0..32).filter(|&p| got.iter().zip(&want).any(|(g, w)| g[p] != w[p])).collect();
        assert!(!differs.is_empty() && differs.iter().all(|p| (14..18).contains(p)), "{differs:?}");
        // Cut to the window: the matt patch at 40..=55 keeps 48..=55.
        let (patch, _) = DefectScene::load_any_for_device(&dir.join("matt-patch.toml"), 32).unwrap();
        assert_eq!(patch.defect_pixels(12), Some((0, 7)));
        // The film at 20..=35 lies outside the window: said, not dropped.
        let e = DefectScene::load_any_for_device(&dir.join("film.toml"), 32).err().unwrap().to_string();
        assert!(e.contains("defect 0 covers pixels 20..=35") && e.contains("48..=79"), "{e}");
        // A plain scene is cut the same way.
        let (plain, note) = DefectScene::load_any_for_device(&dir.join("../handheld.toml"), 32).unwrap();
        assert!(note.is_some() && plain.pixels() == 32 && plain.defect_pixels(12).is_none());
    }

    #[test]
    fn bad_defects_are_refused_with_their_field() {
        let text = "name = \"x\"\nscene = \"../handheld.toml\"\n[[defects]]\nkind = \"film\"\nfirst_pixel = 0\npixels = 4\nalbedo = 0.5\ncoverage = 1.5\n";
        let e = crate::output::config::parse_toml::<DefectSceneFile>(text, "x.toml").unwrap_err().to_string();
        assert!(e.contains("defects[0]") && e.contains("coverage"), "{e}");
        let text = "name = \"x\"\nscene = \"h.toml\"\n[[defects]]\nkind = \"motion\"\nshift_per_frame = 2.0\n";
        let e = crate::output::config::parse_toml::<DefectSceneFile>(text, "x.toml").unwrap_err().to_string();
        assert!(e.contains("skip lines"), "{e}");
    }
}
