//! The rays of one illumination that reach the measured point.
use super::{EmissionSpec, Instrument};
use nalgebra::{Matrix3, Vector3};

/// One ray arriving at the point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Unit direction from the point towards the source, surface frame (z = normal).
    pub dir: Vector3<f64>,
    /// Incidence angle (between the ray and the normal), degrees.
    pub theta_deg: f64,
    /// Irradiance weight, normalised over the illumination (sums to 1).
    pub weight: f64,
}

/// Rotation taking the instrument frame to the surface frame of the point
/// (normal -> z, the instrument's x axis projected on the surface -> x).
pub fn surface_frame(normal: &Vector3<f64>) -> Matrix3<f64> {
    let n = normal.normalize();
    let x = Vector3::x();
    let mut t = x - n * n.dot(&x);
    if t.norm() < 1e-9 {
        t = Vector3::y() - n * n.dot(&Vector3::y());
    }
    let t = t.normalize();
    let b = n.cross(&t);
    Matrix3::from_rows(&[t.transpose(), b.transpose(), n.transpose()])
}

/// Which geometric effects the rays model. Each flag that is off is not
/// computed at all (no per-source positions for far field, no emission
/// lookup, no distance for the inverse square).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayModel {
    /// One ray per point source of the LED (otherwise one ray per LED along
    /// its nominal direction: far field).
    pub near_field: bool,
    /// LED azimuths and offsets across the plane of incidence (otherwise
    /// everything is in the plane of incidence).
    pub three_d: bool,
    /// Irradiance falls as (d / r)^2, d the LED's nominal distance.
    pub inverse_square: bool,
    /// The LED's emission profile about its axis (otherwise isotropic).
    pub emission_profile: bool,
}

impl RayModel {
    /// The model of the original optics: near or far field, 3-D, inverse
    /// square, isotropic sources.
    pub fn legacy(far_field: bool) -> Self {
        Self { near_field: !far_field, three_d: true, inverse_square: true, emission_profile: false }
    }
}

struct PreparedLed {
    /// Unit direction from the centre point to the LED, instrument frame.
    nominal: Vector3<f64>,
    /// LED centre, cm.
    centre: Vector3<f64>,
    /// Unit axis from the LED towards the centre point.
    axis: Vector3<f64>,
    distance: f64,
    intensity: f64,
    /// Point sources; built only for near field.
    sources: Vec<(Vector3<f64>, f64)>,
    /// Built only when the emission profile is modelled.
    emission: Option<EmissionSpec>,
}

/// The instrument's optics prepared once for a ray model: the one place that
/// makes rays. Weights are absolute irradiances (intensity x cos(theta) x
/// the modelled factors), not normalised.
pub struct Optics {
    model: RayModel,
    frame: Matrix3<f64>,
    leds: Vec<PreparedLed>,
}

impl Optics {
    /// Prepares `inst` for `model`.
    pub fn new(inst: &Instrument, model: RayModel) -> Self {
        let leds = (0..inst.m())
            .map(|led| {
                let l = &inst.leds[led];
                let nominal = inst.led_direction(led, model.three_d);
                PreparedLed {
                    nominal,
                    centre: inst.led_centre(led, model.three_d),
                    axis: -nominal,
                    distance: l.distance_cm,
                    intensity: l.intensity,
                    sources: if model.near_field { inst.sources_with(led, model.three_d) } else { Vec::new() },
                    emission: if model.emission_profile {
                        Some(l.emission.clone().unwrap_or(EmissionSpec::Lambertian {}))
                    } else {
                        None
                    },
                }
            })
            .collect();
        Self { model, frame: surface_frame(&inst.normal()), leds }
    }

    /// The ray model.
    pub fn model(&self) -> RayModel {
        self.model
    }

    /// Point sources prepared over all LEDs (0 in far field, where none are built).
    pub fn sources_built(&self) -> usize {
        self.leds.iter().map(|l| l.sources.len()).sum()
    }

    /// Number of LEDs.
    pub fn m(&self) -> usize {
        self.leds.len()
    }

    /// Instrument frame -> surface frame.
    pub fn frame(&self) -> &Matrix3<f64> {
        &self.frame
    }

    /// Calls `f` for every ray of LED `led` reaching `point` (cm, instrument
    /// frame). Rays from behind the surface are skipped.
    pub fn for_each_ray(&self, led: usize, point: &Vector3<f64>, mut f: impl FnMut(Ray)) {
        let l = &self.leds[led];
        let mut one = |src: &Vector3<f64>, dir_inst: Vector3<f64>, intensity: f64| {
            let dir = self.frame * dir_inst;
            let cos = dir.z;
            if cos <= 0.0 {
                return;
            }
            let mut w = intensity * cos;
            if self.model.inverse_square || self.model.emission_profile {
                let to_point = point - src;
                let r2 = to_point.norm_squared();
                if self.model.inverse_square {
                    w *= l.distance * l.distance / r2;
                }
                if let Some(e) = &l.emission {
                    w *= e.relative(to_point.dot(&l.axis) / r2.sqrt());
                }
            }
            f(Ray { dir, theta_deg: cos.clamp(-1.0, 1.0).acos().to_degrees(), weight: w });
        };
        if self.model.near_field {
            for (pos, intensity) in &l.sources {
                let to = pos - point;
                let norm = to.norm();
                one(pos, to / norm, *intensity);
            }
        } else {
            one(&l.centre, l.nominal, l.intensity);
        }
    }

    /// The rays of LED `led` at `point`, absolute weights.
    pub fn rays_at(&self, led: usize, point: &Vector3<f64>) -> Vec<Ray> {
        let mut out = Vec::new();
        self.for_each_ray(led, point, |r| out.push(r));
        out
    }
}

/// The rays of illumination `led` at the point. Near field: one ray per point
/// source, weighted by I cos(theta) / r^2. Far field (condition 1's view of
/// the world): a single ray along the centre direction. Weights are
/// normalised to sum to 1; sources behind the surface contribute nothing.
/// (The original optics; a scene's optics use [`Optics`] with its own model.)
pub fn rays(inst: &Instrument, led: usize, far_field: bool) -> Vec<Ray> {
    let optics = Optics::new(inst, RayModel::legacy(far_field));
    let mut out = optics.rays_at(led, &Vector3::from(inst.point.position_cm));
    let total: f64 = out.iter().map(|r| r.weight).sum();
    if total > 0.0 {
        for r in &mut out {
            r.weight /= total;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_field_rays_spread_around_the_centre_angle() {
        let p = Instrument::patent_profile();
        let r = rays(&p, 0, false);
        assert_eq!(r.len(), 5);
        let sum: f64 = r.iter().map(|r| r.weight).sum();
        assert!((sum - 1.0).abs() < 1e-12);
        let spread = r.iter().map(|r| (r.theta_deg - 33.0).abs()).fold(0.0, f64::max);
        // Outer sources are 0.34 cm off a 10 cm ray: ~1.95 deg.
        assert!((spread - (0.34f64 / 10.0).atan().to_degrees()).abs() < 1e-9, "{spread}");
        // Closer to grazing, cos(theta) falls: the ray nearer the normal weighs more.
        let (lo, hi) = (
            r.iter().min_by(|a, b| a.theta_deg.total_cmp(&b.theta_deg)).unwrap(),
            r.iter().max_by(|a, b| a.theta_deg.total_cmp(&b.theta_deg)).unwrap(),
        );
        assert!(lo.weight > hi.weight);
    }

    #[test]
    fn far_field_is_one_ray_at_the_centre_angle() {
        let p = Instrument::patent_profile();
        for led in 0..p.m() {
            let r = rays(&p, led, true);
            assert_eq!(r.len(), 1);
            assert!((r[0].theta_deg - p.leds[led].centre_deg).abs() < 1e-9);
            assert_eq!(r[0].weight, 1.0);
        }
    }

    #[test]
    fn tilted_normal_changes_the_incidence_angles() {
        let mut p = Instrument::patent_profile();
        let tilt = 5f64.to_radians();
        p.point.normal = [-tilt.sin(), 0.0, tilt.cos()]; // towards the LEDs
        let r = rays(&p, 3, true);
        assert!((r[0].theta_deg - 40.0).abs() < 1e-9, "{}", r[0].theta_deg);
    }
}
