//! Plot output shared by every command that draws (`simulate`, `tradeoff`,
//! `measure`/`estimate --plot`):
//! one font set-up, and SVG and PNG rendered from the same drawing code into
//! memory, so the caller writes both files atomically.
pub mod profiles;
pub mod simulate;
pub mod tradeoff;

use anyhow::{Context, anyhow};
use plotters::coord::Shift;
use plotters::coord::cartesian::Cartesian2d;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::PathBuf;

/// A drawing that can be rendered on any plotters backend.
pub trait Figure {
    /// Draws the whole figure on `root`.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static;
}

/// A chart with f64 axes, as every report's panels are.
pub type XyChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Draws `pts` as a line in `style` with `label` in the legend.
pub fn labelled_line<'a, DB: DrawingBackend + 'a>(
    chart: &mut XyChart<'a, DB>,
    pts: Vec<(f64, f64)>,
    label: &str,
    style: ShapeStyle,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .draw_series(LineSeries::new(pts, style))
        .map_err(|x| anyhow!("{x}"))?
        .label(label)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
    Ok(())
}

/// The reports' legend: upper right, on a translucent white box.
pub fn legend_upper_right<'a, DB: DrawingBackend + 'a>(chart: &mut XyChart<'a, DB>) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 12))
        .draw()
        .map_err(|x| anyhow!("{x}"))
}

/// Renders `fig` at `size` pixels as SVG text and PNG bytes.
pub fn render(fig: &impl Figure, size: (u32, u32)) -> anyhow::Result<(String, Vec<u8>)> {
    ensure_font()?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        fig.draw(&root)?;
        root.present().map_err(|e| anyhow!("SVG: {e:?}"))?;
    }
    let mut rgb = vec![0u8; (size.0 * size.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        fig.draw(&root)?;
        root.present().map_err(|e| anyhow!("PNG: {e:?}"))?;
    }
    let mut png = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png, size.0, size.1);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().context("encoding the PNG")?;
        w.write_image_data(&rgb).context("encoding the PNG")?;
    }
    Ok((svg, png))
}

/// Registers a sans-serif font for the plots' text, once: `HOST_TOOLS_FONT`
/// if set, else the first of the usual system fonts.
pub fn ensure_font() -> anyhow::Result<()> {
    static FONT: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    FONT.get_or_init(|| {
        let mut candidates: Vec<PathBuf> = Vec::new();
        if let Some(p) = std::env::var_os("HOST_TOOLS_FONT") {
            candidates.push(p.into());
        }
        for p in [
            "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/TTF/DejaVuSans.ttf",
            "/usr/share/fonts/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
            "/usr/share/fonts/liberation/LiberationSans-Regular.ttf",
            "/Library/Fonts/Arial.ttf",
            "C:\\Windows\\Fonts\\arial.ttf",
        ] {
            candidates.push(p.into());
        }
        for p in &candidates {
            if let Ok(bytes) = std::fs::read(p) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return Ok(());
                }
            }
        }
        Err(format!(
            "no usable TrueType font for the plot's text (tried {}); install one (Debian: apt-get install fonts-dejavu-core) or set HOST_TOOLS_FONT to a .ttf file",
            candidates.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
        ))
    })
    .clone()
    .map_err(|e| anyhow!(e))
}
