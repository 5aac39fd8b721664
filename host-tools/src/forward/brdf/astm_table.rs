//! A BRDF read from an ASTM E1392 table (`host_tools::output::astm_e1392`):
//! its in-plane values, by reciprocity (f_r(i, s) = f_r(s, i)) also with
//! light and viewer swapped, grouped into slices of one viewer zenith angle,
//! each interpolated linearly in incidence. A prior takes the slice at the
//! instrument's view; a scene surface takes, for each ray, the slice nearest
//! its viewer angle.
use super::{Brdf, Tabulated};
use anyhow::{Context, bail};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// Slices closer than this (deg) are one view.
const SAME_VIEW_DEG: f64 = 0.5;

/// An in-plane measured BRDF from an ASTM E1392 file.
#[derive(Clone, Debug)]
pub struct AstmTable {
    path: PathBuf,
    /// (viewer zenith, R against incidence), ascending in viewer zenith.
    slices: Vec<(f64, Tabulated)>,
}

impl AstmTable {
    /// Reads and checks the file.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let origin = path.display().to_string();
        let t = crate::output::astm_e1392::read(path)?;
        let mut pts: Vec<(f64, f64, f64)> = Vec::new();
        for v in t.in_plane(&origin)? {
            pts.push((v.theta_s, v.theta_i, v.reflectance));
            if (v.theta_s - v.theta_i).abs() > 1e-9 {
                pts.push((v.theta_i, v.theta_s, v.reflectance));
            }
        }
        pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        let mut slices = Vec::new();
        let mut k = 0;
        while k < pts.len() {
            let view = pts[k].0;
            let mut group: Vec<(f64, f64)> = Vec::new();
            while k < pts.len() && pts[k].0 - view < SAME_VIEW_DEG {
                // Repeated incidences (a value and its reciprocal) average.
                match group.last_mut() {
                    Some(last) if (last.0 - pts[k].1).abs() < 1e-9 => last.1 = 0.5 * (last.1 + pts[k].2),
                    _ => group.push((pts[k].1, pts[k].2)),
                }
                k += 1;
            }
            if group.len() >= 2 && group.iter().all(|g| g.0 < 90.0) {
                let (a, r): (Vec<f64>, Vec<f64>) = group.into_iter().unzip();
                let tab = Tabulated::new(a, r).with_context(|| format!("{origin}: viewer at {view} deg"))?;
                slices.push((view, tab));
            }
        }
        if slices.is_empty() {
            bail!(
                "{origin}: no viewer angle has two or more in-plane incidences below 90 deg; a profile needs at least two"
            );
        }
        Ok(Self { path: path.to_path_buf(), slices })
    }

    /// The viewer angles the file covers (deg).
    pub fn views(&self) -> Vec<f64> {
        self.slices.iter().map(|s| s.0).collect()
    }

    /// The profile at the instrument's view, `view_deg` (within 0.5 deg).
    pub fn at_view(&self, view_deg: f64) -> anyhow::Result<&Tabulated> {
        match self.slices.iter().find(|s| (s.0 - view_deg).abs() <= SAME_VIEW_DEG) {
            Some(s) => Ok(&s.1),
            None => bail!(
                "{}: no in-plane data for a viewer at {view_deg} deg (the file has viewers at {:?} deg); measure at the instrument's view",
                self.path.display(),
                self.views()
            ),
        }
    }
}

impl Brdf for AstmTable {
    /// The slice nearest the viewer's zenith angle, at the light's incidence;
    /// outside the measured span 0.
    fn f_r(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> f64 {
        let ti = wi.z.clamp(-1.0, 1.0).acos().to_degrees();
        let to = wo.z.clamp(-1.0, 1.0).acos().to_degrees();
        let s = self
            .slices
            .iter()
            .min_by(|a, b| (a.0 - to).abs().total_cmp(&(b.0 - to).abs()))
            .expect("at least one slice");
        s.1.at(ti).unwrap_or(0.0) / std::f64::consts::PI
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slices_by_view_with_reciprocity_and_refuses_a_missing_view() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("g.astm");
        // A goniometer's table: light fixed at 45 deg, viewer swept: by
        // reciprocity, the profile a viewer at 45 deg sees.
        let pi = std::f64::consts::PI;
        let rows: String = [10.0, 30.0, 50.0, 70.0]
            .iter()
            .map(|ts| format!("45,180,{ts},0,555,0,{}\n", (1.0 + ts / 100.0) / pi))
            .collect();
        std::fs::write(&f, format!("VARS theta_i,phi_i,theta_s,phi_s,wavelength,polarization,BRDF\n{rows}")).unwrap();
        let t = AstmTable::load(&f).unwrap();
        let at45 = t.at_view(45.0).unwrap();
        assert!((at45.at(30.0).unwrap() - 1.3).abs() < 1e-12);
        assert!((at45.at(60.0).unwrap() - 1.6).abs() < 1e-12);
        assert!((t.reflectance(30.0, 45.0) - 1.3).abs() < 1e-12);
        let e = format!("{:#}", t.at_view(20.0).unwrap_err());
        assert!(e.contains("g.astm") && e.contains("no in-plane data for a viewer at 20 deg"), "{e}");
    }
}
