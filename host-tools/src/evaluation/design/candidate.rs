//! Candidate layouts for `design`: variations of a base scene's LED ring and
//! exposure, from a TOML file or the built-in grid.
//!
//! ```toml
//! [[candidate]]
//! name = "11 LEDs, 4 mm dies"
//! leds = { count = 11, first_deg = 33.0, last_deg = 57.0, die_mm = 4.0, die_height_mm = 10.5 }
//! gain = 2400.0          # counts of a perfect diffuser (instrument.sensor.gain)
//! short_exposure = [16, 80]  # exposures 1/16 and 1/80 as long for a saturated frame
//! ```
//!
//! Every field but `name` is optional: what a candidate leaves out is the
//! base scene's. `leds` replaces the base's LEDs with `count` extended dies
//! of `die_mm` in the plane of incidence x `die_height_mm` across it
//! (`die_mm` when absent: a square die), centre rays evenly spread from
//! `first_deg` to `last_deg` (or at `angles_deg`), `distance_cm` away (the
//! base's first LED's distance by default), sampled every
//! [`IN_PLANE_SAMPLE_PITCH_MM`] or finer in the plane of incidence and every
//! [`DIE_SAMPLE_PITCH_MM`] or finer across it, with the base's first LED's
//! emission profile.
use crate::forward::optics::{ExtendedSpec, LedSpec};
use crate::forward::scene::{EffectSpec, Scene};
use crate::output::config::{FieldError, Validate, check_positive, check_range};
use serde::{Deserialize, Serialize};

/// Largest spacing of a die's sample points across the plane of incidence,
/// mm: finer than the sharpest lobe the prior holds is wide at the LEDs'
/// distance (about 1 deg at 6 cm).
pub const DIE_SAMPLE_PITCH_MM: f64 = 0.6;

/// Largest spacing in the plane of incidence, mm: half the pitch across.
/// Along the line each pixel's specular direction moves over the dies in
/// this plane (about 0.1 deg per pixel on the handheld), so a sharp lobe's
/// reading steps from one sample column to the next: at 0.6 mm (0.55 deg,
/// six pixels) the MERL metals' gloss swung by +-20 % with that period, a
/// sampling artefact no real, continuous die has; at 0.3 mm the swing is
/// gone (docs/handheld.md, "Facets edge to edge, finely sampled"). Across the
/// plane every pixel sees the dies alike, so the coarser pitch costs no
/// such swing.
pub const IN_PLANE_SAMPLE_PITCH_MM: f64 = 0.3;

/// A candidates file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CandidateFile {
    /// The candidates, in report order.
    pub candidate: Vec<Candidate>,
}

/// One candidate layout.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Candidate {
    /// Name for the report.
    pub name: String,
    /// The LEDs (the base scene's when absent).
    #[serde(default)]
    pub leds: Option<LedRing>,
    /// The sensor's gain, counts of a perfect diffuser lit along the normal.
    #[serde(default)]
    pub gain: Option<f64>,
    /// Ratios of the long exposure over the shorter ones taken of a frame
    /// that saturates (empty: none).
    #[serde(default)]
    pub short_exposure: Option<Vec<f64>>,
}

/// LEDs on an arc in the plane of incidence.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LedRing {
    /// Number of LEDs (with `first_deg`/`last_deg`).
    #[serde(default)]
    pub count: Option<usize>,
    /// Centre-ray incidence of the first LED, degrees.
    #[serde(default)]
    pub first_deg: Option<f64>,
    /// Centre-ray incidence of the last LED, degrees.
    #[serde(default)]
    pub last_deg: Option<f64>,
    /// Or the centre-ray incidences one by one, degrees.
    #[serde(default)]
    pub angles_deg: Option<Vec<f64>>,
    /// Side of the die (or diffuser) in the plane of incidence, mm.
    pub die_mm: f64,
    /// Its extent across the plane of incidence, mm (`die_mm` when absent).
    /// A slit as wide across as the gloss geometry's receptor (10 deg)
    /// reads a lobe's flux through the gloss window as it reads a mirror's.
    #[serde(default)]
    pub die_height_mm: Option<f64>,
    /// Distance from the line's centre, cm.
    #[serde(default)]
    pub distance_cm: Option<f64>,
}

impl LedRing {
    /// The centre angles.
    pub fn angles(&self) -> Vec<f64> {
        if let Some(a) = &self.angles_deg {
            return a.clone();
        }
        let (c, a, b) = (self.count.unwrap_or(1), self.first_deg.unwrap_or(45.0), self.last_deg.unwrap_or(45.0));
        if c == 1 {
            return vec![0.5 * (a + b)];
        }
        (0..c).map(|i| a + (b - a) * i as f64 / (c - 1) as f64).collect()
    }
}

impl Validate for CandidateFile {
    fn validate(&self) -> Result<(), FieldError> {
        if self.candidate.is_empty() {
            return Err(FieldError::new("candidate", "list at least one `[[candidate]]`"));
        }
        for (i, c) in self.candidate.iter().enumerate() {
            let at = |e: FieldError| e.within(&format!("candidate[{i}]"));
            if c.name.trim().is_empty() {
                return Err(at(FieldError::new("name", "must not be empty")));
            }
            if let Some(g) = c.gain {
                check_range("gain", g, 1e-6, 1e9, "counts").map_err(at)?;
            }
            if let Some(r) = &c.short_exposure
                && !r.is_empty()
            {
                EffectSpec::ShortExposure { ratios: r.clone() }
                    .validate()
                    .map_err(|e| at(FieldError::new("short_exposure", e.message)))?;
            }
            if let Some(l) = &c.leds {
                let at2 = |e: FieldError| at(e.within("leds"));
                check_range("die_mm", l.die_mm, 0.0, 50.0, "mm").map_err(at2)?;
                if let Some(h) = l.die_height_mm {
                    check_range("die_height_mm", h, 0.0, 50.0, "mm").map_err(at2)?;
                }
                if let Some(d) = l.distance_cm {
                    check_positive("distance_cm", d, "cm").map_err(at2)?;
                }
                match (&l.angles_deg, l.count, l.first_deg, l.last_deg) {
                    (Some(a), None, None, None) if !a.is_empty() && a.len() <= brdf_meter::blob::MAX_LEDS => {
                        for (k, x) in a.iter().enumerate() {
                            check_range(&format!("angles_deg[{k}]"), *x, 0.0, 89.0, "deg").map_err(at2)?;
                        }
                    }
                    (None, Some(n), Some(a), Some(b)) if (1..=brdf_meter::blob::MAX_LEDS).contains(&n) => {
                        check_range("first_deg", a, 0.0, 89.0, "deg").map_err(at2)?;
                        check_range("last_deg", b, 0.0, 89.0, "deg").map_err(at2)?;
                    }
                    _ => {
                        return Err(at2(FieldError::new(
                            "count",
                            format!(
                                "give either `angles_deg` (1..={} angles) or `count` (1..={}), `first_deg` and `last_deg`",
                                brdf_meter::blob::MAX_LEDS,
                                brdf_meter::blob::MAX_LEDS
                            ),
                        )));
                    }
                }
            }
        }
        Ok(())
    }
}

impl Candidate {
    /// The base scene with this candidate's LEDs, gain and exposure.
    pub fn apply(&self, base: &Scene) -> Scene {
        let mut s = base.clone();
        s.name = format!("{} / {}", base.name, self.name);
        if let Some(ring) = &self.leds {
            let first = base.instrument.leds.first();
            let distance = ring.distance_cm.or(first.map(|l| l.distance_cm)).unwrap_or(6.0);
            let die_cm = ring.die_mm / 10.0;
            let height_mm = ring.die_height_mm.unwrap_or(ring.die_mm);
            let samples_of = |mm: f64, pitch: f64| ((mm / pitch).ceil() as usize).clamp(1, 99);
            s.instrument.leds = ring
                .angles()
                .iter()
                .enumerate()
                .map(|(i, a)| LedSpec {
                    name: Some(format!("L{}", i + 1)),
                    centre_deg: *a,
                    distance_cm: distance,
                    azimuth_deg: 0.0,
                    cluster: None,
                    sources: None,
                    extended: (die_cm > 0.0 && height_mm > 0.0).then_some(ExtendedSpec {
                        width_cm: die_cm,
                        height_cm: height_mm / 10.0,
                        samples: [
                            samples_of(ring.die_mm, IN_PLANE_SAMPLE_PITCH_MM),
                            samples_of(height_mm, DIE_SAMPLE_PITCH_MM),
                        ],
                    }),
                    intensity: 1.0,
                    emission: first.and_then(|l| l.emission.clone()),
                })
                .collect();
        }
        if let Some(g) = self.gain {
            s.instrument.sensor.gain = g;
        }
        if let Some(r) = &self.short_exposure {
            s.effects.retain(|e| !matches!(e, EffectSpec::ShortExposure { .. }));
            if !r.is_empty() {
                s.effects.push(EffectSpec::ShortExposure { ratios: r.clone() });
            }
        }
        s
    }
}

/// The built-in candidates: 7, 9, 11 and 13 LEDs from 33 to 57 deg with
/// 3, 4 and 5 mm dies, square and as slits as wide across the plane as the
/// gloss window ([`slit_height_mm`]), at the base's gain, and the same at
/// eight times the gain with shorter exposures of 1/16 and 1/80 for
/// saturated frames.
pub fn builtin(base: &Scene) -> Vec<Candidate> {
    let mut out = Vec::new();
    let g = base.instrument.sensor.gain;
    let distance = base.instrument.leds.first().map_or(6.0, |l| l.distance_cm);
    for (gain, short) in [(None, None), (Some(8.0 * g), Some(vec![16.0, 80.0]))] {
        for count in [7, 9, 11, 13] {
            for die in [3.0, 4.0, 5.0] {
                for height in [None, Some(slit_height_mm(distance))] {
                    out.push(Candidate {
                        name: format!(
                            "{count} x {die}{} mm{}",
                            height.map_or(String::new(), |h| format!(" x {h:.1}")),
                            if gain.is_some() { ", gain x8, short 1/16 1/80" } else { "" }
                        ),
                        leds: Some(LedRing {
                            count: Some(count),
                            first_deg: Some(33.0),
                            last_deg: Some(57.0),
                            angles_deg: None,
                            die_mm: die,
                            die_height_mm: height,
                            distance_cm: None,
                        }),
                        gain,
                        short_exposure: short.clone(),
                    });
                }
            }
        }
    }
    out
}

/// The height across the plane, mm, of a slit `distance_cm` away that spans
/// the 45 deg gloss geometry's receptor across the plane
/// (`forward::brdf::GLOSS_APERTURE_ACROSS_DEG`, 10 deg): by reciprocity an
/// LED's extent plays the receptor's part, so its readings carry a lobe's
/// flux through the gloss window as they carry a mirror's.
pub fn slit_height_mm(distance_cm: f64) -> f64 {
    let half = (crate::forward::brdf::GLOSS_APERTURE_ACROSS_DEG / 2.0).to_radians();
    20.0 * distance_cm * half.tan()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slit_spans_the_gloss_window_at_the_leds_distance() {
        // The handheld's: 10.5 mm at 6 cm.
        assert!((slit_height_mm(6.0) - 10.5).abs() < 0.01, "{}", slit_height_mm(6.0));
        assert!((slit_height_mm(12.0) - 2.0 * slit_height_mm(6.0)).abs() < 1e-12);
    }
}
