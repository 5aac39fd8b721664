//! The instrument description (TOML) with the patent profile built in.
use crate::config::{FieldError, Validate, check_positive, check_range};
use crate::grid::{AngleGrid, GridError, GridSpec};
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
    pub name: String,
    /// View angle, degrees, on the opposite side of the normal from the LEDs.
    pub view_deg: f64,
    /// Incidence-angle grid of the BRDF vector.
    pub grid: GridSpec,
    /// The measured point.
    #[serde(default)]
    pub point: PointSpec,
    /// The illuminations, in firing order.
    pub leds: Vec<LedSpec>,
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
            })
            .collect();
        Self { name: "patent-profile".into(), view_deg: 45.0, grid: GridSpec::patent(), point: PointSpec::default(), leds }
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

    /// The point sources of illumination `led`: (position in cm, intensity).
    pub fn sources(&self, led: usize) -> Vec<(Vector3<f64>, f64)> {
        let l = &self.leds[led];
        let (t, p) = (l.centre_deg.to_radians(), l.azimuth_deg.to_radians());
        // Centre direction: on the -x side at azimuth 0, rotated about z by p.
        let rot = |v: Vector3<f64>| Vector3::new(v.x * p.cos() - v.y * p.sin(), v.x * p.sin() + v.y * p.cos(), v.z);
        let dir = rot(Vector3::new(-t.sin(), 0.0, t.cos()));
        // The light plane faces the point: its axes are perpendicular to dir,
        // one in the plane of incidence (u), one across it (v).
        let u = rot(Vector3::new(t.cos(), 0.0, t.sin()));
        let v = dir.cross(&u);
        let centre = Vector3::from(self.point.position_cm) + dir * l.distance_cm;
        let offsets: Vec<([f64; 2], f64)> = match (&l.cluster, &l.sources) {
            (Some(c), _) => (0..c.count)
                .map(|k| ([(k as f64 - (c.count as f64 - 1.0) / 2.0) * c.pitch_cm, 0.0], 1.0))
                .collect(),
            (None, Some(s)) => s.iter().map(|s| (s.offset_cm, s.intensity)).collect(),
            (None, None) => vec![([0.0, 0.0], 1.0)],
        };
        offsets.into_iter().map(|(o, i)| (centre + u * o[0] + v * o[1], i)).collect()
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
        if self.leds.is_empty() {
            return Err(FieldError::new("leds", "at least one illumination is needed"));
        }
        if self.leds.len() > brdf_meter::blob::MAX_LEDS {
            return Err(FieldError::new("leds", format!("at most {} illuminations are supported", brdf_meter::blob::MAX_LEDS)));
        }
        for (i, l) in self.leds.iter().enumerate() {
            let at = |e: FieldError| e.within(&format!("leds[{i}]"));
            check_range("centre_deg", l.centre_deg, 0.0, 89.999, "deg").map_err(at)?;
            check_positive("distance_cm", l.distance_cm, "cm").map_err(at)?;
            check_range("azimuth_deg", l.azimuth_deg, -180.0, 180.0, "deg").map_err(at)?;
            match (&l.cluster, &l.sources) {
                (Some(_), Some(_)) => return Err(at(FieldError::new("sources", "give either `cluster` or `sources`, not both"))),
                (Some(c), None) => {
                    if c.count == 0 {
                        return Err(at(FieldError::new("cluster.count", "must be at least 1")));
                    }
                    check_range("cluster.pitch_cm", c.pitch_cm, 0.0, l.distance_cm, "cm (not beyond the distance)").map_err(at)?;
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
    use crate::config::parse_toml;

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
    fn impossible_led_values_are_refused_with_their_path() {
        let mut p = Instrument::patent_profile();
        p.leds[3].distance_cm = 0.0;
        assert_eq!(p.validate().unwrap_err().path, "leds[3].distance_cm");
        let mut p = Instrument::patent_profile();
        p.leds[1].centre_deg = 95.0;
        assert_eq!(p.validate().unwrap_err().path, "leds[1].centre_deg");
    }
}
