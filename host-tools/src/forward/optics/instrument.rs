//! The instrument description (TOML) with the patent profile built in.
use crate::forward::grid::{AngleGrid, GridError, GridSpec};
use crate::output::config::{FieldError, Validate, check_positive, check_range};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// One illumination: a cluster of point sources on a plane facing the point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LedSpec {
    /// Label for reports.
    #[serde(default)]
    pub name: Option<String>,
    /// Incidence angle of the centre source's ray, degrees.
    pub centre_deg: f64,
    /// Distance from the centre source to the measured point, cm.
    pub distance_cm: f64,
    /// Azimuth of the centre source about the normal; 0 = in the plane of
    /// incidence, on the side opposite the viewer.
    #[serde(default)]
    pub azimuth_deg: f64,
    /// Sources as a regular row along the light plane's in-plane axis.
    #[serde(default)]
    pub cluster: Option<ClusterSpec>,
    /// Sources given one by one (instead of `cluster`).
    #[serde(default)]
    pub sources: Option<Vec<SourceSpec>>,
    /// An extended emitter: a uniformly bright rectangle on the light plane,
    /// centred on the centre source (instead of `cluster` or `sources`).
    #[serde(default)]
    pub extended: Option<ExtendedSpec>,
    /// Total relative intensity of the illumination, split over its sources.
    #[serde(default = "one")]
    pub intensity: f64,
    /// Emission profile about the LED's axis (the axis points from the LED's
    /// centre at the measured point). Used only when a scene lists the
    /// `emission-profile` effect; Lambertian when absent.
    #[serde(default)]
    pub emission: Option<EmissionSpec>,
}

/// A uniformly bright rectangular emitter on the light plane, sampled on a
/// regular grid of point sources (midpoint rule).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExtendedSpec {
    /// Size along the light plane's in-plane axis, cm.
    pub width_cm: f64,
    /// Size across the plane of incidence, cm.
    pub height_cm: f64,
    /// Sample points [along the width, along the height].
    pub samples: [usize; 2],
}

/// How an LED's intensity falls off with the angle from its axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "profile", rename_all = "kebab-case", deny_unknown_fields)]
pub enum EmissionSpec {
    /// I(psi) = I0 cos(psi).
    Lambertian {},
    /// I(psi) = I0 cos(psi)^k (k = 1 is Lambertian; large k is a narrow beam).
    CosPower {
        /// Exponent.
        k: f64,
    },
    /// I(psi) tabulated at angles from the axis (degrees, ascending from 0),
    /// linearly interpolated, 0 beyond the last angle.
    Tabulated {
        /// Angles from the axis, degrees.
        angles_deg: Vec<f64>,
        /// Relative intensity at each angle.
        values: Vec<f64>,
    },
}

impl EmissionSpec {
    /// Relative intensity at angle psi from the axis, given cos(psi) (0 behind
    /// the emitter).
    pub fn relative(&self, cos_psi: f64) -> f64 {
        if cos_psi <= 0.0 {
            return 0.0;
        }
        match self {
            EmissionSpec::Lambertian {} => cos_psi,
            EmissionSpec::CosPower { k } => cos_psi.powf(*k),
            EmissionSpec::Tabulated { angles_deg, values } => {
                let psi = cos_psi.min(1.0).acos().to_degrees();
                let last = angles_deg.len() - 1;
                if psi > angles_deg[last] {
                    return 0.0;
                }
                let k = angles_deg.partition_point(|&a| a <= psi).clamp(1, last);
                let (a0, a1) = (angles_deg[k - 1], angles_deg[k]);
                let t = ((psi - a0) / (a1 - a0)).clamp(0.0, 1.0);
                values[k - 1] * (1.0 - t) + values[k] * t
            }
        }
    }

    fn validate(&self) -> Result<(), FieldError> {
        match self {
            EmissionSpec::Lambertian {} => Ok(()),
            EmissionSpec::CosPower { k } => check_range("k", *k, 0.0, 1e4, ""),
            EmissionSpec::Tabulated { angles_deg, values } => {
                if angles_deg.len() < 2 || angles_deg.len() != values.len() {
                    return Err(FieldError::new("values", "give at least two angles and exactly one value per angle"));
                }
                if angles_deg[0] != 0.0 {
                    return Err(FieldError::new("angles_deg", "the table must start on the axis, at 0 deg"));
                }
                for (i, w) in angles_deg.windows(2).enumerate() {
                    if w[1] <= w[0] || w[1].is_nan() || w[1] > 90.0 {
                        return Err(FieldError::new(
                            format!("angles_deg[{}]", i + 1),
                            "angles must ascend strictly, up to 90 deg",
                        ));
                    }
                }
                for (i, v) in values.iter().enumerate() {
                    check_range(&format!("values[{i}]"), *v, 0.0, 1e6, "")?;
                }
                if values[0] <= 0.0 {
                    return Err(FieldError::new("values[0]", "the on-axis intensity must be > 0"));
                }
                Ok(())
            }
        }
    }
}

/// A regular row of equal point sources, centred on the centre source.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClusterSpec {
    /// Number of sources.
    pub count: usize,
    /// Spacing, cm.
    pub pitch_cm: f64,
}

/// One point source on the light plane.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SourceSpec {
    /// Offset from the centre source on the light plane, cm: [in the plane of
    /// incidence, perpendicular to it].
    pub offset_cm: [f64; 2],
    /// Relative intensity.
    #[serde(default = "one")]
    pub intensity: f64,
}

fn one() -> f64 {
    1.0
}

/// Which way the line of pixels runs on the surface.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LineAxis {
    /// Along the instrument's x axis, in the plane of incidence (incidence
    /// angles change along the line).
    #[default]
    X,
    /// Across the plane of incidence (azimuths change along the line; needs
    /// the `3d-geometry` effect to show).
    Y,
}

/// The line sensor: its pixels, the points they see, its converter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorSpec {
    /// Pixels P read out; pixel k sees the surface point
    /// `(first_pixel + k - (line_pixels - 1) / 2) * pitch / magnification`
    /// from the centre point.
    #[serde(default = "one_usize")]
    pub pixels: usize,
    /// First pixel read out of the sensor's line (a window of it, as a
    /// simulated device with fewer pixels reads a cut of the line).
    #[serde(default)]
    pub first_pixel: usize,
    /// Pixels of the whole line (default: `pixels`).
    #[serde(default)]
    pub line_pixels: Option<usize>,
    /// Pixel pitch on the sensor, micrometres.
    #[serde(default = "default_pitch")]
    pub pitch_um: f64,
    /// Optical magnification (image size / object size).
    #[serde(default = "one")]
    pub magnification: f64,
    /// Direction of the line on the surface.
    #[serde(default)]
    pub line_axis: LineAxis,
    /// Largest raw count (the `saturation` effect clips there).
    #[serde(default = "default_full_scale")]
    pub full_scale: f64,
    /// Counts per unit of irradiance-weighted reflectance factor: a perfect
    /// diffuser lit along the normal by an illumination of intensity 1 at its
    /// nominal distance reads `gain` counts above dark.
    #[serde(default = "default_gain")]
    pub gain: f64,
}

fn one_usize() -> usize {
    1
}
fn default_pitch() -> f64 {
    63.5
}
fn default_full_scale() -> f64 {
    4095.0
}
fn default_gain() -> f64 {
    1000.0
}

impl Default for SensorSpec {
    fn default() -> Self {
        Self {
            pixels: 1,
            first_pixel: 0,
            line_pixels: None,
            pitch_um: default_pitch(),
            magnification: 1.0,
            line_axis: LineAxis::X,
            full_scale: default_full_scale(),
            gain: default_gain(),
        }
    }
}

impl SensorSpec {
    /// Offset along the line of (possibly fractional) pixel `p` from the
    /// centre point, cm.
    pub fn offset_cm(&self, p: f64) -> f64 {
        let line = self.line_pixels.unwrap_or(self.pixels) as f64;
        (self.first_pixel as f64 + p - (line - 1.0) / 2.0) * self.pitch_um * 1e-4 / self.magnification
    }

    /// A window of `pixels` pixels from `first` of this sensor's line.
    pub fn window(&self, first: usize, pixels: usize) -> Self {
        let line = self.line_pixels.unwrap_or(self.pixels);
        Self { pixels, first_pixel: self.first_pixel + first, line_pixels: Some(line), ..self.clone() }
    }
}

/// The measured point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointSpec {
    /// Position, cm, in the instrument frame (the patent point is the origin).
    #[serde(default)]
    pub position_cm: [f64; 3],
    /// Surface normal (need not be unit length).
    #[serde(default = "up")]
    pub normal: [f64; 3],
}

fn up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

impl Default for PointSpec {
    fn default() -> Self {
        Self { position_cm: [0.0; 3], normal: up() }
    }
}

/// The instrument: illuminations, the point, the view and the angle grid.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Instrument {
    /// Name for reports.
    #[serde(default)]
    pub name: String,
    /// View angle, degrees, on the opposite side of the normal from the LEDs.
    pub view_deg: f64,
    /// Distance from the viewer (the lens) to the centre point, cm; absent
    /// means telecentric (every pixel views along `view_deg`). Used with the
    /// `per-pixel-geometry` effect.
    #[serde(default)]
    pub view_distance_cm: Option<f64>,
    /// The line sensor (default: one pixel seeing the centre point).
    #[serde(default)]
    pub sensor: SensorSpec,
    /// Incidence-angle grid of the BRDF vector.
    pub grid: GridSpec,
    /// The measured point.
    #[serde(default)]
    pub point: PointSpec,
    /// The illuminations, in firing order.
    pub leds: Vec<LedSpec>,
    /// The sensor's spectral weighting of R, G, B (measured RGB BRDFs are
    /// seen as their weighted sum); default: luminance (0.2126, 0.7152, 0.0722).
    #[serde(default = "luminance")]
    pub spectral_weights: [f64; 3],
}

fn luminance() -> [f64; 3] {
    crate::forward::brdf::nbrdf::LUMINANCE
}

impl Instrument {
    /// The patent profile (method.md): 7 illuminations with centre rays at
    /// 33..57 deg, each 5 sources 0.17 cm apart on a plane facing the point,
    /// centre 10 cm away; view at 45 deg; grid 25..65 deg in 0.5 deg steps.
    pub fn patent_profile() -> Self {
        let leds = (0..7)
            .map(|i| LedSpec {
                name: Some(format!("L{}", i + 1)),
                centre_deg: 33.0 + 4.0 * i as f64,
                distance_cm: 10.0,
                azimuth_deg: 0.0,
                cluster: Some(ClusterSpec { count: 5, pitch_cm: 0.17 }),
                sources: None,
                extended: None,
                intensity: 1.0,
                emission: None,
            })
            .collect();
        Self {
            name: "patent-profile".into(),
            view_deg: 45.0,
            view_distance_cm: None,
            sensor: SensorSpec::default(),
            grid: GridSpec::patent(),
            point: PointSpec::default(),
            leds,
            spectral_weights: luminance(),
        }
    }

    /// Number of illuminations m.
    pub fn m(&self) -> usize {
        self.leds.len()
    }

    /// The angle grid.
    pub fn grid(&self) -> Result<AngleGrid, GridError> {
        AngleGrid::new(&self.grid)
    }

    /// Centre-ray incidence angles, degrees.
    pub fn centre_angles_deg(&self) -> Vec<f64> {
        self.leds.iter().map(|l| l.centre_deg).collect()
    }

    /// Unit normal of the measured point.
    pub fn normal(&self) -> Vector3<f64> {
        Vector3::from(self.point.normal).normalize()
    }

    /// Unit direction from the point towards the viewer, in the instrument
    /// frame (the viewer is in the x-z plane on the +x side).
    pub fn view_dir(&self) -> Vector3<f64> {
        let t = self.view_deg.to_radians();
        Vector3::new(t.sin(), 0.0, t.cos())
    }

    /// Number of pixels P.
    pub fn pixels(&self) -> usize {
        self.sensor.pixels
    }

    /// The point sources of illumination `led` in 3-D: (position in cm,
    /// intensity), intensities summing to the LED's `intensity`.
    pub fn sources(&self, led: usize) -> Vec<(Vector3<f64>, f64)> {
        self.sources_with(led, true)
    }

    /// Unit direction from the centre point towards LED `led`'s centre, in the
    /// instrument frame. Without 3-D geometry the azimuth is ignored (every
    /// LED in the plane of incidence).
    pub fn led_direction(&self, led: usize, three_d: bool) -> Vector3<f64> {
        let l = &self.leds[led];
        let t = l.centre_deg.to_radians();
        let p = if three_d { l.azimuth_deg.to_radians() } else { 0.0 };
        Vector3::new(-t.sin() * p.cos(), -t.sin() * p.sin(), t.cos())
    }

    /// Position of LED `led`'s centre, cm, instrument frame.
    pub fn led_centre(&self, led: usize, three_d: bool) -> Vector3<f64> {
        Vector3::from(self.point.position_cm) + self.led_direction(led, three_d) * self.leds[led].distance_cm
    }

    /// The point sources of illumination `led`: (position in cm, intensity),
    /// intensities summing to the LED's `intensity`. Without 3-D geometry the
    /// LED lies in the plane of incidence and offsets across it are dropped.
    pub fn sources_with(&self, led: usize, three_d: bool) -> Vec<(Vector3<f64>, f64)> {
        let l = &self.leds[led];
        let t = l.centre_deg.to_radians();
        let p = if three_d { l.azimuth_deg.to_radians() } else { 0.0 };
        // Centre direction: on the -x side at azimuth 0, rotated about z by p.
        let rot = |v: Vector3<f64>| Vector3::new(v.x * p.cos() - v.y * p.sin(), v.x * p.sin() + v.y * p.cos(), v.z);
        let dir = rot(Vector3::new(-t.sin(), 0.0, t.cos()));
        // The light plane faces the point: its axes are perpendicular to dir,
        // one in the plane of incidence (u), one across it (v).
        let u = rot(Vector3::new(t.cos(), 0.0, t.sin()));
        let v = dir.cross(&u);
        let centre = Vector3::from(self.point.position_cm) + dir * l.distance_cm;
        let mut offsets: Vec<([f64; 2], f64)> = match (&l.cluster, &l.sources, &l.extended) {
            (Some(c), _, _) => {
                (0..c.count).map(|k| ([(k as f64 - (c.count as f64 - 1.0) / 2.0) * c.pitch_cm, 0.0], 1.0)).collect()
            }
            (None, Some(s), _) => s.iter().map(|s| (s.offset_cm, s.intensity)).collect(),
            (None, None, Some(e)) => {
                let (nu, nv) = (e.samples[0], if three_d { e.samples[1] } else { 1 });
                let mut out = Vec::with_capacity(nu * nv);
                for a in 0..nu {
                    for b in 0..nv {
                        let x = ((a as f64 + 0.5) / nu as f64 - 0.5) * e.width_cm;
                        let y = if three_d { ((b as f64 + 0.5) / nv as f64 - 0.5) * e.height_cm } else { 0.0 };
                        out.push(([x, y], 1.0));
                    }
                }
                out
            }
            (None, None, None) => vec![([0.0, 0.0], 1.0)],
        };
        if !three_d {
            for o in &mut offsets {
                o.0[1] = 0.0;
            }
        }
        let total: f64 = offsets.iter().map(|o| o.1).sum();
        offsets.into_iter().map(|(o, i)| (centre + u * o[0] + v * o[1], l.intensity * i / total)).collect()
    }
}

impl Validate for Instrument {
    fn validate(&self) -> Result<(), FieldError> {
        check_range("view_deg", self.view_deg, 0.0, 89.999, "deg")?;
        AngleGrid::new(&self.grid).map_err(|e| FieldError::new("grid", e.to_string()))?;
        let n = self.point.normal;
        if !n.iter().all(|x| x.is_finite()) || n.iter().map(|x| x * x).sum::<f64>() < 1e-24 {
            return Err(FieldError::new("point.normal", "must be a finite, non-zero vector"));
        }
        if !self.point.position_cm.iter().all(|x| x.is_finite()) {
            return Err(FieldError::new("point.position_cm", "must be finite"));
        }
        if !self.spectral_weights.iter().all(|w| w.is_finite() && *w >= 0.0)
            || self.spectral_weights.iter().sum::<f64>() <= 0.0
        {
            return Err(FieldError::new("spectral_weights", "must be three finite weights >= 0 with a positive sum"));
        }
        if self.leds.is_empty() {
            return Err(FieldError::new("leds", "at least one illumination is needed"));
        }
        if self.leds.len() > brdf_meter::blob::MAX_LEDS {
            return Err(FieldError::new(
                "leds",
                format!("at most {} illuminations are supported", brdf_meter::blob::MAX_LEDS),
            ));
        }
        if let Some(d) = self.view_distance_cm {
            check_positive("view_distance_cm", d, "cm")?;
        }
        let s = &self.sensor;
        let at_s = |e: FieldError| e.within("sensor");
        if s.pixels == 0 || s.pixels > brdf_meter::blob::MAX_PIXELS {
            return Err(at_s(FieldError::new(
                "pixels",
                format!("{} is impossible; allowed 1..={}", s.pixels, brdf_meter::blob::MAX_PIXELS),
            )));
        }
        if let Some(l) = s.line_pixels
            && s.first_pixel + s.pixels > l
        {
            return Err(at_s(FieldError::new(
                "first_pixel",
                format!(
                    "pixels {}..{} are outside the line of {l} (line_pixels)",
                    s.first_pixel,
                    s.first_pixel + s.pixels
                ),
            )));
        }
        if s.line_pixels.is_none() && s.first_pixel > 0 {
            return Err(at_s(FieldError::new(
                "line_pixels",
                "a window (first_pixel > 0) needs the whole line's line_pixels",
            )));
        }
        check_positive("pitch_um", s.pitch_um, "um").map_err(at_s)?;
        check_positive("magnification", s.magnification, "").map_err(at_s)?;
        check_range("full_scale", s.full_scale, 1.0, 65535.0, "counts (a u16 converter)").map_err(at_s)?;
        check_range("gain", s.gain, 1e-12, 1e12, "counts").map_err(at_s)?;
        for (i, l) in self.leds.iter().enumerate() {
            let at = |e: FieldError| e.within(&format!("leds[{i}]"));
            check_range("centre_deg", l.centre_deg, 0.0, 89.999, "deg").map_err(at)?;
            check_positive("distance_cm", l.distance_cm, "cm").map_err(at)?;
            check_range("azimuth_deg", l.azimuth_deg, -180.0, 180.0, "deg").map_err(at)?;
            check_range("intensity", l.intensity, 1e-12, 1e12, "").map_err(at)?;
            if let Some(e) = &l.emission {
                e.validate().map_err(|e| at(e.within("emission")))?;
            }
            let given = [l.cluster.is_some(), l.sources.is_some(), l.extended.is_some()].iter().filter(|x| **x).count();
            if given > 1 {
                let field = if l.extended.is_some() { "extended" } else { "sources" };
                return Err(at(FieldError::new(field, "give one of `cluster`, `sources` or `extended`, not several")));
            }
            if let Some(e) = &l.extended {
                let at2 = |x: FieldError| at(x.within("extended"));
                check_range("width_cm", e.width_cm, 0.0, l.distance_cm, "cm (not beyond the distance)").map_err(at2)?;
                check_range("height_cm", e.height_cm, 0.0, l.distance_cm, "cm (not beyond the distance)")
                    .map_err(at2)?;
                if e.samples[0] == 0 || e.samples[1] == 0 || e.samples[0] * e.samples[1] > 10_000 {
                    return Err(at2(FieldError::new("samples", "each count must be >= 1 and their product <= 10000")));
                }
            }
            match (&l.cluster, &l.sources) {
                (Some(_), Some(_)) => unreachable!("refused above"),
                (Some(c), None) => {
                    if c.count == 0 {
                        return Err(at(FieldError::new("cluster.count", "must be at least 1")));
                    }
                    check_range("cluster.pitch_cm", c.pitch_cm, 0.0, l.distance_cm, "cm (not beyond the distance)")
                        .map_err(at)?;
                }
                (None, Some(s)) => {
                    if s.is_empty() {
                        return Err(at(FieldError::new("sources", "at least one source is needed")));
                    }
                    for (k, s) in s.iter().enumerate() {
                        let at2 = |e: FieldError| at(e.within(&format!("sources[{k}]")));
                        check_positive("intensity", s.intensity, "").map_err(at2)?;
                        for x in s.offset_cm {
                            check_range("offset_cm", x, -l.distance_cm, l.distance_cm, "cm").map_err(at2)?;
                        }
                    }
                }
                (None, None) => {}
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::config::parse_toml;

    #[test]
    fn patent_profile_survives_a_toml_round_trip_and_validates() {
        let p = Instrument::patent_profile();
        p.validate().unwrap();
        let text = toml::to_string(&p).unwrap();
        let back: Instrument = parse_toml(&text, "roundtrip").unwrap();
        assert_eq!(back, p);
    }

    #[test]
    fn centre_source_sits_at_the_centre_angle_and_distance() {
        let p = Instrument::patent_profile();
        let s = p.sources(2);
        assert_eq!(s.len(), 5);
        let c = s[2].0;
        assert!((c.norm() - 10.0).abs() < 1e-12);
        assert!((c.z.atan2(-c.x).to_degrees() - (90.0 - 41.0)).abs() < 1e-9);
        // Neighbours are 0.17 cm apart, on a plane perpendicular to the centre ray.
        assert!(((s[3].0 - s[2].0).norm() - 0.17).abs() < 1e-12);
        assert!((s[3].0 - s[2].0).dot(&c).abs() < 1e-12);
    }

    #[test]
    fn emission_profiles_fall_off_as_stated_and_bad_tables_are_refused() {
        let c = 60f64.to_radians().cos();
        assert!((EmissionSpec::Lambertian {}.relative(c) - 0.5).abs() < 1e-12);
        assert!((EmissionSpec::CosPower { k: 3.0 }.relative(c) - 0.125).abs() < 1e-12);
        let t = EmissionSpec::Tabulated { angles_deg: vec![0.0, 30.0, 60.0], values: vec![1.0, 0.8, 0.2] };
        assert!((t.relative(45f64.to_radians().cos()) - 0.5).abs() < 1e-9);
        assert_eq!(t.relative(70f64.to_radians().cos()), 0.0);
        assert_eq!(EmissionSpec::Lambertian {}.relative(-0.1), 0.0);
        let mut p = Instrument::patent_profile();
        p.leds[2].emission = Some(EmissionSpec::Tabulated { angles_deg: vec![5.0, 30.0], values: vec![1.0, 0.5] });
        assert_eq!(p.validate().unwrap_err().path, "leds[2].emission.angles_deg");
        p.leds[2].emission =
            Some(EmissionSpec::Tabulated { angles_deg: vec![0.0, 30.0, 20.0], values: vec![1.0, 0.5, 0.1] });
        assert_eq!(p.validate().unwrap_err().path, "leds[2].emission.angles_deg[2]");
    }

    #[test]
    fn extended_emitters_spread_the_intensity_over_their_samples() {
        let mut p = Instrument::patent_profile();
        p.leds[0].cluster = None;
        p.leds[0].extended = Some(ExtendedSpec { width_cm: 0.4, height_cm: 0.2, samples: [4, 3] });
        p.leds[0].intensity = 2.0;
        p.validate().unwrap();
        let s = p.sources_with(0, true);
        assert_eq!(s.len(), 12);
        assert!((s.iter().map(|x| x.1).sum::<f64>() - 2.0).abs() < 1e-12);
        // Samples are midpoints: the outermost sit 3/8 of the width off centre.
        let c = p.led_centre(0, true);
        let far = s.iter().map(|x| (x.0 - c).norm()).fold(0.0, f64::max);
        assert!((far - (0.15f64.powi(2) + (0.2f64 / 3.0).powi(2)).sqrt()).abs() < 1e-12, "{far}");
        assert_eq!(p.sources_with(0, false).len(), 4);
        p.leds[0].cluster = Some(ClusterSpec { count: 2, pitch_cm: 0.1 });
        assert_eq!(p.validate().unwrap_err().path, "leds[0].extended");
    }

    #[test]
    fn impossible_led_values_are_refused_with_their_path() {
        let mut p = Instrument::patent_profile();
        p.leds[3].distance_cm = 0.0;
        assert_eq!(p.validate().unwrap_err().path, "leds[3].distance_cm");
        let mut p = Instrument::patent_profile();
        p.leds[1].centre_deg = 95.0;
        assert_eq!(p.validate().unwrap_err().path, "leds[1].centre_deg");
    }
}
