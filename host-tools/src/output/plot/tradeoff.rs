//! The trade-off plot: host time per point (log axis) against RMSE (log
//! axis), one marker per estimator coloured by family, the Pareto front drawn
//! as a step line through its rows, and every row labelled. SVG and PNG from
//! the same drawing code (plotters).
use crate::evaluation::tradeoff::Row;
use anyhow::anyhow;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

fn colour(group: &str) -> RGBColor {
    match group {
        "linear" => RGBColor(31, 119, 180),
        "prior" => RGBColor(127, 127, 127),
        "fit" => RGBColor(214, 39, 40),
        "clustered" => RGBColor(44, 160, 44),
        "log" => RGBColor(148, 103, 189),
        "format" => RGBColor(255, 127, 14),
        _ => RGBColor(0, 0, 0),
    }
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, rows: &[Row], title: &str) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let ok: Vec<&Row> =
        rows.iter().filter(|r| r.host_seconds_per_point > 0.0 && r.rmse > 0.0 && r.rmse.is_finite()).collect();
    anyhow::ensure!(!ok.is_empty(), "nothing to plot");
    let (mut t0, mut t1, mut e0, mut e1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for r in &ok {
        t0 = t0.min(r.host_seconds_per_point);
        t1 = t1.max(r.host_seconds_per_point);
        e0 = e0.min(r.rmse);
        e1 = e1.max(r.rmse);
    }
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 22))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d((t0 / 3.0..t1 * 3.0).log_scale(), (e0 / 1.5..e1 * 1.5).log_scale())
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .x_desc("host time per point [s] (log)")
        .y_desc("RMSE of the reflectance factor (log)")
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.2}"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    // Pareto front: sorted by time, a step line.
    let mut front: Vec<&Row> = ok.iter().copied().filter(|r| r.pareto).collect();
    front.sort_by(|a, b| a.host_seconds_per_point.total_cmp(&b.host_seconds_per_point));
    let mut steps = Vec::new();
    for (i, r) in front.iter().enumerate() {
        if i > 0 {
            steps.push((r.host_seconds_per_point, front[i - 1].rmse));
        }
        steps.push((r.host_seconds_per_point, r.rmse));
    }
    chart
        .draw_series(LineSeries::new(steps, ShapeStyle { color: BLACK.mix(0.6), filled: false, stroke_width: 2 }))
        .map_err(|e| anyhow!("{e}"))?
        .label("Pareto front")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    for group in ["linear", "prior", "clustered", "log", "format", "fit"] {
        let pts: Vec<&Row> = ok.iter().copied().filter(|r| r.group == group).collect();
        if pts.is_empty() {
            continue;
        }
        let c = colour(group);
        chart
            .draw_series(pts.iter().map(|r| {
                let style = if r.pareto { c.filled() } else { c.stroke_width(2) };
                Circle::new((r.host_seconds_per_point, r.rmse), if r.pareto { 6 } else { 5 }, style)
            }))
            .map_err(|e| anyhow!("{e}"))?
            .label(group)
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, c.filled()));
    }
    // Labels: only the Pareto rows and a few landmarks, to stay readable.
    for r in &ok {
        let landmark = r.pareto || r.group == "fit" || r.group == "linear" || r.group == "log" || r.id.ends_with("q15");
        if !landmark {
            continue;
        }
        chart
            .draw_series(std::iter::once(Text::new(
                r.id.clone(),
                (r.host_seconds_per_point * 1.12, r.rmse * 1.02),
                ("sans-serif", 12).into_font().color(&BLACK.mix(0.8)),
            )))
            .map_err(|e| anyhow!("{e}"))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

/// Writes `stem.svg` and `stem.png`, atomically.
pub fn write(stem: &Path, rows: &[Row], title: &str) -> anyhow::Result<(std::path::PathBuf, std::path::PathBuf)> {
    struct Fig<'a>(&'a [Row], &'a str);
    impl crate::output::plot::Figure for Fig<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
        where
            DB::ErrorType: 'static,
        {
            draw(root, self.0, self.1)
        }
    }
    let (svg_text, png_bytes) = crate::output::plot::render(&Fig(rows, title), (1200, 800))?;
    let svg = stem.with_extension("svg");
    let png = stem.with_extension("png");
    crate::output::io::write_atomic(&svg, svg_text.as_bytes())?;
    crate::output::io::write_atomic(&png, &png_bytes)?;
    Ok((svg, png))
}
