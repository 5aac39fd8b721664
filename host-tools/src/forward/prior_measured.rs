//! Priors that cover real materials: measured sample sets and mixtures of
//! families with explicit weights (claim 2: the correction comes from samples
//! of real BRDFs and measured goniometric reflectance).
//!
//! A prior argument is one family, or a mixture of families joined by `+`,
//! each with its weight after `@` (required for a mixture; they must sum to
//! 1, so the weight of each family is what the user wrote):
//!
//! - `patent`: the patent's Table 5 (16 Ward samples);
//! - `merl`: the vendored MERL set (100 measured materials);
//! - a prior TOML file (`ward_grid`, `samples`, `csv`);
//! - a measured file: `.csv` goniometric (`angle_deg,value`), `.binary`
//!   (MERL), `.json` (NBRDF networks: every material in it), `.astm`
//!   (ASTM E1392 table: its in-plane profile at the instrument's view);
//! - a directory: every such file in it, in name order;
//! - a comma-separated list of measured files.
//!
//! For example `merl@0.8+patent@0.2`. Inside a family the samples share its
//! weight equally. RGB data is seen through the instrument's spectral
//! weights.
use crate::calibration::estimators::scale_free::WeightedSamples;
use crate::forward::brdf::merl_binary::MerlTable;
use crate::forward::brdf::{AstmTable, NbrdfSet};
use crate::forward::grid::AngleGrid;
use crate::forward::prior::{Prior, PriorSpec, read_measured_csv};
use crate::forward::prior_models::{PriorModels, PriorSample, SampleModel};
use anyhow::{Context, bail, ensure};
use nalgebra::{DMatrix, DVector};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// One family of samples.
#[derive(Clone, Debug, PartialEq)]
pub enum Family {
    /// The patent's Table 5.
    Patent,
    /// The vendored MERL set.
    Merl,
    /// A prior TOML file.
    Toml(PathBuf),
    /// Measured files (`.csv`, `.binary`, `.json`, `.astm`).
    Files(Vec<PathBuf>),
}

/// A parsed prior argument: families with weights summing to 1.
#[derive(Clone, Debug, PartialEq)]
pub struct PriorMix {
    /// (label, family, weight).
    pub families: Vec<(String, Family, f64)>,
}

const MEASURED_EXTS: [&str; 4] = ["csv", "binary", "json", "astm"];

fn ext_of(p: &Path) -> String {
    p.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

fn family_of(text: &str) -> anyhow::Result<Family> {
    Ok(match text {
        "patent" => Family::Patent,
        "merl" => Family::Merl,
        _ if text.contains(',') => {
            let files: Vec<PathBuf> = text.split(',').map(|s| PathBuf::from(s.trim())).collect();
            for f in &files {
                ensure!(
                    MEASURED_EXTS.contains(&ext_of(f).as_str()),
                    "{}: a list holds measured files (.csv, .binary, .json, .astm)",
                    f.display()
                );
            }
            Family::Files(files)
        }
        _ => {
            let p = PathBuf::from(text);
            if p.is_dir() {
                let mut files: Vec<PathBuf> = std::fs::read_dir(&p)
                    .with_context(|| format!("{}: cannot list the directory", p.display()))?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|f| MEASURED_EXTS.contains(&ext_of(f).as_str()))
                    .collect();
                files.sort();
                ensure!(
                    !files.is_empty(),
                    "{}: no measured files (.csv, .binary, .json, .astm) in the directory",
                    p.display()
                );
                Family::Files(files)
            } else if ext_of(&p) == "toml" {
                Family::Toml(p)
            } else if MEASURED_EXTS.contains(&ext_of(&p).as_str()) {
                Family::Files(vec![p])
            } else if !p.exists() {
                bail!(
                    "{text:?}: no such file or directory, and not `patent` or `merl` (a family is one of those, a \
                     directory, a prior .toml or a measured .csv/.binary/.json/.astm file): check the path"
                )
            } else {
                bail!(
                    "{text:?}: not `patent`, `merl`, a directory, a prior .toml or a measured .csv/.binary/.json/.astm file"
                )
            }
        }
    })
}

impl PriorMix {
    /// Parses a prior argument (see the module docs).
    pub fn parse(arg: &str) -> anyhow::Result<Self> {
        let parts: Vec<&str> = arg.split('+').map(str::trim).collect();
        ensure!(parts.iter().all(|p| !p.is_empty()), "prior {arg:?}: an empty family");
        let mut families = Vec::new();
        for part in &parts {
            let (text, weight) = match part.rsplit_once('@') {
                Some((t, w)) => {
                    let w: f64 = w
                        .trim()
                        .parse()
                        .with_context(|| format!("prior {arg:?}: weight {w:?} of {t:?} is not a number"))?;
                    ensure!(
                        w.is_finite() && w > 0.0 && w <= 1.0,
                        "prior {arg:?}: weight {w} of {t:?} must be in (0, 1]"
                    );
                    (t, Some(w))
                }
                None => (*part, None),
            };
            families.push((text.to_string(), family_of(text)?, weight));
        }
        if families.len() == 1 {
            let (l, f, w) = families.pop().unwrap();
            ensure!(w.is_none_or(|w| w == 1.0), "prior {arg:?}: a single family has weight 1");
            return Ok(Self { families: vec![(l, f, 1.0)] });
        }
        let mut out = Vec::new();
        for (l, f, w) in families {
            let Some(w) = w else { bail!("prior {arg:?}: in a mixture every family needs its weight (`{l}@0.5`)") };
            out.push((l, f, w));
        }
        let total: f64 = out.iter().map(|x| x.2).sum();
        ensure!((total - 1.0).abs() < 1e-9, "prior {arg:?}: the weights sum to {total}, not 1");
        Ok(Self { families: out })
    }

    /// The samples as models (RGB data seen through `spectral`), each
    /// family's weight shared equally by its samples, each rough model also
    /// stretched across the plane of incidence by the default factors
    /// (`crate::forward::prior_models::DEFAULT_ACROSS`, which only optics
    /// that see across the plane read). Profiles (CSV, ASTM) are taken at
    /// `view_deg` on `grid`.
    pub fn models(&self, grid: &AngleGrid, view_deg: f64, spectral: [f64; 3]) -> anyhow::Result<PriorModels> {
        let mut out = PriorModels::default().with_across(&crate::forward::prior_models::DEFAULT_ACROSS);
        for (label, fam, w) in &self.families {
            let c = family_models(fam, grid, view_deg, spectral).with_context(|| format!("prior family {label:?}"))?;
            ensure!(!c.is_empty(), "prior family {label:?} has no samples");
            let each = w / c.len() as f64;
            out.samples.extend(c.into_iter().map(|(name, model)| PriorSample {
                name,
                family: label.clone(),
                weight: each,
                model,
            }));
        }
        Ok(out)
    }

    /// The samples on the grid (reflectance factors at `view_deg`, RGB data
    /// weighted by `spectral`) with their weights, and the names.
    pub fn samples(
        &self,
        grid: &AngleGrid,
        view_deg: f64,
        spectral: [f64; 3],
    ) -> anyhow::Result<(WeightedSamples, Vec<String>)> {
        let models = self.models(grid, view_deg, spectral)?;
        let ws = checked_on_grid(&models, grid, view_deg)?;
        Ok((ws, models.names()))
    }

    /// The Wiener prior of the mixture: `R_pp = sum_k w_k rho_k rho_k^T`.
    pub fn prior(
        &self,
        grid: &AngleGrid,
        view_deg: f64,
        spectral: [f64; 3],
    ) -> anyhow::Result<(Prior, WeightedSamples)> {
        let (ws, _) = self.samples(grid, view_deg, spectral)?;
        Ok((weighted_prior(&ws), ws))
    }
}

/// The models' samples on the grid, refusing a value that is not a finite,
/// non-negative reflectance factor (naming the sample and the bin).
pub fn checked_on_grid(models: &PriorModels, grid: &AngleGrid, view_deg: f64) -> anyhow::Result<WeightedSamples> {
    let ws = models.on_grid(grid, view_deg);
    if let Some((idx, x)) = ws.samples.iter().enumerate().find(|(_, x)| !x.is_finite() || **x < 0.0) {
        bail!(
            "prior sample {} ({}), bin {}: value {x} is not a finite, non-negative reflectance factor",
            idx / grid.n(),
            models.samples[idx / grid.n()].name,
            idx % grid.n()
        );
    }
    Ok(ws)
}

/// `Prior` (R_pp and samples) of weighted samples.
pub fn weighted_prior(ws: &WeightedSamples) -> Prior {
    let scaled =
        DMatrix::from_fn(ws.samples.nrows(), ws.samples.ncols(), |j, k| ws.samples[(j, k)] * ws.weights[k].sqrt());
    Prior { samples: ws.samples.clone(), r_pp: &scaled * scaled.transpose() }
}

/// A profile measured over incidence angles, resampled onto the grid.
fn profile_on_grid(t: &crate::forward::brdf::Tabulated, grid: &AngleGrid, f: &Path) -> anyhow::Result<SampleModel> {
    let mut col = DVector::zeros(grid.n());
    for (j, th) in grid.bins_deg().iter().enumerate() {
        col[j] = t.at(*th).with_context(|| {
            format!("{}: cannot resample onto the grid; measure over the grid's span or narrow the grid", f.display())
        })?;
    }
    Ok(SampleModel::Profile(col))
}

/// A family's samples as (name, model).
pub fn family_models(
    fam: &Family,
    grid: &AngleGrid,
    view_deg: f64,
    spectral: [f64; 3],
) -> anyhow::Result<Vec<(String, SampleModel)>> {
    let mut out = Vec::new();
    let add_set = |set: &NbrdfSet, origin: &str, out: &mut Vec<(String, SampleModel)>| {
        for i in 0..set.len() {
            let mat = set.material(i, spectral);
            out.push((format!("{origin}:{}", mat.name()), SampleModel::Brdf(Arc::new(mat))));
        }
    };
    match fam {
        Family::Patent => {
            for (c, (_, model)) in PriorSpec::patent().models(grid, Path::new("."))?.into_iter().enumerate() {
                out.push((format!("patent:{c}"), model));
            }
        }
        Family::Merl => add_set(&NbrdfSet::merl(), "merl", &mut out),
        Family::Toml(p) => {
            let (spec, base) = PriorSpec::load(p).with_context(|| format!("reading the prior {}", p.display()))?;
            for (c, (_, model)) in spec.models(grid, &base)?.into_iter().enumerate() {
                out.push((format!("{}:{c}", p.display()), model));
            }
        }
        Family::Files(files) => {
            for f in files {
                match ext_of(f).as_str() {
                    "csv" => out.push((f.display().to_string(), profile_on_grid(&read_measured_csv(f)?, grid, f)?)),
                    "binary" => {
                        let t = MerlTable::load_monochrome(f, spectral)?;
                        out.push((f.display().to_string(), SampleModel::Brdf(Arc::new(t))));
                    }
                    "json" => add_set(&NbrdfSet::load(f)?, &f.display().to_string(), &mut out),
                    "astm" => {
                        let table = AstmTable::load(f)?;
                        out.push((f.display().to_string(), profile_on_grid(table.at_view(view_deg)?, grid, f)?));
                    }
                    _ => bail!("{}: not a measured file (.csv, .binary, .json, .astm)", f.display()),
                }
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::nbrdf::LUMINANCE;

    #[test]
    fn mixtures_parse_with_explicit_weights_and_refuse_the_rest() {
        let m = PriorMix::parse("merl@0.8+patent@0.2").unwrap();
        assert_eq!(m.families.len(), 2);
        assert_eq!(m.families[0].1, Family::Merl);
        assert_eq!(m.families[1].2, 0.2);
        assert_eq!(PriorMix::parse("merl").unwrap().families[0].2, 1.0);
        for (bad, why) in [
            ("merl+patent", "needs its weight"),
            ("merl@0.7+patent@0.2", "sum to"),
            ("merl@x+patent@0.5", "not a number"),
            ("merl@0.5", "weight 1"),
            ("nothing.xyz", "no such file or directory, and not `patent`"),
            ("src/lib.rs", "\"src/lib.rs\": not `patent`"),
            ("merl@0.5+", "empty family"),
        ] {
            let e = format!("{:#}", PriorMix::parse(bad).unwrap_err());
            assert!(e.contains(why), "{bad}: {e}");
        }
    }

    #[test]
    fn an_astm_e1392_file_is_a_prior_sample_at_the_instruments_view() {
        use crate::output::profile::{ExportInfo, Profile};
        let dir = tempfile::tempdir().unwrap();
        let grid = AngleGrid::patent();
        let ward = crate::forward::brdf::Ward::new(0.3, 0.7, 0.08).unwrap();
        let truth = SampleModel::Brdf(Arc::new(ward)).on_grid(&grid, 45.0);
        let p = Profile {
            line: 0,
            point: 3,
            flags: Vec::new(),
            theta_i_deg: grid.bins_deg().to_vec(),
            reflectance: truth.iter().copied().collect(),
            uncertainty: vec![0.01; grid.n()],
            readings: Vec::new(),
        };
        let info = ExportInfo {
            view_deg: 45.0,
            source: "test".into(),
            instrument: "test".into(),
            calibration: "none".into(),
            timestamp: "2026-11-22T00:00:00+00:00".into(),
            solid_angle_sr: None,
        };
        let f = dir.path().join("w.astm");
        crate::output::astm_e1392::write(&f, std::slice::from_ref(&p), &info).unwrap();
        let (ws, names) = PriorMix::parse(&f.display().to_string()).unwrap().samples(&grid, 45.0, LUMINANCE).unwrap();
        assert_eq!(names, vec![f.display().to_string()]);
        for j in 0..grid.n() {
            assert!((ws.samples[(j, 0)] - truth[j]).abs() < 1e-12 * truth[j].max(1.0), "bin {j}");
        }
        // Another view has no data: the error names the file and the views it has.
        let e = format!(
            "{:#}",
            PriorMix::parse(&f.display().to_string()).unwrap().samples(&grid, 30.0, LUMINANCE).unwrap_err()
        );
        assert!(e.contains("w.astm") && e.contains("viewer at 30 deg") && e.contains("[45.0]"), "{e}");
    }

    #[test]
    fn families_from_files_directories_and_lists_with_weights() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.csv"), "20,1.0\n70,2.0\n").unwrap();
        std::fs::write(dir.path().join("b.csv"), "20,0.5\n70,0.5\n").unwrap();
        std::fs::write(dir.path().join("notes.txt"), "ignored").unwrap();
        let t = MerlTable { dims: [4, 4, 8], values: vec![1500.0; 3 * 128], channel_weights: LUMINANCE };
        t.save(&dir.path().join("c.binary")).unwrap();
        let grid = AngleGrid::patent();
        let arg = format!("{}@0.5+patent@0.5", dir.path().display());
        let (ws, names) = PriorMix::parse(&arg).unwrap().samples(&grid, 45.0, LUMINANCE).unwrap();
        assert_eq!(ws.samples.ncols(), 3 + 16);
        assert!(names[0].ends_with("a.csv") && names[2].ends_with("c.binary"));
        assert!((ws.weights[0] - 0.5 / 3.0).abs() < 1e-15 && (ws.weights[3] - 0.5 / 16.0).abs() < 1e-15);
        // Every stored value 1500: f_r = the channel scales x 1500, luminance-weighted
        // (kept in f32: `MerlMono`).
        let want = std::f64::consts::PI * (0.2126 + 0.7152 * 1.15 + 0.0722 * 1.66);
        assert!((ws.samples[(40, 2)] - want).abs() < 1e-6 * want, "{}", ws.samples[(40, 2)]);
        let list = format!("{},{}", dir.path().join("a.csv").display(), dir.path().join("b.csv").display());
        let (ws, _) = PriorMix::parse(&list).unwrap().samples(&grid, 45.0, LUMINANCE).unwrap();
        assert_eq!(ws.samples.ncols(), 2);
        let (p, _) = PriorMix::parse("merl").unwrap().prior(&grid, 45.0, LUMINANCE).unwrap();
        assert_eq!(p.samples.ncols(), 100);
        // Malformed measured input names file:line.
        std::fs::write(dir.path().join("bad.csv"), "20,1.0\n30,abc\n").unwrap();
        let e = format!(
            "{:#}",
            PriorMix::parse(&dir.path().join("bad.csv").display().to_string())
                .unwrap()
                .samples(&grid, 45.0, LUMINANCE)
                .unwrap_err()
        );
        assert!(e.contains("bad.csv:2"), "{e}");
        std::fs::write(dir.path().join("bad.binary"), [0u8; 20]).unwrap();
        let e = format!(
            "{:#}",
            PriorMix::parse(&dir.path().join("bad.binary").display().to_string())
                .unwrap()
                .samples(&grid, 45.0, LUMINANCE)
                .unwrap_err()
        );
        assert!(e.contains("bad.binary"), "{e}");
    }
}
