//! The test families: the surfaces a calibration is judged on, grouped by
//! where they come from (measured, analytic Ward, analytic GGX, gloss
//! standards), each a list of named reflection models.
//!
//! Every family is deterministic (no random draw chooses a material), so
//! two runs and two calibrations are scored on the very same surfaces.
use crate::forward::brdf::merl_binary::MerlTable;
use crate::forward::brdf::{Brdf, Ggx, NbrdfSet, Ward};
use crate::forward::prior::{PATENT_TEST_ALPHA, PATENT_TEST_RHO_D};
use crate::forward::prior_measured::{Family, PriorMix};
use anyhow::{Context, bail, ensure};
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

/// Whether `b` reflects any light in the plane of incidence where an
/// instrument of this kind looks: incidence 0-85 deg (1 deg apart), views
/// 30-60 deg (5 deg apart), a mirror's reflection included.
fn reflects_in_plane(b: &dyn Brdf) -> bool {
    (0..=85).any(|ti| {
        let ti = f64::from(ti);
        b.mirror_reflectance(ti) > 0.0 || (30..=60).step_by(5).any(|to| b.reflectance(ti, f64::from(to)) > 0.0)
    })
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

    /// The measured surfaces named by `arg` (`accuracy --set`), seen
    /// through `spectral`: `merl` (the vendored set), an NBRDF `.json` set
    /// (every material in it, by its name), a MERL `.binary` table (named
    /// by its file), or a directory or comma-separated list of them, as
    /// `--prior` names measured files. A profile known only in-plane
    /// (`.csv`, `.astm`) is refused: a surface is read through the
    /// instrument's every ray and its gloss readings are defined in three
    /// dimensions, which take the whole BRDF.
    pub fn measured_files(arg: &str, spectral: [f64; 3]) -> anyhow::Result<Self> {
        let mix = PriorMix::parse(arg).with_context(|| format!("--set {arg:?}"))?;
        ensure!(mix.families.len() == 1, "--set {arg:?}: one set of surfaces, not a mixture");
        let files = match &mix.families[0].1 {
            Family::Merl => return Ok(Self::measured("the vendored MERL set", &NbrdfSet::merl(), spectral)),
            Family::Files(files) => files,
            Family::Patent | Family::Toml(_) => bail!(
                "--set {arg:?}: the surfaces are measured files (NBRDF .json sets, MERL .binary tables, a directory \
                 or a comma list of them) or `merl`; a prior of models is `--prior`'s"
            ),
        };
        let mut materials: Vec<(String, Arc<dyn Brdf>)> = Vec::new();
        for f in files {
            ensure!(f.is_file(), "{}: no such file (--set {arg:?})", f.display());
            match f.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
                Some("json") => {
                    let set = NbrdfSet::load(f)?;
                    for i in 0..set.len() {
                        let m = set.material(i, spectral);
                        materials.push((m.name().to_string(), Arc::new(m)));
                    }
                }
                Some("binary") => {
                    let t = MerlTable::load_monochrome(f, spectral)?;
                    let name = f.file_stem().map_or_else(|| f.display().to_string(), |s| s.to_string_lossy().into());
                    materials.push((name, Arc::new(t)));
                }
                _ => bail!(
                    "{}: an in-plane profile is not a surface the instrument can be simulated on (its rays and the \
                     three-dimensional gloss readings take the whole BRDF); give NBRDF .json or MERL .binary files, \
                     and use profiles in a prior (`--prior`)",
                    f.display()
                ),
            }
        }
        ensure!(!materials.is_empty(), "--set {arg:?}: no surfaces in it");
        if let Some((name, _)) = materials.iter().find(|(_, b)| !reflects_in_plane(b.as_ref())) {
            bail!(
                "--set {arg:?}: surface {name:?} reflects no light in the plane of incidence (zero at every incidence \
                 0-85 deg, for views 30-60 deg): every figure is relative to a surface's peak, so it cannot be \
                 scored; leave it out of the set"
            );
        }
        Ok(Self { name: "measured".into(), source: arg.into(), materials })
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
    use crate::forward::brdf::nbrdf::LUMINANCE;

    /// Two of the vendored set's networks as a set of their own, a MERL
    /// table and a profile, in a directory.
    #[test]
    fn measured_surfaces_come_from_nbrdf_sets_merl_tables_directories_and_lists() {
        let dir = tempfile::tempdir().unwrap();
        let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/data/merl-nbrdf.json")).unwrap();
        let all: serde_json::Value = serde_json::from_str(&text).unwrap();
        let mut two = all.clone();
        let keep: Vec<String> = all["materials"].as_object().unwrap().keys().take(2).cloned().collect();
        two["materials"].as_object_mut().unwrap().retain(|k, _| keep.contains(k));
        let json = dir.path().join("two.json");
        std::fs::write(&json, serde_json::to_string(&two).unwrap()).unwrap();
        let t = MerlTable { dims: [4, 4, 8], values: vec![1500.0; 3 * 128], channel_weights: LUMINANCE };
        let binary = dir.path().join("grey.binary");
        t.save(&binary).unwrap();

        let names = |f: &TestFamily| f.materials.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
        let from_dir = TestFamily::measured_files(&dir.path().display().to_string(), LUMINANCE).unwrap();
        assert_eq!(names(&from_dir), vec!["grey".to_string(), keep[0].clone(), keep[1].clone()]);
        assert_eq!(from_dir.name, "measured");
        let list = format!("{},{}", json.display(), binary.display());
        assert_eq!(TestFamily::measured_files(&list, LUMINANCE).unwrap().materials.len(), 3);
        assert_eq!(TestFamily::measured_files("merl", LUMINANCE).unwrap().materials.len(), 100);

        // A profile, a prior of models and a mixture are refused, naming why.
        let csv = dir.path().join("profile.csv");
        std::fs::write(&csv, "20,1.0\n70,2.0\n").unwrap();
        let e = format!("{:#}", TestFamily::measured_files(&dir.path().display().to_string(), LUMINANCE).unwrap_err());
        assert!(e.contains("profile.csv") && e.contains("in-plane profile") && e.contains("--prior"), "{e}");
        let e = format!("{:#}", TestFamily::measured_files("patent", LUMINANCE).unwrap_err());
        assert!(e.contains("measured files"), "{e}");
        let e = format!(
            "{:#}",
            TestFamily::measured_files(&format!("merl@0.5+{}@0.5", json.display()), LUMINANCE).unwrap_err()
        );
        assert!(e.contains("not a mixture"), "{e}");
    }

    /// A table measured only away from the plane of incidence has nothing
    /// its figures could be relative to: refused, naming the surface.
    #[test]
    fn a_surface_that_reflects_nothing_in_the_plane_is_refused_by_name() {
        use crate::forward::brdf::{light_dir, view_dir};
        let cells = 4 * 4 * 8;
        let mut t = MerlTable { dims: [4, 4, 8], values: vec![1500.0; 3 * cells], channel_weights: LUMINANCE };
        for ti in 0..=85 {
            for to in (30..=60).step_by(5) {
                if let Some(c) = t.cell(&light_dir(f64::from(ti)), &view_dir(f64::from(to))) {
                    (0..3).for_each(|k| t.values[k * cells + c] = 0.0);
                }
            }
        }
        assert!(t.values.iter().any(|v| *v > 0.0), "some cell out of the plane keeps its value");
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("dark.binary");
        t.save(&path).unwrap();
        let e = format!("{:#}", TestFamily::measured_files(&path.display().to_string(), LUMINANCE).unwrap_err());
        assert!(e.contains("\"dark\"") && e.contains("reflects no light in the plane"), "{e}");
        // The same table lit in the plane is a surface.
        t.values.iter_mut().for_each(|v| *v = 1500.0);
        t.save(&path).unwrap();
        assert_eq!(TestFamily::measured_files(&path.display().to_string(), LUMINANCE).unwrap().materials.len(), 1);
    }

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
