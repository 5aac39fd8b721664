//! Scene tests: the library, each effect on its own, white calibration,
//! malformed files, and what training and the simulated sensor get.
use super::pipeline::Mode;
use super::*;
use crate::forward::brdf::BrdfSpec;
use crate::forward::grid::AngleGrid;
use crate::forward::optics::{EmissionSpec, system_matrix};
use std::path::PathBuf;

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

fn library() -> Vec<(PathBuf, Scene)> {
    let mut files = Vec::new();
    for dir in [scenes_dir(), scenes_dir().join("hard")] {
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "toml") {
                files.push(p);
            }
        }
    }
    files.sort();
    files.into_iter().map(|p| (p.clone(), Scene::load(&p).unwrap_or_else(|e| panic!("{e}")))).collect()
}

fn load(rel: &str) -> Scene {
    Scene::load(&scenes_dir().join(rel)).unwrap_or_else(|e| panic!("{e}"))
}

/// The handheld instrument with exactly `effects` and `surface`.
fn handheld_with(effects: Vec<EffectSpec>, brdf: BrdfSpec) -> Scene {
    let mut s = load("handheld.toml");
    s.effects = effects;
    s.surface = SurfaceSpec { brdf, segments: Vec::new() };
    s.validate().unwrap();
    s
}

fn ward() -> BrdfSpec {
    BrdfSpec::Ward { rho_d: 0.35, rho_s: None, alpha: 0.12 }
}

fn white_tile() -> BrdfSpec {
    BrdfSpec::Lambertian { rho: 1.0 }
}

fn noise(sigma: f64, seed: u64) -> EffectSpec {
    EffectSpec::Noise {
        model: NoiseModel::Proportional,
        sigma: Some(sigma),
        sigma_counts: None,
        electrons_per_count: None,
        read_sigma_counts: None,
        seed,
    }
}

fn sim(s: &Scene) -> Simulator {
    Simulator::new(s).unwrap_or_else(|e| panic!("{e:#}"))
}

#[test]
fn every_library_scene_parses_validates_and_simulates_finite() {
    let lib = library();
    let names: Vec<String> = lib.iter().map(|(p, _)| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    for want in [
        "patent-profile.toml",
        "handheld.toml",
        "far-field.toml",
        "near-singular.toml",
        "grazing.toml",
        "sharp-lobe.toml",
    ] {
        assert!(names.iter().any(|n| n == want), "scenes/ lacks {want}: {names:?}");
    }
    assert!(lib.iter().filter(|(p, _)| p.parent().unwrap().ends_with("hard")).count() >= 9);
    for (path, s) in &lib {
        let sim = sim(s);
        for line in 0..3 {
            let r = sim.simulate_line(line, Mode::Full);
            assert!(r.raw.iter().flatten().all(|x| x.is_finite()), "{}: raw not finite", path.display());
            assert!(r.corrected.iter().all(|x| x.is_finite()), "{}: corrected not finite", path.display());
        }
        assert!(sim.white().iter().all(|w| *w > 0.0 && w.is_finite()));
        // Training's view of every scene is finite too, at every zone count tried.
        for z in [1, s.instrument.pixels()] {
            for zm in zone_system_matrices(s, z).unwrap_or_else(|e| panic!("{}: {e:#}", path.display())) {
                assert!(zm.h.iter().all(|x| x.is_finite() && *x >= 0.0));
            }
        }
    }
}

#[test]
fn pipeline_holds_exactly_the_listed_stages_in_stage_order() {
    for (path, s) in library() {
        let names = Pipeline::new(&s).names();
        let mut listed: Vec<&str> = s.effects.iter().map(|e| e.name()).collect();
        listed.sort_by_key(|n| STAGE_ORDER.iter().position(|x| x == n));
        assert_eq!(names, listed, "{}", path.display());
    }
    let far = load("far-field.toml");
    assert!(Pipeline::new(&far).names().is_empty());
    assert_eq!(Pipeline::new(&far).ray_model(), crate::forward::optics::RayModel::default());
    // Listed out of order: run in stage order.
    let s = handheld_with(
        vec![
            EffectSpec::Quantisation { step_counts: 1.0 },
            EffectSpec::Saturation {},
            noise(0.01, 3),
            EffectSpec::NearField {},
        ],
        ward(),
    );
    assert_eq!(Pipeline::new(&s).names(), ["near-field", "noise", "saturation", "quantisation"]);
}

#[test]
fn patent_profile_scene_is_the_original_optics() {
    let s = load("patent-profile.toml");
    assert_eq!(s, Scene::patent_profile());
    let inst = Instrument::patent_profile();
    let g = AngleGrid::patent();
    let h = pixel_system_matrix(&s, 0.0).unwrap();
    assert!((&h - system_matrix(&inst, &g, false).unwrap()).amax() < 1e-14);
    // Noise-free corrected readings are the original simulate_readings.
    let sim = sim(&s);
    let r = sim.simulate_line(0, Mode::NoNoise);
    let w = s.surface.brdf.build().unwrap();
    let v = crate::forward::optics::simulate_readings(&inst, w.as_ref(), false);
    for k in 0..7 {
        assert!((r.corrected[k] - v[k]).abs() < 1e-12 * v[k], "LED {k}: {} vs {}", r.corrected[k], v[k]);
    }
    // The far-field idealisation of the same instrument is the original far field.
    let mut far = s.clone();
    far.effects.clear();
    assert!((pixel_system_matrix(&far, 0.0).unwrap() - system_matrix(&inst, &g, true).unwrap()).amax() < 1e-14);
}

#[test]
fn the_far_field_scene_is_the_handheld_instrument_without_effects() {
    // What far field costs and buys is measured against the handheld, so
    // when the handheld's optics change the idealisation must follow.
    let (far, hand) = (load("far-field.toml"), load("handheld.toml"));
    assert_eq!(far.instrument, hand.instrument);
    assert!(far.effects.is_empty());
}

#[test]
fn far_field_gives_every_ray_the_centre_angle_and_builds_no_sources() {
    let s = load("far-field.toml");
    let optics = Optics::new(&s.instrument, s.ray_model());
    assert_eq!(optics.sources_built(), 0, "far field builds no per-source positions");
    for px in [0.0, 63.5, 127.0] {
        for led in 0..s.instrument.m() {
            let rays = optics.rays_at(led, &s.pixel_point(px));
            assert_eq!(rays.len(), 1);
            assert!((rays[0].theta_deg - s.instrument.leds[led].centre_deg).abs() < 1e-9);
        }
    }
    // Near field: one ray per sample point of each extended LED, spread
    // around the centre angle.
    let near = handheld_with(vec![EffectSpec::NearField {}, EffectSpec::ThreeDGeometry {}], ward());
    let optics = Optics::new(&near.instrument, near.ray_model());
    let per_led = near.instrument.leds[3].extended.as_ref().map(|e| e.samples[0] * e.samples[1]).unwrap();
    assert_eq!(optics.sources_built(), 7 * per_led);
    let rays = optics.rays_at(3, &near.pixel_point(0.0));
    assert_eq!(rays.len(), per_led);
    assert!(rays.iter().any(|r| (r.theta_deg - 45.0).abs() > 0.5));
    assert!(rays.iter().any(|r| r.dir.y.abs() > 1e-3));
    // In-plane (no 3d-geometry): the emitter's height collapses, one row of rays, all in the plane.
    let flat = handheld_with(vec![EffectSpec::NearField {}], ward());
    let rays = Optics::new(&flat.instrument, flat.ray_model()).rays_at(3, &flat.pixel_point(0.0));
    assert_eq!(rays.len(), flat.instrument.leds[3].extended.as_ref().unwrap().samples[0]);
    assert!(rays.iter().all(|r| r.dir.y == 0.0));
    // Near field alone spreads each H row over several bins; far field is one-hot.
    let h = pixel_system_matrix(&flat, 0.0).unwrap();
    let hf = pixel_system_matrix(&s, 63.5).unwrap();
    for i in 0..7 {
        assert!(h.row(i).iter().filter(|x| **x > 0.0).count() >= 3);
        assert_eq!(hf.row(i).iter().filter(|x| **x > 0.0).count(), 1);
    }
}

#[test]
fn without_noise_two_runs_are_identical_and_with_noise_the_seed_decides() {
    let quiet = handheld_with(
        vec![EffectSpec::NearField {}, EffectSpec::DarkOffset { counts: 50.0, fixed_pattern_rms: 0.0, seed: 1 }],
        ward(),
    );
    let a = sim(&quiet).simulate_line(0, Mode::Full);
    let b = sim(&quiet).simulate_line(5, Mode::Full);
    assert_eq!(a.raw, b.raw);
    let noisy = handheld_with(vec![EffectSpec::NearField {}, noise(0.02, 7)], ward());
    let s = sim(&noisy);
    assert_eq!(s.simulate_line(2, Mode::Full).raw, sim(&noisy).simulate_line(2, Mode::Full).raw);
    assert_ne!(s.simulate_line(2, Mode::Full).raw, s.simulate_line(3, Mode::Full).raw);
    // Noise changes only the LED frames' values around the noise-free ones.
    let clean = s.simulate_line(2, Mode::NoNoise);
    let full = s.simulate_line(2, Mode::Full);
    assert!(full.raw[0].iter().all(|x| *x == 0.0), "proportional noise on a zero dark frame is zero");
    let mut sum = 0.0;
    let mut sum2 = 0.0;
    let mut count = 0.0;
    for (f, c) in full.raw[1..].iter().zip(&clean.raw[1..]) {
        for (x, y) in f.iter().zip(c) {
            let z = (x - y) / y;
            sum += z;
            sum2 += z * z;
            count += 1.0;
        }
    }
    let (mean, sd) = (sum / count, (sum2 / count - (sum / count).powi(2)).sqrt());
    assert!(mean.abs() < 0.003 && (sd - 0.02).abs() < 0.002, "mean {mean}, sd {sd} over {count}");
}

#[test]
fn a_perfect_diffuser_reads_one_after_white_calibration_in_every_geometry() {
    for (path, mut s) in library() {
        s.surface = SurfaceSpec { brdf: white_tile(), segments: Vec::new() };
        let sim = sim(&s);
        for r in [sim.simulate_line(0, Mode::Reference), sim.simulate_line(3, Mode::Reference)] {
            for (i, v) in r.corrected.iter().enumerate() {
                assert!((v - 1.0).abs() < 1e-12, "{}: reading {i} = {v}", path.display());
            }
        }
        if !s.has("led-drift") {
            for v in sim.simulate_line(1, Mode::NoNoise).corrected {
                assert!((v - 1.0).abs() < 1e-12, "{}: {v}", path.display());
            }
        }
    }
}

/// Each effect on its own, added to the far-field idealisation, changes
/// what it should and nothing else.
mod one_effect {
    use super::*;

    fn base() -> Scene {
        let mut s = handheld_with(Vec::new(), ward());
        s.instrument.leds[0].azimuth_deg = 30.0;
        s
    }

    fn with(e: EffectSpec) -> Scene {
        let mut s = base();
        s.effects.push(e);
        s
    }

    fn rays(s: &Scene, led: usize, px: f64) -> Vec<crate::forward::optics::Ray> {
        Optics::new(&s.instrument, s.ray_model()).rays_at(led, &s.pixel_point(px))
    }

    #[test]
    fn three_d_geometry_moves_only_the_off_plane_led() {
        let (b, t) = (base(), with(EffectSpec::ThreeDGeometry {}));
        let (rb, rt) = (rays(&b, 0, 0.0), rays(&t, 0, 0.0));
        assert_eq!(rb[0].dir.y, 0.0);
        assert!(rt[0].dir.y.abs() > 0.1);
        assert!((rt[0].theta_deg - rb[0].theta_deg).abs() < 1e-9, "the incidence angle is the LED's either way");
        for led in 1..7 {
            assert_eq!(rays(&b, led, 0.0), rays(&t, led, 0.0));
        }
    }

    #[test]
    fn per_pixel_geometry_spreads_the_line_and_nothing_else() {
        let b = sim(&base()).simulate_line(0, Mode::Full);
        assert!(b.corrected.chunks(7).all(|c| c == &b.corrected[..7]), "every pixel alike without it");
        let t = with(EffectSpec::PerPixelGeometry {});
        let r = sim(&t).simulate_line(0, Mode::Full);
        // The viewer is 5 cm away: the view direction, hence the reading, changes along the line.
        assert_ne!(r.corrected[..7], r.corrected[127 * 7..]);
        // The centre pixels sit symmetrically about the centre point.
        let (p63, p64) = (t.pixel_point(63.0), t.pixel_point(64.0));
        assert!((p63.x + p64.x).abs() < 1e-12 && (p64.x - p63.x - 63.5e-4).abs() < 1e-12);
        // Far field: the rays are parallel, the incidence angles do not move.
        assert_eq!(rays(&t, 2, 0.0)[0].theta_deg, rays(&t, 2, 127.0)[0].theta_deg);
        assert!(r.raw[0].iter().all(|x| *x == 0.0));
    }

    #[test]
    fn inverse_square_scales_weights_by_distance_only() {
        let t = with(EffectSpec::InverseSquare {});
        // At the centre point r = d: nothing changes (to rounding of the distance).
        for (a, b) in sim(&base()).signal().iter().zip(sim(&t).signal()) {
            assert!((a - b).abs() <= 1e-12 * a.abs(), "{a} {b}");
        }
        // With per-pixel points, the weight changes by (d / r)^2 and the angle does not.
        let mut pp = base();
        pp.effects.push(EffectSpec::PerPixelGeometry {});
        let mut ppi = pp.clone();
        ppi.effects.push(EffectSpec::InverseSquare {});
        let (a, b) = (rays(&pp, 0, 0.0)[0], rays(&ppi, 0, 0.0)[0]);
        assert_eq!(a.theta_deg, b.theta_deg);
        let led = pp.instrument.led_centre(0, false);
        let r = (led - pp.pixel_point(0.0)).norm();
        assert!((b.weight / a.weight - (6.0 / r).powi(2)).abs() < 1e-12);
    }

    #[test]
    fn emission_profile_changes_weights_not_angles() {
        let mut near = base();
        near.effects.push(EffectSpec::NearField {});
        for l in &mut near.instrument.leds {
            l.emission = Some(EmissionSpec::CosPower { k: 40.0 });
        }
        let mut em = near.clone();
        em.effects.push(EffectSpec::EmissionProfile {});
        let (a, b) = (rays(&near, 3, 0.0), rays(&em, 3, 0.0));
        assert_eq!(a.len(), b.len());
        let ratio: Vec<f64> = a.iter().zip(&b).map(|(x, y)| y.weight / x.weight).collect();
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(x.theta_deg, y.theta_deg);
        }
        // Off-axis sample points are dimmed, so the ratios are not all equal.
        let (lo, hi) = ratio.iter().fold((f64::MAX, 0.0f64), |(l, h), r| (l.min(*r), h.max(*r)));
        assert!(hi <= 1.0 && lo < hi * 0.999, "{lo}..{hi}");
    }

    #[test]
    fn drift_scales_led_frames_by_time_and_leaves_dark_and_white() {
        let rate = 1e-4;
        let t = with(EffectSpec::LedDrift { rate: DriftRate::Common(rate) });
        let (sb, st) = (sim(&base()), sim(&t));
        assert_eq!(sb.white(), st.white());
        let (rb, rt) = (sb.simulate_line(2, Mode::Full), st.simulate_line(2, Mode::Full));
        assert_eq!(rb.raw[0], rt.raw[0]);
        for k in 0..7 {
            let time = (2 * 8 + 1 + k) as f64;
            for px in [0, 100] {
                assert!((rt.raw[1 + k][px] / rb.raw[1 + k][px] - (1.0 + rate * time)).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn per_led_drift_scales_each_leds_frames_by_its_own_rate() {
        // LEDs drifting each at its own rate, one of them dimming: each
        // LED's frames (at every exposure) by its own factor, the dark
        // frame and the white untouched.
        let rates: Vec<f64> = (0..7).map(|k| 1e-4 * (k as f64 - 2.0)).collect();
        let t = with(EffectSpec::LedDrift { rate: DriftRate::PerLed(rates.clone()) });
        let (sb, st) = (sim(&base()), sim(&t));
        assert_eq!(sb.white(), st.white());
        let (rb, rt) = (sb.simulate_line(3, Mode::Full), st.simulate_line(3, Mode::Full));
        assert_eq!(rb.raw[0], rt.raw[0]);
        for (k, rate) in rates.iter().enumerate() {
            let time = (3 * 8 + 1 + k) as f64;
            for px in [0, 64, 127] {
                let got = rt.raw[1 + k][px] / rb.raw[1 + k][px];
                assert!((got - (1.0 + rate * time)).abs() < 1e-12, "LED {k} pixel {px}: {got}");
            }
        }
        // One rate for all is the same as that rate listed per LED.
        let common = sim(&with(EffectSpec::LedDrift { rate: DriftRate::Common(3e-5) }));
        let listed = sim(&with(EffectSpec::LedDrift { rate: DriftRate::PerLed(vec![3e-5; 7]) }));
        assert_eq!(common.simulate_line(5, Mode::Full).raw, listed.simulate_line(5, Mode::Full).raw);
    }

    #[test]
    fn ambient_and_dark_offset_add_counts_that_white_calibration_removes() {
        let b = sim(&base()).simulate_line(0, Mode::Full);
        for e in [
            EffectSpec::AmbientLight { counts: 40.0 },
            EffectSpec::DarkOffset { counts: 60.0, fixed_pattern_rms: 3.0, seed: 9 },
        ] {
            let name = e.name();
            let r = sim(&with(e)).simulate_line(0, Mode::Full);
            for (fb, ft) in b.raw.iter().zip(&r.raw) {
                for (x, y) in fb.iter().zip(ft) {
                    assert!(y - x > 30.0, "{name}: {x} -> {y}");
                }
            }
            // Every frame of a pixel gets the same added counts.
            let d0 = r.raw[0][5] - b.raw[0][5];
            assert!((r.raw[4][5] - b.raw[4][5] - d0).abs() < 1e-9, "{name}");
            for (x, y) in b.corrected.iter().zip(&r.corrected) {
                assert!((x - y).abs() < 1e-12, "{name}: corrected {x} vs {y}");
            }
        }
    }

    #[test]
    fn nonlinearity_bends_the_counts_and_the_factory_correction_straightens_the_readings() {
        // A dark matt sample, read well within the converter's range.
        let grey = |mut s: Scene| {
            s.surface.brdf = BrdfSpec::Lambertian { rho: 0.08 };
            s
        };
        let t = grey(with(EffectSpec::Nonlinearity { gamma: 1.01 }));
        let (b, r) = (sim(&grey(base())).simulate_line(0, Mode::Full), sim(&t).simulate_line(0, Mode::Full));
        assert_eq!(r.raw[0], b.raw[0]);
        let fs = 4095.0;
        assert!((r.raw[4][0] - fs * (b.raw[4][0] / fs).powf(1.01)).abs() < 1e-9);
        // White-calibrated as they are read, the bent counts are off by up
        // to a few per cent (a dark reading against the brighter white) ...
        let mut white = t.clone();
        white.surface.brdf = white_tile();
        let w = sim(&white).simulate_line(0, Mode::Reference).raw;
        let m = t.instrument.m();
        let bent = |px: usize, k: usize| (r.raw[1 + k][px] - r.raw[0][px]) / (w[1 + k][px] - w[0][px]);
        let worst = |f: &dyn Fn(usize, usize) -> f64| {
            (0..r.raw[0].len())
                .flat_map(|px| (0..m).map(move |k| (px, k)))
                .map(|(px, k)| (f(px, k) / b.corrected[px * m + k] - 1.0).abs())
                .fold(0.0, f64::max)
        };
        assert!(worst(&bent) > 0.02, "{}", worst(&bent));
        // ... and made linear by the factory's correction, as the device
        // does, they are within 0.2 % of a linear sensor's.
        assert!(sim(&t).linearity().is_some_and(|l| !l.clamped));
        assert!(worst(&|px, k| r.corrected[px * m + k]) < 2e-3, "{}", worst(&|px, k| r.corrected[px * m + k]));
        // A white tile still reads one.
        assert!(sim(&white).simulate_line(0, Mode::Full).corrected.iter().all(|v| (v - 1.0).abs() < 1e-6));
        // A linear sensor is not measured at all.
        assert!(sim(&base()).linearity().is_none());
    }

    #[test]
    fn saturation_clips_only_what_exceeds_full_scale() {
        let mut s = base();
        s.instrument.sensor.gain = 3000.0; // the specular LEDs exceed 4095
        let b = sim(&s).simulate_line(0, Mode::Full);
        s.effects.push(EffectSpec::Saturation {});
        let r = sim(&s).simulate_line(0, Mode::Full);
        let mut clipped = 0;
        for (fb, fr) in b.raw.iter().zip(&r.raw) {
            for (x, y) in fb.iter().zip(fr) {
                if *x > 4095.0 {
                    assert_eq!(*y, 4095.0);
                    clipped += 1;
                } else {
                    assert_eq!(x, y);
                }
            }
        }
        assert!(clipped > 0);
    }

    #[test]
    fn quantisation_rounds_to_the_step() {
        let b = sim(&base()).simulate_line(0, Mode::Full);
        let r = sim(&with(EffectSpec::Quantisation { step_counts: 4.0 })).simulate_line(0, Mode::Full);
        for (fb, fr) in b.raw.iter().zip(&r.raw) {
            for (x, y) in fb.iter().zip(fr) {
                assert!((y / 4.0).fract() == 0.0 && (x - y).abs() <= 2.0, "{x} -> {y}");
            }
        }
        assert!(b.raw[1].iter().any(|x| x.fract() != 0.0), "the unquantised frame is continuous");
    }

    #[test]
    fn noise_models_draw_the_variance_they_state() {
        let mut s = base();
        s.surface.brdf = white_tile();
        s.effects = vec![EffectSpec::Noise {
            model: NoiseModel::ShotRead,
            sigma: None,
            sigma_counts: None,
            electrons_per_count: Some(4.0),
            read_sigma_counts: Some(2.0),
            seed: 3,
        }];
        let sm = sim(&s);
        let clean = sm.simulate_line(0, Mode::NoNoise).raw;
        let (mut n, mut s2) = (0.0, 0.0);
        for line in 0..20 {
            let r = sm.simulate_line(line, Mode::Full).raw;
            for px in 0..128 {
                let d = r[1][px] - clean[1][px];
                s2 += d * d;
                n += 1.0;
            }
        }
        let expect = clean[1][0] / 4.0 + 4.0;
        assert!((s2 / n / expect - 1.0).abs() < 0.1, "variance {} vs {expect}", s2 / n);
    }
}

#[test]
fn readings_do_not_depend_on_the_sensor_gain() {
    let lo = load("hard/gain-1e-6.toml");
    let hi = load("hard/gain-1e6.toml");
    let mut unit = lo.clone();
    unit.instrument.sensor.gain = 1.0;
    let (a, b, c) = (sim(&lo), sim(&hi), sim(&unit));
    for line in 0..3 {
        let (ra, rb, rc) =
            (a.simulate_line(line, Mode::Full), b.simulate_line(line, Mode::Full), c.simulate_line(line, Mode::Full));
        for ((x, y), z) in ra.corrected.iter().zip(&rb.corrected).zip(&rc.corrected) {
            assert!((x - z).abs() < 1e-12 * z.abs() && (y - z).abs() < 1e-12 * z.abs(), "{x} {y} {z}");
        }
    }
}

#[test]
fn training_sees_the_optics_and_never_the_surface_or_the_noise() {
    let s = load("handheld.toml");
    let zones = zone_system_matrices(&s, 4).unwrap();
    assert_eq!(zones.iter().map(|z| z.first_pixel).collect::<Vec<_>>(), [0, 32, 64, 96]);
    assert_eq!(zones[3].last_pixel, 127);
    assert_eq!(zones[0].centre_pixel, 15.5);
    for z in &zones {
        assert_eq!(z.h.shape(), (7, 81));
        for i in 0..7 {
            assert!((z.h.row(i).sum() - 1.0).abs() < 1e-12);
        }
    }
    // The near-field geometry moves along the line: the zones differ.
    assert!((&zones[0].h - &zones[3].h).amax() > 0.05);
    let mut other = s.clone();
    other.surface.brdf = BrdfSpec::Lambertian { rho: 0.2 };
    other.effects.retain(|e| !matches!(e, EffectSpec::Noise { .. }));
    let again = zone_system_matrices(&other, 4).unwrap();
    for (a, b) in zones.iter().zip(&again) {
        assert_eq!(a.h, b.h);
    }
    assert_eq!(pixel_system_matrix(&s, 15.5).unwrap(), zones[0].h);
    assert!(zone_system_matrices(&s, 0).is_err() && zone_system_matrices(&s, 129).is_err());
    assert_eq!(zone_system_matrices(&s, 128).unwrap().len(), 128);
}

#[test]
fn white_reference_and_raw_frames_have_the_blob_and_link_layouts() {
    let s = load("handheld.toml");
    let w = white_reference(&s).unwrap();
    assert_eq!(w.len(), 128 * 7);
    // Gain 2400: a perfect diffuser reads 1,000-2,500 counts above dark.
    assert!(w.iter().all(|x| *x > 1000.0 && *x < 2500.0), "{:?}", &w[..7]);
    let frames = raw_frames(&s, 0).unwrap();
    // The long exposure's dark and LED frames, then each shorter exposure's.
    assert_eq!(frames.len(), 3 * 8);
    assert!(frames.iter().all(|f| f.len() == 128));
    // Dark first (dark offset + ambient, ~75 counts), then the LEDs.
    let mean = |f: &[u16]| f.iter().map(|x| *x as f64).sum::<f64>() / f.len() as f64;
    assert!((mean(&frames[0]) - 75.0).abs() < 5.0, "{}", mean(&frames[0]));
    assert!(frames[1..8].iter().all(|f| mean(f) > mean(&frames[0]) + 50.0));
    // The u16 frames are the simulator's raw counts.
    let sm = sim(&s);
    let raw = sm.simulate_line(0, Mode::Full).raw;
    for (f, r) in frames.iter().zip(&raw) {
        for (a, b) in f.iter().zip(r) {
            assert_eq!(*a as f64, *b);
        }
    }
    // Correcting the u16 frames with the blob's white gives the host readings.
    let corrected = sm.correct(&frames.iter().map(|f| f.iter().map(|x| *x as f64).collect()).collect::<Vec<_>>());
    assert!(corrected.iter().all(|x| x.is_finite() && *x > 0.0));
    // Counts the u16 link cannot carry are an error, not a silent clip.
    let mut hot = s.clone();
    hot.instrument.sensor.gain = 1e5;
    hot.effects.retain(|e| !matches!(e, EffectSpec::Saturation {}));
    let e = format!("{:#}", raw_frames(&hot, 0).unwrap_err());
    assert!(e.contains("u16") && e.contains("instrument.leds[") && e.contains("saturation"), "{e}");
    hot.effects.push(EffectSpec::Saturation {});
    assert!(raw_frames(&hot, 0).unwrap()[4].contains(&4095));
}

#[test]
fn segments_vary_the_surface_along_the_line() {
    let mut s = handheld_with(vec![EffectSpec::NearField {}], ward());
    s.surface.segments.push(SegmentSpec { first_pixel: 100, last_pixel: 127, brdf: white_tile() });
    let r = sim(&s).simulate_line(0, Mode::Full);
    assert!(r.corrected[100 * 7..].iter().all(|v| (v - 1.0).abs() < 1e-12));
    assert!(r.corrected[..100 * 7].iter().all(|v| (v - 1.0).abs() > 1e-3));
}

mod malformed {
    use super::*;

    const GOOD: &str = r#"name = "t"
effects = [
  { kind = "near-field" },
  { kind = "noise", model = "proportional", sigma = 0.02 },
]
[instrument]
view_deg = 45.0
grid = { start_deg = 25.0, stop_deg = 65.0, step_deg = 0.5 }
sensor = { pixels = 8, gain = 100.0 }
[[instrument.leds]]
centre_deg = 40.0
distance_cm = 10.0
[surface]
brdf = { model = "ward", rho_d = 0.3, alpha = 0.05 }
"#;

    fn err(text: &str) -> crate::output::config::ConfigError {
        Scene::parse(text, "bad.toml").unwrap_err()
    }

    #[test]
    fn the_reference_text_is_good() {
        let s = Scene::parse(GOOD, "good.toml").unwrap();
        assert_eq!(Pipeline::new(&s).names(), ["near-field", "noise"]);
    }

    #[test]
    fn an_unknown_effect_names_the_file_line_and_the_known_effects() {
        let e = err(&GOOD.replace("\"near-field\"", "\"near-feild\""));
        let s = e.to_string();
        assert!(s.starts_with("bad.toml:3:"), "{s}");
        assert!(s.contains("near-feild") && s.contains("near-field") && s.contains("quantisation"), "{s}");
    }

    /// `e` reads `bad.toml:LINE:COL: ...` and mentions every word in `words`.
    fn at(e: &crate::output::config::ConfigError, line: usize, words: &[&str]) {
        let s = e.to_string();
        assert!(s.starts_with(&format!("bad.toml:{line}:")), "{s}");
        for w in words {
            assert!(s.contains(w), "{s} lacks {w}");
        }
    }

    #[test]
    fn missing_fields_name_the_line_and_field() {
        at(&err(&GOOD.replace(", sigma = 0.02", "")), 4, &["`sigma`", "proportional"]);
        at(
            &err(&GOOD
                .replace("{ kind = \"noise\", model = \"proportional\", sigma = 0.02 }", "{ kind = \"led-drift\" }")),
            4,
            &["rate_per_frame"],
        );
        at(&err(&GOOD.replace("{ kind = \"near-field\" }", "{ }")), 3, &["`kind`", "near-field"]);
        let e = err(&GOOD.replace("distance_cm = 10.0\n", ""));
        assert!(e.to_string().contains("distance_cm") && e.line_col.is_some(), "{e}");
        let e = err(&GOOD.replace("[surface]\nbrdf = { model = \"ward\", rho_d = 0.3, alpha = 0.05 }\n", ""));
        assert!(e.to_string().contains("surface") && e.line_col.is_some(), "{e}");
    }

    #[test]
    fn impossible_values_name_the_line_and_field() {
        for (from, to, field, line) in [
            ("gain = 100.0", "gain = -1.0", "instrument.sensor.gain", 9),
            ("pixels = 8", "pixels = 0", "instrument.sensor.pixels", 9),
            ("sigma = 0.02", "sigma = 2.0", "effects[1].sigma", 4),
            ("centre_deg = 40.0", "centre_deg = 95.0", "instrument.leds[0].centre_deg", 11),
            ("alpha = 0.05", "alpha = -0.05", "surface.brdf", 14),
        ] {
            let e = err(&GOOD.replace(from, to));
            assert_eq!(e.field.as_deref(), Some(field), "{e}");
            assert_eq!(e.line_col.map(|l| l.0), Some(line), "{e}");
            assert!(e.to_string().starts_with(&format!("bad.toml:{line}:")), "{e}");
        }
    }

    #[test]
    fn per_led_drift_rates_are_one_per_led_in_range_and_not_with_a_common_rate() {
        let drift = |fields: &str| {
            GOOD.replace(
                "{ kind = \"noise\", model = \"proportional\", sigma = 0.02 }",
                &format!("{{ kind = \"led-drift\", {fields} }}"),
            )
        };
        // The reference instrument has one LED.
        let s = Scene::parse(&drift("rates_per_frame = [2e-5]"), "good.toml").unwrap();
        assert_eq!(s.effects[1], EffectSpec::LedDrift { rate: DriftRate::PerLed(vec![2e-5]) });
        let e = err(&drift("rates_per_frame = [2e-5, 1e-5]"));
        assert_eq!(e.field.as_deref(), Some("effects[1].rates_per_frame"), "{e}");
        at(&e, 4, &["2 rate(s) for 1 LED(s)", "instrument.leds"]);
        let e = err(&drift("rates_per_frame = [0.5]"));
        assert_eq!(e.field.as_deref(), Some("effects[1].rates_per_frame[0]"), "{e}");
        at(&err(&drift("rates_per_frame = []")), 4, &["one rate per LED"]);
        at(&err(&drift("rate_per_frame = 1e-5, rates_per_frame = [1e-5]")), 4, &["not both"]);
        at(&err(&drift("rate_per_frame = 1e-5, seed = 3")), 4, &["`seed`", "does not apply"]);
    }

    #[test]
    fn effects_listed_twice_or_with_foreign_parameters_are_refused() {
        let e = err(&GOOD
            .replace("{ kind = \"near-field\" }", "{ kind = \"noise\", model = \"additive\", sigma_counts = 1.0 }"));
        assert_eq!(e.field.as_deref(), Some("effects[1].kind"), "{e}");
        at(&e, 4, &["listed twice"]);
        at(
            &err(&GOOD.replace("sigma = 0.02", "sigma = 0.02, sigma_counts = 3.0")),
            4,
            &["`sigma_counts`", "does not apply"],
        );
        at(
            &err(&GOOD.replace("{ kind = \"near-field\" }", "{ kind = \"near-field\", gamma = 2 }")),
            3,
            &["`gamma`", "no parameters"],
        );
        at(&err(&GOOD.replace("{ kind = \"near-field\" }", "{ kind = \"near-field\", pitch = 2 }")), 3, &["pitch"]);
    }

    #[test]
    fn a_per_pixel_line_that_cannot_show_is_refused() {
        let text = GOOD
            .replace(
                "sensor = { pixels = 8, gain = 100.0 }",
                "sensor = { pixels = 8, gain = 100.0, line_axis = \"y\" }",
            )
            .replace("{ kind = \"near-field\" },", "{ kind = \"near-field\" }, { kind = \"per-pixel-geometry\" },");
        let e = err(&text);
        assert_eq!(e.field.as_deref(), Some("instrument.sensor.line_axis"), "{e}");
        at(&e, 9, &["3d-geometry"]);
        let ok = text.replace(
            "{ kind = \"per-pixel-geometry\" },",
            "{ kind = \"per-pixel-geometry\" }, { kind = \"3d-geometry\" },",
        );
        let s = Scene::parse(&ok, "ok.toml").unwrap();
        assert!((s.pixel_point(0.0).y + 3.5 * 63.5e-4).abs() < 1e-12);
    }

    #[test]
    fn a_missing_file_is_named() {
        let e = Scene::load(Path::new("/nonexistent/scene.toml")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/scene.toml"), "{e}");
    }
}

#[test]
fn an_unlisted_effect_costs_nothing_far_field_is_over_ten_times_faster() {
    // The ratio is ~1e3 on this machine (see examples/scene_speed.rs); 10x
    // is the issue's bar, far enough below to hold on a busy machine.
    let fast = time_simulation(&load("far-field.toml"), 0.2).unwrap();
    let full = time_simulation(&load("handheld.toml"), 0.2).unwrap();
    let ratio = full.as_secs_f64() / fast.as_secs_f64();
    assert!(ratio >= 10.0, "far field {fast:?}, full {full:?}: only {ratio:.1}x");
}

#[test]
fn scenes_survive_a_toml_round_trip() {
    for (path, s) in library() {
        let text = toml::to_string(&s).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let back = Scene::parse(&text, "roundtrip").unwrap_or_else(|e| panic!("{}: {e}\n{text}", path.display()));
        assert_eq!(back, s, "{}", path.display());
    }
}

#[test]
fn an_astm_e1392_table_is_a_scene_surface_and_a_bad_one_names_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("tile.astm");
    // A measured profile at the instrument's 45 deg view: the Ward surface's.
    let w = ward().build().unwrap();
    let rows: String = (0..=17)
        .map(|k| {
            let t = 5.0 * k as f64;
            format!("{t},180,45,0,555,0,{:e}\n", w.reflectance(t, 45.0) / std::f64::consts::PI)
        })
        .collect();
    std::fs::write(&f, format!("VARS theta_i,phi_i,theta_s,phi_s,wavelength,polarization,BRDF\n{rows}")).unwrap();
    let text = std::fs::read_to_string(scenes_dir().join("patent-profile.toml")).unwrap();
    let start = text.find("[surface]").unwrap();
    let mut scene_text = text[..start].to_string();
    scene_text
        .push_str(&format!("[surface]\nbrdf = {{ model = \"astm-e1392\", file = {:?} }}\n", f.display().to_string()));
    let s = Scene::parse(&scene_text, "astm-scene.toml").unwrap();
    let (models, _) = s.surface_brdfs().unwrap();
    for t in [5.0, 40.0, 45.0, 85.0] {
        let (a, b) = (models[0].reflectance(t, 45.0), w.reflectance(t, 45.0));
        assert!((a - b).abs() < 1e-9 * b, "{t}: {a} vs {b}");
    }
    // Linear between the 5-degree samples.
    let mid = 0.5 * (w.reflectance(20.0, 45.0) + w.reflectance(25.0, 45.0));
    assert!((models[0].reflectance(22.5, 45.0) - mid).abs() < 1e-9 * mid);
    // The scene simulates with it.
    let r = sim(&s).simulate_line(0, Mode::NoNoise);
    assert!(r.corrected.iter().all(|x| x.is_finite() && *x > 0.0));
    // A missing file: the scene's error names the field and the file.
    let bad = scene_text.replace("tile.astm", "missing.astm");
    let e = Scene::parse(&bad, "astm-scene.toml").unwrap_err().to_string();
    assert!(e.contains("surface.brdf") && e.contains("missing.astm"), "{e}");
}
