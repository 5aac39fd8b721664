//! The options `measure` and `estimate` share for what they hand the user
//! besides their CSV/JSON: a plot of chosen points' BRDF profiles and the
//! standard files (BiRD universal BRDF JSON, ASTM E1392 tables).
use crate::device::measurement_result::{BrdfResult, MeasurementResult};
use crate::output::profile::{ExportInfo, Profile};
use anyhow::{Context, bail, ensure};
use std::path::PathBuf;

/// A calibration as the files name it: its estimator kind and CRC.
pub fn calibration_label(view: &brdf_meter::blob::BlobView<'_>) -> String {
    format!("{} blob crc {:#010x}", crate::calibration::estimators::kind_name(view.estimator()), view.crc())
}

/// The instrument's view angle the files assume unless told (deg).
pub const DEFAULT_VIEW_DEG: f64 = 45.0;

/// Plot and standard-file options.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct ExportArgs {
    /// Plot chosen points' BRDF profiles with their uncertainty band and
    /// gloss readings; .svg or .png by the name.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    /// Points to plot, comma-separated: pixels of the first line (estimate
    /// without a `pixel` column: rows of the readings); default: first,
    /// middle, last.
    #[arg(long, value_delimiter = ',', value_name = "P,P,...")]
    pub plot_points: Vec<usize>,
    /// Write every point as one BiRD universal BRDF JSON file.
    #[arg(long, value_name = "FILE")]
    pub bird: Option<PathBuf>,
    /// Write every point as an ASTM E1392 table (BRDF in sr^-1); more than
    /// one point: one file each, named `STEM-l<line>-p<point>.EXT`.
    #[arg(long, value_name = "FILE")]
    pub astm: Option<PathBuf>,
    /// Write the result's mean BRDF, with its combined standard
    /// uncertainty per bin and the gloss readings' results, as one ASTM
    /// E1392 table.
    #[arg(long, value_name = "FILE")]
    pub result_astm: Option<PathBuf>,
    /// Write the result's mean BRDF as one BiRD universal BRDF JSON file:
    /// its combined standard uncertainty per bin, and per bin and reading
    /// the coverage factor, expanded uncertainty and interval.
    #[arg(long, value_name = "FILE")]
    pub result_bird: Option<PathBuf>,
    /// The instrument's view angle (deg): the scatter direction in the files,
    /// and the mirror incidence the points' specular peak is sought about.
    #[arg(long, default_value_t = DEFAULT_VIEW_DEG, value_name = "DEG")]
    pub view_deg: f64,
    /// Solid angle one detector element sees (sr), for the BiRD file (its
    /// schema requires it; the meter's description does not hold it).
    #[arg(long, value_name = "SR")]
    pub solid_angle_sr: Option<f64>,
}

impl ExportArgs {
    /// Refuses impossible options before anything is measured.
    pub fn check(&self) -> anyhow::Result<()> {
        ensure!(
            self.view_deg.is_finite() && (0.0..90.0).contains(&self.view_deg),
            "--view-deg {}: a view angle is in [0, 90) deg",
            self.view_deg
        );
        if let Some(sr) = self.solid_angle_sr {
            ensure!(
                sr.is_finite() && sr > 0.0 && sr <= 4.0 * std::f64::consts::PI,
                "--solid-angle-sr {sr}: must be in (0, 4 pi]"
            );
        }
        if let Some(p) = &self.plot {
            let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
            if ext != "svg" && ext != "png" {
                bail!(
                    "--plot {}: the plot is written as .svg or .png; give a file name with one of those",
                    p.display()
                );
            }
        }
        Ok(())
    }

    /// What the files say of where their points came from: `source` the
    /// command, `instrument` what read them, `calibration` the blob
    /// (`calibration_label`, and what else the command adds), now.
    pub fn info(&self, source: &str, instrument: String, calibration: String) -> ExportInfo {
        ExportInfo {
            view_deg: self.view_deg,
            source: source.into(),
            instrument,
            calibration,
            timestamp: crate::output::profile::utc_now(),
            solid_angle_sr: self.solid_angle_sr,
        }
    }

    /// Writes everything asked for, the points' files ([`Self::write`])
    /// and the result's ([`Self::write_result`]), and prints a line per
    /// file.
    pub fn write_and_say(
        &self,
        profiles: &[Profile],
        result: &MeasurementResult,
        info: &ExportInfo,
        title: &str,
    ) -> anyhow::Result<()> {
        for line in self.write(profiles, info, title)?.into_iter().chain(self.write_result(result, info)?) {
            println!("{line}");
        }
        Ok(())
    }

    /// The points to plot: `plot_points` among the first line's points, or
    /// its first, middle and last.
    pub fn chosen<'a>(&self, profiles: &'a [Profile]) -> anyhow::Result<Vec<&'a Profile>> {
        let Some(first) = profiles.first().map(|p| p.line) else { bail!("no points to plot") };
        let line: Vec<&Profile> = profiles.iter().filter(|p| p.line == first).collect();
        if self.plot_points.is_empty() {
            let mut idx = vec![0, line.len() / 2, line.len() - 1];
            idx.dedup();
            return Ok(idx.into_iter().map(|i| line[i]).collect());
        }
        self.plot_points
            .iter()
            .map(|&k| {
                line.iter().copied().find(|p| usize::from(p.point) == k).ok_or_else(|| {
                    anyhow::anyhow!(
                        "--plot-points {k}: line {first} has points {}..={}; choose among them",
                        line.first().map_or(0, |p| p.point),
                        line.last().map_or(0, |p| p.point)
                    )
                })
            })
            .collect()
    }

    /// Writes what was asked for; returns one line per file for the user.
    pub fn write(&self, profiles: &[Profile], info: &ExportInfo, title: &str) -> anyhow::Result<Vec<String>> {
        let mut said = Vec::new();
        if let Some(p) = &self.plot {
            let chosen: Vec<Profile> = self.chosen(profiles)?.into_iter().cloned().collect();
            crate::output::plot::profiles::write(p, title, &chosen)?;
            said.push(format!("plot of {} point(s): {}", chosen.len(), p.display()));
        }
        if let Some(p) = &self.bird {
            crate::output::bird::write(p, profiles, info)?;
            let missing = crate::output::bird::check_required(&crate::output::bird::document(profiles, info));
            said.push(format!("BiRD universal BRDF file: {}", p.display()));
            if !missing.is_empty() {
                said.push(format!(
                    "  the BiRD schema also requires {} (give --solid-angle-sr for the detector's solid angle)",
                    missing.join(", ")
                ));
            }
        }
        if let Some(p) = &self.astm {
            let names = crate::output::astm_e1392::write(p, profiles, info)?;
            said.push(match names.as_slice() {
                [one] => format!("ASTM E1392 table: {}", one.display()),
                many => format!(
                    "ASTM E1392 tables: {} files, {} .. {}",
                    many.len(),
                    many[0].display(),
                    many[many.len() - 1].display()
                ),
            });
        }
        Ok(said)
    }

    /// Writes the result's mean BRDF where `--result-astm` and
    /// `--result-bird` ask; what was written (or why nothing was), one line
    /// per file, for the user.
    pub fn write_result(&self, result: &MeasurementResult, info: &ExportInfo) -> anyhow::Result<Vec<String>> {
        let asked: Vec<&PathBuf> = self.result_astm.iter().chain(&self.result_bird).collect();
        if asked.is_empty() {
            return Ok(Vec::new());
        }
        let Some(b) = &result.brdf else {
            return Ok(asked
                .iter()
                .map(|p| format!("{}: not written, no point of the result has a finite estimate", p.display()))
                .collect());
        };
        let mean = Profile {
            line: 0,
            point: 0,
            flags: Vec::new(),
            theta_i_deg: b.bins_deg.iter().map(|x| f64::from(*x)).collect(),
            reflectance: b.value.clone(),
            uncertainty: b.u.clone(),
            readings: result.readings.iter().map(|r| (r.reading.to_string(), r.value, r.u)).collect(),
        };
        let sample = result.sample();
        let mut said = Vec::new();
        if let Some(path) = &self.result_astm {
            let more = result_astm_coverage(result, b);
            let text = crate::output::astm_e1392::sample_text(&sample, &mean, &more, info);
            crate::output::io::write_atomic(path, text.as_bytes())
                .with_context(|| format!("writing the ASTM E1392 file {}", path.display()))?;
            said.push(format!("ASTM E1392 table of the result: {}", path.display()));
        }
        if let Some(path) = &self.result_bird {
            let coverage = result_bird_coverage(result, b);
            crate::output::bird::write_result(path, &mean, &sample, coverage, info)?;
            said.push(format!("BiRD universal BRDF file of the result: {}", path.display()));
        }
        Ok(said)
    }
}

/// A result's coverage for its ASTM table's header, beside the standard
/// uncertainties the table holds: each reading's expanded uncertainty, k
/// and interval, and the range of the bins' coverage factors.
fn result_astm_coverage(result: &MeasurementResult, b: &BrdfResult) -> Vec<(String, String)> {
    let percent = 100.0 * result.coverage_probability;
    let readings = result.readings.iter().map(|r| {
        (
            format!("{}_EXPANDED", r.reading.to_ascii_uppercase()),
            format!(
                "U {} at k = {:.2} ({percent:.2} %): interval {} .. {}",
                r.expanded_u, r.coverage_factor, r.interval[0], r.interval[1]
            ),
        )
    });
    let (k_lo, k_hi) = b.coverage_factor.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), k| (lo.min(*k), hi.max(*k)));
    let bins =
        ("BRDF_EXPANDED".to_string(), format!("U = k u_BRDF per bin, k {k_lo:.2} to {k_hi:.2} ({percent:.2} %)"));
    readings.chain([bins]).collect()
}

/// A result's coverage for its BiRD file's ad hoc section, in the file's
/// unit, sr^-1 (the reflectance factor / pi): the coverage probability,
/// per bin the coverage factor, expanded uncertainty and interval, the
/// points, and the readings' results as the result document gives them.
fn result_bird_coverage(result: &MeasurementResult, b: &BrdfResult) -> serde_json::Value {
    let per_sr = |x: &f64| x / std::f64::consts::PI;
    serde_json::json!({
        "coverage_probability": result.coverage_probability,
        "coverage_factor": b.coverage_factor,
        "expanded_uncertainty_BRDF": b.expanded_u.iter().map(per_sr).collect::<Vec<_>>(),
        "interval_BRDF": b.interval.iter().map(|[lo, hi]| [per_sr(lo), per_sr(hi)]).collect::<Vec<_>>(),
        "points": b.points,
        "out_of_prior": result.out_of_prior,
        "saturated_left_out": result.saturated,
        "readings": result.readings,
    })
}
