//! `simulate`'s figure: the reflectance factor against incidence (truth on
//! the grid, corrected readings at the LEDs' centre angles) beside the raw
//! counts along the line.
use crate::forward::scene::readings::Output;
use anyhow::anyhow;
use plotters::coord::Shift;
use plotters::prelude::*;

const SIZE: (u32, u32) = (1400, 560);

/// The plot as SVG text and PNG bytes.
pub fn plots(out: &Output) -> anyhow::Result<(String, Vec<u8>)> {
    struct Fig<'a>(&'a Output);
    impl super::Figure for Fig<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
        where
            DB::ErrorType: 'static,
        {
            draw(root, self.0)
        }
    }
    super::render(&Fig(out), SIZE)
}

fn colour(i: usize) -> RGBColor {
    const C: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
    ];
    C[i % C.len()]
}

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.filter(|x| x.is_finite()).fold((f64::MAX, f64::MIN), |(l, h), x| (l.min(x), h.max(x)));
    if lo > hi {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.08).max(hi.abs() * 1e-3).max(1e-12);
    (lo - pad, hi + pad)
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, out: &Output) -> anyhow::Result<()> {
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{x:?}");
    root.fill(&WHITE).map_err(e)?;
    let (top, root) = root.split_vertically(56);
    top.draw_text(
        &format!("scene `{}`: {} pixel(s) x {} LED(s)", out.scene, out.pixels, out.leds.len()),
        &("sans-serif", 20).into_font().color(&BLACK),
        (12, 6),
    )
    .map_err(e)?;
    top.draw_text(&format!("stages: {}", stage_list(out)), &("sans-serif", 14).into_font().color(&BLACK), (12, 32))
        .map_err(e)?;
    let (left, right) = root.split_horizontally(SIZE.0 / 2);
    let line0 = &out.lines[0];
    let p = out.pixels;
    let shown: Vec<usize> = if p == 1 { vec![0] } else { vec![0, p / 2, p - 1] };

    // Left: reflectance factor against incidence: the truth on the grid and
    // the white-calibrated readings at each LED's centre angle.
    let (x0, x1) = range(out.bins_deg.iter().copied());
    let (y0, y1) = range(
        shown
            .iter()
            .flat_map(|&px| out.truth.rho[px].iter().chain(&line0.corrected[px]).copied().collect::<Vec<_>>())
            .chain(std::iter::once(0.0)),
    );
    let mut c = ChartBuilder::on(&left)
        .caption("Reflectance factor: truth (lines) and corrected readings (dots)", ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(e)?;
    c.configure_mesh()
        .x_desc("incidence of the LED's centre ray at the pixel's point (deg)")
        .y_desc("reflectance factor R")
        .y_label_formatter(&|v| tick(*v))
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    for (i, &px) in shown.iter().enumerate() {
        let col = colour(i);
        c.draw_series(LineSeries::new(
            out.bins_deg.iter().copied().zip(out.truth.rho[px].iter().copied()),
            col.stroke_width(2),
        ))
        .map_err(e)?
        .label(format!("pixel {px}"))
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], col.stroke_width(2)));
        c.draw_series(
            out.incidence_deg[px].iter().zip(&line0.corrected[px]).map(|(x, y)| Circle::new((*x, *y), 5, col.filled())),
        )
        .map_err(e)?;
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(e)?;

    // Right: raw counts along the line, one curve per LED, and the dark frame.
    let (r0, r1) = range(line0.raw.iter().flatten().chain(&line0.dark).copied().chain(std::iter::once(0.0)));
    let (xa, xb) = if p == 1 { (-1.0, 1.0) } else { (-0.5, p as f64 - 0.5) };
    let mut c = ChartBuilder::on(&right)
        .caption(format!("Raw counts along the line (line {})", line0.line), ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(xa..xb, r0..r1)
        .map_err(e)?;
    c.configure_mesh()
        .x_desc("pixel")
        .y_desc("counts")
        .y_label_formatter(&|v| tick(*v))
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    let mut series: Vec<(String, &Vec<f64>, RGBColor)> = vec![("dark".to_string(), &line0.dark, BLACK)];
    for (k, f) in line0.raw.iter().enumerate() {
        series.push((format!("{} ({:.0} deg)", out.leds[k], out.centre_deg[k]), f, colour(k)));
    }
    for (name, f, col) in series {
        let pts: Vec<(f64, f64)> = f.iter().enumerate().map(|(i, y)| (i as f64, *y)).collect();
        if p == 1 {
            c.draw_series(pts.iter().map(|pt| Circle::new(*pt, 5, col.filled())))
                .map_err(e)?
                .label(name)
                .legend(move |(x, y)| Circle::new((x + 9, y), 4, col.filled()));
        } else {
            c.draw_series(LineSeries::new(pts, col.stroke_width(2)))
                .map_err(e)?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], col.stroke_width(2)));
        }
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 12))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(e)?;
    Ok(())
}

/// A compact tick label: plain below 1e5, scientific above or for tiny values.
fn tick(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 {
        "0".into()
    } else if !(1e-2..1e5).contains(&a) {
        format!("{v:.2e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}

fn stage_list(out: &Output) -> String {
    if out.stages.is_empty() { "no effects (far field, ideal sensor)".into() } else { out.stages.join(", ") }
}
