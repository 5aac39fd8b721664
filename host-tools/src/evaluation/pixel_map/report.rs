//! The per-pixel map's outputs: a markdown summary and table, CSV (one row
//! per pixel), JSON (everything, each material's errors too) and a plot
//! against pixel (held-out error beside interpolation's, the black glass's
//! reading, the tiles' gloss error).
use super::peaks::PeakSummary;
use super::{FlagScore, PixelMap};
use crate::evaluation::coverage_interval::percent_with_interval;
use crate::evaluation::metrology::metrics::BAD_ERROR;
use crate::evaluation::metrology::report::NEAR_TWIN;
use crate::output::plot::{Figure, labelled_line, legend_upper_right, render};
use anyhow::anyhow;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// A share in per cent to 0.1, `-` when unknown.
fn pct(x: f64) -> String {
    if x.is_finite() { format!("{:.1} %", 100.0 * x) } else { "-".into() }
}

/// `caught % (n bad) / false %`, a dash where there is nothing to share.
fn flag_cell(f: &FlagScore) -> String {
    format!("{} ({}) / {}", pct(f.caught()), f.bad, pct(f.false_alarms()))
}

/// [`flag_cell`] and the median errors of the flagged points and of the rest.
fn flag_cell_with_errors(f: &FlagScore, [flagged, rest]: [f64; 2]) -> String {
    let err = |x: f64| if x.is_finite() { format!("{x:.3}") } else { "-".into() };
    format!("{}; median error {} / {}", flag_cell(f), err(flagged), err(rest))
}

/// A [`PeakSummary`] as one cell: height error median / 90th, all peaks,
/// the resolved ones and interpolation's; share not resolved; resolved
/// heights and widths within k = 2 (points with a peak in truth, read
/// without one).
fn peak_cell(p: &PeakSummary) -> String {
    format!(
        "{:.1} / {:.1} % (resolved {:.1} / {:.1} %; interpolation {:.1} / {:.1} %); {}; {} / {} ({}, {})",
        100.0 * p.height_rel[0],
        100.0 * p.height_rel[1],
        100.0 * p.resolved_height_rel[0],
        100.0 * p.resolved_height_rel[1],
        100.0 * p.interpolation_height_rel[0],
        100.0 * p.interpolation_height_rel[1],
        pct(p.unresolved),
        pct(p.resolved_coverage),
        pct(p.width_coverage),
        p.points,
        p.missed
    )
}

/// The summary and the per-pixel table (every `stride`-th pixel and the last).
pub fn markdown(map: &PixelMap, stride: usize) -> String {
    let mut s = String::new();
    let q = |x: [f64; 3]| format!("{:.3} / {:.3} / {:.3}", x[0], x[1], x[2]);
    let bg = &map.black_glass;
    let _ = writeln!(
        s,
        "{} on `{}`, {} zones; {} held-out folds, {} lines per material\n",
        map.kind, map.scene, map.zones, map.folds, map.lines
    );
    let _ = writeln!(s, "| figure | value |\n|---|---|");
    let _ =
        writeln!(s, "| BRDF error / peak, held out (median / 90th / worst over material x pixel) | {} |", q(map.error));
    let _ = writeln!(s, "| linear interpolation, the same points | {} |", q(map.interpolation));
    let g = |e: &super::GlossErrors| {
        let part = |x: [f64; 2], n: usize| {
            if n == 0 { "- (0)".to_string() } else { format!("{:.1} / {:.1} % ({n})", 100.0 * x[0], 100.0 * x[1]) }
        };
        format!("{}; above: {}", part(e.low, e.low_count), part(e.high, e.high_count))
    };
    let _ = writeln!(
        s,
        "| gloss, held out: relative error median / 90th (material x pixel) up to {} GU | {} |",
        crate::evaluation::metrology::metrics::GLOSS_SPLIT_GU,
        g(&map.gloss)
    );
    let _ = writeln!(s, "| linear interpolation's gloss, the same points | {} |", g(&map.gloss_interpolation));
    let _ = writeln!(
        s,
        "| haze (HU) and distinctness (% points), held out: absolute error median / 90th (material x pixel) | {} |",
        haze_distinctness(&map.haze_distinctness)
    );
    let _ = writeln!(
        s,
        "| held-out bins within k = 2 of their stated uncertainty (95 % interval over the materials) | {} |",
        percent_with_interval(map.bin_coverage, map.bin_coverage_interval)
    );
    let _ = writeln!(
        s,
        "| held-out readings within k = 2 of their stated uncertainty: gloss / haze / distinctness (material x pixel x line) | {} |",
        reading_coverage_cell(map.reading_coverage)
    );
    let _ = writeln!(
        s,
        "| held-out results within their U (k = 2): gloss / haze / distinctness (per material, the centre zones' mean over pixels and lines, U as `measure` states it) | {} |",
        reading_coverage_cell(map.result_coverage)
    );
    let _ = writeln!(
        s,
        "| out-of-prior flag, held out: of points worse than {BAD_ERROR:.2} of their peak, share flagged (n) / of the rest; median BRDF error of the flagged points / of the rest | {} |",
        flag_cell_with_errors(&map.flag, map.flag_error_medians)
    );
    if let Some(n) = map.held_out_nearness {
        let _ = writeln!(
            s,
            "| held out: nearest prior sample its fold trained on (RMS over the bins / the material's peak, at the scene's view): median; within {NEAR_TWIN} (near twins); materials the estimator reads better (median over the pixels) than that sample is to them | {n} |"
        );
    }
    let _ = writeln!(
        s,
        "| specular peaks, held out: height relative error median / 90th (all peaks; resolved ones; interpolation's); not resolved by the calibration; resolved heights / widths within k = 2 (points with a peak in truth, read without one) | {} |",
        peak_cell(&map.peaks)
    );
    if let Some(k) = &map.flag_in_training {
        let _ = writeln!(
            s,
            "| out-of-prior flag in training, kinds of material held out whole (what `train` prints): of those worse than {BAD_ERROR:.2}, share flagged / of the rest | {} / {} |",
            pct(k.caught()),
            pct(k.false_alarms())
        );
    }
    let _ = writeln!(
        s,
        "| out-of-prior statistic of each calibration (the held-out folds', then the whole prior's) | {} |",
        map.flag_statistics.join(", ")
    );
    let _ = writeln!(
        s,
        "| black glass: per-pixel mean GU (lowest .. highest) | {:.2} .. {:.2} |",
        bg.mean_range_gu[0], bg.mean_range_gu[1]
    );
    let _ = writeln!(s, "| black glass: largest per-pixel 1 sigma over lines, GU | {:.2} |", bg.max_pixel_sd_gu);
    let _ = writeln!(s, "| black glass: 1 sigma of the line's mean, GU | {:.3} |", bg.line_mean_sd_gu);
    let _ = writeln!(s, "| black glass: pixels without a reading / saturated | {} / {} |", bg.no_reading, bg.saturated);
    let _ = writeln!(s, "| black glass: points flagged out of prior (a mirror) | {} |", pct(bg.out_of_prior));
    let _ = writeln!(
        s,
        "| gloss tiles: mean / worst abs(delta GU) over tile x pixel | {:.2} / {:.2} |",
        map.tiles[0], map.tiles[1]
    );
    let tiles: Vec<String> = map.tile_gu.iter().map(|(_, g)| format!("{g:.1}")).collect();
    let _ = writeln!(s, "| gloss tiles' GU at the centre pixel | {} |", tiles.join(", "));
    let tb = &map.tiles_brdf.all;
    let _ =
        writeln!(s, "| gloss tiles' BRDF error / peak (median / 90th / worst over tile x pixel) | {} |", q(tb.error));
    let _ = writeln!(s, "| linear interpolation, the same points | {} |", q(tb.interpolation));
    let _ = writeln!(
        s,
        "| gloss tiles' bins within k = 2 of their stated uncertainty; points flagged out of prior | {:.1} %; {:.1} % |",
        100.0 * tb.bin_coverage,
        100.0 * tb.out_of_prior
    );
    let _ = writeln!(
        s,
        "| gloss tiles' out-of-prior flag: of points worse than {BAD_ERROR:.2}, share flagged (n) / of the rest | {} |",
        flag_cell(&tb.flag)
    );
    let own = &map.own_surface;
    let _ = writeln!(
        s,
        "| the scene's own surface `{}`: BRDF error / peak (median / 90th / worst over the pixels) | {} |",
        own.surface,
        q(own.brdf.error)
    );
    let _ = writeln!(s, "| linear interpolation, the same points | {} |", q(own.brdf.interpolation));
    let _ = writeln!(
        s,
        "| the scene's own surface: bins within k = 2 of their stated uncertainty; points flagged out of prior | {:.1} %; {} |",
        100.0 * own.brdf.bin_coverage,
        pct(own.brdf.out_of_prior)
    );
    if let Some(u) = &map.unseen {
        let left = if u.in_prior.is_empty() {
            String::new()
        } else {
            format!("; {} left out as prior samples: {}", u.in_prior.len(), u.in_prior.join(", "))
        };
        let _ = writeln!(
            s,
            "| unseen set `{}` ({} surfaces{left}), by the calibration on the whole prior: BRDF error / peak (median / 90th / worst over surface x pixel) | {} |",
            u.source,
            u.materials.len(),
            q(u.summary.error)
        );
        let _ = writeln!(s, "| linear interpolation, the same points | {} |", q(u.summary.interpolation));
        let _ = writeln!(
            s,
            "| unseen set's gloss: relative error median / 90th up to {} GU | {} |",
            crate::evaluation::metrology::metrics::GLOSS_SPLIT_GU,
            g(&u.summary.gloss)
        );
        let _ =
            writeln!(s, "| linear interpolation's gloss, the same points | {} |", g(&u.summary.gloss_interpolation));
        let _ = writeln!(
            s,
            "| unseen set's haze (HU) and distinctness (% points): absolute error median / 90th | {} |",
            haze_distinctness(&u.summary.haze_distinctness)
        );
        let _ = writeln!(
            s,
            "| unseen set's bins within k = 2 of their stated uncertainty (95 % interval over the surfaces) | {} |",
            percent_with_interval(u.summary.bin_coverage, u.summary.bin_coverage_interval)
        );
        let _ = writeln!(
            s,
            "| unseen set's readings within k = 2 of their stated uncertainty: gloss / haze / distinctness | {} |",
            reading_coverage_cell(u.summary.reading_coverage)
        );
        let _ = writeln!(
            s,
            "| unseen set's results within their U (k = 2): gloss / haze / distinctness (per surface, the centre zones' mean) | {} |",
            reading_coverage_cell(u.summary.result_coverage)
        );
        let _ = writeln!(
            s,
            "| unseen set's out-of-prior flag: of points worse than {BAD_ERROR:.2}, share flagged (n) / of the rest; median error of the flagged / of the rest | {} |",
            flag_cell_with_errors(&u.flag, u.flag_error_medians)
        );
        let _ = writeln!(s, "| unseen set's specular peaks | {} |", peak_cell(&u.peaks));
        if let Some(n) = u.nearness {
            let _ = writeln!(
                s,
                "| unseen set's nearest prior sample (RMS over the bins / the surface's peak, at the scene's view): median; within {NEAR_TWIN} (near twins); surfaces the estimator reads better (median over the pixels) than that sample is to them | {n} |"
            );
        }
    }
    let _ = writeln!(s);
    s.push_str(&read_worst("Held-out materials", &map.materials));
    if let Some(u) = &map.unseen {
        s.push_str(&read_worst(&format!("Unseen set `{}`", u.source), &u.materials));
    }
    let _ = writeln!(
        s,
        "| pixel | view deg | zone | error median / 90th / worst | interpolation median / 90th / worst | out of prior | saturated | black glass GU (1 sigma) | tiles mean / worst abs dGU | peak resolution deg | peaks not resolved |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
    let last = map.pixels.len().saturating_sub(1);
    for r in map.pixels.iter().filter(|r| r.pixel % stride.max(1) == 0 || r.pixel == last) {
        let _ = writeln!(
            s,
            "| {} | {:.2} | {} | {} | {} | {:.0} % | {:.0} % | {:.2} ({:.2}) | {:.2} / {:.2} | {:.2} | {:.0} % |",
            r.pixel,
            r.view_deg,
            r.zone,
            q(r.error),
            q(r.interpolation),
            100.0 * r.out_of_prior,
            100.0 * r.saturated,
            r.black_glass_gu,
            r.black_glass_sd_gu,
            r.tiles_mean_abs_gu,
            r.tiles_max_abs_gu,
            r.peak_resolution_deg,
            100.0 * r.peaks_unresolved
        );
    }
    s
}

/// How many materials [`read_worst`] lists.
pub const READ_WORST: usize = 8;

/// The materials of `rows` with the most points worse than [`BAD_ERROR`]
/// (at most [`READ_WORST`], by that share, then by their median error),
/// each with what the flag raised on it and its error beside
/// interpolation's, and the share of all the bad points they hold: a
/// calibration's bad estimates are mostly whole materials, read badly at
/// every pixel, and this says which, and whether the flag says so. Empty
/// when no point is worse.
pub fn read_worst(what: &str, rows: &[super::MaterialRow]) -> String {
    let bad_share = |r: &super::MaterialRow| r.flag.bad as f64 / (r.flag.bad + r.flag.good).max(1) as f64;
    let total: usize = rows.iter().map(|r| r.flag.bad).sum();
    if total == 0 {
        return String::new();
    }
    // Each material's keys once (its median sorts its pixels), not per comparison.
    let mut keyed: Vec<(f64, f64, &super::MaterialRow)> = rows
        .iter()
        .filter(|r| r.flag.bad > 0)
        .map(|r| (bad_share(r), crate::evaluation::pixel_error::quantiles(&r.error)[0], r))
        .collect();
    keyed.sort_by(|a, b| b.0.total_cmp(&a.0).then(b.1.total_cmp(&a.1)));
    let mut worst: Vec<&super::MaterialRow> = keyed.into_iter().map(|k| k.2).collect();
    let with_bad = worst.len();
    worst.truncate(READ_WORST);
    let held: usize = worst.iter().map(|r| r.flag.bad).sum();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{what} read worst: {with_bad} of {} have points worse than {BAD_ERROR:.2} of their peak; these {} hold {} of those {total} points.\n",
        rows.len(),
        worst.len(),
        pct(held as f64 / total as f64)
    );
    let _ = writeln!(
        s,
        "| material | points worse than {BAD_ERROR:.2} | of them flagged | of the rest flagged | error median / 90th over pixels | interpolation median / 90th | nearest prior sample (RMS over the bins / peak) |\n|---|---|---|---|---|---|---|"
    );
    for r in worst {
        let (e, i) = (
            crate::evaluation::pixel_error::quantiles(&r.error),
            crate::evaluation::pixel_error::quantiles(&r.interpolation),
        );
        let nearest = r.nearest_training.as_ref().map_or("-".into(), ToString::to_string);
        let _ = writeln!(
            s,
            "| {} | {} ({}) | {} | {} | {:.3} / {:.3} | {:.3} / {:.3} | {nearest} |",
            r.name,
            pct(bad_share(r)),
            r.flag.bad,
            pct(r.flag.caught()),
            pct(r.flag.false_alarms()),
            e[0],
            e[1],
            i[0],
            i[1]
        );
    }
    let _ = writeln!(s);
    s
}

/// One row per pixel.
pub fn csv(map: &PixelMap) -> anyhow::Result<Vec<u8>> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "pixel",
        "view_deg",
        "zone",
        "error_median",
        "error_p90",
        "error_worst",
        "interpolation_median",
        "interpolation_p90",
        "interpolation_worst",
        "out_of_prior",
        "saturated",
        "black_glass_gu",
        "black_glass_sd_gu",
        "black_glass_saturated",
        "tiles_mean_abs_gu",
        "tiles_max_abs_gu",
        "peak_resolution_deg",
        "peaks_unresolved",
    ])?;
    for r in &map.pixels {
        let f = |x: f64| format!("{x:.6}");
        w.write_record([
            r.pixel.to_string(),
            f(r.view_deg),
            r.zone.to_string(),
            f(r.error[0]),
            f(r.error[1]),
            f(r.error[2]),
            f(r.interpolation[0]),
            f(r.interpolation[1]),
            f(r.interpolation[2]),
            f(r.out_of_prior),
            f(r.saturated),
            f(r.black_glass_gu),
            f(r.black_glass_sd_gu),
            r.black_glass_saturated.to_string(),
            f(r.tiles_mean_abs_gu),
            f(r.tiles_max_abs_gu),
            f(r.peak_resolution_deg),
            f(r.peaks_unresolved),
        ])?;
    }
    Ok(w.into_inner()?)
}

/// "G / H / D %" of per-reading coverages ("-" for a reading none has).
fn reading_coverage_cell(c: [f64; 3]) -> String {
    c.map(|x| if x.is_finite() { format!("{:.1}", 100.0 * x) } else { "-".into() }).join(" / ") + " %"
}

/// "haze H50 / H90 HU, distinctness D50 / D90 % (interpolation: ...)".
fn haze_distinctness(e: &[super::HazeDistinctnessErrors; 2]) -> String {
    let one = |x: &super::HazeDistinctnessErrors| {
        format!(
            "haze {:.2} / {:.2} HU, distinctness {:.1} / {:.1} %",
            x.haze_hu[0], x.haze_hu[1], x.distinctness_pct[0], x.distinctness_pct[1]
        )
    };
    format!("{} (linear interpolation: {})", one(&e[0]), one(&e[1]))
}

struct MapPlot<'a>(&'a PixelMap);

impl Figure for MapPlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let map = self.0;
        let e = |x: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{x}");
        root.fill(&WHITE).map_err(e)?;
        let panels = root.split_evenly((3, 1));
        let p = map.pixels.len().max(1) as f64;
        let blue = RGBColor(31, 119, 180);
        let red = RGBColor(214, 39, 40);
        let green = RGBColor(44, 160, 44);
        // Error.
        let ymax = map.pixels.iter().map(|r| r.error[1].max(r.interpolation[1])).fold(0.05, f64::max) * 1.2;
        let mut c = ChartBuilder::on(&panels[0])
            .caption(
                format!("{} on {}, {} zones: held-out error per pixel", map.kind, map.scene, map.zones),
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(25)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..p, 0.0..ymax)
            .map_err(e)?;
        c.configure_mesh().y_desc("error / peak").label_style(("sans-serif", 12)).draw().map_err(e)?;
        for (label, col, q, interp) in [
            ("median", blue.to_rgba(), 0, false),
            ("90th", blue.mix(0.5), 1, false),
            ("interpolation median", red.to_rgba(), 0, true),
        ] {
            let pts: Vec<(f64, f64)> = map
                .pixels
                .iter()
                .map(|r| (r.pixel as f64, if interp { r.interpolation[q] } else { r.error[q] }))
                .collect();
            labelled_line(&mut c, pts, label, ShapeStyle { color: col, filled: true, stroke_width: 2 })?;
        }
        legend_upper_right(&mut c)?;
        // Black glass.
        let finite: Vec<f64> = map.pixels.iter().map(|r| r.black_glass_gu).filter(|x| x.is_finite()).collect();
        let (lo, hi) = finite.iter().fold((99.0f64, 101.0f64), |a, x| (a.0.min(*x), a.1.max(*x)));
        let mut c = ChartBuilder::on(&panels[1])
            .margin(10)
            .x_label_area_size(25)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..p, (lo - 0.5)..(hi + 0.5))
            .map_err(e)?;
        c.configure_mesh().y_desc("black glass GU").label_style(("sans-serif", 12)).draw().map_err(e)?;
        c.draw_series(map.pixels.iter().filter(|r| r.black_glass_gu.is_finite()).map(|r| {
            PathElement::new(
                vec![
                    (r.pixel as f64, r.black_glass_gu - r.black_glass_sd_gu),
                    (r.pixel as f64, r.black_glass_gu + r.black_glass_sd_gu),
                ],
                green.mix(0.5),
            )
        }))
        .map_err(e)?;
        c.draw_series(
            map.pixels
                .iter()
                .filter(|r| r.black_glass_gu.is_finite())
                .map(|r| Circle::new((r.pixel as f64, r.black_glass_gu), 2, green.filled())),
        )
        .map_err(e)?;
        c.draw_series(LineSeries::new([(0.0, 100.0), (p, 100.0)], BLACK.mix(0.4))).map_err(e)?;
        // Tiles.
        let tmax = map.pixels.iter().map(|r| r.tiles_max_abs_gu).filter(|x| x.is_finite()).fold(1.0, f64::max) * 1.2;
        let mut c = ChartBuilder::on(&panels[2])
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..p, 0.0..tmax)
            .map_err(e)?;
        c.configure_mesh().x_desc("pixel").y_desc("tiles |dGU|").label_style(("sans-serif", 12)).draw().map_err(e)?;
        for (label, q, col) in [("mean", 0, blue), ("worst", 1, red)] {
            let pts: Vec<(f64, f64)> = map
                .pixels
                .iter()
                .map(|r| (r.pixel as f64, if q == 0 { r.tiles_mean_abs_gu } else { r.tiles_max_abs_gu }))
                .filter(|x| x.1.is_finite())
                .collect();
            labelled_line(&mut c, pts, label, ShapeStyle { color: col.to_rgba(), filled: true, stroke_width: 2 })?;
        }
        legend_upper_right(&mut c)?;
        Ok(())
    }
}

/// Writes `pixel-map.md`, `.csv`, `.json`, `.svg`, `.png` into `dir`, atomically.
pub fn write(dir: &Path, map: &PixelMap, stride: usize) -> anyhow::Result<Vec<PathBuf>> {
    use crate::output::io::write_atomic;
    let mut out = Vec::new();
    let mut put = |name: &str, bytes: &[u8]| -> anyhow::Result<()> {
        let p = dir.join(name);
        write_atomic(&p, bytes)?;
        out.push(p);
        Ok(())
    };
    put("pixel-map.md", markdown(map, stride).as_bytes())?;
    put("pixel-map.csv", &csv(map)?)?;
    put("pixel-map.json", &serde_json::to_vec_pretty(map)?)?;
    let (svg, png) = render(&MapPlot(map), (1000, 1000))?;
    put("pixel-map.svg", svg.as_bytes())?;
    put("pixel-map.png", &png)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evaluation::pixel_map::MaterialRow;

    /// A material of two pixels with `bad` of its `points` worse than
    /// `BAD_ERROR`, `caught` of them flagged, and `errors` per pixel.
    fn material(name: &str, points: usize, bad: usize, caught: usize, errors: [f64; 2]) -> MaterialRow {
        MaterialRow {
            name: name.into(),
            error: errors.to_vec(),
            interpolation: vec![0.15; 2],
            gloss_true: vec![10.0; 2],
            gloss: vec![10.0; 2],
            gloss_interpolation: vec![10.0; 2],
            bin_coverage: vec![1.0; 2],
            haze_distinctness_error: [vec![[0.0; 2]; 2], vec![[0.0; 2]; 2]],
            reading_coverage: vec![[1.0; 3]; 2],
            result_covered: [1.0, 1.0, f64::NAN],
            flag: FlagScore { bad, bad_flagged: caught, good: points - bad, good_flagged: 1 },
            flag_errors: Default::default(),
            nearest_training: Some(crate::evaluation::metrology::NearestSample {
                name: format!("near-{name}"),
                distance: 0.05,
            }),
        }
    }

    #[test]
    fn the_result_coverage_is_the_share_of_materials_whose_result_covers_their_truth() {
        let mut rows = vec![material("a", 10, 0, 0, [0.05; 2]), material("b", 10, 0, 0, [0.05; 2])];
        rows[1].result_covered = [1.0, 0.0, f64::NAN];
        rows.push(MaterialRow { result_covered: [0.0, f64::NAN, f64::NAN], ..material("c", 10, 0, 0, [0.05; 2]) });
        let c = super::super::rows::result_coverage(&rows);
        assert_eq!((c[0], c[1]), (2.0 / 3.0, 0.5), "{c:?}");
        assert!(c[2].is_nan(), "no material has the reading's result");
        assert_eq!(reading_coverage_cell(c), "66.7 / 50.0 / - %");
    }

    #[test]
    fn the_materials_read_worst_are_those_with_the_most_bad_points_and_hold_their_share() {
        let mut rows = vec![
            material("fine", 10, 0, 0, [0.02, 0.03]),
            material("half", 10, 5, 1, [0.09, 0.12]),
            material("all", 10, 10, 0, [0.2, 0.3]),
            material("half-worse", 10, 5, 5, [0.11, 0.2]),
        ];
        rows.extend((0..READ_WORST).map(|i| material(&format!("one-{i}"), 10, 1, 0, [0.05, 0.11])));
        let s = read_worst("Held-out materials", &rows);
        // Eleven materials have bad points; the eight listed hold 25 of 28.
        assert!(s.starts_with("Held-out materials read worst: 11 of 12 have points worse than 0.10"), "{s}");
        assert!(s.contains("these 8 hold 89.3 % of those 28 points"), "{s}");
        let listed: Vec<&str> = s.lines().filter(|l| l.starts_with("| ") && !l.starts_with("| material")).collect();
        assert_eq!(listed.len(), READ_WORST, "{s}");
        // By the share of bad points, ties by the median error.
        assert!(listed[0].starts_with("| all | 100.0 % (10) | 0.0 % | - |"), "{s}");
        assert!(listed[0].ends_with("| near-all (0.050) |"), "{s}");
        assert!(listed[1].starts_with("| half-worse | 50.0 % (5) | 100.0 % | 20.0 % |"), "{s}");
        assert!(listed[2].starts_with("| half | 50.0 % (5) | 20.0 % | 20.0 % |"), "{s}");
        assert!(!s.contains("| fine |"), "{s}");
        // Nothing to say when no point is worse.
        assert_eq!(read_worst("x", &rows[..1]), "");
    }
}
