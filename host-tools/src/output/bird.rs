//! BiRD universal BRDF data format (JSON): the file format the EURAMET
//! projects BiRD (16NRM08) and BxDiff (18SIB03) agreed on, validated by the
//! consortium's JSON Schema (draft 2020-12, version 1.0) and read by their
//! viewer BiRDview. A file is `{"metadata": {...}, "data": {"variables":
//! [...], "values": [[...], ...]}}`: every row of `values` one BRDF value with
//! the variables that were varied, in the order `variables` lists them.
//!
//! The meter writes the variables `line`, `point`, `theta_i`, `phi_i`,
//! `theta_r`, `phi_r` (deg), `BRDF` and its standard uncertainty `uBRDF`
//! (sr^-1: the reflectance factor R divided by pi). Metadata the meter
//! cannot know (who measured, where, the sample) is written as
//! `"not recorded"` for the user to fill in; environment is `"NA"`.
//!
//! [`check_required`] checks a document against the schema's required lists,
//! vendored in `host-tools/data/bird-schema-required.json` (source named
//! there); [`read`] checks them too before taking the data.
use crate::output::profile::{ExportInfo, PHI_LIGHT_DEG, PHI_VIEW_DEG, Profile};
use anyhow::{Context, bail, ensure};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::Path;

/// The schema a written file names (its `metadata.schema`).
pub const SCHEMA_URI: &str =
    "https://raw.githubusercontent.com/BiRD-project/BiRD_view/master/BRDF_JSON_schema/brdf_json_schema_v1.0.json";

const REQUIRED: &str = include_str!("../../data/bird-schema-required.json");
const NOT_RECORDED: &str = "not recorded";
const VARIABLES: [(&str, &str, &str); 8] = [
    ("line", "", "Line of the measurement (the sensor's scan number)."),
    ("point", "", "Point (pixel) on the line."),
    ("theta_i", "deg", "Illumination light/beam incidence zenith angle."),
    ("phi_i", "deg", "Illumination light/beam incidence azimuthal angle."),
    ("theta_r", "deg", "Reflected light/beam observation zenith angle."),
    ("phi_r", "deg", "Reflected light/beam observation azimuthal angle."),
    ("BRDF", "sr-1", "Bidirectional reflectance distribution function: the meter's reflectance factor divided by pi."),
    ("uBRDF", "sr-1", "Standard uncertainty of BRDF (k = 1), predicted by the calibration for this point."),
];

/// The BiRD document of `profiles`.
pub fn document(profiles: &[Profile], info: &ExportInfo) -> Value {
    let mut values = Vec::new();
    for p in profiles {
        for ((t, r), u) in p.theta_i_deg.iter().zip(&p.reflectance).zip(&p.uncertainty) {
            values.push(json!([p.line, p.point, t, PHI_LIGHT_DEG, info.view_deg, PHI_VIEW_DEG, r / PI, u / PI]));
        }
    }
    let variables: Vec<Value> = VARIABLES
        .iter()
        .map(|(name, unit, description)| json!({"name": name, "type": "number", "unit": unit, "description": description}))
        .collect();
    let flagged: Vec<String> = profiles
        .iter()
        .filter(|p| !p.flags.is_empty())
        .map(|p| format!("line {} point {}: {}", p.line, p.point, p.flags.join(", ")))
        .collect();
    // The gloss readings per point (value and standard uncertainty), which
    // the schema has no field for.
    let readings: Vec<Value> = profiles
        .iter()
        .filter(|p| !p.readings.is_empty())
        .map(|p| {
            let mut o = json!({ "line": p.line, "point": p.point });
            for (name, v, u) in &p.readings {
                o[name.as_str()] = json!(v);
                o[format!("u_{name}")] = json!(u);
            }
            o
        })
        .collect();
    let mut detection = json!({
        "name": "line sensor at a fixed view",
        "sensors": [{ "name": "line sensor", "type": "linear photodiode array" }]
    });
    if let Some(sr) = info.solid_angle_sr {
        detection["solid_angle"] = json!({ "value": sr, "unit": "sr" });
    }
    json!({
        "metadata": {
            "schema": SCHEMA_URI,
            "id": format!("urn:brdf-meter:{}:{}", info.calibration.replace(' ', "-"), info.timestamp),
            "type": "BRDF",
            "name": format!("{} ({} point(s))", info.source, profiles.len()),
            "timestamp": info.timestamp,
            "provenance": {
                "organization": NOT_RECORDED,
                "location": {
                    "country": NOT_RECORDED, "city": NOT_RECORDED, "street": NOT_RECORDED,
                    "building_nr": NOT_RECORDED, "postal_code": NOT_RECORDED
                },
                "email": NOT_RECORDED,
                "contact_person": NOT_RECORDED
            },
            "description": format!(
                "In-plane BRDF profiles measured by the handheld gloss/BRDF meter (Wiener estimation from one reading per LED at each point); calibration {}.",
                info.calibration
            ),
            "method": "measurement",
            "instrumentation": {
                "name": info.instrument,
                "operation_type": "relative",
                "illumination_system": {
                    "name": "LEDs in the plane of incidence, each lit in turn",
                    "source": { "name": "LED", "type": "LED" },
                    "beam": { "shape": "near-field cone of each LED" }
                },
                "detection_system": detection,
                "comments": format!("Viewer at theta_r = {} deg; the white reference is a perfect diffuser.", info.view_deg)
            },
            "software": { "name": "host-tools", "version": env!("CARGO_PKG_VERSION"), "description": info.source },
            "sample": {
                "name": NOT_RECORDED,
                "type": NOT_RECORDED,
                "dimensions": {},
                "shape": NOT_RECORDED,
                "zero_azimuth_location": "the light's side of the plane of incidence is phi = 180 deg, the viewer's phi = 0 deg"
            },
            "environment": "NA",
            "adhoc_section": { "gloss_readings": readings },
            "comments": if flagged.is_empty() { "no point flagged".to_string() } else { format!("flagged: {}", flagged.join("; ")) }
        },
        "data": { "variables": variables, "values": values }
    })
}

/// The BiRD document of a measurement's result: `mean`, its mean BRDF
/// (`uncertainty` the combined standard uncertainty, k = 1), over what
/// `sample` names, with `coverage` (per bin and reading the coverage
/// factor, the expanded uncertainty and the interval, which the schema has
/// no field for) as its ad hoc section's `result`. A mean is of no one
/// line or point, so it has neither variable; its readings are in
/// `coverage`.
pub fn result_document(mean: &Profile, sample: &str, coverage: Value, info: &ExportInfo) -> Value {
    let mut doc = document(std::slice::from_ref(mean), info);
    // Each row's cells, and the variables, in `VARIABLES`' order.
    let without_line_and_point = |cells: &[Value]| -> Vec<Value> {
        cells
            .iter()
            .zip(VARIABLES)
            .filter(|(_, (name, ..))| !matches!(*name, "line" | "point"))
            .map(|(c, _)| c.clone())
            .collect()
    };
    let data = &mut doc["data"];
    let vars = data["variables"].as_array_mut().expect("document writes its variables");
    *vars = without_line_and_point(vars);
    for v in vars.iter_mut().filter(|v| v["name"] == "uBRDF") {
        v["description"] = json!(
            "Combined standard uncertainty of BRDF (k = 1) of the result's mean: the calibration's, the \
             repeatability and the white reference's; its coverage factor and expanded uncertainty per row are in \
             metadata.adhoc_section.result."
        );
    }
    for row in data["values"].as_array_mut().expect("document writes its rows") {
        let cells = row.as_array_mut().expect("a row is an array");
        *cells = without_line_and_point(cells);
    }
    let meta = &mut doc["metadata"];
    meta["name"] = json!(format!("{}: result, {sample}", info.source));
    meta["adhoc_section"] = json!({ "result": coverage });
    meta["comments"] = json!(sample);
    doc
}

/// Writes a measurement's result ([`result_document`]) as a BiRD file,
/// atomically.
pub fn write_result(
    path: &Path,
    mean: &Profile,
    sample: &str,
    coverage: Value,
    info: &ExportInfo,
) -> anyhow::Result<()> {
    let t = pretty(&result_document(mean, sample, coverage, info))?;
    crate::output::io::write_atomic(path, t.as_bytes())
        .with_context(|| format!("writing the result's BiRD file {}", path.display()))
}

/// A document as pretty JSON text, ending in a newline.
fn pretty(doc: &Value) -> anyhow::Result<String> {
    let mut t = serde_json::to_string_pretty(doc).context("serialising the BiRD file")?;
    t.push('\n');
    Ok(t)
}

/// The document as pretty JSON text.
pub fn to_text(profiles: &[Profile], info: &ExportInfo) -> anyhow::Result<String> {
    pretty(&document(profiles, info))
}

/// Writes `profiles` as a BiRD file, atomically.
pub fn write(path: &Path, profiles: &[Profile], info: &ExportInfo) -> anyhow::Result<()> {
    crate::output::io::write_atomic(path, to_text(profiles, info)?.as_bytes())
        .with_context(|| format!("writing the BiRD file {}", path.display()))
}

fn at<'a>(doc: &'a Value, path: &str) -> Option<&'a Value> {
    if path.is_empty() {
        return Some(doc);
    }
    path.split('.').try_fold(doc, |v, k| v.get(k))
}

/// Every required field the vendored schema lists that `doc` lacks, as
/// `path.field` strings (empty: all present).
pub fn check_required(doc: &Value) -> Vec<String> {
    let req: Value = serde_json::from_str(REQUIRED).expect("the vendored required lists are valid JSON");
    let aliases = &req["aliases"];
    let na: Vec<&str> = req["not_applicable_allowed"].as_array().unwrap().iter().filter_map(Value::as_str).collect();
    let mut missing = Vec::new();
    for (path, fields) in req["required"].as_object().unwrap() {
        let obj = match at(doc, path) {
            Some(Value::String(s)) if s == "NA" && na.contains(&path.as_str()) => continue,
            Some(v @ Value::Object(_)) => v,
            // An absent parent is reported by its own parent's list.
            None if path.contains('.') => continue,
            _ => {
                missing.push(format!("{} (an object)", if path.is_empty() { "the document" } else { path }));
                continue;
            }
        };
        for f in fields.as_array().unwrap().iter().filter_map(Value::as_str) {
            let alias = aliases.get(f).and_then(Value::as_str);
            if obj.get(f).is_none() && alias.is_none_or(|a| obj.get(a).is_none()) {
                missing.push(if path.is_empty() { f.to_string() } else { format!("{path}.{f}") });
            }
        }
    }
    if let Some(vars) = at(doc, "data.variables").and_then(Value::as_array) {
        for (i, v) in vars.iter().enumerate() {
            for f in req["variable_required"].as_array().unwrap().iter().filter_map(Value::as_str) {
                if v.get(f).is_none() {
                    missing.push(format!("data.variables[{i}].{f}"));
                }
            }
        }
        for (name, units) in req["variables_contain"].as_object().unwrap() {
            let ok = vars
                .iter()
                .any(|v| v["name"] == name.as_str() && units.as_array().unwrap().iter().any(|u| v["unit"] == *u));
            if !ok {
                missing.push(format!("data.variables: a `{name}` variable with unit {units}"));
            }
        }
    }
    missing
}

/// Reads a BiRD file: checks the required fields, then takes the profiles
/// back (rows grouped by `line` and `point` when the file has them, else one
/// profile; angles in deg or rad; values at this file's `theta_r`).
pub fn read(path: &Path) -> anyhow::Result<(Vec<Profile>, f64)> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("{}: cannot read the BiRD file", path.display()))?;
    let doc: Value = serde_json::from_str(&text).map_err(|e| {
        anyhow::anyhow!(
            "{}:{}:{}: not JSON ({e}); a BiRD file is one JSON object with `metadata` and `data`",
            path.display(),
            e.line(),
            e.column()
        )
    })?;
    let missing = check_required(&doc);
    ensure!(
        missing.is_empty(),
        "{}: not a BiRD universal BRDF file: missing {}; see {SCHEMA_URI}",
        path.display(),
        missing.join(", ")
    );
    let vars = doc["data"]["variables"].as_array().unwrap();
    let col = |name: &str| vars.iter().position(|v| v["name"] == name);
    let scale =
        |name: &str| if vars.iter().any(|v| v["name"] == name && v["unit"] == "rad") { 180.0 / PI } else { 1.0 };
    let (ti, tr, b) = (col("theta_i").unwrap(), col("theta_r").unwrap(), col("BRDF").unwrap());
    let ub = col("uBRDF").unwrap();
    let (line_c, point_c) = (col("line"), col("point"));
    let Some(rows) = doc["data"]["values"].as_array() else {
        bail!("{}: `data.values` is not an array of rows", path.display())
    };
    let mut groups: BTreeMap<(u32, u16), Profile> = BTreeMap::new();
    let mut view = None;
    for (r, row) in rows.iter().enumerate() {
        let cells = row.as_array().filter(|c| c.len() == vars.len()).with_context(|| {
            format!("{}: data.values[{r}]: expected {} numbers, one per variable", path.display(), vars.len())
        })?;
        let num = |c: usize| -> anyhow::Result<f64> {
            cells[c].as_f64().with_context(|| {
                format!("{}: data.values[{r}][{c}] ({}): {} is not a number", path.display(), vars[c]["name"], cells[c])
            })
        };
        let v = num(tr)? * scale("theta_r");
        match view {
            None => view = Some(v),
            Some(w) if (w - v).abs() > 1e-9 => bail!(
                "{}: data.values[{r}]: theta_r {v} deg differs from {w} deg; the meter reads profiles at one view",
                path.display()
            ),
            _ => {}
        }
        let key = (line_c.map_or(Ok(0.0), &num)? as u32, point_c.map_or(Ok(0.0), &num)? as u16);
        let p = groups.entry(key).or_insert_with(|| Profile {
            line: key.0,
            point: key.1,
            flags: Vec::new(),
            theta_i_deg: Vec::new(),
            reflectance: Vec::new(),
            uncertainty: Vec::new(),
            readings: Vec::new(),
        });
        p.theta_i_deg.push(num(ti)? * scale("theta_i"));
        p.reflectance.push(num(b)? * PI);
        p.uncertainty.push(num(ub)? * PI);
    }
    ensure!(!groups.is_empty(), "{}: `data.values` has no rows", path.display());
    Ok((groups.into_values().collect(), view.unwrap()))
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn sample() -> (Vec<Profile>, ExportInfo) {
        let angles: Vec<f64> = (0..5).map(|k| 20.0 + 10.0 * k as f64).collect();
        let p = |line, point, s: f64| Profile {
            line,
            point,
            flags: if point == 7 { vec!["saturated".into()] } else { Vec::new() },
            theta_i_deg: angles.clone(),
            reflectance: angles.iter().map(|a| s * (1.0 + (a / 7.0).sin())).collect(),
            uncertainty: angles.iter().map(|a| 0.01 * s * a / 30.0).collect(),
            readings: vec![("gloss_gu".into(), 80.0 * s, 0.5)],
        };
        let info = ExportInfo {
            view_deg: 45.0,
            source: "host-tools measure".into(),
            instrument: "QEMU instrument".into(),
            calibration: "wiener crc 0x12345678".into(),
            timestamp: "2026-11-22T10:00:00+00:00".into(),
            solid_angle_sr: Some(2.5e-3),
        };
        (vec![p(0, 0, 1.0), p(0, 7, 0.3), p(1, 31, 2.5)], info)
    }

    #[test]
    fn round_trip_keeps_every_value_and_the_view() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("m.bird.json");
        let (profiles, info) = sample();
        write(&f, &profiles, &info).unwrap();
        let (back, view) = read(&f).unwrap();
        assert_eq!(view, 45.0);
        assert_eq!(back.len(), 3);
        for (a, b) in profiles.iter().zip(&back) {
            assert_eq!((a.line, a.point), (b.line, b.point));
            assert_eq!(a.theta_i_deg, b.theta_i_deg);
            for (x, y) in a.reflectance.iter().zip(&b.reflectance).chain(a.uncertainty.iter().zip(&b.uncertainty)) {
                assert!((x - y).abs() <= 1e-15 * x.abs().max(1e-300), "{x} vs {y}");
            }
        }
    }

    #[test]
    fn a_written_file_has_every_field_the_schema_requires() {
        let (profiles, info) = sample();
        let doc = document(&profiles, &info);
        assert_eq!(check_required(&doc), Vec::<String>::new());
        // Without the detector's solid angle, that is the one field missing.
        let unknown = ExportInfo { solid_angle_sr: None, ..info.clone() };
        assert_eq!(
            check_required(&document(&profiles, &unknown)),
            vec!["metadata.instrumentation.detection_system.solid_angle".to_string()]
        );
        assert_eq!(doc["metadata"]["schema"], SCHEMA_URI);
        assert_eq!(doc["metadata"]["adhoc_section"]["gloss_readings"][2]["gloss_gu"], 200.0);
        assert_eq!(doc["metadata"]["adhoc_section"]["gloss_readings"][2]["u_gloss_gu"], 0.5);
        assert_eq!(doc["data"]["values"].as_array().unwrap().len(), 15);
        assert_eq!(
            doc["data"]["values"][0].as_array().unwrap().len(),
            doc["data"]["variables"].as_array().unwrap().len()
        );
        // The check does find what is missing.
        let mut bad = doc.clone();
        bad["metadata"].as_object_mut().unwrap().remove("timestamp");
        bad["metadata"]["provenance"]["location"].as_object_mut().unwrap().remove("city");
        bad["data"]["variables"].as_array_mut().unwrap().retain(|v| v["name"] != "uBRDF");
        let m = check_required(&bad);
        assert!(m.contains(&"metadata.timestamp".to_string()), "{m:?}");
        assert!(m.contains(&"metadata.provenance.location.city".to_string()), "{m:?}");
        assert!(m.iter().any(|x| x.contains("`uBRDF`")), "{m:?}");
    }

    #[test]
    fn bad_files_get_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("bad.json");
        std::fs::write(&f, "{\n  \"metadata\": {,\n}").unwrap();
        let e = format!("{:#}", read(&f).unwrap_err());
        assert!(e.contains("bad.json:2:") && e.contains("not JSON"), "{e}");
        std::fs::write(&f, "{\"metadata\": {}, \"data\": {\"variables\": [], \"values\": []}}").unwrap();
        let e = format!("{:#}", read(&f).unwrap_err());
        assert!(e.contains("not a BiRD universal BRDF file") && e.contains("metadata.schema"), "{e}");
        let (profiles, info) = sample();
        let mut doc = document(&profiles, &info);
        doc["data"]["values"][3] = json!([0, 0, 20.0]);
        std::fs::write(&f, serde_json::to_string(&doc).unwrap()).unwrap();
        let e = format!("{:#}", read(&f).unwrap_err());
        assert!(e.contains("data.values[3]: expected 8 numbers"), "{e}");
    }
}
