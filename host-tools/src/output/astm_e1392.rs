//! ASTM E1392 angle-resolved scatter data as a text table.
//!
//! ASTM E1392 (angle-resolved optical scatter measurements on specular or
//! diffuse surfaces) says what a scatter measurement reports: the incident
//! direction (theta_i, phi_i), the scatter direction (theta_s, phi_s), the
//! wavelength, the polarisation and the BRDF in sr^-1. It fixes no byte
//! layout; the tabular form here is the one BRDF tools call "ASTM" (`.astm`,
//! as the Cornell reflectance data are published): `KEY value` header lines,
//! a `VARS` line naming the comma-separated columns, `NUM_POINTS`, then one
//! row per measured value. `#` starts a comment.
//!
//! The meter's values are reflectance factors R = pi f_r, so the file holds
//! `BRDF = R / pi` (and its standard uncertainty `u_BRDF`, an extra column);
//! angles in degrees, light at phi_i = 180 deg, viewer at phi_s = 0 deg;
//! the wavelength column is the nominal 555 nm of the broadband
//! (luminance-weighted) white LEDs; polarisation 0 = unpolarised (1 = s,
//! 2 = p). The reader takes any column order by the `VARS` names.
use crate::output::profile::{ExportInfo, PHI_LIGHT_DEG, PHI_VIEW_DEG, Profile};
use anyhow::{Context, bail, ensure};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Nominal wavelength written for the broadband meter (nm): the photopic peak.
pub const NOMINAL_WAVELENGTH_NM: f64 = 555.0;
/// The columns written, in order.
pub const VARS: [&str; 8] = ["theta_i", "phi_i", "theta_s", "phi_s", "wavelength", "polarization", "BRDF", "u_BRDF"];

/// One profile as ASTM E1392 text, named by its line and point.
pub fn to_text(p: &Profile, info: &ExportInfo) -> String {
    sample_text(&format!("line {} point {}", p.line, p.point), p, &[], info)
}

/// One profile as ASTM E1392 text, its `SAMPLE` named `sample` (a
/// measurement's result is no one point: `crate::device::measurement_result`),
/// with `more` header lines (`KEY`, value) after its readings: a result's
/// expanded uncertainties.
pub fn sample_text(sample: &str, p: &Profile, more: &[(String, String)], info: &ExportInfo) -> String {
    let mut t = String::new();
    let q = |s: &str| s.replace('"', "'");
    let _ =
        writeln!(t, "# ASTM E1392 angle-resolved scatter data: BRDF in sr^-1 (the meter's reflectance factor / pi)");
    let _ = writeln!(
        t,
        "# angles in deg; light at phi_i = 180, viewer at phi_s = 0; polarization 0 = unpolarized, 1 = s, 2 = p"
    );
    let _ = writeln!(
        t,
        "# wavelength: broadband white LEDs seen with luminance weights; {NOMINAL_WAVELENGTH_NM} nm is nominal"
    );
    let _ = writeln!(t, "SOURCE \"{}\"", q(&info.source));
    let _ = writeln!(t, "INSTRUMENT \"{}\"", q(&info.instrument));
    let _ = writeln!(t, "CALIBRATION \"{}\"", q(&info.calibration));
    let _ = writeln!(t, "SAMPLE \"{}\"", q(sample));
    let _ = writeln!(t, "DATE \"{}\"", info.timestamp);
    for (name, v, u) in &p.readings {
        let _ = writeln!(t, "{} \"{v} (standard uncertainty {u})\"", name.to_ascii_uppercase());
    }
    for (key, value) in more {
        let _ = writeln!(t, "{key} \"{}\"", q(value));
    }
    if !p.flags.is_empty() {
        let _ = writeln!(t, "FLAGS \"{}\"", p.flags.join(","));
    }
    let _ = writeln!(t, "VARS {}", VARS.join(","));
    let _ = writeln!(t, "NUM_POINTS {}", p.theta_i_deg.len());
    for ((ti, r), u) in p.theta_i_deg.iter().zip(&p.reflectance).zip(&p.uncertainty) {
        let _ = writeln!(
            t,
            "{ti},{PHI_LIGHT_DEG},{},{PHI_VIEW_DEG},{NOMINAL_WAVELENGTH_NM},0,{:e},{:e}",
            info.view_deg,
            r / PI,
            u / PI
        );
    }
    t
}

/// The file each profile goes to: `base` itself for one profile, else
/// `STEM-l<line>-p<point>.EXT` beside it.
pub fn file_names(base: &Path, profiles: &[Profile]) -> Vec<PathBuf> {
    if profiles.len() == 1 {
        return vec![base.to_path_buf()];
    }
    let stem = base.file_stem().map_or("measure".into(), |s| s.to_string_lossy().into_owned());
    let ext = base.extension().map(|e| format!(".{}", e.to_string_lossy())).unwrap_or_default();
    profiles.iter().map(|p| base.with_file_name(format!("{stem}-l{}-p{}{ext}", p.line, p.point))).collect()
}

/// Writes every profile (see [`file_names`]), each atomically; returns the paths.
pub fn write(base: &Path, profiles: &[Profile], info: &ExportInfo) -> anyhow::Result<Vec<PathBuf>> {
    let names = file_names(base, profiles);
    for (p, f) in profiles.iter().zip(&names) {
        crate::output::io::write_atomic(f, to_text(p, info).as_bytes())
            .with_context(|| format!("writing the ASTM E1392 file {}", f.display()))?;
    }
    Ok(names)
}

/// An ASTM E1392 table as read: header keywords, column names, rows.
#[derive(Clone, Debug, PartialEq)]
pub struct AstmTable {
    /// `KEY value` header lines (quotes removed), in file order.
    pub header: Vec<(String, String)>,
    /// Column names from `VARS`, lower case.
    pub vars: Vec<String>,
    /// The rows.
    pub rows: Vec<Vec<f64>>,
    /// Each row's line in the file (1-based), for errors.
    pub row_lines: Vec<usize>,
}

fn polarisation_code(tok: &str) -> Option<f64> {
    match tok.to_ascii_lowercase().as_str() {
        "u" | "unpolarized" | "unpolarised" => Some(0.0),
        "s" => Some(1.0),
        "p" => Some(2.0),
        _ => None,
    }
}

/// Reads a table; every problem names the file, the line and what to do.
pub fn read(path: &Path) -> anyhow::Result<AstmTable> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the ASTM E1392 file", path.display()))?;
    parse(&text, &path.display().to_string())
}

/// Parses table text; `origin` names it in errors.
pub fn parse(text: &str, origin: &str) -> anyhow::Result<AstmTable> {
    let mut t = AstmTable { header: Vec::new(), vars: Vec::new(), rows: Vec::new(), row_lines: Vec::new() };
    let mut num_points: Option<(usize, usize)> = None;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let s = raw.split('#').next().unwrap_or("").trim();
        if s.is_empty() {
            continue;
        }
        let first = s.chars().next().unwrap();
        if first.is_ascii_digit() || matches!(first, '-' | '+' | '.') {
            ensure!(
                !t.vars.is_empty(),
                "{origin}:{line}: a data row before the VARS line; put `VARS {}` above the rows",
                VARS.join(",")
            );
            let toks: Vec<&str> = s.split(|c: char| c == ',' || c.is_whitespace()).filter(|x| !x.is_empty()).collect();
            ensure!(
                toks.len() == t.vars.len(),
                "{origin}:{line}: {} value(s), but VARS names {} column(s) ({})",
                toks.len(),
                t.vars.len(),
                t.vars.join(",")
            );
            let mut row = Vec::with_capacity(toks.len());
            for (c, tok) in toks.iter().enumerate() {
                let x = match tok.parse::<f64>() {
                    Ok(x) if x.is_finite() => x,
                    _ if t.vars[c] == "polarization" => polarisation_code(tok).with_context(|| {
                        format!("{origin}:{line}: column {} (polarization): {tok:?} is not 0/1/2 or u/s/p", c + 1)
                    })?,
                    _ => bail!("{origin}:{line}: column {} ({}): {tok:?} is not a finite number", c + 1, t.vars[c]),
                };
                row.push(x);
            }
            t.rows.push(row);
            t.row_lines.push(line);
            continue;
        }
        let (key, value) = s.split_once(|c: char| c.is_whitespace() || c == ':').unwrap_or((s, ""));
        let value = value.trim().trim_matches('"').to_string();
        match key.to_ascii_uppercase().as_str() {
            "VARS" => {
                t.vars = value
                    .split(|c: char| c == ',' || c.is_whitespace())
                    .filter(|x| !x.is_empty())
                    .map(str::to_ascii_lowercase)
                    .collect();
                ensure!(!t.vars.is_empty(), "{origin}:{line}: VARS names no columns");
            }
            "NUM_POINTS" => {
                let n = value
                    .parse()
                    .map_err(|_| anyhow::anyhow!("{origin}:{line}: NUM_POINTS {value:?} is not a count of rows"))?;
                num_points = Some((n, line));
            }
            k => t.header.push((k.to_string(), value)),
        }
    }
    ensure!(
        !t.vars.is_empty(),
        "{origin}: no VARS line; an ASTM E1392 table names its columns with `VARS {}`",
        VARS.join(",")
    );
    ensure!(!t.rows.is_empty(), "{origin}: no data rows after VARS");
    if let Some((n, line)) = num_points {
        ensure!(n == t.rows.len(), "{origin}:{line}: NUM_POINTS says {n} but the file has {} row(s)", t.rows.len());
    }
    Ok(t)
}

/// One in-plane value: incidence, scatter zenith (deg) and reflectance factor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InPlane {
    /// theta_i (deg).
    pub theta_i: f64,
    /// theta_s (deg).
    pub theta_s: f64,
    /// R = pi f_r.
    pub reflectance: f64,
}

impl AstmTable {
    fn col(&self, names: &[&str]) -> Option<usize> {
        names.iter().find_map(|n| self.vars.iter().position(|v| v == n))
    }

    /// The values in the plane of incidence (light and viewer on opposite
    /// sides of the normal, or either at the normal) as reflectance factors.
    /// Refuses several wavelengths (the meter is broadband: give one) and
    /// impossible angles or values, naming the line.
    pub fn in_plane(&self, origin: &str) -> anyhow::Result<Vec<InPlane>> {
        let need = |names: &[&str]| {
            self.col(names).with_context(|| {
                format!("{origin}: no `{}` column in VARS ({}); the meter needs it", names[0], self.vars.join(","))
            })
        };
        let (ti, ts, b) = (need(&["theta_i"])?, need(&["theta_s", "theta_r"])?, need(&["brdf"])?);
        let (pi_c, ps_c) = (self.col(&["phi_i"]), self.col(&["phi_s", "phi_r"]));
        if let Some(w) = self.col(&["wavelength"]) {
            let first = self.rows[0][w];
            if let Some(k) = self.rows.iter().position(|r| (r[w] - first).abs() > 1e-9) {
                bail!(
                    "{origin}:{}: wavelength {} besides {first}: the meter is broadband; keep one wavelength (or a luminance-weighted value) per file",
                    self.row_lines[k],
                    self.rows[k][w]
                );
            }
        }
        let mut out = Vec::new();
        for (r, line) in self.rows.iter().zip(&self.row_lines) {
            for (c, name) in [(ti, "theta_i"), (ts, "theta_s")] {
                ensure!(
                    (0.0..=90.0).contains(&r[c]),
                    "{origin}:{line}: {name} {} deg is outside [0, 90] (angles are in degrees)",
                    r[c]
                );
            }
            ensure!(r[b] >= 0.0, "{origin}:{line}: BRDF {} is negative; a BRDF is >= 0 sr^-1", r[b]);
            let dphi = match (pi_c, ps_c) {
                (Some(a), Some(s)) => (r[s] - r[a]).rem_euclid(360.0),
                _ => 180.0,
            };
            if r[ti] < 1e-9 || r[ts] < 1e-9 || (dphi - 180.0).abs() < 0.5 {
                out.push(InPlane { theta_i: r[ti], theta_s: r[ts], reflectance: PI * r[b] });
            }
        }
        ensure!(
            !out.is_empty(),
            "{origin}: no value in the plane of incidence (|phi_s - phi_i| = 180 deg); the meter measures in-plane"
        );
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> (Profile, ExportInfo) {
        let angles: Vec<f64> = (0..7).map(|k| 15.0 + 10.0 * k as f64).collect();
        let p = Profile {
            line: 2,
            point: 9,
            flags: vec!["out-of-prior".into()],
            reflectance: angles.iter().map(|a| 0.2 + (a / 20.0).cos().abs()).collect(),
            uncertainty: angles.iter().map(|a| 1e-3 * a).collect(),
            readings: vec![("haze_hu".into(), 12.5, 0.25)],
            theta_i_deg: angles,
        };
        let info = ExportInfo {
            view_deg: 45.0,
            source: "host-tools estimate".into(),
            instrument: "offline".into(),
            calibration: "scale-free crc 0xabcdef01".into(),
            timestamp: "2026-11-22T10:00:00+00:00".into(),
            solid_angle_sr: None,
        };
        (p, info)
    }

    #[test]
    fn round_trip_gives_back_the_reflectance_factors_in_plane() {
        let (p, info) = sample();
        let text = to_text(&p, &info);
        assert!(text.contains("VARS theta_i,phi_i,theta_s,phi_s,wavelength,polarization,BRDF,u_BRDF"));
        let t = parse(&text, "m.astm").unwrap();
        assert_eq!(t.rows.len(), 7);
        assert!(t.header.contains(&("SAMPLE".into(), "line 2 point 9".into())));
        assert!(t.header.contains(&("HAZE_HU".into(), "12.5 (standard uncertainty 0.25)".into())));
        let v = t.in_plane("m.astm").unwrap();
        for (k, x) in v.iter().enumerate() {
            assert_eq!(x.theta_i, p.theta_i_deg[k]);
            assert_eq!(x.theta_s, 45.0);
            assert!((x.reflectance - p.reflectance[k]).abs() < 1e-14 * p.reflectance[k], "{x:?}");
        }
        // BRDF in the file is R / pi.
        let brdf = t.rows[0][6];
        assert!((brdf * PI - p.reflectance[0]).abs() < 1e-14);
    }

    #[test]
    fn several_profiles_go_to_one_file_each() {
        let (p, _) = sample();
        let q = Profile { line: 3, point: 0, ..p.clone() };
        let names = file_names(Path::new("out/m.astm"), &[p.clone(), q]);
        assert_eq!(names, vec![PathBuf::from("out/m-l2-p9.astm"), PathBuf::from("out/m-l3-p0.astm")]);
        assert_eq!(file_names(Path::new("out/m.astm"), &[p]), vec![PathBuf::from("out/m.astm")]);
    }

    #[test]
    fn bad_tables_name_the_line_and_what_to_do() {
        for (text, want) in [
            ("SOURCE x\n20,180,45,0,555,0,0.1\n", "f.astm:2: a data row before the VARS line"),
            ("VARS theta_i,theta_s,BRDF\n20,45\n", "f.astm:2: 2 value(s), but VARS names 3"),
            ("VARS theta_i,theta_s,BRDF\n20,45,abc\n", "f.astm:2: column 3 (brdf): \"abc\" is not a finite number"),
            (
                "VARS theta_i,theta_s,BRDF\nNUM_POINTS 3\n20,45,0.1\n",
                "f.astm:2: NUM_POINTS says 3 but the file has 1 row(s)",
            ),
            ("# nothing\n", "f.astm: no VARS line"),
        ] {
            let e = format!("{:#}", parse(text, "f.astm").unwrap_err());
            assert!(e.contains(want), "{text:?}: {e}");
        }
        for (text, want) in [
            ("VARS theta_i,theta_s,BRDF\n20,95,0.1\n", "f.astm:2: theta_s 95 deg is outside [0, 90]"),
            ("VARS theta_i,theta_s,BRDF\n20,45,-0.1\n", "f.astm:2: BRDF -0.1 is negative"),
            ("VARS theta_i,theta_s,wavelength,BRDF\n20,45,500,0.1\n30,45,600,0.1\n", "f.astm:3: wavelength 600"),
            ("VARS theta_i,phi_i,theta_s,phi_s,BRDF\n20,0,45,90,0.1\n", "no value in the plane of incidence"),
            ("VARS theta_i,BRDF\n20,0.1\n", "no `theta_s` column"),
        ] {
            let e = format!("{:#}", parse(text, "f.astm").unwrap().in_plane("f.astm").unwrap_err());
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }
}
