//! The point schema pinned byte for byte: a fixed set of points written by
//! `measure`'s path (device records on a fixed test blob) and by `estimate`
//! (the same blob applied to fixed readings), checked in under
//! `host-tools/tests/golden/points/` and compared byte for byte, so a change
//! to a name, an order, a unit or a number's text cannot pass unnoticed.
//! The two files' headers are the same: one schema whatever the source.
//! Each command's result document (`device::measurement_result`: the
//! readings' means with their uncertainty budgets) is pinned beside them;
//! its version is `host_tools::device::measurement_result::SCHEMA_VERSION`.
//!
//! A difference means the files changed. If a field was renamed, removed,
//! added, moved or changed its meaning, unit or rule for when it is
//! missing, bump
//! `host_tools::output::points::SCHEMA_VERSION` and say so in
//! docs/point-schema.md; then regenerate with
//!
//!     GOLDEN_REGENERATE=1 cargo test --release -p host-tools --test point_schema
//!
//! and read the diff before committing it.
use brdf_meter::blob::{BlobView, Dims};
use brdf_meter::protocol::{BinRange, Encoding, flags};
use brdf_meter::test_blobs::TestBlobParts;
use host_tools::device::link::PointRecord;
use std::path::{Path, PathBuf};

const REGENERATE: &str = "GOLDEN_REGENERATE";

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/points")
}

/// A fixed blob: 21 bins of 0.5 deg over 40..50 deg (the specular aperture
/// about 45 deg and a little beyond), 3 readings, 2 zones of 4 pixels, a
/// peak resolution of 1 deg. Its matrices make an estimate a lobe (zone 0
/// at 45 deg, zone 1 at 46 deg) times the first reading over a level the
/// second reading gives.
fn blob() -> Vec<u8> {
    let mut parts = TestBlobParts::new(21, 3, 2, 4, 1.0);
    assert_eq!(parts.dims, Dims { n: 21, m: 3, zones: 2, pixels: 4 });
    parts.grid = (0..21).map(|i| 40.0 + 0.5 * i as f32).collect();
    let lobes = [lobe(&parts.grid, 0.0, 1.0, 45.0, 2.5), lobe(&parts.grid, 0.0, 1.0, 46.0, 3.0)];
    parts.mats = lobes.iter().flat_map(|l| l.iter().flat_map(|&x| [x, 1.0, 0.0])).collect();
    parts.peak_resolution_deg = Some(1.0);
    parts.encode()
}

/// A lobe of `height` over `base`, a parabola falling to the base `reach`
/// deg from `centre` (arithmetic only, so the same bits on every host).
fn lobe(grid: &[f32], base: f32, height: f32, centre: f32, reach: f32) -> Vec<f32> {
    grid.iter().map(|&t| base + height * (1.0 - ((t - centre) / reach).powi(2)).max(0.0)).collect()
}

fn record(line: u32, point: u16, zone: u16, flags: u8, sigma_scale: f32, readings: [[f32; 3]; 2]) -> PointRecord {
    PointRecord {
        line,
        seq: line * 4 + u32::from(point),
        point,
        zone,
        flags,
        cluster: 0,
        sigma_scale,
        readings: readings[0],
        reading_sigma: readings[1],
        bins: BinRange::all(21),
        encoding: Encoding::F32,
        values: Vec::new(),
        corrected: Vec::new(),
    }
}

/// What the points show: a glossy lobe with every reading; the same on a
/// scale-free point (its uncertainty scaled); a matte point (no peak, no
/// distinctness); a saturated point on a high diffuse level in the zone
/// without readings (a height but no width); a non-finite point (zeros, no
/// readings); a lobe narrower than the calibration resolves (no
/// uncertainty of its height and width).
fn records(grid: &[f32]) -> Vec<PointRecord> {
    let nan = f32::NAN;
    let mut r = vec![
        record(0, 0, 0, 0, 1.0, [[152.25, 3.5, 88.0], [4.0, 0.25, 2.5]]),
        record(0, 1, 0, 0, 1.75, [[151.5, 3.75, 87.5], [7.0, 0.4375, 4.25]]),
        record(0, 2, 0, 0, 1.0, [[8.0, 2.0, nan], [0.5, 0.125, nan]]),
        record(0, 3, 1, flags::SATURATED, 1.0, [[nan; 3], [nan; 3]]),
        record(1, 0, 0, flags::NON_FINITE, 1.0, [[nan; 3], [nan; 3]]),
        record(1, 1, 0, 0, 1.0, [[310.5, 1.25, 96.5], [9.0, 0.25, 1.5]]),
    ];
    r[0].values = lobe(grid, 0.05, 1.5, 45.0, 2.5);
    r[1].values = lobe(grid, 0.0625, 1.5, 45.5, 2.5);
    r[2].values = vec![0.8; 21];
    r[3].values = lobe(grid, 0.75, 0.5, 47.0, 2.0);
    r[4].values = vec![0.0; 21];
    r[5].values = lobe(grid, 0.05, 3.0, 45.0, 0.75);
    r
}

/// The readings `estimate` is given (`simulate`'s `points.csv` layout, a
/// comment first): a glossy point in zone 0, a lobe on a high level in zone
/// 1 (a height, no width), a flat one (no peak).
const READINGS: &str = "# fixed readings for the point schema's golden file\n\
line,pixel,r0,r1,r2\n\
0,0,1.25,0.125,7.0\n\
0,3,0.375,0.625,1.0\n\
1,2,0.0,0.3,2.0\n";

/// The files as they are written now: (name, bytes).
fn written() -> Vec<(&'static str, Vec<u8>)> {
    let bytes = blob();
    let view = BlobView::parse(&bytes).unwrap();
    let grid: Vec<f32> = (0..21).map(|j| view.grid_deg(j)).collect();
    let m = host_tools::device::measurement::measurement_points(&view, &records(&grid), 45.0);
    let zones = host_tools::device::measurement_result::centre_zones(&view);
    let m_result = host_tools::device::measurement_result::measurement_result(
        &view,
        &zones,
        &host_tools::device::measurement::calibration_points(&view, &records(&grid), 45.0),
    );
    let dir = tempfile::tempdir().unwrap();
    let (cal, readings) = (dir.path().join("cal.blob"), dir.path().join("r.csv"));
    std::fs::write(&cal, &bytes).unwrap();
    std::fs::write(&readings, READINGS).unwrap();
    let (csv, json, result) = (dir.path().join("e.csv"), dir.path().join("e.json"), dir.path().join("r.json"));
    host_tools::cli::estimate::run(host_tools::cli::estimate::Args {
        blob: cal,
        readings,
        corrected_with: Default::default(),
        out: csv.clone(),
        json: Some(json.clone()),
        zone: 0,
        result: Some(result.clone()),
        result_zones: vec![],
        exports: host_tools::cli::exports::ExportArgs { view_deg: 45.0, ..Default::default() },
    })
    .unwrap();
    vec![
        ("measure.csv", m.csv().unwrap()),
        ("measure.json", m.json().unwrap()),
        ("estimate.csv", std::fs::read(&csv).unwrap()),
        ("estimate.json", std::fs::read(&json).unwrap()),
        ("measure-result.json", m_result.json().unwrap()),
        ("estimate-result.json", std::fs::read(&result).unwrap()),
    ]
}

#[test]
fn the_point_schema_is_byte_for_byte_the_golden_files() {
    let files = written();
    if std::env::var_os(REGENERATE).is_some() {
        std::fs::create_dir_all(golden_dir()).unwrap();
        for (name, bytes) in &files {
            std::fs::write(golden_dir().join(name), bytes).unwrap();
        }
        return;
    }
    for (name, bytes) in &files {
        let path = golden_dir().join(name);
        let want =
            std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}; generate it with {REGENERATE}=1", path.display()));
        if *bytes != want {
            let (got, want) = (String::from_utf8_lossy(bytes), String::from_utf8_lossy(&want));
            let line = got
                .lines()
                .zip(want.lines())
                .position(|(a, b)| a != b)
                .unwrap_or(got.lines().count().min(want.lines().count()));
            panic!(
                "{} differs from what is written now, first at line {}:\n  golden: {}\n  now:    {}\n\
                 If a field was renamed, removed, added, moved or changed its meaning, unit or missing rule, bump SCHEMA_VERSION \
                 (host-tools/src/output/points.rs) and docs/point-schema.md; then regenerate with \
                 {REGENERATE}=1 cargo test --release -p host-tools --test point_schema",
                path.display(),
                line + 1,
                want.lines().nth(line).unwrap_or("(end of file)"),
                got.lines().nth(line).unwrap_or("(end of file)"),
            );
        }
    }
}

#[test]
fn measure_and_estimate_write_the_same_fields_and_the_peaks_read_back() {
    let files = written();
    let text = |k: usize| String::from_utf8(files[k].1.clone()).unwrap();
    let (mcsv, ecsv) = (text(0), text(2));
    // The header (the second line) is the same; the comments differ in the source only.
    assert_eq!(mcsv.lines().nth(1), ecsv.lines().nth(1));
    assert_eq!(mcsv.lines().next().unwrap().replace("source measure", "source estimate"), ecsv.lines().next().unwrap());
    let j: serde_json::Value = serde_json::from_slice(&files[1].1).unwrap();
    let e: serde_json::Value = serde_json::from_slice(&files[3].1).unwrap();
    let keys = |v: &serde_json::Value| v.as_object().unwrap().keys().cloned().collect::<Vec<_>>();
    assert_eq!(keys(&j), keys(&e));
    assert_eq!(keys(&j["points"][0]), keys(&e["points"][0]));
    // The estimate's rows carry their line and pixel, and the pixel's zone;
    // their peaks are the blob's lobes.
    let q = &e["points"];
    assert_eq!((&q[1]["line"], &q[1]["pixel"], &q[1]["zone"]), (&0.into(), &3.into(), &1.into()));
    assert_eq!((q[0]["peak_rf"].as_f64().unwrap() as f32, q[0]["peak_deg"].as_f64().unwrap()), (1.375, 45.0));
    assert!(q[0]["peak_width_deg"].as_f64().unwrap() > 0.0);
    assert_eq!((q[1]["peak_rf"].as_f64().unwrap() as f32, q[1]["peak_deg"].as_f64().unwrap()), (1.0, 46.0));
    assert!(q[1]["peak_width_deg"].is_null() && q[2]["peak_rf"].is_null());
    // The glossy point: the parabola's top and its width at half of it,
    // the top's u the blob's for the bin, the scale-free point's scaled.
    let p = &j["points"];
    let f = |i: usize, k: &str| p[i][k].as_f64().unwrap_or(f64::NAN);
    assert_eq!(f(0, "peak_rf") as f32, 1.55);
    assert_eq!(f(0, "peak_deg"), 45.0);
    // Half of 1.55 is 0.05 + 1.5 (1 - (d / 2.5)^2) at d = 2.5 sqrt(1 - 0.725 / 1.5);
    // linear between 0.5 deg bins, the chord of the parabola within 0.02 deg a side.
    let fwhm = 2.0 * 2.5 * (1.0 - 0.725f64 / 1.5).sqrt();
    assert!((f(0, "peak_width_deg") - fwhm).abs() < 0.04, "{fwhm}: {}", p[0]);
    assert!(f(0, "u_peak_width_deg") > 0.0);
    let u_bin = |i: usize, j: usize| p[i]["u_rho"][j].as_f64().unwrap();
    assert_eq!((f(0, "u_peak_rf"), f(1, "peak_deg")), (u_bin(0, 10), 45.5));
    assert_eq!(f(1, "u_peak_rf"), u_bin(1, 11));
    assert!((u_bin(1, 11) - 1.75 * u_bin(0, 11)).abs() < 1e-6);
    // The matte point: no peak, no distinctness; the saturated one a height, no width.
    assert!(p[2]["peak_rf"].is_null() && p[2]["distinctness_pct"].is_null());
    assert_eq!((f(3, "peak_rf") as f32, f(3, "peak_deg")), (1.25, 47.0));
    assert!(p[3]["peak_width_deg"].is_null() && p[3]["flags"] == serde_json::json!(["saturated"]));
    assert!(p[4]["peak_rf"].is_null() && p[4]["flags"] == serde_json::json!(["non-finite"]));
    // Every CSV row has the header's fields, read by the csv crate with `#` comments.
    for csv in [&mcsv, &ecsv] {
        let mut r = csv::ReaderBuilder::new().comment(Some(b'#')).from_reader(csv.as_bytes());
        let n = r.headers().unwrap().len();
        let rows: Vec<csv::StringRecord> = r.records().map(Result::unwrap).collect();
        assert!(!rows.is_empty() && rows.iter().all(|row| row.len() == n));
    }
}
