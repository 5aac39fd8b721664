//! The point schema: how `measure` (the device's estimates) and `estimate`
//! (offline, the device's rule on logged readings) write their points, one
//! schema for both, so a point reads the same wherever it came from.
//! `docs/point-schema.md` documents every field; a golden file pins the
//! bytes (`host-tools/tests/point_schema.rs`).
//!
//! One list of fields (`Points::fields`) makes both files: a CSV row or
//! a JSON object per point, with the same names in the same order; a
//! per-bin field is one CSV column per bin (`rho_<deg>`) and one JSON array
//! (`rho`, the degrees in the document's `bins_deg`). The CSV's first line
//! is a `#` comment with the schema, its version, the calibration and the
//! units (no comma in it, so even a reader that does not skip comments sees
//! one cell); the JSON carries the same as fields. A number that is not
//! there (NaN: no reading, no peak) is an empty CSV field and a JSON null.
//! Numbers are written as the shortest text that reads back to the same f32,
//! identical in the CSV and the JSON.
use crate::device::reference::flag_names;
use crate::output::peak::{Peak, specular_peak};
use anyhow::Context;
use brdf_meter::protocol::flags::NON_FINITE;
use brdf_meter::shape::READINGS;
use serde::ser::{SerializeMap, Serializer};
use std::borrow::Cow;
use std::path::Path;

/// The schema's name, in both files.
pub const SCHEMA: &str = "brdf-meter/points";
/// The schema's version: bumped when a field is renamed, removed, added,
/// moved or changes its meaning, unit or rule for when it is missing
/// (`docs/point-schema.md`).
pub const SCHEMA_VERSION: u32 = 3;

/// The unit of each quantity, by field name; a field `u_X` is the standard
/// uncertainty of `X` in the same unit. Units that are the same stand
/// together (the CSV's comment groups them).
pub const UNITS: [(&str, &str); 12] = [
    ("rho", RF),
    ("peak_rf", RF),
    ("gloss_gu", "GU (specular gloss units: the black-glass standard n = 1.567 reads 100)"),
    ("haze_hu", "HU (haze units: on the gloss units' black-glass scale)"),
    ("distinctness_pct", "%"),
    ("bins_deg", "deg"),
    ("view_deg", "deg"),
    ("peak_deg", "deg"),
    ("peak_width_deg", "deg"),
    ("peak_resolution_deg", "deg"),
    ("zone", "index"),
    ("cluster", "index"),
];
const RF: &str = "reflectance factor R = pi f_r (a perfect diffuser is 1)";

/// What the `u_` fields are, in both files.
pub const UNCERTAINTY: &str = "u_X is the standard uncertainty (k = 1) of X in the unit of X";

/// The gloss readings' fields and their uncertainties', in the readings'
/// order (`brdf_meter::gloss::NAMES`, checked by a test).
const READING_FIELDS: [[&str; 2]; READINGS] =
    [["gloss_gu", "u_gloss_gu"], ["haze_hu", "u_haze_hu"], ["distinctness_pct", "u_distinctness_pct"]];

/// One point, from the device or offline.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// The line it was measured on (`None`: offline, the input had no `line` column).
    pub line: Option<u64>,
    /// Its pixel on the line (`None`: offline, the input had no `pixel` column).
    pub pixel: Option<u64>,
    /// The calibration zone that estimated it.
    pub zone: u16,
    /// The cluster within the zone (piecewise calibrations; 0 otherwise).
    pub cluster: u8,
    /// Flag bits (`brdf_meter::protocol::flags`), written by name.
    pub flags: u8,
    /// The reflectance factor per bin.
    pub rho: Vec<f32>,
    /// Its standard uncertainty per bin.
    pub u_rho: Vec<f32>,
    /// The gloss readings (`brdf_meter::gloss`; NaN: no reading).
    pub readings: [f32; READINGS],
    /// Their standard uncertainties.
    pub u_readings: [f32; READINGS],
}

/// `; N peak(s) not resolved (narrower than W deg)` for a summary line,
/// nothing when no peak is unresolved or the calibration records no
/// resolution.
pub fn unresolved_note(u: Option<Unresolved>) -> String {
    match u {
        Some(Unresolved { peaks, narrower_than_deg: (lo, hi) }) if peaks > 0 => {
            let w = if hi - lo < 0.005 { format!("{hi:.2}") } else { format!("{lo:.2}-{hi:.2}") };
            format!("; {peaks} peak(s) not resolved (narrower than {w} deg at their pixels: no uncertainty stated)")
        }
        _ => String::new(),
    }
}

/// A calibration's peak resolutions as [`Points`] holds them: its own (the
/// widest) and each pixel's.
pub fn peak_resolutions(view: &brdf_meter::blob::BlobView<'_>) -> (Option<f64>, Vec<f64>) {
    let own = (0..view.dims().pixels).map(|p| view.peak_resolution_at(p).map_or(f64::NAN, f64::from)).collect();
    (view.peak_resolution_deg().map(f64::from), own)
}

/// The peaks a set of points' calibration does not resolve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unresolved {
    /// How many points' peaks are not resolved (`peak_resolved` false).
    pub peaks: usize,
    /// The narrowest and the widest width below which the points' pixels
    /// resolve no peak (`RESOLVED_WIDTH_FACTOR` times their resolutions).
    pub narrower_than_deg: (f64, f64),
}

/// A set of points and what they are on: one CSV file, one JSON document.
#[derive(Clone, Debug, PartialEq)]
pub struct Points {
    /// The command that made them: `measure` or `estimate`.
    pub source: &'static str,
    /// CRC of the calibration blob that estimated them.
    pub calibration_crc: u32,
    /// The view angle (deg): the specular peak is sought about its mirror incidence.
    pub view_deg: f64,
    /// The calibration's peak resolution (deg; `None`: it records none),
    /// the widest over its pixels: narrower peaks are not resolved
    /// (`crate::output::peak`).
    pub peak_resolution_deg: Option<f64>,
    /// Each pixel's own peak resolution (deg, by pixel; NaN or past the end:
    /// the calibration's): a point's peak is judged at its pixel's.
    pub pixel_peak_resolution_deg: Vec<f64>,
    /// The calibration's factors on a resolved peak's uncertainties
    /// (`crate::output::peak`; `None`: it records none).
    pub peak_factors: Option<crate::output::peak::PeakFactors>,
    /// Incidence of each bin (deg).
    pub bins_deg: Vec<f32>,
    /// The points.
    pub points: Vec<Point>,
}

/// A field's value.
enum Value<'a> {
    /// A whole number, or nothing.
    Whole(Option<u64>),
    /// Flag bits, written by name.
    Flags(u8),
    /// One number per bin.
    Bins(Cow<'a, [f32]>),
    /// A number (NaN: nothing).
    Number(f32),
    /// Yes or no, or nothing.
    Bool(Option<bool>),
}

/// The shortest text that reads back to `x`, as serde_json writes an f32;
/// empty when `x` is not a number.
fn number_text(x: f32) -> String {
    if x.is_finite() { serde_json::to_string(&x).expect("a finite f32 serialises") } else { String::new() }
}

/// Which gloss readings scale with the readings (and so with the white
/// reference they are divided by, and the gloss scale), in the readings'
/// order: gloss and haze do; distinctness, a ratio of two of them, does
/// not.
pub const READINGS_SCALE: [bool; READINGS] = [true, true, false];

/// `u`, the standard uncertainty of the value `x`, with a reference's
/// relative standard uncertainty `rel` added in quadrature.
fn add_relative(u: f32, x: f32, rel: f64) -> f32 {
    f64::from(u).hypot(rel * f64::from(x)) as f32
}

/// The relative standard uncertainty a calibration's references give its
/// gloss and haze readings: the white reference's and the gloss scale's, in
/// quadrature ([`Points::with_reference_uncertainties`]).
fn on_gloss_readings(white: f64, gloss_scale: f64) -> f64 {
    white.hypot(gloss_scale)
}

impl Points {
    /// Every stated uncertainty with the calibration's standards' relative
    /// standard uncertainties added in quadrature, as relative terms (a
    /// standardised calibration's, `brdf_meter::blob::with_white_uncertainty`
    /// and `with_gloss_uncertainty`):
    /// - the white reference's `white` on each value that scales with the
    ///   readings: every bin's reflectance, gloss and haze (and so the
    ///   specular peak's height, which `crate::output::peak` takes from the
    ///   bins); not distinctness, a ratio;
    /// - the gloss scale's `gloss_scale` (the black glass's) on gloss and
    ///   haze, which are read on its scale.
    ///
    /// Both are taken whole on gloss and haze: the white's cancels in a
    /// gloss standardised right after it only as far as the LEDs drifted
    /// alike, so stating it is the safe side. Nothing changes when both
    /// are 0.
    pub fn with_reference_uncertainties(mut self, white: f64, gloss_scale: f64) -> Self {
        let add = add_relative;
        let on_readings = on_gloss_readings(white, gloss_scale);
        for p in &mut self.points {
            if white > 0.0 {
                for (u, x) in p.u_rho.iter_mut().zip(&p.rho) {
                    *u = add(*u, *x, white);
                }
            }
            if on_readings > 0.0 {
                for k in (0..READINGS).filter(|k| READINGS_SCALE[*k]) {
                    p.u_readings[k] = add(p.u_readings[k], p.readings[k], on_readings);
                }
            }
        }
        self
    }

    /// [`Self::with_reference_uncertainties`] with those the calibration
    /// `view` states (`BlobView::white_uncertainty`, `gloss_uncertainty`).
    pub fn with_standards_of(self, view: &brdf_meter::blob::BlobView<'_>) -> Self {
        self.with_reference_uncertainties(f64::from(view.white_uncertainty()), f64::from(view.gloss_uncertainty()))
    }

    /// The points as profiles for the plot and the standard files, the
    /// same values and uncertainties as the schema's files: each on its
    /// line and pixel, or (offline, without them) on line 0 at its row.
    pub fn profiles(&self) -> Vec<crate::output::profile::Profile> {
        let theta_i_deg: Vec<f64> = self.bins_deg.iter().map(|x| f64::from(*x)).collect();
        let wide = |x: &[f32]| x.iter().map(|y| f64::from(*y)).collect::<Vec<f64>>();
        self.points
            .iter()
            .enumerate()
            .map(|(row, p)| crate::output::profile::Profile {
                line: p.line.map_or(0, |l| u32::try_from(l).unwrap_or(u32::MAX)),
                point: u16::try_from(p.pixel.unwrap_or(row as u64)).unwrap_or(u16::MAX),
                flags: flag_names(p.flags).into_iter().map(String::from).collect(),
                theta_i_deg: theta_i_deg.clone(),
                reflectance: wide(&p.rho),
                uncertainty: wide(&p.u_rho),
                readings: crate::device::measurement::readings_of(&p.readings, &p.u_readings),
            })
            .collect()
    }

    /// A point's fields in the schema's order, with its specular peak.
    fn fields<'a>(&self, p: &'a Point) -> Vec<(&'static str, Value<'a>)> {
        let peak = self.peak(p);
        // A non-finite point's values are the device's guard (zeros, so a
        // reader that ignores flags sees a flat curve), no estimate: it has no
        // uncertainty, whichever source (the device's frame scales the
        // calibration's, `estimate` zeroes it).
        let u_rho = if p.flags & NON_FINITE != 0 {
            Cow::Owned(vec![f32::NAN; p.u_rho.len()])
        } else {
            Cow::Borrowed(p.u_rho.as_slice())
        };
        let mut f = vec![
            ("line", Value::Whole(p.line)),
            ("pixel", Value::Whole(p.pixel)),
            ("zone", Value::Whole(Some(u64::from(p.zone)))),
            ("cluster", Value::Whole(Some(u64::from(p.cluster)))),
            ("flags", Value::Flags(p.flags)),
            ("rho", Value::Bins(Cow::Borrowed(&p.rho))),
            ("u_rho", Value::Bins(u_rho)),
        ];
        for (k, [name, u]) in READING_FIELDS.into_iter().enumerate() {
            f.extend([(name, Value::Number(p.readings[k])), (u, Value::Number(p.u_readings[k]))]);
        }
        // The peak is computed in f64 from f32 bins; written as f32 like every other number.
        f.extend([
            ("peak_rf", Value::Number(peak.rf as f32)),
            ("u_peak_rf", Value::Number(peak.u_rf as f32)),
            ("peak_deg", Value::Number(peak.deg as f32)),
            ("peak_width_deg", Value::Number(peak.width_deg as f32)),
            ("u_peak_width_deg", Value::Number(peak.u_width_deg as f32)),
            ("peak_resolution_deg", Value::Number(self.resolution_of(p).map_or(f32::NAN, |r| r as f32))),
            ("peak_resolved", Value::Bool(peak.resolved)),
        ]);
        f
    }

    /// How many points' specular peaks the calibration does not resolve
    /// (`peak_resolved` false), and the widths below which their pixels do
    /// not (`None`: the calibration records no resolution).
    pub fn unresolved_peaks(&self) -> Option<Unresolved> {
        self.peak_resolution_deg?;
        let f = crate::output::peak::RESOLVED_WIDTH_FACTOR;
        let widths = self.points.iter().filter_map(|p| self.resolution_of(p)).map(|r| f * r);
        let narrower_than_deg = widths.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), w| (lo.min(w), hi.max(w)));
        let peaks = self.points.iter().filter(|p| self.peak(p).resolved == Some(false)).count();
        Some(Unresolved { peaks, narrower_than_deg })
    }

    /// The peak resolution point `p` is judged at: its pixel's own, else
    /// the calibration's.
    fn resolution_of(&self, p: &Point) -> Option<f64> {
        let own = p.pixel.and_then(|i| self.pixel_peak_resolution_deg.get(i as usize)).filter(|r| r.is_finite());
        own.copied().or(self.peak_resolution_deg)
    }

    /// Point `p`'s specular peak as the files write it: sought about the
    /// view, read at its pixel's resolution.
    fn peak(&self, p: &Point) -> Peak {
        specular_peak(&self.bins_deg, &p.rho, &p.u_rho, self.view_deg).stated(self.resolution_of(p), self.peak_factors)
    }

    /// The CSV's first line: schema, version, where the points came from, and the units.
    fn csv_comment(&self) -> anyhow::Result<String> {
        let mut groups: Vec<(Vec<&str>, &str)> = Vec::new();
        for (q, unit) in UNITS {
            match groups.last_mut() {
                Some((names, u)) if *u == unit => names.push(q),
                _ => groups.push((vec![q], unit)),
            }
        }
        let units: Vec<String> = groups.iter().map(|(names, unit)| format!("{} = {unit}", names.join(" "))).collect();
        Ok(format!(
            "# {SCHEMA} schema_version {SCHEMA_VERSION}; source {}; calibration_crc {:#010x}; view_deg {}; \
             peak_resolution_deg {}; {UNCERTAINTY}; units: {}\n",
            self.source,
            self.calibration_crc,
            // As the JSON writes them.
            serde_json::to_string(&self.view_deg).context("the view angle")?,
            serde_json::to_string(&self.peak_resolution_deg).context("the peak resolution")?,
            units.join("; ")
        ))
    }

    /// The CSV file: the comment line, the header, one row per point.
    pub fn csv(&self) -> anyhow::Result<Vec<u8>> {
        let mut w = csv::Writer::from_writer(self.csv_comment()?.into_bytes());
        let n = self.bins_deg.len();
        let template = Point {
            line: None,
            pixel: None,
            zone: 0,
            cluster: 0,
            flags: 0,
            rho: vec![f32::NAN; n],
            u_rho: vec![f32::NAN; n],
            readings: [f32::NAN; READINGS],
            u_readings: [f32::NAN; READINGS],
        };
        let mut header = Vec::new();
        for (name, v) in self.fields(&template) {
            match v {
                Value::Bins(_) => header.extend(self.bins_deg.iter().map(|d| format!("{name}_{d}"))),
                _ => header.push(name.to_string()),
            }
        }
        w.write_record(&header).context("writing the CSV header")?;
        for (i, p) in self.points.iter().enumerate() {
            anyhow::ensure!(
                p.rho.len() == n && p.u_rho.len() == n,
                "point {i}: {} value(s) and {} uncertainties for {n} bins",
                p.rho.len(),
                p.u_rho.len()
            );
            let mut rec = Vec::with_capacity(header.len());
            for (_, v) in self.fields(p) {
                match v {
                    Value::Whole(x) => rec.push(x.map_or(String::new(), |x| x.to_string())),
                    Value::Flags(bits) => rec.push(flag_names(bits).join("|")),
                    Value::Bins(xs) => rec.extend(xs.iter().map(|&x| number_text(x))),
                    Value::Number(x) => rec.push(number_text(x)),
                    Value::Bool(x) => rec.push(x.map_or(String::new(), |x| x.to_string())),
                }
            }
            w.write_record(&rec).with_context(|| format!("writing point {i} to the CSV"))?;
        }
        w.into_inner().map_err(|e| anyhow::anyhow!("writing the CSV: {e}"))
    }

    /// The JSON document (pretty, ending in a newline).
    pub fn json(&self) -> anyhow::Result<Vec<u8>> {
        let mut out = serde_json::to_vec_pretty(&JsonDocument(self)).context("serialising the JSON")?;
        out.push(b'\n');
        Ok(out)
    }

    /// Writes the CSV and, when asked, the JSON, each atomically; both are
    /// made before either is written.
    pub fn write(&self, csv: &Path, json: Option<&Path>) -> anyhow::Result<()> {
        let csv_bytes = self.csv()?;
        let json_bytes = json.map(|_| self.json()).transpose()?;
        crate::output::io::write_atomic(csv, &csv_bytes).with_context(|| format!("writing {}", csv.display()))?;
        if let (Some(p), Some(b)) = (json, json_bytes) {
            crate::output::io::write_atomic(p, &b).with_context(|| format!("writing {}", p.display()))?;
        }
        Ok(())
    }
}

/// The document: the schema's fields, then the points.
struct JsonDocument<'a>(&'a Points);

impl serde::Serialize for JsonDocument<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let d = self.0;
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("schema", SCHEMA)?;
        m.serialize_entry("schema_version", &SCHEMA_VERSION)?;
        m.serialize_entry("source", d.source)?;
        m.serialize_entry("calibration_crc", &format!("{:#010x}", d.calibration_crc))?;
        m.serialize_entry("view_deg", &d.view_deg)?;
        m.serialize_entry("peak_resolution_deg", &d.peak_resolution_deg)?;
        m.serialize_entry("uncertainty", UNCERTAINTY)?;
        m.serialize_entry("units", &Units)?;
        m.serialize_entry("bins_deg", &d.bins_deg)?;
        let points: Vec<JsonPoint<'_>> = d.points.iter().map(|p| JsonPoint(d.fields(p))).collect();
        m.serialize_entry("points", &points)?;
        m.end()
    }
}

/// The units as an object, in [`UNITS`]' order.
struct Units;

impl serde::Serialize for Units {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_map(UNITS)
    }
}

/// One point as an object of its fields.
struct JsonPoint<'a>(Vec<(&'static str, Value<'a>)>);

impl serde::Serialize for JsonPoint<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (name, v) in &self.0 {
            // serde_json writes a non-finite f32 as null.
            match v {
                Value::Whole(x) => m.serialize_entry(name, x)?,
                Value::Flags(bits) => m.serialize_entry(name, &flag_names(*bits))?,
                Value::Bins(xs) => m.serialize_entry(name, xs)?,
                Value::Number(x) => m.serialize_entry(name, x)?,
                Value::Bool(x) => m.serialize_entry(name, x)?,
            }
        }
        m.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf_meter::protocol::flags;

    fn points() -> Points {
        let bins: Vec<f32> = (0..21).map(|i| 40.0 + 0.5 * i as f32).collect();
        let lobe: Vec<f32> = bins.iter().map(|&t| 0.2 + (1.0 - (t - 45.0).abs() / 2.0).max(0.0)).collect();
        Points {
            source: "measure",
            calibration_crc: 0x00c0_ffee,
            view_deg: 45.0,
            peak_resolution_deg: Some(0.75),
            pixel_peak_resolution_deg: vec![],
            peak_factors: None,
            bins_deg: bins.clone(),
            points: vec![
                Point {
                    line: Some(3),
                    pixel: Some(17),
                    zone: 1,
                    cluster: 2,
                    flags: flags::SATURATED | flags::OUT_OF_PRIOR,
                    rho: lobe.clone(),
                    u_rho: vec![0.01; 21],
                    readings: [80.5, 2.25, 97.0],
                    u_readings: [0.5, 0.125, 1.0],
                },
                Point {
                    line: None,
                    pixel: None,
                    zone: 0,
                    cluster: 0,
                    flags: 0,
                    rho: vec![0.3; 21],
                    u_rho: vec![0.02; 21],
                    readings: [f32::NAN; READINGS],
                    u_readings: [f32::NAN; READINGS],
                },
            ],
        }
    }

    #[test]
    fn the_csv_and_the_json_have_the_same_fields_in_the_same_order() {
        let p = points();
        let csv = String::from_utf8(p.csv().unwrap()).unwrap();
        let mut lines = csv.lines();
        let comment = lines.next().unwrap();
        assert!(
            comment.starts_with("# brdf-meter/points schema_version 3; source measure; calibration_crc 0x00c0ffee")
        );
        assert!(!comment.contains(','), "a reader that does not skip comments sees one cell: {comment}");
        for (q, unit) in UNITS {
            assert!(comment.contains(q) && comment.contains(unit), "{q} {unit}: {comment}");
        }
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let text = String::from_utf8(p.json().unwrap()).unwrap();
        let j: serde_json::Value = serde_json::from_str(&text).unwrap();
        // The first point's keys in the order written (serde_json's map sorts
        // them): the pretty printer puts them 6 spaces in, one a line.
        let first = &text[text.find("\"points\": [").unwrap()..];
        let keys: Vec<&str> = first
            .lines()
            .take_while(|l| *l != "    },")
            .filter_map(|l| l.strip_prefix("      \"")?.split('"').next())
            .collect();
        // The CSV's columns are the JSON's keys with the per-bin ones spread out.
        let spread: Vec<String> = keys
            .iter()
            .flat_map(|k| match *k {
                "rho" | "u_rho" => p.bins_deg.iter().map(|d| format!("{k}_{d}")).collect(),
                _ => vec![k.to_string()],
            })
            .collect();
        assert_eq!(header, spread);
        assert_eq!(&keys[..7], &["line", "pixel", "zone", "cluster", "flags", "rho", "u_rho"]);
        assert_eq!(header[5], "rho_40");
        assert_eq!(header[6], "rho_40.5");
        assert_eq!(header[26], "u_rho_40");
        assert_eq!(
            &keys[7..],
            &[
                "gloss_gu",
                "u_gloss_gu",
                "haze_hu",
                "u_haze_hu",
                "distinctness_pct",
                "u_distinctness_pct",
                "peak_rf",
                "u_peak_rf",
                "peak_deg",
                "peak_width_deg",
                "u_peak_width_deg",
                "peak_resolution_deg",
                "peak_resolved"
            ]
        );
        // The reading fields are the library's names.
        for (k, name) in brdf_meter::gloss::NAMES.iter().enumerate() {
            assert_eq!(READING_FIELDS[k], [*name, &format!("u_{name}")]);
        }
        assert_eq!(j["schema"], SCHEMA);
        assert_eq!(j["schema_version"], 3);
        assert_eq!(j["calibration_crc"], "0x00c0ffee");
        assert_eq!(j["units"].as_object().unwrap().len(), UNITS.len());
        assert_eq!(j["bins_deg"].as_array().unwrap().len(), 21);
    }

    #[test]
    fn values_are_the_same_text_in_both_files_and_missing_ones_are_empty_or_null() {
        let p = points();
        let csv = String::from_utf8(p.csv().unwrap()).unwrap();
        let rows: Vec<Vec<&str>> = csv.lines().skip(2).map(|l| l.split(',').collect()).collect();
        let j: serde_json::Value = serde_json::from_slice(&p.json().unwrap()).unwrap();
        let first = &j["points"][0];
        assert_eq!(&rows[0][..5], &["3", "17", "1", "2", "saturated|out-of-prior"]);
        assert_eq!(first["flags"], serde_json::json!(["saturated", "out-of-prior"]));
        assert_eq!(rows[0][47], "80.5");
        assert_eq!(first["gloss_gu"], 80.5);
        // The peak: the triangle's top over its level, 2 deg wide at half of it.
        let (rf, width) = (first["peak_rf"].as_f64().unwrap(), first["peak_width_deg"].as_f64().unwrap());
        assert!((rf - 1.2).abs() < 1e-6 && first["peak_deg"] == 45.0, "{first}");
        assert!((width - 2.4).abs() < 1e-5, "half of 1.2 is 0.2 + 0.4, 1.2 deg either side: {first}");
        assert_eq!(first["u_peak_rf"].as_f64().unwrap() as f32, 0.01);
        // 2.4 deg wide at a resolution of 0.75: resolved; the flat point has no peak.
        assert_eq!((rows[0][59], &first["peak_resolved"]), ("true", &serde_json::json!(true)));
        assert_eq!((rows[1][59], &j["points"][1]["peak_resolved"]), ("", &serde_json::Value::Null));
        assert_eq!(j["peak_resolution_deg"], 0.75);
        // Each point states the resolution it was judged at: the calibration's
        // when its pixel has none of its own (or it has no pixel).
        assert_eq!((rows[0][58], rows[1][58]), ("0.75", "0.75"));
        assert_eq!(j["points"][1]["peak_resolution_deg"], 0.75);
        // The triangle is resolved; a resolution of 2 deg would not resolve it.
        let peaks = |p: &Points| p.unresolved_peaks().map(|u| u.peaks);
        let f = crate::output::peak::RESOLVED_WIDTH_FACTOR;
        assert_eq!(p.unresolved_peaks(), Some(Unresolved { peaks: 0, narrower_than_deg: (f * 0.75, f * 0.75) }));
        let coarse = Points { peak_resolution_deg: Some(2.0), ..p.clone() };
        assert_eq!(peaks(&coarse), Some(1));
        assert_eq!(Points { peak_resolution_deg: None, ..p.clone() }.unresolved_peaks(), None);
        // A pixel's own resolution decides for its points: pixel 17 resolves
        // 0.75 deg, finer than the calibration's widest (2 deg), and so the
        // triangle the widest would not; the second point, of no pixel, is
        // judged at the widest.
        let own = Points { pixel_peak_resolution_deg: [vec![f64::NAN; 17], vec![0.75]].concat(), ..coarse.clone() };
        assert_eq!(peaks(&own), Some(0));
        assert_eq!(own.unresolved_peaks().unwrap().narrower_than_deg, (f * 0.75, f * 2.0));
        let own_csv = String::from_utf8(own.csv().unwrap()).unwrap();
        let cells = |row: usize| own_csv.lines().nth(row).unwrap().split(',').nth(58).map(str::to_string);
        assert_eq!((cells(2), cells(3)), (Some("0.75".into()), Some("2.0".into())));
        assert_eq!(
            unresolved_note(Some(Unresolved { peaks: 3, narrower_than_deg: (f * 0.75, f * 2.0) })),
            "; 3 peak(s) not resolved (narrower than 1.06-2.83 deg at their pixels: no uncertainty stated)"
        );
        assert_eq!(unresolved_note(coarse.unresolved_peaks()).matches("narrower than 2.83 deg").count(), 1);
        let json = String::from_utf8(p.json().unwrap()).unwrap();
        for (col, name) in [(47, "gloss_gu"), (53, "peak_rf"), (56, "peak_width_deg"), (57, "u_peak_width_deg")] {
            let line = format!("\"{name}\": {}", rows[0][col]);
            assert!(json.lines().any(|l| l.trim().trim_end_matches(',') == line), "{line} not in {json}");
        }
        // No line, pixel, readings or peak: empty in the CSV, null in the JSON.
        let second = &j["points"][1];
        assert_eq!(&rows[1][..5], &["", "", "0", "0", ""]);
        // (Its pixel's resolution it has: the calibration's.)
        assert!(rows[1][47..].iter().enumerate().all(|(i, f)| f.is_empty() == (i != 11)), "{:?}", &rows[1][47..]);
        for k in ["line", "pixel", "gloss_gu", "u_distinctness_pct", "peak_rf", "peak_width_deg"] {
            assert!(second[k].is_null(), "{k}: {}", second[k]);
        }
        assert_eq!(second["flags"], serde_json::json!([]));
    }

    #[test]
    fn a_non_finite_point_has_its_zeros_and_no_uncertainty() {
        let mut p = points();
        p.points[0].flags = flags::NON_FINITE;
        p.points[0].rho = vec![0.0; 21];
        let csv = String::from_utf8(p.csv().unwrap()).unwrap();
        let row: Vec<&str> = csv.lines().nth(2).unwrap().split(',').collect();
        assert!(row[5..26].iter().all(|f| *f == "0.0") && row[26..47].iter().all(|f| f.is_empty()), "{row:?}");
        let j: serde_json::Value = serde_json::from_slice(&p.json().unwrap()).unwrap();
        assert!(j["points"][0]["u_rho"].as_array().unwrap().iter().all(serde_json::Value::is_null));
        assert!(j["points"][0]["peak_rf"].is_null());
        // The other point keeps its uncertainty.
        assert_eq!(j["points"][1]["u_rho"][0].as_f64().map(|u| u as f32), Some(0.02));
    }

    #[test]
    fn a_point_of_other_bins_is_refused_and_nothing_is_written() {
        let mut p = points();
        p.points[1].u_rho.pop();
        let dir = tempfile::tempdir().unwrap();
        let (c, j) = (dir.path().join("p.csv"), dir.path().join("p.json"));
        let e = p.write(&c, Some(&j)).unwrap_err().to_string();
        assert!(e.contains("point 1: 21 value(s) and 20 uncertainties for 21 bins"), "{e}");
        assert!(!c.exists() && !j.exists());
        points().write(&c, Some(&j)).unwrap();
        assert!(c.exists() && j.exists());
    }

    /// The plot's and the standard files' profiles carry the files'
    /// values: a point on its line and pixel, or offline on line 0 at its row.
    #[test]
    fn profiles_carry_the_files_values_on_their_line_and_pixel() {
        let p = points();
        let pr = p.profiles();
        assert_eq!((pr[0].line, pr[0].point, pr[1].line, pr[1].point), (3, 17, 0, 1));
        assert_eq!(pr[0].flags, vec!["saturated", "out-of-prior"]);
        assert_eq!(pr[0].theta_i_deg[2], 41.0);
        assert_eq!(pr[0].reflectance[10], f64::from(p.points[0].rho[10]));
        assert_eq!(pr[1].uncertainty, vec![f64::from(0.02f32); 21]);
        assert_eq!(pr[0].readings[1], ("haze_hu".to_string(), 2.25, 0.125));
        assert_eq!(pr[0].readings.len(), 3);
        assert!(pr[1].readings.is_empty());
    }

    #[test]
    fn a_standardised_calibrations_uncertainties_are_added_to_what_scales_with_them() {
        let p = points();
        // (By their text: the point without readings holds NaN.)
        let same = format!("{:?}", p.clone().with_reference_uncertainties(0.0, 0.0));
        assert_eq!(same, format!("{p:?}"), "nothing stated, nothing changes");
        let quad = |u: f32, x: f32, rel: f64| (f64::from(u).powi(2) + (rel * f64::from(x)).powi(2)).sqrt();
        for (white, gloss) in [(0.01, 0.0), (0.0, 0.02), (0.01, 0.02)] {
            let w = p.clone().with_reference_uncertainties(white, gloss);
            for (a, b) in p.points.iter().zip(&w.points) {
                for ((u, x), v) in a.u_rho.iter().zip(&a.rho).zip(&b.u_rho) {
                    let want = quad(*u, *x, white);
                    assert!((f64::from(*v) - want).abs() <= 1e-6 * want, "{v} vs {want}");
                }
                for (k, scales) in READINGS_SCALE.iter().enumerate() {
                    if *scales && a.readings[k].is_finite() {
                        let want = quad(a.u_readings[k], a.readings[k], f64::hypot(white, gloss));
                        assert!((f64::from(b.u_readings[k]) - want).abs() <= 1e-6 * want, "reading {k}");
                    } else if a.u_readings[k].is_finite() {
                        assert_eq!(b.u_readings[k], a.u_readings[k], "reading {k}");
                    }
                }
            }
        }
        assert_eq!(brdf_meter::gloss::NAMES[2], "distinctness_pct", "the reading that does not scale");
    }
}
