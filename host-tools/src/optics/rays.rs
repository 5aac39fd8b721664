//! The rays of one illumination that reach the measured point.
use super::Instrument;
use nalgebra::Vector3;

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
pub(super) fn surface_frame(normal: &Vector3<f64>) -> nalgebra::Matrix3<f64> {
    let n = normal.normalize();
    let x = Vector3::x();
    let mut t = x - n * n.dot(&x);
    if t.norm() < 1e-9 {
        t = Vector3::y() - n * n.dot(&Vector3::y());
    }
    let t = t.normalize();
    let b = n.cross(&t);
    nalgebra::Matrix3::from_rows(&[t.transpose(), b.transpose(), n.transpose()])
}

/// The rays of illumination `led` at the point. Near field: one ray per point
/// source, weighted by I cos(theta) / r^2. Far field (condition 1's view of
/// the world): a single ray along the centre direction. Weights are
/// normalised to sum to 1; sources behind the surface contribute nothing.
pub fn rays(inst: &Instrument, led: usize, far_field: bool) -> Vec<Ray> {
    let frame = surface_frame(&inst.normal());
    let p = Vector3::from(inst.point.position_cm);
    let l = &inst.leds[led];
    let mut out: Vec<Ray> = if far_field {
        let (t, a) = (l.centre_deg.to_radians(), l.azimuth_deg.to_radians());
        let d = Vector3::new(-t.sin() * a.cos(), -t.sin() * a.sin(), t.cos());
        let dir = (frame * d).normalize();
        vec![Ray { dir, theta_deg: dir.z.clamp(-1.0, 1.0).acos().to_degrees(), weight: 1.0 }]
    } else {
        inst.sources(led)
            .into_iter()
            .filter_map(|(pos, intensity)| {
                let to = pos - p;
                let r2 = to.norm_squared();
                let dir = frame * (to / r2.sqrt());
                let cos = dir.z;
                (cos > 0.0).then(|| Ray { dir, theta_deg: cos.clamp(-1.0, 1.0).acos().to_degrees(), weight: intensity * cos / r2 })
            })
            .collect()
    };
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
        let (lo, hi) = (r.iter().min_by(|a, b| a.theta_deg.total_cmp(&b.theta_deg)).unwrap(), r.iter().max_by(|a, b| a.theta_deg.total_cmp(&b.theta_deg)).unwrap());
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
