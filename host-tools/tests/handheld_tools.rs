//! The tools a user of the handheld meets, end to end on small cuts of its
//! line (so each runs in seconds): every zone count trains for every kind;
//! `simulate` writes `points.csv` and `estimate` reads it with each row's
//! pixel, as the device does; a calibration for other optics is refused;
//! `design` tells a layout with gaps between its LEDs from one without;
//! `pixel-map` reads held-out materials, the black glass and the tiles at
//! every pixel.
use brdf_meter::blob::{BlobView, EstimatorKind};
use host_tools::calibration::demo::{scene_prior, train_scene};
use host_tools::forward::pairs::Criterion;
use host_tools::forward::scene::Scene;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn handheld() -> Scene {
    Scene::load(&root().join("scenes/handheld.toml")).unwrap()
}

fn host_tools(args: &[&str]) -> (bool, String) {
    let out =
        std::process::Command::new(env!("CARGO_BIN_EXE_host-tools")).args(args).current_dir(root()).output().unwrap();
    (out.status.success(), format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr)))
}

#[test]
fn every_zone_count_trains_for_every_kind() {
    let cut = handheld().window(60, 6).unwrap();
    let prior = scene_prior(&cut, "patent").unwrap();
    for kind in [EstimatorKind::Wiener, EstimatorKind::ScaleFree, EstimatorKind::ScaleFreePiecewise] {
        for zones in 1..=6 {
            let t = train_scene(&cut, zones, 0.01, kind, &prior, Criterion::PeakRelative)
                .unwrap_or_else(|e| panic!("{kind:?}, {zones} zones: {e:#}"));
            let v = BlobView::parse(&t.blob).unwrap();
            assert_eq!((v.estimator(), v.dims().zones, v.dims().pixels), (kind, zones, 6));
            // One gloss reference per pixel, every pixel reading the standard.
            assert!((0..6).all(|p| v.gloss_reference(p).is_some_and(|s| s > 0.0)), "{kind:?} {zones}");
        }
    }
}

#[test]
fn estimate_reads_simulates_points_csv_pixel_by_pixel_as_the_device_does() {
    let dir = tempfile::tempdir().unwrap();
    let cut = handheld().window(56, 16).unwrap();
    let scene_path = dir.path().join("cut.toml");
    std::fs::write(&scene_path, toml::to_string(&cut).unwrap()).unwrap();
    let prior = scene_prior(&cut, "merl").unwrap();
    let t = train_scene(&cut, 4, 0.01, EstimatorKind::ScaleFree, &prior, Criterion::PeakRelative).unwrap();
    let blob_path = dir.path().join("cal.blob");
    std::fs::write(&blob_path, &t.blob).unwrap();
    let sim_dir = dir.path().join("sim");
    let (ok, out) =
        host_tools(&["simulate", scene_path.to_str().unwrap(), "--out", sim_dir.to_str().unwrap(), "--lines", "2"]);
    assert!(ok, "{out}");
    let est = dir.path().join("est.csv");
    let (ok, out) = host_tools(&[
        "estimate",
        "--blob",
        blob_path.to_str().unwrap(),
        "--readings",
        sim_dir.join("points.csv").to_str().unwrap(),
        "--out",
        est.to_str().unwrap(),
    ]);
    assert!(ok, "{out}");
    // Each row with its pixel's zone and gloss reference, bit for bit.
    let view = BlobView::parse(&t.blob).unwrap();
    let rows = host_tools::cli::estimate::read_readings(&sim_dir.join("points.csv"), 7).unwrap();
    assert_eq!(rows.len(), 2 * 16);
    let csv = std::fs::read_to_string(&est).unwrap();
    // The point schema: its comment line, then the header.
    let mut lines = csv.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(&header[..5], &["line", "pixel", "zone", "cluster", "flags"]);
    let gu_col = header.iter().position(|h| *h == brdf_meter::gloss::NAMES[0]).unwrap();
    for (r, line) in rows.iter().zip(lines) {
        let f: Vec<&str> = line.split(',').collect();
        let p = r.pixel.unwrap();
        assert_eq!((f[1], f[2]), (p.to_string().as_str(), view.zone_of_pixel(p).to_string().as_str()));
        let want = host_tools::device::reference::PointEstimator::new(view, view.zone_of_pixel(p))
            .unwrap()
            .apply_pixel(p, &r.v);
        assert_eq!(f[gu_col].parse::<f32>().unwrap().to_bits(), want.readings[0].to_bits(), "pixel {p}");
    }
}

#[test]
fn a_calibration_for_other_optics_is_refused_with_the_reason() {
    let cut = handheld().for_device(16).unwrap();
    let patent = host_tools::forward::scene::frames::patent_scene(16);
    let t = host_tools::calibration::demo::train_for_scene(&patent, 1, 0.02).unwrap();
    let e = host_tools::forward::scene::frames::check_optics(&cut, &BlobView::parse(&t.blob).unwrap()).unwrap_err();
    assert!(format!("{e:#}").contains("trained for other optics"), "{e:#}");
    // Its own calibration passes.
    let own =
        train_scene(&cut, 1, 0.02, EstimatorKind::Wiener, &scene_prior(&cut, "patent").unwrap(), Criterion::Plain)
            .unwrap();
    host_tools::forward::scene::frames::check_optics(&cut, &BlobView::parse(&own.blob).unwrap()).unwrap();
    // Standardised for LEDs that drifted (each by its own factor), it is
    // still for these optics; a pixel's profile changed is not.
    let view = BlobView::parse(&own.blob).unwrap();
    let (p, m) = (view.dims().pixels, view.dims().m);
    let drifted: Vec<f32> = (0..p * m).map(|k| view.white(k / m, k % m) * (1.1 + 0.05 * (k % m) as f32)).collect();
    let mut standardised = own.blob.clone();
    brdf_meter::blob::rewrite_white(&mut standardised, &drifted).unwrap();
    host_tools::forward::scene::frames::check_optics(&cut, &BlobView::parse(&standardised).unwrap()).unwrap();
    let mut bent = drifted.clone();
    bent[5 * m + 2] *= 1.05;
    brdf_meter::blob::rewrite_white(&mut standardised, &bent).unwrap();
    let e =
        host_tools::forward::scene::frames::check_optics(&cut, &BlobView::parse(&standardised).unwrap()).unwrap_err();
    assert!(format!("{e:#}").contains("at pixel 5, LED 2"), "{e:#}");
}

#[test]
fn design_tells_a_layout_with_gaps_from_one_without() {
    let dir = tempfile::tempdir().unwrap();
    let cands = dir.path().join("c.toml");
    std::fs::write(
        &cands,
        r#"
[[candidate]]
name = "7 evenly 3 mm"
leds = { count = 7, first_deg = 33.0, last_deg = 57.0, die_mm = 3.0 }
[[candidate]]
name = "7 about specular 4 mm slits"
leds = { angles_deg = [31.0, 38.0, 41.5, 45.0, 48.5, 52.0, 59.0], die_mm = 4.0, die_height_mm = 10.5 }
gain = 2400.0
short_exposure = [16.0, 80.0]
"#,
    )
    .unwrap();
    let out = dir.path().join("design");
    let (ok, text) = host_tools(&[
        "design",
        "--candidates",
        cands.to_str().unwrap(),
        "--pixels",
        "0,64,127",
        "--folds",
        "4",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("design.json")).unwrap()).unwrap();
    assert!(j[0]["uncovered"].as_u64().unwrap() > 0, "evenly spread 3 mm dies leave gaps");
    assert_eq!(j[1]["uncovered"].as_u64().unwrap(), 0, "the handheld's layout covers every pixel");
    assert_eq!(j[1]["metal_saturated"][1].as_u64().unwrap(), 0, "no metal saturates the shortest exposure");
    // A die's extent across the plane is its own (a slit), the other's square.
    let dims = |k: usize| (j[k]["die_mm"].as_f64().unwrap(), j[k]["die_height_mm"].as_f64().unwrap());
    assert_eq!((dims(0), dims(1)), ((3.0, 3.0), (4.0, 10.5)));
    // The gloss reading's predicted error: slits as wide as the gloss
    // window across the plane read it within a few per cent; square dies
    // with gaps do not.
    let gloss = |k: usize| j[k]["gloss"][1].as_f64().unwrap();
    assert!(gloss(1) < 0.15 && gloss(1) < gloss(0), "{} {}", gloss(0), gloss(1));
    for f in ["design.md", "design.csv", "summary.svg", "summary.png", "candidate-7-about-specular-4-mm-slits.png"] {
        assert!(out.join(f).exists(), "{f}");
    }
}

#[test]
fn pixel_map_reads_every_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let cut = handheld().window(48, 12).unwrap();
    let mut prior = scene_prior(&cut, "merl").unwrap();
    prior.samples.truncate(20);
    for s in &mut prior.samples {
        s.weight = 1.0 / 20.0;
    }
    let spec = host_tools::evaluation::pixel_map::MapSpec {
        scene: cut,
        zones: 3,
        kind: EstimatorKind::ScaleFree,
        criterion: Criterion::PeakRelative,
        clusters: None,
        false_alarm: host_tools::calibration::estimators::scale_free::DEFAULT_FALSE_ALARM,
        prior,
        folds: 4,
        lines: 1,
        gloss_lines: 3,
        acq: brdf_meter::platform::timing::ACQUISITION,
        seed: 1,
        unseen: Some(unseen_set()),
    };
    let map = host_tools::evaluation::pixel_map::run(&spec, &|_| {}).unwrap();
    assert_eq!((map.pixels.len(), map.materials.len()), (12, 20));
    assert!(map.error[0] > 0.0 && map.error[0] < map.interpolation[0], "{:?} {:?}", map.error, map.interpolation);
    assert_eq!(map.black_glass.no_reading, 0);
    assert!(
        (map.black_glass.mean_range_gu[0] - 100.0).abs() < 3.0
            && (map.black_glass.mean_range_gu[1] - 100.0).abs() < 3.0
    );
    // Every held-out (material, pixel) has a gloss reading, scored against
    // the definitions in three dimensions, and so has interpolation. The
    // slits span the gloss window across the plane, so both read it within
    // a few per cent at the median (here 20 materials train the zones).
    let g = &map.gloss;
    assert_eq!(g.low_count + g.high_count, 12 * 20);
    let gi = &map.gloss_interpolation;
    assert_eq!(gi.low_count + gi.high_count, 12 * 20);
    assert!(g.low[0] > 0.0 && g.low[0] < 0.10 && g.low[0] <= g.low[1], "{g:?}");
    assert!(gi.low[0] > 0.0 && gi.low[0] < 0.10, "{gi:?}");
    let m = &map.materials[0];
    assert!(m.gloss_true.iter().zip(&m.gloss).all(|(t, e)| *t > 0.0 && e.is_finite()), "{m:?}");
    // The frames' stated uncertainty is scored on the held-out materials
    // and on the tiles, surfaces of families no prior holds, whose BRDF is
    // read beside interpolation's.
    assert_eq!(m.bin_coverage.len(), 12);
    assert!((0.5..=1.0).contains(&map.bin_coverage), "{}", map.bin_coverage);
    // And each reading's: every held-out point here has all three readings.
    assert_eq!(m.reading_coverage.len(), 12);
    assert!(m.reading_coverage.iter().flatten().all(|c| (0.0..=1.0).contains(c)), "{:?}", m.reading_coverage);
    assert!(map.reading_coverage.iter().all(|c| (0.5..=1.0).contains(c)), "{:?}", map.reading_coverage);
    let (per_tile, t) = (&map.tiles_brdf.per_tile, &map.tiles_brdf.all);
    assert_eq!(per_tile.len(), host_tools::evaluation::pixel_map::gloss_tiles().len());
    assert!(t.error[0] > 0.0 && t.interpolation[0] > 0.0 && t.error[1] <= t.error[2], "{t:?}");
    assert!((0.5..=1.0).contains(&t.bin_coverage) && (0.0..=1.0).contains(&t.out_of_prior), "{t:?}");
    // Whether the flag predicts error is scored on every point read: each
    // line of each pixel of each held-out material, and of each tile.
    let f = &map.flag;
    assert_eq!(f.bad + f.good, 12 * 20, "{f:?}");
    assert!(f.bad_flagged <= f.bad && f.good_flagged <= f.good, "{f:?}");
    // Each material's own points, which together are the map's.
    assert!(map.materials.iter().all(|m| m.flag.bad + m.flag.good == 12), "{:?}", map.materials[0].flag);
    let summed = map
        .materials
        .iter()
        .fold(Default::default(), |a: host_tools::evaluation::metrology::metrics::FlagScore, m| a.merged(m.flag));
    assert_eq!(summed, *f);
    assert_eq!(t.flag.bad + t.flag.good, 12 * per_tile.len() * 3, "{:?}", t.flag);
    // And on the scene's own surface, the one it is set up to read (a flag
    // raised there is what inspection cannot be taught on), and the
    // black glass's flags.
    let own = &map.own_surface.brdf;
    assert!(map.own_surface.surface.contains("\"model\""), "{}", map.own_surface.surface);
    assert!(own.error[0] > 0.0 && own.error[1] <= own.error[2] && own.interpolation[0] > 0.0, "{own:?}");
    assert_eq!(own.flag.bad + own.flag.good, 12 * 3, "{:?}", own.flag);
    assert!((0.0..=1.0).contains(&own.out_of_prior) && (0.0..=1.0).contains(&map.black_glass.out_of_prior));
    // The held-out points' specular peaks, as `measure` writes them: every
    // point whose truth has one is counted, read with a peak or without.
    let pk = &map.peaks;
    assert!(pk.points > 0 && pk.missed <= pk.points, "{pk:?}");
    assert!((0.0..=1.0).contains(&pk.unresolved), "{pk:?}");
    assert!(pk.height_rel[0] <= pk.height_rel[1] && pk.interpolation_height_rel[0] > 0.0, "{pk:?}");
    // Every pixel states the resolution its peaks are judged at (a few
    // bins: far below the LEDs' spacing).
    assert!(map.pixels.iter().all(|r| (0.3..2.0).contains(&r.peak_resolution_deg)), "{:?}", map.pixels);
    // And the share of its peaks it leaves unresolved: the line's share is
    // among its pixels' (each pixel's own peaks, counted once).
    let shares: Vec<f64> = map.pixels.iter().map(|r| r.peaks_unresolved).collect();
    assert!(shares.iter().all(|x| (0.0..=1.0).contains(x)), "{shares:?}");
    let (lo, hi) = shares.iter().fold((1.0f64, 0.0f64), |(a, b), x| (a.min(*x), b.max(*x)));
    assert!(lo <= pk.unresolved && pk.unresolved <= hi, "{lo} {} {hi}", pk.unresolved);
    // Beside it, what each calibration's training chose and said of its
    // flag: the four folds' statistics and the whole prior's, and the
    // whole prior's score on kinds held out (the prior's weights, which
    // sum to one over each zone's held-out readings: every zone counts
    // alike).
    assert_eq!(map.flag_statistics.len(), 4 + 1, "{:?}", map.flag_statistics);
    assert!(map.flag_statistics.iter().all(|f| f == "linear" || f == "log-ratio"), "{:?}", map.flag_statistics);
    let k = map.flag_in_training.expect("the root form's training scores its flag on kinds held out");
    assert!((k.bad + k.good - 3.0).abs() < 1e-9 && k.bad_flagged <= k.bad && k.good_flagged <= k.good, "{k:?}");
    host_tools::evaluation::pixel_map::report::write(dir.path(), &map, 4).unwrap();
    assert!(dir.path().join("pixel-map.png").exists());
    let md = std::fs::read_to_string(dir.path().join("pixel-map.md")).unwrap();
    assert!(md.contains("| gloss, held out: relative error"), "{md}");
    assert!(md.contains("(what `train` prints)") && md.contains("statistic of each calibration"), "{md}");
    assert!(md.contains("| gloss tiles' BRDF error / peak") && md.contains("stated uncertainty"), "{md}");
    assert!(md.contains("| out-of-prior flag, held out: of points worse than 0.10"), "{md}");
    // Which materials it reads worst, when any point is worse than 0.10.
    if f.bad > 0 {
        assert!(
            md.contains("Held-out materials read worst: ") && md.contains("| material | points worse than 0.10 |"),
            "{md}"
        );
    }
    // Every held-out material is named near a sample its fold trained on.
    let near = map.held_out_nearness.expect("the held-out materials' nearness");
    assert_eq!(near.surfaces, 20);
    for m in &map.materials {
        let n = m.nearest_training.as_ref().expect("a nearest sample its fold trained on");
        assert!(n.name != m.name && n.distance > 0.0, "{}: {n:?}", m.name);
    }
    assert!(near.median > 0.0 && md.contains("| held out: nearest prior sample its fold trained on"), "{md}");
    // The unseen set: the two surfaces the truncated prior lacks are read
    // at every pixel beside interpolation; the prior sample among them is
    // left out and named.
    let u = map.unseen.as_ref().expect("asked for");
    let vendored =
        host_tools::evaluation::metrology::families::TestFamily::measured_files("merl", [1.0 / 3.0; 3]).unwrap();
    assert_eq!(u.in_prior, vec![vendored.materials[0].0.clone()]);
    assert_eq!(u.materials.iter().map(|m| m.name.as_str()).collect::<Vec<_>>(), ["unseen-a", "unseen-b"]);
    assert_eq!(u.materials[0].error.len(), 12);
    assert!(u.summary.error[0] > 0.0 && u.summary.interpolation[0] > 0.0, "{:?}", u.summary);
    assert_eq!(u.summary.gloss.low_count + u.summary.gloss.high_count, 12 * 2);
    assert_eq!(u.flag.bad + u.flag.good, 12 * 2, "{:?}", u.flag);
    assert!(md.contains("| unseen set `test set` (2 surfaces; 1 left out as prior samples"), "{md}");
    // Each is named with the prior sample nearest it: one of the 20 the
    // truncated prior holds, at a distance above 0 (it is not one of them).
    for m in &u.materials {
        let n = m.nearest_training.as_ref().expect("a nearest prior sample");
        assert!(spec.prior.samples.iter().any(|s| s.name == n.name) && n.distance > 1e-6, "{n:?}");
    }
    let near = u.nearness.expect("the set's nearness");
    assert_eq!(near.surfaces, 2);
    assert!(md.contains("| unseen set's nearest prior sample"), "{md}");
}

/// Two of the vendored materials the truncated prior lacks (renamed) and
/// one it holds.
fn unseen_set() -> host_tools::evaluation::pixel_map::unseen::UnseenSpec {
    let spectral = handheld().instrument.spectral_weights;
    let all = host_tools::evaluation::metrology::families::TestFamily::measured_files("merl", spectral).unwrap();
    let m = &all.materials;
    let materials = vec![
        ("unseen-a".to_string(), m[40].1.clone()),
        (m[0].0.clone(), m[0].1.clone()),
        ("unseen-b".to_string(), m[41].1.clone()),
    ];
    host_tools::evaluation::pixel_map::unseen::UnseenSpec { source: "test set".into(), materials }
}

/// A standardisation replayed offline: the handheld's LEDs drifting each at
/// its own rate, the white tile read 2,000 lines on and the calibration
/// standardised on it; the Ward sample read then is estimated by the
/// standardised calibration `--corrected-with` the one its readings were
/// corrected with (the white it was trained with), and reads what it read
/// at calibration. Without `--corrected-with` the drift is all still there.
#[test]
fn a_standardisation_replays_offline_with_the_readings_white() {
    use host_tools::forward::scene::{DriftRate, EffectSpec};
    let dir = tempfile::tempdir().unwrap();
    let mut cut = handheld().window(60, 8).unwrap();
    let rates = vec![0.6e-5, 1.4e-5, 0.8e-5, 1.2e-5, 1.0e-5, 0.7e-5, 1.3e-5];
    for e in cut.effects.iter_mut() {
        if let EffectSpec::LedDrift { rate } = e {
            *rate = DriftRate::PerLed(rates.clone());
        }
    }
    let scene = dir.path().join("uneven.toml");
    std::fs::write(&scene, toml::to_string(&cut).unwrap()).unwrap();
    let prior = scene_prior(&cut, "patent").unwrap();
    let t = train_scene(&cut, 1, 0.01, EstimatorKind::Wiener, &prior, Criterion::PeakRelative).unwrap();
    let cal = dir.path().join("cal.blob");
    std::fs::write(&cal, &t.blob).unwrap();
    let p = |x: &Path| x.to_str().unwrap().to_string();
    let simulate = |surface: &str, line: &str, lines: &str, out: &Path| {
        let (ok, text) = host_tools(&[
            "simulate",
            &p(&scene),
            "--surface",
            surface,
            "--line",
            line,
            "--lines",
            lines,
            "--out",
            &p(out),
        ]);
        assert!(ok, "{text}");
        out.join("points.csv")
    };
    let tile = simulate("{ model = \"lambertian\", rho = 0.99 }", "2000", "16", &dir.path().join("tile"));
    let std_blob = dir.path().join("std.blob");
    let report = dir.path().join("std.json");
    let (ok, text) = host_tools(&[
        "standardise",
        "--blob",
        &p(&cal),
        "--readings",
        &p(&tile),
        "--tile-rf",
        "0.99",
        "--out",
        &p(&std_blob),
        "--report",
        &p(&report),
    ]);
    assert!(ok, "{text}");
    // Each LED's own drift found: 1 + rate x about 16,070 frames.
    let found: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    for r in found["readings"].as_array().unwrap() {
        let k = r["reading"].as_u64().unwrap() as usize;
        let want = 1.0 + rates[k] * 16_070.0;
        assert!((r["ratio_median"].as_f64().unwrap() - want).abs() < 0.01, "LED {k}: {r} against {want}");
    }
    let ward = "{ model = \"ward\", rho_d = 0.2, alpha = 0.15 }";
    let mean_gloss = |blob: &Path, readings: &Path, extra: &[&str], tag: &str| -> f64 {
        let out = dir.path().join(format!("{tag}.json"));
        let mut args = vec!["estimate", "--blob", blob.to_str().unwrap(), "--readings", readings.to_str().unwrap()];
        let (csv, json) = (p(&dir.path().join(format!("{tag}.csv"))), p(&out));
        args.extend(["--out", &csv, "--json", &json]);
        args.extend(extra);
        let (ok, text) = host_tools(&args);
        assert!(ok, "{text}");
        let e: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
        let g: Vec<f64> = e["points"].as_array().unwrap().iter().map(|x| x["gloss_gu"].as_f64().unwrap()).collect();
        g.iter().sum::<f64>() / g.len() as f64
    };
    let at_calibration = mean_gloss(&cal, &simulate(ward, "0", "4", &dir.path().join("w0")), &[], "e0");
    let later = simulate(ward, "2020", "4", &dir.path().join("w1"));
    let cal_s = p(&cal);
    let replayed = mean_gloss(&std_blob, &later, &["--corrected-with", &cal_s], "e1");
    let as_logged = mean_gloss(&std_blob, &later, &[], "e2");
    assert!((replayed / at_calibration - 1.0).abs() < 0.01, "{replayed} against {at_calibration} at calibration");
    assert!(as_logged / at_calibration > 1.12, "{as_logged} against {at_calibration}");
    // A white that is not this instrument's drifted (one pixel's 5 % off
    // its neighbours' under an LED) is refused, naming the file and pixel.
    let view = BlobView::parse(&t.blob).unwrap();
    let m = view.dims().m;
    let mut bent: Vec<f32> = (0..8 * m).map(|k| view.white(k / m, k % m)).collect();
    bent[5 * m + 2] *= 1.05;
    let mut other = t.blob.clone();
    brdf_meter::blob::rewrite_white(&mut other, &bent).unwrap();
    let other_path = dir.path().join("other.blob");
    std::fs::write(&other_path, &other).unwrap();
    let e3 = p(&dir.path().join("e3.csv"));
    let (ok, text) = host_tools(&[
        "estimate",
        "--blob",
        &p(&cal),
        "--readings",
        &p(&later),
        "--corrected-with",
        &p(&other_path),
        "--out",
        &e3,
    ]);
    assert!(!ok, "{text}");
    assert!(text.contains("other.blob") && text.contains("at pixel 5"), "{text}");
    assert!(!dir.path().join("e3.csv").exists());
}
