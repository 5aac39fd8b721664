//! A material whose lobe is wider across the plane of incidence than the
//! material as measured, and exactly the same in the plane.
//!
//! An isotropic microfacet lobe seen at 45 deg is `cos 45 deg`, about 0.7,
//! as wide across the plane of incidence as along it: tilting the light
//! across the plane moves the half vector by `1 / (2 cos theta_d)` of the
//! tilt, along it by a half. Most measured materials follow that (the MERL
//! set's glossy lobes, 0.65-0.75), but woven, brushed and effect-pigment
//! finishes do not: measured sets hold lobes as wide across the plane as
//! along it, and up to three times as wide (satins, pearlescent and
//! colour-shifting paints). An instrument whose LEDs reach across the plane
//! (the handheld's facets span 10 deg across it, the gloss window's
//! width) reads a lobe's flux across the plane, not its in-plane height, so
//! a prior that only knows the 0.7 of isotropic lobes reads such a surface's
//! in-plane peak two to three times too high. A prior therefore also holds
//! each material stretched across the plane
//! (`crate::forward::prior_models::PriorModels::variants`).
//!
//! The stretch divides the component across the plane (y) of both
//! directions by `s` before the material is evaluated: in-plane directions
//! are unchanged, so the material's in-plane values (an instrument's truth)
//! are exactly the original's, and a direction tilted across the plane by
//! a small angle is evaluated at `1/s` of that tilt, so the lobe is `s`
//! times as wide across. The same map on both directions keeps the pair's
//! reciprocity. The lobe's flux grows with its width (about `s` times), so
//! a bright glossy material stretched three times may reflect more than it
//! receives: as a prior sample it is a shape of lobe to learn, which the
//! scale-free estimators scale by the readings, not a physical material. A
//! mirror spike is a spike whichever way it is stretched and is kept.
//!
//! "Across the plane" is the frame's y axis: every pixel's plane of
//! incidence is the x-z plane when the line runs along x (the handheld's,
//! and the default). A line along y with 3-D geometry tilts the off-centre
//! pixels' planes, and there a stretch is partly along their plane: their
//! truth is then the stretched material's own, no longer the original's.
use super::Brdf;
use nalgebra::Vector3;
use std::sync::Arc;

/// `inner` with its lobe `s` times as wide across the plane of incidence.
#[derive(Debug)]
pub struct Stretched {
    inner: Arc<dyn Brdf>,
    inverse: f64,
}

impl Stretched {
    /// `inner` stretched `s` (> 0) times across the plane.
    pub fn new(inner: Arc<dyn Brdf>, s: f64) -> Self {
        assert!(s > 0.0 && s.is_finite(), "stretch across the plane {s} must be positive");
        Self { inner, inverse: 1.0 / s }
    }
}

impl Brdf for Stretched {
    fn f_r(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> f64 {
        let squeeze = |w: &Vector3<f64>| Vector3::new(w.x, w.y * self.inverse, w.z).normalize();
        self.inner.f_r(&squeeze(wi), &squeeze(wo))
    }

    fn mirror_reflectance(&self, theta_deg: f64) -> f64 {
        self.inner.mirror_reflectance(theta_deg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::{Ward, light_dir, view_dir};

    /// The light at incidence 45 deg tilted across the plane by `deg`.
    fn across(deg: f64) -> Vector3<f64> {
        let t = deg.to_radians();
        light_dir(45.0) * t.cos() + Vector3::new(0.0, t.sin(), 0.0)
    }

    /// Where a lobe falls to half its value at the mirror direction as the
    /// light tilts across the plane, degrees.
    fn half_width_across(b: &dyn Brdf) -> f64 {
        let wo = view_dir(45.0);
        let peak = b.f_r(&across(0.0), &wo);
        (1..4000).map(|k| k as f64 * 0.005).find(|d| b.f_r(&across(*d), &wo) < 0.5 * peak).unwrap()
    }

    #[test]
    fn in_the_plane_it_is_the_material_and_across_it_the_lobe_is_s_times_as_wide() {
        let ward: Arc<dyn Brdf> = Arc::new(Ward::patent(0.3, 0.05));
        let wide = Stretched::new(ward.clone(), 3.0);
        for t in [25.0, 40.0, 44.5, 45.0, 47.0, 60.0] {
            let (a, b) = (wide.reflectance(t, 45.0), ward.reflectance(t, 45.0));
            assert!((a - b).abs() <= 1e-12 * b, "in-plane at {t} deg: {a} vs {b}");
        }
        let (h0, h3) = (half_width_across(ward.as_ref()), half_width_across(&wide));
        // An isotropic lobe at 45 deg is cos 45 deg as wide across as along.
        assert!((h3 / h0 - 3.0).abs() < 0.05, "half widths {h0} and {h3} deg");
        let narrow = Stretched::new(ward.clone(), 0.5);
        assert!((half_width_across(&narrow) / h0 - 0.5).abs() < 0.05);
    }

    #[test]
    fn the_stretch_keeps_reciprocity_and_a_mirror_spike() {
        let ward: Arc<dyn Brdf> = Arc::new(Ward::patent(0.3, 0.05));
        let s = Stretched::new(ward, 2.0);
        let (a, b) = (across(2.0), Vector3::new(0.6, -0.1, 0.79).normalize());
        assert!((s.f_r(&a, &b) - s.f_r(&b, &a)).abs() < 1e-12);
        let glass: Arc<dyn Brdf> = Arc::new(crate::forward::brdf::SmoothDielectric::black_glass());
        assert_eq!(Stretched::new(glass.clone(), 2.0).mirror_reflectance(45.0), glass.mirror_reflectance(45.0));
    }
}
