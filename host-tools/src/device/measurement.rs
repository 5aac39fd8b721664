//! A measurement as files: one CSV row and one JSON object per point, with
//! its BRDF vector, flags, the calibration's predicted per-bin
//! uncertainty for the point's zone, and the point's gloss readings with
//! their standard uncertainties as the device streamed them
//! (`brdf_meter::gloss`; NaN in the CSV, null in the JSON, when the
//! calibration carries no gloss section).
use crate::device::link::PointRecord;
use crate::device::reference::flag_names;
use brdf_meter::blob::BlobView;
use brdf_meter::gloss;
use brdf_meter::shape::READINGS;
use serde::Serialize;

/// One point in the JSON.
#[derive(Serialize)]
pub struct PointJson<'a> {
    pub line: u32,
    pub point: u16,
    pub zone: u16,
    pub flags: Vec<&'static str>,
    pub values: &'a [f32],
    pub uncertainty: Vec<f32>,
    pub readings: [f32; READINGS],
    pub reading_sigma: [f32; READINGS],
}

/// The JSON document.
#[derive(Serialize)]
pub struct MeasureJson<'a> {
    pub blob_crc: u32,
    pub lines: u32,
    pub angles_deg: Vec<f32>,
    pub points: Vec<PointJson<'a>>,
}

/// The CSV text and the JSON document of `points`, measured over `lines`
/// lines with the calibration `view`, on the bins the measurement streamed
/// (every bin unless it asked for a subset; one subset per measurement).
pub fn measurement_files<'a>(view: &BlobView<'_>, lines: u32, points: &'a [PointRecord]) -> (String, MeasureJson<'a>) {
    let d = view.dims();
    let bins: Vec<usize> = points.first().map_or(brdf_meter::protocol::BinRange::all(d.n), |p| p.bins).bins().collect();
    let angles: Vec<f32> = bins.iter().map(|&j| view.grid_deg(j)).collect();
    // The calibration's per-bin uncertainty for the point's zone, times the
    // point's own scale (1 for the linear estimators; the readings' scale for
    // the scale-free ones, whose estimate and uncertainty scale with the point).
    let unc = |p: &PointRecord| -> Vec<f32> {
        bins.iter()
            .map(|&j| view.uncertainty_of(p.zone as usize, p.cluster as usize, j) * p.sigma_scale.abs())
            .collect()
    };
    // CSV: one row per point, rho then uncertainty for each angle.
    let mut csv = String::from("line,point,zone,flags");
    for g in &angles {
        csv.push_str(&format!(",rho_{g}"));
    }
    for g in &angles {
        csv.push_str(&format!(",u_{g}"));
    }
    for r in gloss::NAMES {
        csv.push_str(&format!(",{r}"));
    }
    for r in gloss::NAMES {
        csv.push_str(&format!(",u_{r}"));
    }
    csv.push('\n');
    for p in points {
        csv.push_str(&format!("{},{},{},{}", p.line, p.point, p.zone, flag_names(p.flags).join("|")));
        for v in &p.values {
            csv.push_str(&format!(",{v:e}"));
        }
        for u in unc(p) {
            csv.push_str(&format!(",{u:e}"));
        }
        for r in p.readings.iter().chain(&p.reading_sigma) {
            csv.push_str(&format!(",{r:e}"));
        }
        csv.push('\n');
    }
    let json = MeasureJson {
        blob_crc: view.crc(),
        lines,
        angles_deg: angles,
        points: points
            .iter()
            .map(|p| PointJson {
                line: p.line,
                point: p.point,
                zone: p.zone,
                flags: flag_names(p.flags),
                values: &p.values,
                uncertainty: unc(p),
                readings: p.readings,
                reading_sigma: p.reading_sigma,
            })
            .collect(),
    };
    (csv, json)
}
