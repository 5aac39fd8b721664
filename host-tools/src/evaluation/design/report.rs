//! The `design` report: one table row per candidate (markdown, CSV, JSON),
//! a plot per candidate (held-out error and specular margin against pixel)
//! and a summary plot (error against time per line).
use super::CandidateScore;
use crate::output::plot::{Figure, labelled_line, legend_upper_right, render};
use anyhow::anyhow;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// The markdown table.
pub fn table(scores: &[CandidateScore], estimator: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| candidate | m | die mm (in-plane x across) | gain | short | {estimator} median / 90th / worst | interpolation median / 90th / worst | gloss rel. error median / 90th (interpolation) | uncovered px | min margin deg | black glass sat. long/short | metal sat. long/short | line ms (worst) | estimation ms |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for c in scores {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} x {:.1} | {:.0} | {} | {:.3} / {:.3} / {:.3} | {:.3} / {:.3} / {:.3} | {:.1} / {:.1} % ({:.1} / {:.1} %) | {} | {:+.2} | {} / {} | {} / {} | {:.1} ({:.1}) | {:.2} |",
            c.name,
            c.m,
            c.die_mm,
            c.die_height_mm,
            c.gain,
            if c.short_exposure.is_empty() {
                "-".into()
            } else {
                c.short_exposure.iter().map(|r| format!("1/{r:.0}")).collect::<Vec<_>>().join(" ")
            },
            c.error[0],
            c.error[1],
            c.error[2],
            c.interpolation[0],
            c.interpolation[1],
            c.interpolation[2],
            100.0 * c.gloss[0],
            100.0 * c.gloss[1],
            100.0 * c.gloss_interpolation[0],
            100.0 * c.gloss_interpolation[1],
            c.uncovered,
            c.min_margin_deg,
            c.black_glass_saturated[0],
            c.black_glass_saturated[1],
            c.metal_saturated[0],
            c.metal_saturated[1],
            c.acquisition_ms + c.estimation_ms,
            c.acquisition_worst_ms + c.estimation_ms,
            c.estimation_ms
        );
    }
    s
}

/// The CSV table.
pub fn csv(scores: &[CandidateScore]) -> anyhow::Result<Vec<u8>> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "candidate",
        "m",
        "die_mm",
        "die_height_mm",
        "gain",
        "short_exposures",
        "error_median",
        "error_p90",
        "error_worst",
        "interpolation_median",
        "interpolation_p90",
        "interpolation_worst",
        "gloss_rel_median",
        "gloss_rel_p90",
        "gloss_rel_worst",
        "gloss_interpolation_rel_median",
        "gloss_interpolation_rel_p90",
        "uncovered_pixels",
        "min_margin_deg",
        "black_glass_saturated_long",
        "black_glass_saturated_short",
        "metal_saturated_long",
        "metal_saturated_short",
        "acquisition_ms",
        "acquisition_worst_ms",
        "estimation_ms",
    ])?;
    for c in scores {
        let f = |x: f64| format!("{x:.6}");
        w.write_record([
            c.name.clone(),
            c.m.to_string(),
            f(c.die_mm),
            f(c.die_height_mm),
            f(c.gain),
            c.short_exposure.iter().map(|r| format!("{r}")).collect::<Vec<_>>().join(" "),
            f(c.error[0]),
            f(c.error[1]),
            f(c.error[2]),
            f(c.interpolation[0]),
            f(c.interpolation[1]),
            f(c.interpolation[2]),
            f(c.gloss[0]),
            f(c.gloss[1]),
            f(c.gloss[2]),
            f(c.gloss_interpolation[0]),
            f(c.gloss_interpolation[1]),
            c.uncovered.to_string(),
            f(c.min_margin_deg),
            c.black_glass_saturated[0].to_string(),
            c.black_glass_saturated[1].to_string(),
            c.metal_saturated[0].to_string(),
            c.metal_saturated[1].to_string(),
            f(c.acquisition_ms),
            f(c.acquisition_worst_ms),
            f(c.estimation_ms),
        ])?;
    }
    Ok(w.into_inner()?)
}

struct PixelPlot<'a>(&'a CandidateScore);

impl Figure for PixelPlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let c = self.0;
        let e = |x: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{x}");
        root.fill(&WHITE).map_err(e)?;
        let (top, bottom) = root.split_vertically(root.dim_in_pixel().1 * 3 / 5);
        let p = c.coverage.len().max(1) as f64;
        let ymax =
            c.pixel_errors.iter().flat_map(|(_, a, b)| [a[1], b[1]]).filter(|x| x.is_finite()).fold(0.05f64, f64::max)
                * 1.15;
        let mut chart = ChartBuilder::on(&top)
            .caption(&c.name, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..p, 0.0..ymax)
            .map_err(e)?;
        chart.configure_mesh().y_desc("held-out error / peak").label_style(("sans-serif", 13)).draw().map_err(e)?;
        let series = [
            ("estimator median", RGBColor(31, 119, 180), 0usize, false),
            ("estimator 90th", RGBColor(31, 119, 180), 1, true),
            ("interpolation median", RGBColor(214, 39, 40), 0, false),
        ];
        for (label, col, q, dashed) in series {
            let interp = label.starts_with("interpolation");
            let pts: Vec<(f64, f64)> =
                c.pixel_errors.iter().map(|(px, a, b)| (*px as f64, if interp { b[q] } else { a[q] })).collect();
            let style = ShapeStyle { color: col.mix(if dashed { 0.5 } else { 1.0 }), filled: true, stroke_width: 2 };
            chart.draw_series(pts.iter().map(|pt| Circle::new(*pt, 3, style))).map_err(e)?;
            labelled_line(&mut chart, pts, label, style)?;
        }
        legend_upper_right(&mut chart)?;
        let (lo, hi) = c.coverage.iter().fold((0.0f64, 0.0f64), |a, x| (a.0.min(x.margin_deg), a.1.max(x.margin_deg)));
        let mut cov = ChartBuilder::on(&bottom)
            .margin(12)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..p, (lo - 0.2)..(hi + 0.2))
            .map_err(e)?;
        cov.configure_mesh()
            .x_desc("pixel")
            .y_desc("specular margin [deg]")
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(e)?;
        cov.draw_series(LineSeries::new([(0.0, 0.0), (p, 0.0)], BLACK.mix(0.4))).map_err(e)?;
        cov.draw_series(LineSeries::new(
            c.coverage.iter().map(|x| (x.pixel as f64, x.margin_deg)),
            ShapeStyle { color: RGBColor(44, 160, 44).to_rgba(), filled: true, stroke_width: 2 },
        ))
        .map_err(e)?;
        Ok(())
    }
}

struct Summary<'a>(&'a [CandidateScore]);

impl Figure for Summary<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let e = |x: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{x}");
        root.fill(&WHITE).map_err(e)?;
        let pts: Vec<(f64, f64, &str, bool)> = self
            .0
            .iter()
            .map(|c| (c.acquisition_ms + c.estimation_ms, c.error[1], c.name.as_str(), c.uncovered == 0))
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect();
        anyhow::ensure!(!pts.is_empty(), "nothing to plot");
        let (t0, t1) = pts.iter().fold((f64::INFINITY, 0.0f64), |a, p| (a.0.min(p.0), a.1.max(p.0)));
        let (e0, e1) = pts.iter().fold((f64::INFINITY, 0.0f64), |a, p| (a.0.min(p.1), a.1.max(p.1)));
        let mut chart = ChartBuilder::on(root)
            .caption("held-out error (90th percentile) against time per line", ("sans-serif", 20))
            .margin(20)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d((t0 * 0.9)..(t1 * 1.1), (e0 * 0.9)..(e1 * 1.1))
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("time per line: acquisition + estimation [ms]")
            .y_desc("90th percentile error / peak")
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(e)?;
        for (t, err, name, covered) in &pts {
            let col = if *covered { RGBColor(44, 160, 44) } else { RGBColor(214, 39, 40) };
            chart.draw_series(std::iter::once(Circle::new((*t, *err), 5, col.filled()))).map_err(e)?;
            chart
                .draw_series(std::iter::once(Text::new(
                    name.to_string(),
                    (*t, *err),
                    ("sans-serif", 11).into_font().color(&BLACK.mix(0.8)),
                )))
                .map_err(e)?;
        }
        Ok(())
    }
}

fn slug(name: &str) -> String {
    let s: String =
        name.chars().map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' }).collect();
    s.split('-').filter(|p| !p.is_empty()).collect::<Vec<_>>().join("-")
}

/// Writes `design.md`, `design.csv`, `design.json`, `summary.svg/png` and one
/// `candidate-NAME.svg/png` per candidate into `dir`, atomically; returns the paths.
pub fn write(dir: &Path, scores: &[CandidateScore], estimator: &str) -> anyhow::Result<Vec<PathBuf>> {
    use crate::output::io::write_atomic;
    let mut out = Vec::new();
    let mut put = |name: String, bytes: &[u8]| -> anyhow::Result<()> {
        let p = dir.join(name);
        write_atomic(&p, bytes)?;
        out.push(p);
        Ok(())
    };
    put("design.md".into(), table(scores, estimator).as_bytes())?;
    put("design.csv".into(), &csv(scores)?)?;
    put("design.json".into(), &serde_json::to_vec_pretty(scores)?)?;
    let (svg, png) = render(&Summary(scores), (1000, 700))?;
    put("summary.svg".into(), svg.as_bytes())?;
    put("summary.png".into(), &png)?;
    for c in scores {
        let (svg, png) = render(&PixelPlot(c), (900, 700))?;
        let stem = format!("candidate-{}", slug(&c.name));
        put(format!("{stem}.svg"), svg.as_bytes())?;
        put(format!("{stem}.png"), &png)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::slug;

    #[test]
    fn file_names_come_from_candidate_names() {
        assert_eq!(slug("11 x 4.0 mm, gain x8"), "11-x-4-0-mm-gain-x8");
    }
}
