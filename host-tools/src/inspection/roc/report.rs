//! The ROC run's table (markdown, as the README carries it) and plot
//! (probability of detection against false calls per 10^4 defect-free
//! lines, one curve per case, the operating point marked).
use super::Roc;
use crate::output::plot::{Figure, render};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::Path;

/// Threshold factors the curves are drawn at.
fn factors() -> Vec<f64> {
    (0..=80).map(|i| 10f64.powf(-1.0 + 2.0 * i as f64 / 80.0)).collect()
}

/// The table: per case the device's detections at the recipe's operating
/// point, and the detection at the threshold that allows 1 false call per
/// 10^4 defect-free lines over the lines run.
pub fn markdown(r: &Roc) -> String {
    let c1 = r.factor_for(1.0);
    let mut s = String::new();
    let t = &r.teach;
    // Every window the recipe has (one that is off is -inf..+inf).
    let mut windows = String::new();
    for ([lo, hi], (name, unit)) in t.windows.iter().zip([("gloss", "GU"), ("haze", "HU"), ("distinctness", "%")]) {
        if lo.is_finite() || hi.is_finite() {
            let _ = write!(windows, ", {name} window {lo:+.2}..{hi:+.2} {unit}");
        }
    }
    let _ = writeln!(
        s,
        "Recipe: taught on {} lines, {} groups, distance threshold {:.1}{windows}, reference gloss sd {:.3} GU (median pixel), teach quality {:.2}, min defect {} px.",
        t.lines, t.groups, t.threshold, t.reading_sd[0], t.quality, r.min_pixels
    );
    let _ = writeln!(
        s,
        "Defect-free lines: {}; false calls at the operating point: {} ({:.2} per 10^4 lines). Threshold factor for 1 false call per 10^4 over these lines: {:.3}.\n",
        r.clean_lines,
        r.false_calls,
        1e4 * r.false_calls as f64 / r.clean_lines as f64,
        c1
    );
    let _ = writeln!(
        s,
        "| defect | size (px) | magnitude | lines | detected (device, operating point) | PoD | PoD at 1 false call / 10^4 |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for c in &r.cases {
        let at = c.scores.iter().filter(|x| **x > c1).count() as f64 / c.scores.len() as f64;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {:.3} | {:.3} |",
            c.case.kind, c.case.pixels, c.case.magnitude, c.lines, c.detected, c.pod, at
        );
    }
    s
}

struct Curves<'a>(&'a Roc);

impl Figure for Curves<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let r = self.0;
        root.fill(&WHITE)?;
        let floor = 1e4 / r.clean_scores.len().max(1) as f64 / 2.0;
        let mut chart = ChartBuilder::on(root)
            .caption("Inspection: detection against false calls (simulated handheld)", ("sans-serif", 20))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d((floor..1e4).log_scale(), 0.0..1.02)?;
        chart
            .configure_mesh()
            .x_desc("false calls per 10^4 defect-free lines")
            .y_desc("probability of detection")
            .draw()?;
        for (i, c) in r.cases.iter().enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            let pts: Vec<(f64, f64)> = factors()
                .into_iter()
                .map(|f| {
                    let pod = c.scores.iter().filter(|x| **x > f).count() as f64 / c.scores.len() as f64;
                    (r.false_calls_at(f).max(floor), pod)
                })
                .collect();
            chart
                .draw_series(LineSeries::new(pts, colour.stroke_width(2)))?
                .label(format!("{} {} px {}", c.case.kind, c.case.pixels, c.case.magnitude))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], colour.stroke_width(2)));
            let op = (r.false_calls_at(1.0).max(floor), c.pod);
            chart.draw_series(std::iter::once(Circle::new(op, 4, colour.filled())))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(SeriesLabelPosition::LowerRight)
            .draw()?;
        Ok(())
    }
}

/// Writes the plot (SVG or PNG by the extension).
pub fn plot(r: &Roc, path: &Path) -> anyhow::Result<()> {
    let (svg, png) = render(&Curves(r), (900, 600))?;
    let bytes = if path.extension().is_some_and(|e| e == "svg") { svg.into_bytes() } else { png };
    crate::output::io::write_atomic(path, &bytes)
}
