//! Measured isotropic BRDFs as NBRDF networks (Sztrajman et al. 2021): each
//! material is a 6-21-21-3 MLP fitted to its measured data (the MERL set is
//! vendored in `host-tools/data/merl-nbrdf.json`, attribution in
//! `host-tools/data/README.md`).
//!
//! Evaluation (the data's README): half vector h, theta_h, phi_h; difference
//! vector `d = R_y(-theta_h) R_z(-phi_h) w_i`; input `[sin theta_h, 0,
//! cos theta_h, d]`; two ReLU layers and a linear one; `f_r = max(exp(y) - 1,
//! 0)` per RGB channel. A monochrome sensor sees a weighted sum of the three
//! channels (the instrument's spectral weighting; luminance by default).
use super::Brdf;
use anyhow::{Context, bail, ensure};
use nalgebra::Vector3;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// The format tag of the NBRDF JSON files.
pub const NBRDF_FORMAT: &str = "nbrdf-mlp-6-21-21-3";
/// Rec. 709 luminance weights of R, G, B: the default spectral weighting.
pub const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];
/// The vendored MERL set (100 materials).
pub const MERL_JSON: &str = include_str!("../../../data/merl-nbrdf.json");

const HIDDEN: usize = 21;

/// One material's network weights (row-major as stored: x is a row vector).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NbrdfWeights {
    w1: Vec<Vec<f64>>,
    b1: Vec<f64>,
    w2: Vec<Vec<f64>>,
    b2: Vec<f64>,
    w3: Vec<Vec<f64>>,
    b3: Vec<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NbrdfFile {
    format: String,
    materials: BTreeMap<String, NbrdfWeights>,
}

impl NbrdfWeights {
    fn check(&self) -> Result<(), String> {
        let shape = |name: &str, a: &Vec<Vec<f64>>, r: usize, c: usize| -> Result<(), String> {
            if a.len() != r || a.iter().any(|row| row.len() != c) {
                return Err(format!("`{name}` must be {r} x {c}"));
            }
            if a.iter().flatten().any(|x| !x.is_finite()) {
                return Err(format!("`{name}` holds a non-finite value"));
            }
            Ok(())
        };
        let vec = |name: &str, a: &Vec<f64>, n: usize| -> Result<(), String> {
            if a.len() != n || a.iter().any(|x| !x.is_finite()) {
                return Err(format!("`{name}` must be {n} finite values"));
            }
            Ok(())
        };
        shape("w1", &self.w1, 6, HIDDEN)?;
        vec("b1", &self.b1, HIDDEN)?;
        shape("w2", &self.w2, HIDDEN, HIDDEN)?;
        vec("b2", &self.b2, HIDDEN)?;
        shape("w3", &self.w3, HIDDEN, 3)?;
        vec("b3", &self.b3, 3)
    }

    /// RGB f_r (1/sr) for unit directions above the surface.
    pub fn rgb(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        let (theta_h, d) = half_and_difference(wi, wo);
        let x = [theta_h.sin(), 0.0, theta_h.cos(), d.x, d.y, d.z];
        let mut a1 = [0.0; HIDDEN];
        for (k, out) in a1.iter_mut().enumerate() {
            let s: f64 = self.b1[k] + (0..6).map(|i| x[i] * self.w1[i][k]).sum::<f64>();
            *out = s.max(0.0);
        }
        let mut a2 = [0.0; HIDDEN];
        for (k, out) in a2.iter_mut().enumerate() {
            let s: f64 = self.b2[k] + (0..HIDDEN).map(|i| a1[i] * self.w2[i][k]).sum::<f64>();
            *out = s.max(0.0);
        }
        let mut rgb = [0.0; 3];
        for (c, out) in rgb.iter_mut().enumerate() {
            let y: f64 = self.b3[c] + (0..HIDDEN).map(|i| a2[i] * self.w3[i][c]).sum::<f64>();
            *out = (y.exp() - 1.0).max(0.0);
        }
        rgb
    }
}

/// A measured material as seen by a monochrome sensor.
#[derive(Clone, Debug)]
pub struct Nbrdf {
    name: String,
    weights: Arc<NbrdfWeights>,
    channel_weights: [f64; 3],
}

impl Nbrdf {
    /// The material's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The same material seen through other spectral weights of R, G, B.
    pub fn with_channel_weights(mut self, w: [f64; 3]) -> Self {
        self.channel_weights = w;
        self
    }
}

impl Brdf for Nbrdf {
    fn f_r(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> f64 {
        let rgb = self.weights.rgb(wi, wo);
        rgb.iter().zip(&self.channel_weights).map(|(f, w)| f * w).sum()
    }
}

/// A set of NBRDF materials, in name order.
#[derive(Clone, Debug)]
pub struct NbrdfSet {
    materials: Vec<(String, Arc<NbrdfWeights>)>,
}

impl NbrdfSet {
    /// Parses an NBRDF JSON document; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> anyhow::Result<Self> {
        let file: NbrdfFile = serde_json::from_str(text)
            .map_err(|e| anyhow::anyhow!("{origin}:{}:{}: not an NBRDF file: {e}", e.line(), e.column()))?;
        ensure!(file.format == NBRDF_FORMAT, "{origin}: format {:?} is not {NBRDF_FORMAT:?}", file.format);
        ensure!(!file.materials.is_empty(), "{origin}: the file lists no materials");
        let mut materials = Vec::with_capacity(file.materials.len());
        for (name, w) in file.materials {
            if let Err(why) = w.check() {
                bail!("{origin}: material {name:?}: {why}");
            }
            materials.push((name, Arc::new(w)));
        }
        Ok(Self { materials })
    }

    /// Reads an NBRDF JSON file.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
        Self::parse(&text, &path.display().to_string())
    }

    /// The vendored MERL set (100 materials).
    pub fn merl() -> Self {
        Self::parse(MERL_JSON, "merl-nbrdf.json").expect("the vendored MERL set is valid")
    }

    /// Number of materials.
    pub fn len(&self) -> usize {
        self.materials.len()
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.materials.is_empty()
    }

    /// Material names.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.materials.iter().map(|(n, _)| n.as_str())
    }

    /// Material `i` seen through `channel_weights`.
    pub fn material(&self, i: usize, channel_weights: [f64; 3]) -> Nbrdf {
        let (name, w) = &self.materials[i];
        Nbrdf { name: name.clone(), weights: Arc::clone(w), channel_weights }
    }

    /// The material called `name`.
    pub fn by_name(&self, name: &str, channel_weights: [f64; 3]) -> anyhow::Result<Nbrdf> {
        let i = self.materials.iter().position(|(n, _)| n == name).with_context(|| {
            let some: Vec<&str> = self.names().take(5).collect();
            format!("no material {name:?} in the set (it has {}: {}, ...)", self.len(), some.join(", "))
        })?;
        Ok(self.material(i, channel_weights))
    }
}

/// Rusinkiewicz's half/difference parametrisation of a direction pair (the
/// one MERL data and the NBRDF networks are indexed by): the half vector's
/// polar angle `theta_h` and the difference vector `d = R_y(-theta_h)
/// R_z(-phi_h) w_i`.
pub(crate) fn half_and_difference(wi: &Vector3<f64>, wo: &Vector3<f64>) -> (f64, Vector3<f64>) {
    let h = (wi + wo).normalize();
    let theta_h = h.z.clamp(-1.0, 1.0).acos();
    let phi_h = h.y.atan2(h.x);
    // R_z(-phi_h), then R_y(-theta_h).
    let (sp, cp) = (-phi_h).sin_cos();
    let a = Vector3::new(cp * wi.x - sp * wi.y, sp * wi.x + cp * wi.y, wi.z);
    let (st, ct) = (-theta_h).sin_cos();
    (theta_h, Vector3::new(ct * a.x + st * a.z, a.y, -st * a.x + ct * a.z))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::{light_dir, view_dir};

    /// The data README's check values: w_o at +45 deg, w_i at -theta,
    /// luminance, reflectance factor pi f_r.
    #[test]
    fn check_values_of_the_readme() {
        let set = NbrdfSet::merl();
        assert_eq!(set.len(), 100);
        let table = [
            ("alum-bronze", [0.322763, 31.5429, 0.590174]),
            ("blue-acrylic", [0.0813567, 117.5, 0.12931]),
            ("gold-metallic-paint", [0.771823, 1.55675, 1.12866]),
            ("white-paint", [0.381938, 1.14481, 0.423087]),
            ("black-obsidian", [0.00398554, 95.9076, 0.00668837]),
        ];
        for (name, want) in table {
            let mat = set.by_name(name, LUMINANCE).unwrap();
            for (theta, w) in [30.0, 45.0, 60.0].iter().zip(want) {
                let got = std::f64::consts::PI * mat.f_r(&light_dir(*theta), &view_dir(45.0));
                assert!((got - w).abs() <= 1e-5 * w.abs().max(1e-3), "{name} at {theta}: {got} vs {w}");
            }
        }
    }

    #[test]
    fn malformed_files_are_refused_with_the_reason() {
        let e = NbrdfSet::parse("{\"format\": \"x\", \"materials\": {}}", "f.json").unwrap_err();
        assert!(format!("{e:#}").contains("format"), "{e:#}");
        let e = NbrdfSet::parse("{\"format\": \"nbrdf-mlp-6-21-21-3\",\n \"materials\": 3}", "f.json").unwrap_err();
        assert!(format!("{e:#}").starts_with("f.json:2:"), "{e:#}");
        let bad = "{\"format\": \"nbrdf-mlp-6-21-21-3\", \"materials\": {\"a\": {\"w1\": [[1]], \"b1\": [], \"w2\": [], \"b2\": [], \"w3\": [], \"b3\": []}}}";
        let e = NbrdfSet::parse(bad, "f.json").unwrap_err();
        assert!(format!("{e:#}").contains("`w1` must be 6 x 21"), "{e:#}");
        assert!(NbrdfSet::merl().by_name("unobtainium", LUMINANCE).is_err());
    }
}
