//! What a measurement tells its user at a glance: per line, how many points,
//! the mean and spread (sample standard deviation over the points) of each
//! gloss reading (`brdf_meter::gloss`: specular GU, haze HU, distinctness %),
//! and how many points carry each flag. `measure` and `estimate` print it.
use crate::device::reference::flag_names;
use brdf_meter::gloss;
use brdf_meter::protocol::flags;
use brdf_meter::shape::READINGS;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// What the summary needs of one point.
#[derive(Clone, Copy, Debug)]
pub struct SummaryPoint {
    /// Its line (`None`: offline readings without a `line` column).
    pub line: Option<u32>,
    /// Flag bits (`brdf_meter::protocol::flags`).
    pub flags: u8,
    /// Its gloss readings (NaN: none).
    pub readings: [f32; READINGS],
}

/// Mean and spread of one reading over a line's points that have it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Spread {
    /// Points with a finite reading.
    pub count: usize,
    /// Their mean.
    pub mean: f64,
    /// Their sample standard deviation (0 for one point).
    pub sd: f64,
}

/// One line of the summary.
#[derive(Clone, Debug, PartialEq)]
pub struct LineSummary {
    /// The line (`None`: the offline readings without a `line` column).
    pub line: Option<u32>,
    /// Points.
    pub points: usize,
    /// Each reading, in `gloss::NAMES` order.
    pub readings: [Spread; READINGS],
    /// Flag name -> points carrying it, in name order.
    pub flags: BTreeMap<&'static str, usize>,
}

/// The count, mean and sample standard deviation of `xs`.
pub fn spread(xs: &[f64]) -> Spread {
    let n = xs.len();
    if n == 0 {
        return Spread::default();
    }
    let mean = xs.iter().sum::<f64>() / n as f64;
    let sd = if n < 2 { 0.0 } else { (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt() };
    Spread { count: n, mean, sd }
}

/// The summary, one entry per line in line order.
pub fn summarise(points: impl IntoIterator<Item = SummaryPoint>) -> Vec<LineSummary> {
    let mut by_line: BTreeMap<Option<u32>, Vec<SummaryPoint>> = BTreeMap::new();
    for p in points {
        by_line.entry(p.line).or_default().push(p);
    }
    by_line
        .into_iter()
        .map(|(line, pts)| {
            // A saturated point's values are not to be used: its flag is
            // counted, its readings are not (as the result leaves it out).
            let readings = std::array::from_fn(|r| {
                let xs: Vec<f64> = pts
                    .iter()
                    .filter(|p| p.flags & flags::SATURATED == 0)
                    .map(|p| f64::from(p.readings[r]))
                    .filter(|x| x.is_finite())
                    .collect();
                spread(&xs)
            });
            let mut flags = BTreeMap::new();
            for p in &pts {
                for f in flag_names(p.flags) {
                    *flags.entry(f).or_insert(0) += 1;
                }
            }
            LineSummary { line, points: pts.len(), readings, flags }
        })
        .collect()
}

/// The summary as a plain-text table.
pub fn table(lines: &[LineSummary]) -> String {
    let mut t = String::new();
    let heads = ["gloss GU", "haze HU", "distinctness %"];
    let _ = write!(t, "{:<6} {:>6}", "line", "points");
    for h in heads {
        let _ = write!(t, "  {:>26}", format!("{h} (mean ± sd)"));
    }
    let _ = writeln!(t, "  flags");
    for l in lines {
        let line = l.line.map_or("all".to_string(), |x| x.to_string());
        let _ = write!(t, "{line:<6} {:>6}", l.points);
        for s in &l.readings {
            let cell = if s.count == 0 {
                "-".to_string()
            } else if s.count < l.points {
                format!("{:.2} ± {:.2} ({} pts)", s.mean, s.sd, s.count)
            } else {
                format!("{:.2} ± {:.2}", s.mean, s.sd)
            };
            let _ = write!(t, "  {cell:>26}");
        }
        let flags: Vec<String> = l.flags.iter().map(|(k, v)| format!("{k} {v}")).collect();
        let _ = writeln!(t, "  {}", if flags.is_empty() { "none".to_string() } else { flags.join(", ") });
    }
    if lines.iter().all(|l| l.readings.iter().all(|s| s.count == 0)) {
        let _ =
            writeln!(t, "(no gloss readings: the calibration carries no gloss section; `-` marks a missing reading)");
    }
    debug_assert_eq!(gloss::NAMES.len(), heads.len());
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf_meter::protocol::flags;

    fn p(line: u32, f: u8, r: [f32; READINGS]) -> SummaryPoint {
        SummaryPoint { line: Some(line), flags: f, readings: r }
    }

    #[test]
    fn per_line_mean_spread_and_flag_counts() {
        let nan = f32::NAN;
        let s = summarise([
            p(1, 0, [80.0, 2.0, 90.0]),
            p(0, flags::SATURATED, [10.0, 1.0, nan]),
            p(0, 0, [20.0, 3.0, nan]),
            p(0, flags::SATURATED | flags::OUT_OF_PRIOR, [30.0, 5.0, 70.0]),
        ]);
        assert_eq!(s.len(), 2);
        assert_eq!((s[0].line, s[0].points, s[1].line, s[1].points), (Some(0), 3, Some(1), 1));
        // The saturated points' readings are left out; their flags count.
        assert_eq!(s[0].readings[0], Spread { count: 1, mean: 20.0, sd: 0.0 });
        assert_eq!(s[0].readings[1], Spread { count: 1, mean: 3.0, sd: 0.0 });
        assert_eq!(s[0].readings[2], Spread { count: 0, mean: 0.0, sd: 0.0 });
        assert_eq!(s[0].flags.get("saturated"), Some(&2));
        assert_eq!(s[0].flags.get("out-of-prior"), Some(&1));
        let t = table(&s);
        let rows: Vec<&str> = t.lines().collect();
        assert!(rows[0].starts_with("line") && rows[0].contains("gloss GU (mean ± sd)") && rows[0].contains("flags"));
        assert!(
            rows[1].starts_with("0") && rows[1].contains("20.00 ± 0.00 (1 pts)") && rows[1].contains("  -  "),
            "{}",
            rows[1]
        );
        assert!(rows[1].ends_with("out-of-prior 1, saturated 2"), "{}", rows[1]);
        assert!(rows[2].contains("80.00 ± 0.00") && rows[2].ends_with("none"));
        assert_eq!(rows.len(), 3);
    }

    #[test]
    fn without_readings_the_table_says_why() {
        let t = table(&summarise([SummaryPoint { line: None, flags: 0, readings: gloss::NO_READINGS }]));
        assert!(t.lines().nth(1).unwrap().starts_with("all"), "{t}");
        assert!(t.contains("  -") && t.contains("no gloss readings"), "{t}");
    }
}
