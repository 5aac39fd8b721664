//! The system matrix H and simulated readings.
use super::{Instrument, Optics, RayModel, rays};
use crate::forward::brdf::Brdf;
use crate::forward::grid::AngleGrid;
use nalgebra::{DMatrix, DVector, Vector3};

/// Why the optics could not be modelled on a grid.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum OpticsError {
    /// A ray falls outside the angle grid, so H would lose light.
    #[error("illumination {led}: a ray arrives at {theta_deg:.3} deg, outside the grid {lo}..{hi} deg; widen the grid")]
    RayOutsideGrid {
        /// Illumination index.
        led: usize,
        /// Ray angle.
        theta_deg: f64,
        /// Grid start.
        lo: f64,
        /// Grid end.
        hi: f64,
    },
    /// No light reaches the point (every source behind the surface, or an
    /// emission profile that sends nothing towards it).
    #[error(
        "illumination {led}: no light reaches the point (every source is behind the surface or emits nothing towards it)"
    )]
    NoLight {
        /// Illumination index.
        led: usize,
    },
}

/// H (m x n): row i is illumination i's normalised ray distribution spread
/// onto the grid by linear interpolation. Every row sums to 1.
pub fn system_matrix(inst: &Instrument, grid: &AngleGrid, far_field: bool) -> Result<DMatrix<f64>, OpticsError> {
    let optics = Optics::new(inst, RayModel::legacy(far_field));
    system_matrix_at(&optics, grid, &Vector3::from(inst.point.position_cm))
}

/// H (m x n) at `point` (cm, instrument frame) for prepared optics: row i is
/// LED i's rays spread onto the grid by linear interpolation, divided by the
/// LED's total irradiance there (white-standard calibration), so every row
/// sums to 1.
pub fn system_matrix_at(optics: &Optics, grid: &AngleGrid, point: &Vector3<f64>) -> Result<DMatrix<f64>, OpticsError> {
    let mut h = DMatrix::zeros(optics.m(), grid.n());
    for led in 0..optics.m() {
        let mut total = 0.0;
        let mut outside = None;
        optics.for_each_ray(led, point, |r| {
            if r.weight <= 0.0 {
                return;
            }
            match grid.split(r.theta_deg) {
                Some(parts) => {
                    for (j, f) in parts {
                        h[(led, j)] += r.weight * f;
                    }
                    total += r.weight;
                }
                None => outside = outside.or(Some(r.theta_deg)),
            }
        });
        if let Some(theta_deg) = outside {
            return Err(OpticsError::RayOutsideGrid {
                led,
                theta_deg,
                lo: grid.bins_deg()[0],
                hi: *grid.bins_deg().last().unwrap(),
            });
        }
        if total.is_nan() || total <= 0.0 || !total.is_finite() {
            return Err(OpticsError::NoLight { led });
        }
        h.row_mut(led).scale_mut(1.0 / total);
    }
    Ok(h)
}

/// Noise-free white-calibrated readings v (m): each illumination's rays
/// evaluated with the continuous BRDF at their exact directions, so the
/// discretisation error of H is real, not hidden.
pub fn simulate_readings(inst: &Instrument, brdf: &dyn Brdf, far_field: bool) -> DVector<f64> {
    let wo = surface_view(inst);
    // A mirror spike is spread over the grid's bin kernel (`brdf::ray_reflectance`).
    let step = inst.grid().map_or(0.5, |g| g.step_deg());
    let theta_o = wo.z.clamp(-1.0, 1.0).acos().to_degrees();
    DVector::from_iterator(
        inst.m(),
        (0..inst.m()).map(|led| {
            rays(inst, led, far_field)
                .iter()
                .map(|r| {
                    r.weight * crate::forward::brdf::ray_reflectance(brdf, &r.dir, &wo, r.theta_deg, theta_o, step)
                })
                .sum::<f64>()
        }),
    )
}

fn surface_view(inst: &Instrument) -> nalgebra::Vector3<f64> {
    super::rays::surface_frame(&inst.normal()) * inst.view_dir()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::{Lambertian, Ward};

    #[test]
    fn every_row_sums_to_one() {
        let p = Instrument::patent_profile();
        let g = p.grid().unwrap();
        for far in [false, true] {
            let h = system_matrix(&p, &g, far).unwrap();
            assert_eq!(h.shape(), (7, 81));
            for i in 0..7 {
                assert!((h.row(i).sum() - 1.0).abs() < 1e-12, "row {i} far={far}");
                assert!(h.row(i).iter().all(|x| *x >= 0.0));
            }
        }
    }

    #[test]
    fn far_field_rows_are_one_hot_at_the_centre_angle() {
        let p = Instrument::patent_profile();
        let g = p.grid().unwrap();
        let h = system_matrix(&p, &g, true).unwrap();
        for (i, c) in p.centre_angles_deg().iter().enumerate() {
            let j = g.bins_deg().iter().position(|b| (b - c).abs() < 1e-9).unwrap();
            assert!((h[(i, j)] - 1.0).abs() < 1e-12);
            assert_eq!(h.row(i).iter().filter(|x| **x != 0.0).count(), 1);
        }
    }

    #[test]
    fn near_field_rows_spread_over_about_eight_bins() {
        let p = Instrument::patent_profile();
        let h = system_matrix(&p, &p.grid().unwrap(), false).unwrap();
        let nz = h.row(3).iter().filter(|x| **x > 0.0).count();
        assert!((7..=10).contains(&nz), "{nz} bins");
    }

    #[test]
    fn perfect_diffuser_reads_one_and_h_predicts_smooth_brdfs() {
        let p = Instrument::patent_profile();
        let g = p.grid().unwrap();
        for far in [false, true] {
            let v = simulate_readings(&p, &Lambertian::perfect(), far);
            assert!(v.iter().all(|x| (x - 1.0).abs() < 1e-12), "{v}");
        }
        // A broad lobe is nearly linear between bins: H rho ~ v.
        let w = Ward::patent(0.3, 0.3);
        let rho = DVector::from_iterator(g.n(), g.bins_deg().iter().map(|t| w.reflectance(*t, 45.0)));
        let h = system_matrix(&p, &g, false).unwrap();
        let v = simulate_readings(&p, &w, false);
        assert!(((&h * rho) - &v).amax() < 1e-4 * v.amax());
    }

    #[test]
    fn a_ray_off_the_grid_is_an_error_not_lost_light() {
        let mut p = Instrument::patent_profile();
        p.grid.stop_deg = 50.0;
        let g = p.grid().unwrap();
        assert!(matches!(system_matrix(&p, &g, false), Err(OpticsError::RayOutsideGrid { led: 4, .. })));
    }
}
