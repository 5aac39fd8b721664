//! A measurement as files: its points in the point schema
//! (`output::points`: one CSV row and one JSON object per point, with its
//! BRDF vector, the calibration's predicted per-bin uncertainty for the
//! point's zone, its flags, its gloss readings with their standard
//! uncertainties as the device streamed them (`brdf_meter::gloss`; none
//! when the calibration carries no gloss section) and its specular peak),
//! which also make the profiles for the plot and the standard files
//! (`Points::profiles`).
use crate::device::link::PointRecord;
use crate::output::points::{Point, Points};
use brdf_meter::blob::BlobView;
use brdf_meter::gloss;
use brdf_meter::shape::READINGS;

/// The points of a measurement with the calibration `view`, on the bins it
/// streamed (every bin unless it asked for a subset; one subset per
/// measurement), the specular peak sought about `view_deg`'s mirror
/// incidence: [`calibration_points`] with the standards' uncertainties.
pub fn measurement_points(view: &BlobView<'_>, points: &[PointRecord], view_deg: f64) -> Points {
    // A standardised calibration's white reference (and gloss scale) is
    // known to a relative uncertainty that every value (gloss and haze)
    // carries.
    calibration_points(view, points, view_deg).with_standards_of(view)
}

/// The same with the uncertainties the calibration states, before its
/// standards' are added (what a result's budget takes apart,
/// `crate::device::measurement_result`).
pub fn calibration_points(view: &BlobView<'_>, points: &[PointRecord], view_deg: f64) -> Points {
    let d = view.dims();
    let bins = points.first().map_or(brdf_meter::protocol::BinRange::all(d.n), |p| p.bins);
    let (peak_resolution_deg, pixel_peak_resolution_deg) = crate::output::points::peak_resolutions(view);
    Points {
        source: "measure",
        calibration_crc: view.crc(),
        view_deg,
        peak_resolution_deg,
        pixel_peak_resolution_deg,
        peak_factors: view.peak_factors(),
        bins_deg: bins.bins().map(|j| view.grid_deg(j)).collect(),
        points: points
            .iter()
            .map(|p| Point {
                line: Some(u64::from(p.line)),
                pixel: Some(u64::from(p.point)),
                zone: p.zone,
                cluster: p.cluster,
                flags: p.flags,
                rho: p.values.clone(),
                // The calibration's per-bin uncertainty for the point's zone,
                // times the point's own scale (1 for the linear estimators; the
                // readings' scale for the scale-free ones, whose estimate and
                // uncertainty scale with the point).
                u_rho: point_uncertainty(view, p),
                readings: p.readings,
                u_readings: p.reading_sigma,
            })
            .collect(),
    }
}

/// The calibration's per-bin standard uncertainty for point `p` on the bins
/// it carries: its zone's and cluster's, from the table its estimate takes
/// on those bins (sharp or broad, `brdf_meter::band`), for its scale and
/// (root form) its own estimate (`BlobView::point_uncertainty`).
pub fn point_uncertainty(view: &BlobView<'_>, p: &PointRecord) -> Vec<f32> {
    let bins: Vec<f32> = p.bins.bins().map(|j| view.grid_deg(j)).collect();
    let table = view.band_table(&bins, &p.values);
    p.bins
        .bins()
        .zip(&p.values)
        .map(|(j, v)| view.point_uncertainty(table, (p.zone as usize, p.cluster as usize), j, *v, p.sigma_scale))
        .collect()
}

/// The finite readings as (name, value, standard uncertainty).
pub fn readings_of(r: &[f32; READINGS], u: &[f32; READINGS]) -> Vec<(String, f64, f64)> {
    (0..READINGS)
        .filter(|&k| r[k].is_finite())
        .map(|k| (gloss::NAMES[k].to_string(), f64::from(r[k]), f64::from(u[k])))
        .collect()
}

/// What the summary needs of each point.
pub fn summary_points(points: &[PointRecord]) -> Vec<crate::device::measurement_summary::SummaryPoint> {
    points
        .iter()
        .map(|p| crate::device::measurement_summary::SummaryPoint {
            line: Some(p.line),
            flags: p.flags,
            readings: p.readings,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf_meter::protocol::flags;

    fn record(line: u32, point: u16, scale: f32, flags: u8) -> PointRecord {
        PointRecord {
            line,
            seq: line * 4 + u32::from(point),
            point,
            zone: 0,
            flags,
            cluster: 0,
            sigma_scale: scale,
            readings: [80.0 + f32::from(point), 2.0, f32::NAN],
            reading_sigma: [0.5, 0.1, f32::NAN],
            bins: brdf_meter::protocol::BinRange::all(9),
            encoding: brdf_meter::protocol::Encoding::F32,
            values: (0..9).map(|j| 0.5 + 0.1 * j as f32 * scale).collect(),
            corrected: Vec::new(),
        }
    }

    #[test]
    fn a_measurements_points_carry_their_pixels_bins_and_uncertainty() {
        let bytes = brdf_meter::test_blobs::test_blob(9, 3, 1, 4, 1.0);
        let view = BlobView::parse(&bytes).unwrap();
        let subset = brdf_meter::protocol::BinRange { first: 1, step: 2, count: 4 };
        let mut points: Vec<PointRecord> = (0..2).map(|p| record(1, p, 2.0, 0)).collect();
        for p in &mut points {
            p.bins = subset;
            p.values.truncate(4);
        }
        let doc = measurement_points(&view, &points, 45.0);
        assert_eq!((doc.source, doc.calibration_crc, doc.view_deg), ("measure", view.crc(), 45.0));
        assert_eq!(doc.bins_deg, subset.bins().map(|j| view.grid_deg(j)).collect::<Vec<_>>());
        let p = &doc.points[1];
        assert_eq!((p.line, p.pixel, p.zone, p.readings[0], p.u_readings[1]), (Some(1), Some(1), 0, 81.0, 0.1));
        assert_eq!(p.u_rho, subset.bins().map(|j| view.uncertainty_of(0, 0, j) * 2.0).collect::<Vec<_>>());
    }

    #[test]
    fn a_measurement_plots_with_its_band_and_readings_and_summarises() {
        let bytes = brdf_meter::test_blobs::test_blob(9, 3, 1, 4, 1.0);
        let view = BlobView::parse(&bytes).unwrap();
        let points: Vec<PointRecord> =
            (0..4).map(|p| record(0, p, 1.0 + f32::from(p), if p == 2 { flags::SATURATED } else { 0 })).collect();
        let profiles = measurement_points(&view, &points, 45.0).profiles();
        assert_eq!(profiles.len(), 4);
        assert_eq!((profiles[3].line, profiles[3].point), (0, 3));
        // The band is the blob's per-bin uncertainty times the point's scale.
        for j in 0..9 {
            let want = f64::from(view.uncertainty_of(0, 0, j) * 3.0);
            assert_eq!(profiles[2].uncertainty[j], want);
        }
        assert_eq!(profiles[2].flags, vec!["saturated".to_string()]);
        assert_eq!(
            profiles[1].readings,
            vec![("gloss_gu".to_string(), 81.0, 0.5), ("haze_hu".to_string(), 2.0, 0.1_f32 as f64)]
        );
        let dir = tempfile::tempdir().unwrap();
        let svg = dir.path().join("m.svg");
        crate::output::plot::profiles::write(&svg, "test measurement", &profiles[..3]).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.len() > 5_000, "{} bytes", text.len());
        // One shaded band per point, its legend with the readings.
        assert_eq!(text.matches("<polygon").count(), 3, "{text}");
        assert!(text.contains("line 0 point 1, gloss 81.0 ± 0.5 GU, haze 2.0 ± 0.1 HU"), "legend missing");
        assert!(text.contains("[saturated]"));
        let png = dir.path().join("m.png");
        crate::output::plot::profiles::write(&png, "test measurement", &profiles[..1]).unwrap();
        let bytes = std::fs::read(&png).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        assert!(bytes.len() > 10_000);
        let e = crate::output::plot::profiles::write(&dir.path().join("m.pdf"), "t", &profiles).unwrap_err();
        assert!(e.to_string().contains(".svg or .png"), "{e}");
        // The summary of the same points.
        let s = crate::device::measurement_summary::summarise(summary_points(&points));
        assert_eq!(s.len(), 1);
        assert_eq!(s[0].readings[0].mean, (80.0 + 81.0 + 83.0) / 3.0, "the saturated point's is left out");
        assert_eq!(s[0].flags.get("saturated"), Some(&1));
    }
}
