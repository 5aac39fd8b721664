//! The BRDF profiles of chosen points (`measure --plot`, `estimate --plot`):
//! reflectance factor against incidence, each point's +-1 standard
//! uncertainty band (the calibration's per-bin uncertainty times the point's
//! scale) shaded behind its line, and its gloss readings in the legend.
//! The band stops at 0 ([`band_edges`]): a reflectance factor below it is
//! not one the surface can have, however wide the uncertainty (the mirror
//! bin of a lobe the LEDs do not resolve), as the result's coverage
//! intervals stop there too (`device::measurement_result`).
use crate::output::profile::Profile;
use anyhow::{anyhow, bail};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

const SIZE: (u32, u32) = (1100, 650);

const COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
];

/// The band drawn about reflectance factor `r` with standard uncertainty
/// `u`: `r +- u`, never below 0 (the result's coverage interval at k = 1).
pub fn band_edges(r: f64, u: f64) -> (f64, f64) {
    use crate::device::measurement_result::{REFLECTANCE_FACTOR_DOMAIN, coverage_interval};
    let [lo, hi] = coverage_interval(r, u, REFLECTANCE_FACTOR_DOMAIN);
    (lo, hi)
}

/// The figure.
pub struct ProfilePlot<'a> {
    /// Title line.
    pub title: String,
    /// The points drawn.
    pub profiles: &'a [Profile],
}

/// A legend entry: the point and its readings with their uncertainties.
pub fn legend(p: &Profile) -> String {
    let mut s = format!("line {} point {}", p.line, p.point);
    for (name, v, u) in &p.readings {
        let unit = match name.as_str() {
            "gloss_gu" => " GU",
            "haze_hu" => " HU",
            "distinctness_pct" => " %",
            _ => "",
        };
        let label = name.split('_').next().unwrap_or(name);
        s.push_str(&format!(", {label} {v:.1} ± {u:.1}{unit}"));
    }
    if !p.flags.is_empty() {
        s.push_str(&format!(" [{}]", p.flags.join(", ")));
    }
    s
}

impl super::Figure for ProfilePlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let e = |x: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {x:?}");
        root.fill(&WHITE).map_err(e)?;
        let all = || self.profiles.iter().flat_map(|p| p.theta_i_deg.iter().copied());
        let (x0, x1) = all().fold((f64::MAX, f64::MIN), |(l, h), x| (l.min(x), h.max(x)));
        let hi = self
            .profiles
            .iter()
            .flat_map(|p| p.reflectance.iter().zip(&p.uncertainty).map(|(r, u)| r + u))
            .filter(|x| x.is_finite())
            .fold(0.0f64, f64::max);
        let lo = self
            .profiles
            .iter()
            .flat_map(|p| p.reflectance.iter().zip(&p.uncertainty).map(|(r, u)| band_edges(*r, *u).0.min(*r)))
            .filter(|x| x.is_finite())
            .fold(0.0f64, f64::min);
        let pad = 0.05 * (hi - lo).max(1e-6);
        let mut c = ChartBuilder::on(root)
            .caption(&self.title, ("sans-serif", 20))
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(x0..x1.max(x0 + 1e-6), (lo - pad)..(hi + pad))
            .map_err(e)?;
        c.configure_mesh()
            .x_desc("incidence theta_i (deg)")
            .y_desc("reflectance factor R = pi f_r")
            .label_style(("sans-serif", 13))
            .axis_desc_style(("sans-serif", 14))
            .draw()
            .map_err(e)?;
        for (k, p) in self.profiles.iter().enumerate() {
            let col = COLOURS[k % COLOURS.len()];
            let pts = || p.theta_i_deg.iter().zip(p.reflectance.iter().zip(&p.uncertainty));
            let band: Vec<(f64, f64)> = pts()
                .map(|(t, (r, u))| (*t, band_edges(*r, *u).1))
                .chain(pts().rev().map(|(t, (r, u))| (*t, band_edges(*r, *u).0)))
                .collect();
            c.draw_series(std::iter::once(Polygon::new(band, col.mix(0.2)))).map_err(e)?;
            c.draw_series(LineSeries::new(pts().map(|(t, (r, _))| (*t, *r)), col.stroke_width(2)))
                .map_err(e)?
                .label(legend(p))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], col.stroke_width(2)));
        }
        c.configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 13))
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(e)?;
        Ok(())
    }
}

/// Renders the figure and writes it atomically as SVG or PNG by `path`'s extension.
pub fn write(path: &Path, title: &str, profiles: &[Profile]) -> anyhow::Result<()> {
    anyhow::ensure!(!profiles.is_empty(), "{}: no points to plot", path.display());
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if ext != "svg" && ext != "png" {
        bail!("{}: the plot is written as .svg or .png; give a file name with one of those", path.display());
    }
    let (svg, png) = super::render(&ProfilePlot { title: title.to_string(), profiles }, SIZE)?;
    let bytes = if ext == "svg" { svg.into_bytes() } else { png };
    crate::output::io::write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::band_edges;

    #[test]
    fn the_band_stops_at_zero() {
        assert_eq!(band_edges(0.5, 0.1), (0.4, 0.6));
        assert_eq!(band_edges(13.4, 91.0), (0.0, 104.4));
        assert_eq!(band_edges(0.0, 0.2), (0.0, 0.2));
    }
}
