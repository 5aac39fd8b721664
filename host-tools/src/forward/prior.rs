//! Priors (claim 2): R_pp = <rho rho^T> over a set of sample BRDFs, each
//! sampled on the angle grid as reflectance factors at the instrument's view.
//!
//! Samples come from parametric grids (the patent's Table 5 built in),
//! explicit lists of models, or measured goniometric CSV files
//! (`angle_deg,value` rows) resampled onto the grid by linear interpolation.
use crate::forward::brdf::{Brdf, BrdfSpec, Tabulated, Ward};
use crate::forward::grid::AngleGrid;
use crate::output::config::{FieldError, Validate, check_range};
use anyhow::{Context, bail};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Diffuse albedos of the patent's test set (Table 4).
pub const PATENT_TEST_RHO_D: [f64; 10] =
    [0.2477, 0.2578, 0.3075, 0.3098, 0.3482, 0.4067, 0.4178, 0.5982, 0.8541, 0.9391];
/// Roughnesses of the patent's test set (Table 4).
pub const PATENT_TEST_ALPHA: [f64; 12] =
    [0.0305, 0.0518, 0.0525, 0.0578, 0.0743, 0.0815, 0.0599, 0.0699, 0.0918, 0.0974, 0.0987, 0.0991];
/// Diffuse albedos of the patent's training set (Table 5).
pub const PATENT_TRAIN_RHO_D: [f64; 2] = [0.1, 0.95];
/// Roughnesses of the patent's training set (Table 5).
pub const PATENT_TRAIN_ALPHA: [f64; 8] = [0.0200, 0.0314, 0.0429, 0.0543, 0.0657, 0.0771, 0.0886, 0.1000];

/// A set of sample BRDFs: the models (for simulation) and their labels.
#[derive(Debug)]
pub struct SampleSet {
    /// A label per sample.
    pub names: Vec<String>,
    /// The samples.
    pub brdfs: Vec<Box<dyn Brdf>>,
}

impl SampleSet {
    /// Ward samples over a grid of parameters, rho_s = 1 - rho_d.
    pub fn ward_grid(rho_d: &[f64], alpha: &[f64]) -> Self {
        let mut names = Vec::new();
        let mut brdfs: Vec<Box<dyn Brdf>> = Vec::new();
        for &d in rho_d {
            for &a in alpha {
                names.push(format!("ward(rho_d={d}, alpha={a})"));
                brdfs.push(Box::new(Ward::patent(d, a)));
            }
        }
        Self { names, brdfs }
    }

    /// The patent's training set (Table 5): 16 Ward BRDFs.
    pub fn patent_training() -> Self {
        Self::ward_grid(&PATENT_TRAIN_RHO_D, &PATENT_TRAIN_ALPHA)
    }

    /// The patent's test set (Table 4): 120 Ward BRDFs.
    pub fn patent_test() -> Self {
        Self::ward_grid(&PATENT_TEST_RHO_D, &PATENT_TEST_ALPHA)
    }

    /// Number of samples K.
    pub fn len(&self) -> usize {
        self.brdfs.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.brdfs.is_empty()
    }

    /// The samples on the grid, as reflectance factors at `view_deg`: n x K.
    pub fn on_grid(&self, grid: &AngleGrid, view_deg: f64) -> DMatrix<f64> {
        DMatrix::from_fn(grid.n(), self.len(), |j, k| self.brdfs[k].reflectance(grid.bins_deg()[j], view_deg))
    }
}

/// The prior: R_pp (n x n) and the samples it came from (n x K).
#[derive(Clone, Debug)]
pub struct Prior {
    /// The samples on the grid, one per column.
    pub samples: DMatrix<f64>,
    /// R_pp = <rho rho^T>, the patent's (non-centred) correlation matrix.
    pub r_pp: DMatrix<f64>,
}

impl Prior {
    /// Builds R_pp from samples on the grid (n x K).
    pub fn from_samples(samples: DMatrix<f64>) -> anyhow::Result<Self> {
        let k = samples.ncols();
        if k == 0 {
            bail!("the prior has no samples; give at least one sample BRDF");
        }
        if let Some((idx, x)) = samples.iter().enumerate().find(|(_, x)| !x.is_finite() || **x < 0.0) {
            let (j, s) = (idx % samples.nrows(), idx / samples.nrows());
            bail!("prior sample {s}, bin {j}: value {x} is not a finite, non-negative reflectance factor");
        }
        let r_pp = (&samples * samples.transpose()) / k as f64;
        Ok(Self { samples, r_pp })
    }

    /// Number of bins n.
    pub fn n(&self) -> usize {
        self.r_pp.nrows()
    }

    /// Sample `k` as a vector.
    pub fn sample(&self, k: usize) -> DVector<f64> {
        self.samples.column(k).into_owned()
    }
}

/// A parametric grid of Ward samples in a prior file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WardGridSpec {
    /// Diffuse albedos.
    pub rho_d: Vec<f64>,
    /// Roughnesses.
    pub alpha: Vec<f64>,
}

/// A prior file: any mix of parametric grids, explicit models and measured
/// CSV files (paths relative to the prior file).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PriorSpec {
    /// Parametric Ward grids (rho_s = 1 - rho_d).
    #[serde(default)]
    pub ward_grid: Vec<WardGridSpec>,
    /// Explicit models.
    #[serde(default)]
    pub samples: Vec<BrdfSpec>,
    /// Measured goniometric samples, one CSV file each.
    #[serde(default)]
    pub csv: Vec<PathBuf>,
}

impl Validate for PriorSpec {
    fn validate(&self) -> Result<(), FieldError> {
        if self.ward_grid.is_empty() && self.samples.is_empty() && self.csv.is_empty() {
            return Err(FieldError::new("", "the prior lists no samples: add `ward_grid`, `samples` or `csv`"));
        }
        for (g, spec) in self.ward_grid.iter().enumerate() {
            let at = |e: FieldError| e.within(&format!("ward_grid[{g}]"));
            if spec.rho_d.is_empty() || spec.alpha.is_empty() {
                return Err(at(FieldError::new("rho_d", "rho_d and alpha need at least one value each")));
            }
            for x in &spec.rho_d {
                check_range("rho_d", *x, 0.0, 1.0, "").map_err(at)?;
            }
            for x in &spec.alpha {
                check_range("alpha", *x, 1e-4, 1.0, "").map_err(at)?;
            }
        }
        for (i, s) in self.samples.iter().enumerate() {
            s.build().map_err(|e| FieldError::new(format!("samples[{i}]"), e.to_string()))?;
        }
        Ok(())
    }
}

impl PriorSpec {
    /// The patent's training set (Table 5).
    pub fn patent() -> Self {
        Self {
            ward_grid: vec![WardGridSpec { rho_d: PATENT_TRAIN_RHO_D.to_vec(), alpha: PATENT_TRAIN_ALPHA.to_vec() }],
            ..Default::default()
        }
    }

    /// Loads a prior file.
    pub fn load(path: &Path) -> anyhow::Result<(Self, PathBuf)> {
        let spec: Self = crate::output::config::load_toml(path)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok((spec, base))
    }

    /// The prior named on the command line: `patent` (Table 5, built in), a
    /// measured sample CSV (`angle_deg,value` rows) or a prior TOML file;
    /// with the directory its CSV paths are resolved against.
    pub fn from_arg(arg: &str) -> anyhow::Result<(Self, PathBuf)> {
        use anyhow::Context;
        if arg == "patent" {
            return Ok((Self::patent(), PathBuf::from(".")));
        }
        let p = Path::new(arg);
        if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv")) {
            Ok((Self { csv: vec![p.to_path_buf()], ..Default::default() }, PathBuf::new()))
        } else {
            Self::load(p).with_context(|| format!("reading the prior {}", p.display()))
        }
    }

    /// The listed samples as models: the Ward grids and explicit models as
    /// reflection models, each CSV file as its profile on the grid (paths
    /// resolved against `base`), with a label each.
    pub fn models(
        &self,
        grid: &AngleGrid,
        base: &Path,
    ) -> anyhow::Result<Vec<(String, crate::forward::prior_models::SampleModel)>> {
        use crate::forward::prior_models::SampleModel;
        use std::sync::Arc;
        let mut out = Vec::new();
        for g in &self.ward_grid {
            let set = SampleSet::ward_grid(&g.rho_d, &g.alpha);
            out.extend(set.names.into_iter().zip(set.brdfs).map(|(n, b)| (n, SampleModel::Brdf(Arc::from(b)))));
        }
        for s in &self.samples {
            out.push((format!("{s:?}"), SampleModel::Brdf(Arc::from(s.build()?))));
        }
        for p in &self.csv {
            let path = base.join(p);
            let t = read_measured_csv(&path)?;
            let mut col = DVector::zeros(grid.n());
            for (j, th) in grid.bins_deg().iter().enumerate() {
                col[j] = t.at(*th).with_context(|| {
                    format!(
                        "{}: cannot resample onto the grid; measure over the grid's span or narrow the grid",
                        path.display()
                    )
                })?;
            }
            out.push((path.display().to_string(), SampleModel::Profile(col)));
        }
        Ok(out)
    }

    /// Samples every listed BRDF on the grid at `view_deg` and builds the prior.
    /// CSV paths are resolved against `base`.
    pub fn build(&self, grid: &AngleGrid, view_deg: f64, base: &Path) -> anyhow::Result<Prior> {
        let cols: Vec<DVector<f64>> = self.models(grid, base)?.iter().map(|(_, m)| m.on_grid(grid, view_deg)).collect();
        Prior::from_samples(DMatrix::from_columns(&cols))
    }
}

/// Reads a measured goniometric sample: rows of `angle_deg,value` (a header
/// row and `#` comments are allowed). Every problem names the file, line and field.
pub fn read_measured_csv(path: &Path) -> anyhow::Result<Tabulated> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_path(path)
        .with_context(|| format!("{}: cannot open the measured sample", path.display()))?;
    let (mut angles, mut values) = (Vec::new(), Vec::new());
    for (row, rec) in rdr.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: malformed CSV", path.display()))?;
        let line = rec.position().map_or(0, |p| p.line());
        if rec.len() != 2 {
            bail!("{}:{line}: expected 2 fields `angle_deg,value`, found {}", path.display(), rec.len());
        }
        let parse = |k: usize, field: &str| -> anyhow::Result<Option<f64>> {
            match rec[k].parse::<f64>() {
                Ok(x) => Ok(Some(x)),
                Err(_) if row == 0 => Ok(None), // a header row
                Err(_) => bail!("{}:{line}: field `{field}`: {:?} is not a number", path.display(), &rec[k]),
            }
        };
        match (parse(0, "angle_deg")?, parse(1, "value")?) {
            (Some(a), Some(v)) => {
                // Check each row where its line is known; Tabulated::new
                // repeats the checks for callers without a file.
                if !a.is_finite() {
                    bail!("{}:{line}: field `angle_deg`: {a} is not a finite number", path.display());
                }
                if !v.is_finite() {
                    bail!("{}:{line}: field `value`: {v} is not a finite number", path.display());
                }
                if v < 0.0 {
                    bail!("{}:{line}: field `value`: {v} is negative; a reflectance factor is >= 0", path.display());
                }
                if !(0.0..90.0).contains(&a) {
                    bail!("{}:{line}: field `angle_deg`: {a} deg is outside [0, 90)", path.display());
                }
                if angles.last().is_some_and(|&prev| a <= prev) {
                    bail!(
                        "{}:{line}: field `angle_deg`: {a} deg is not above the previous row's; sort the rows and remove duplicates",
                        path.display()
                    );
                }
                angles.push(a);
                values.push(v);
            }
            (None, None) => {}
            _ => bail!("{}:{line}: a row must be two numbers or the header `angle_deg,value`", path.display()),
        }
    }
    Tabulated::new(angles, values).map_err(|e| {
        // Sample index -> line is exact when there is no header or comment;
        // the message names the sample either way.
        anyhow::anyhow!("{}: field `value`/`angle_deg`: {e}", path.display())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::config::parse_toml;

    #[test]
    fn patent_training_prior_has_16_samples_and_is_symmetric_psd() {
        let g = AngleGrid::patent();
        let p = PriorSpec::patent().build(&g, 45.0, Path::new(".")).unwrap();
        assert_eq!(p.samples.shape(), (81, 16));
        assert!((&p.r_pp - p.r_pp.transpose()).amax() == 0.0);
        let eig = p.r_pp.clone().symmetric_eigenvalues();
        assert!(eig.min() > -1e-9 * eig.max());
        // Rank is at most the sample count.
        assert!(eig.iter().filter(|e| **e > 1e-9 * eig.max()).count() <= 16);
        assert_eq!(SampleSet::patent_test().len(), 120);
    }

    #[test]
    fn csv_samples_are_resampled_and_bad_rows_name_file_line_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("good.csv");
        std::fs::write(&good, "angle_deg,value\n# white tile\n20,1.0\n70,2.0\n").unwrap();
        std::fs::write(
            dir.path().join("p.toml"),
            "csv = [\"good.csv\"]\n[[ward_grid]]\nrho_d = [0.5]\nalpha = [0.05]\n",
        )
        .unwrap();
        let (spec, base) = PriorSpec::load(&dir.path().join("p.toml")).unwrap();
        let g = AngleGrid::patent();
        let p = spec.build(&g, 45.0, &base).unwrap();
        assert_eq!(p.samples.ncols(), 2);
        assert!((p.samples[(0, 1)] - 1.1).abs() < 1e-12); // 25 deg: 1 + 5/50

        let bad = dir.path().join("bad.csv");
        std::fs::write(&bad, "20,1.0\n30,abc\n").unwrap();
        let e = format!("{:#}", read_measured_csv(&bad).unwrap_err());
        assert!(e.contains("bad.csv:2") && e.contains("`value`"), "{e}");
        std::fs::write(&bad, "20,1.0\n30,-0.2\n").unwrap();
        let e = format!("{:#}", read_measured_csv(&bad).unwrap_err());
        assert!(e.contains("bad.csv:2") && e.contains("negative"), "{e}");
        std::fs::write(&bad, "20,1.0\n30,NaN\n").unwrap();
        let e = format!("{:#}", read_measured_csv(&bad).unwrap_err());
        assert!(e.contains("bad.csv:2") && e.contains("finite"), "{e}");
        std::fs::write(&bad, "# header comment\n20,1.0\n20,2.0\n").unwrap();
        let e = format!("{:#}", read_measured_csv(&bad).unwrap_err());
        assert!(e.contains("bad.csv:3") && e.contains("`angle_deg`"), "{e}");
        // Too narrow for the grid.
        std::fs::write(&bad, "30,1.0\n40,1.0\n").unwrap();
        let spec = PriorSpec { csv: vec![bad.clone()], ..Default::default() };
        assert!(
            format!("{:#}", spec.build(&g, 45.0, Path::new("")).unwrap_err()).contains("outside the measured span")
        );
    }

    #[test]
    fn prior_files_refuse_impossible_values_and_empty_priors() {
        let e = parse_toml::<PriorSpec>("[[ward_grid]]\nrho_d = [0.5, 1.5]\nalpha = [0.05]\n", "p.toml").unwrap_err();
        assert_eq!(e.field.as_deref(), Some("ward_grid[0].rho_d"));
        assert_eq!(e.line_col.map(|l| l.0), Some(2));
        assert!(parse_toml::<PriorSpec>("", "p.toml").is_err());
        assert!(Prior::from_samples(DMatrix::from_element(3, 1, f64::NAN)).is_err());
    }
}
