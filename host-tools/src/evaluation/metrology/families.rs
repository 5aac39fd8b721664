//! The test families: the surfaces a calibration is judged on, grouped by
//! where they come from (measured, analytic Ward, analytic GGX, gloss
//! standards), each a list of named reflection models.
//!
//! Every family is deterministic (no random draw chooses a material), so
//! two runs and two calibrations are scored on the very same surfaces.
use crate::forward::brdf::{Brdf, Ggx, NbrdfSet, Ward};
use crate::forward::prior::{PATENT_TEST_ALPHA, PATENT_TEST_RHO_D};
use std::sync::Arc;

/// Diffuse albedos of the GGX family (between Table 4's extremes).
pub const GGX_RHO_D: [f64; 4] = [0.15, 0.35, 0.55, 0.75];
/// GGX roughnesses of the GGX family: 0.025 to 0.115 in steps of 0.01
/// (Table 4's Ward roughness range, widened a little on both sides).
pub const GGX_ALPHA: [f64; 10] = [0.025, 0.035, 0.045, 0.055, 0.065, 0.075, 0.085, 0.095, 0.105, 0.115];

/// One family of test surfaces.
#[derive(Clone, Debug)]
pub struct TestFamily {
    /// Name in the tables (`measured`, `ward`, `ggx`, `gloss standards`).
    pub name: String,
    /// Where the surfaces come from, for the report.
    pub source: String,
    /// The surfaces: (name, model).
    pub materials: Vec<(String, Arc<dyn Brdf>)>,
}

impl TestFamily {
    /// Every material of a measured NBRDF set, seen through `spectral`.
    pub fn measured(source: &str, set: &NbrdfSet, spectral: [f64; 3]) -> Self {
        let materials = (0..set.len())
            .map(|i| {
                let m = set.material(i, spectral);
                (m.name().to_string(), Arc::new(m) as Arc<dyn Brdf>)
            })
            .collect();
        Self { name: "measured".into(), source: source.into(), materials }
    }

    /// The patent's 120 test patterns (Table 4): Ward, `rho_s = 1 - rho_d`.
    pub fn ward() -> Self {
        let mut materials: Vec<(String, Arc<dyn Brdf>)> = Vec::new();
        for d in PATENT_TEST_RHO_D {
            for a in PATENT_TEST_ALPHA {
                materials.push((format!("ward(rho_d={d}, alpha={a})"), Arc::new(Ward::patent(d, a))));
            }
        }
        Self { name: "ward".into(), source: "the patent's Table 4 (120 Ward BRDFs)".into(), materials }
    }

    /// 40 GGX lobes: every albedo of [`GGX_RHO_D`] with every roughness of
    /// [`GGX_ALPHA`], specular scale `1 - rho_d` and no Fresnel fall-off
    /// (`f0 = 1`): the Ward test set's energy split in another lobe shape.
    pub fn ggx() -> Self {
        let mut materials: Vec<(String, Arc<dyn Brdf>)> = Vec::new();
        for d in GGX_RHO_D {
            for a in GGX_ALPHA {
                let b = Ggx::new(d, 1.0 - d, a, 1.0).expect("parameters in range");
                materials.push((format!("ggx(rho_d={d}, alpha={a})"), Arc::new(b)));
            }
        }
        Self { name: "ggx".into(), source: "40 GGX lobes (4 albedos x 10 roughnesses)".into(), materials }
    }

    /// The gloss standards every calibration's gloss rows are fitted with
    /// (`calibration::gloss_rows::standards`): polished dielectrics over
    /// several bases, and rough dielectric tiles.
    pub fn gloss_standards() -> Self {
        let s = crate::calibration::gloss_rows::standards();
        let materials = s
            .samples
            .into_iter()
            .map(|p| match p.model {
                crate::forward::prior_models::SampleModel::Brdf(b) => (p.name, b),
                crate::forward::prior_models::SampleModel::Profile(_) => unreachable!("the standards are models"),
            })
            .collect();
        Self { name: "gloss standards".into(), source: "the gloss rows' standards".into(), materials }
    }

    /// At most `count` of the materials, evenly spread over the list (the
    /// first always kept): a reduced run that still spans the family.
    pub fn at_most(mut self, count: usize) -> Self {
        let len = self.materials.len();
        if count < len {
            let keep: Vec<usize> = (0..count).map(|i| i * len / count).collect();
            let mut i = 0;
            self.materials.retain(|_| {
                i += 1;
                keep.contains(&(i - 1))
            });
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_families_have_their_documented_sizes_and_reduce_evenly() {
        assert_eq!(TestFamily::ward().materials.len(), 120);
        assert_eq!(TestFamily::ggx().materials.len(), 40);
        assert!(TestFamily::gloss_standards().materials.len() >= 10);
        let r = TestFamily::ward().at_most(4);
        let names: Vec<&str> = r.materials.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names.len(), 4);
        assert_eq!(names[0], TestFamily::ward().materials[0].0);
        assert_eq!(TestFamily::ggx().at_most(100).materials.len(), 40);
    }
}
