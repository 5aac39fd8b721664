//! The metrology evaluation on a reduced set (a few surfaces, one draw):
//! its figures are computed on the truths both methods share, and it sees
//! what it is built to see, a physically impossible estimate.
use clap::Parser;
use host_tools::cli::train::{CalibrationArgs, Setup};
use host_tools::evaluation::metrology::families::TestFamily;
use host_tools::evaluation::metrology::metrics::Row;
use host_tools::evaluation::metrology::{Config, Report, run};
use host_tools::forward::brdf::{Brdf, Lambertian};
use std::sync::Arc;

/// `train`'s flags, parsed as `accuracy` parses them.
#[derive(Parser)]
struct Flags {
    #[command(flatten)]
    cal: CalibrationArgs,
}

fn setup(flags: &[&str]) -> Setup {
    let args = std::iter::once("accuracy").chain(flags.iter().copied());
    Flags::try_parse_from(args).unwrap().cal.setup().unwrap()
}

fn evaluate(flags: &[&str], families: &[TestFamily], noise_rel: f64) -> Report {
    let s = setup(flags);
    let cfg = Config { draws: 1, noise_rel, ..Default::default() };
    run(&s.spec(), &s.inst, &s.grid, families, &cfg, &|_| {}).unwrap()
}

fn row<'a>(r: &'a Report, family: &str, method: &str) -> &'a Row {
    r.rows.iter().find(|x| x.family == family && x.method == method).unwrap()
}

#[test]
fn a_flat_surface_is_read_exactly_by_interpolation_against_the_same_truth() {
    // A diffuser's readings are its albedo at every LED and its truth is
    // flat: interpolation is exact, so any error is the evaluation's own.
    let flat = TestFamily {
        name: "diffusers".into(),
        source: "test".into(),
        materials: [0.2, 0.5, 0.9]
            .iter()
            .map(|a| (format!("lambert {a}"), Arc::new(Lambertian { rho: *a }) as Arc<dyn Brdf>))
            .collect(),
    };
    let r = evaluate(&[], &[flat], 0.0);
    assert_eq!(r.folds, 0, "a diffuser is no sample of the default (measured) prior");
    for m in &r.materials {
        assert!(m.error_interpolation < 1e-6, "{}: {}", m.name, m.error_interpolation);
        assert!(m.error_estimator.is_finite() && m.error_estimator > 1e-4, "{}: {}", m.name, m.error_estimator);
        // Both methods' gloss is scored against the same truth: a diffuser's
        // in-plane and three-dimensional readings agree.
        let (g, gi) = (m.readings_true[0], m.readings_interpolation[0]);
        assert!((gi - g).abs() < 0.01 * g, "{}: interpolation {gi} GU, truth {g} GU", m.name);
        // The draw, one by one: its error is the surface's (one draw), and
        // the quantities a flag could be built on are there beside it.
        let [d] = &m.draws[..] else { panic!("{}: one draw, got {}", m.name, m.draws.len()) };
        assert!((d.error - m.error_estimator).abs() < 1e-12, "{}: {d:?}", m.name);
        assert!(d.stat.is_finite() && d.stat >= 0.0, "{}: {d:?}", m.name);
        assert!(
            d.brightest_share > 1.0 / 7.0 - 1e-9 && d.brightest_share < 0.5,
            "{}: a diffuser lights every LED: {d:?}",
            m.name
        );
        assert!((0.0..=1.0).contains(&d.bin_coverage), "{}: {d:?}", m.name);
    }
    let i = row(&r, "diffusers", "interpolation");
    assert!(i.error.max < 1e-6 && i.impossible == 0.0);
    assert!(
        i.bin_coverage.is_none() && i.band.is_none() && i.flag_caught.is_none(),
        "interpolation states no uncertainty, raises no flag"
    );
    assert!(i.bin_coverage_interval.is_none());
    let e = row(&r, "diffusers", "estimator");
    assert!(e.bin_coverage.is_some() && e.reading_coverage.is_some());
    // The coverage's interval over the three surfaces holds the coverage.
    let ([lo, hi], c) = (e.bin_coverage_interval.unwrap(), e.bin_coverage.unwrap());
    assert!(0.0 <= lo && lo <= c && c <= hi && hi <= 1.0, "{lo} {c} {hi}");
    assert!(e.band.is_some_and(|b| b.median > 0.0 && b.median.is_finite()), "{:?}", e.band);
    assert!(r.tables().contains("| diffusers | interpolation | 3 |"), "{}", r.tables());
}

#[test]
fn the_root_form_is_never_negative_where_a_linear_wiener_is() {
    let ward = || vec![TestFamily::ward().at_most(12)];
    let root = evaluate(&["--estimator", "scale-free", "--prior", "merl"], &ward(), 0.02);
    let linear = evaluate(&["--estimator", "wiener", "--prior", "merl"], &ward(), 0.02);
    let (r, l) = (row(&root, "ward", "estimator"), row(&linear, "ward", "estimator"));
    assert_eq!((r.materials, l.materials), (12, 12));
    assert_eq!(r.impossible, 0.0, "{}", root.tables());
    assert!(l.impossible > 0.5, "{}", linear.tables());
    // The same draws and truths for interpolation under either calibration.
    let (ri, li) = (row(&root, "ward", "interpolation"), row(&linear, "ward", "interpolation"));
    assert_eq!(ri.error.median, li.error.median);
}

#[test]
fn measured_materials_in_the_prior_are_read_by_calibrations_trained_without_them() {
    let set = host_tools::forward::brdf::NbrdfSet::merl();
    let spectral = host_tools::forward::optics::Instrument::patent_profile().spectral_weights;
    let fams = vec![TestFamily::measured("merl", &set, spectral).at_most(6)];
    let r = evaluate(&["--estimator", "scale-free", "--prior", "merl", "--form", "linear"], &fams, 0.02);
    assert_eq!((r.folds, r.trainings), (5, 5), "every surface a prior sample: folds only");
    assert_eq!(r.clusters, vec![1; 5], "each calibration's matrices per zone, reported (one: not piecewise)");
    assert!(
        r.flag_forms.len() == 5 && r.flag_forms.iter().all(|f| f == "linear" || f == "log-ratio"),
        "each calibration's flag statistic, reported: {:?}",
        r.flag_forms
    );
    assert_eq!(r.families[0].in_training, 6);
    assert!(r.materials.iter().all(|m| m.fold.is_some()));
    // The nearest prior sample is one the reading calibration trained on:
    // another material, never the surface itself (which its fold left out).
    for m in &r.materials {
        let n = m.nearest_training.as_ref().expect("a nearest training sample");
        assert!(n.name != format!("merl:{}", m.name) && n.distance > 1e-6, "{}: {n:?}", m.name);
    }
    let near = r.families[0].nearest.expect("the family's nearness");
    assert_eq!(near.surfaces, 6);
    assert!(near.median > 0.0 && near.near_twins <= 6 && near.read_better <= 6, "{near:?}");
}

#[test]
fn the_device_applying_an_interpolation_calibration_scores_as_the_evaluations_interpolation() {
    // Two independent paths to the same BRDF estimate (the blob's matrix
    // through the device's f32 kernel; the evaluation's f64 weights) must
    // give the same error on the same draws and truths.
    let r = evaluate(&["--estimator", "interpolation"], &[TestFamily::ward().at_most(6)], 0.02);
    let (e, i) = (row(&r, "ward", "estimator"), row(&r, "ward", "interpolation"));
    for (a, b) in [(e.error.median, i.error.median), (e.error.max, i.error.max)] {
        assert!((a - b).abs() < 1e-5 * b, "device {a}, evaluation {b}");
    }
}

#[test]
fn smooth_lobes_come_out_smooth_at_the_exact_specular_bin() {
    // A smooth Ward lobe's estimate by the default calibration must not dip
    // at the mirror incidence. The measured prior's glossy lobes are cusps,
    // most of their peak within a bin, so that one bin holds energy no other
    // does; one linear map (the scale-free kind: a dip of 8.5 % of the peak
    // in the root form, 33 % in the linear) cannot tell such a lobe from a
    // broad one by seven readings and carves the difference into every
    // smooth lobe. The piecewise kind's clusters keep the narrow lobes
    // apart, and the prior's rougher finishes of each material give the
    // round tops a few degrees wide their own evidence: without them Ward
    // lobes of alpha 0.04-0.06 (8-11 deg wide at half height) dipped 6-10 %
    // of the peak (`--finishes none`). Between a cusp and the finishes a
    // lobe a few degrees wide is still read from both, and how deep the dip
    // is there depends on the clusters: with the four random folds picked
    // before the count was guarded by kinds held out, Table 4's alpha 0.03
    // lobes dipped 11-14 %, with the six taken now 2-3 % (alpha 0.035:
    // 4 %): docs/guide/real-materials.md.
    use host_tools::device::reference::PointEstimator;
    use host_tools::forward::brdf::Ward;
    use host_tools::forward::optics::simulate_readings;
    let s = setup(&[]);
    let trained = host_tools::calibration::train::train(&s.spec()).unwrap();
    let view = brdf_meter::blob::BlobView::parse(&trained.blob).unwrap();
    let est = PointEstimator::new(view, 0).unwrap();
    let bins = s.grid.bins_deg();
    // The mirror incidence is the view's polar angle (light and viewer on
    // either side of the normal in the plane).
    let mirror = (0..bins.len())
        .min_by(|a, b| (bins[*a] - s.inst.view_deg).abs().total_cmp(&(bins[*b] - s.inst.view_deg).abs()))
        .unwrap();
    assert!(mirror >= 4 && mirror + 4 < bins.len(), "the grid covers the mirror incidence with room either side");
    // (rho_d, alpha, the largest dip allowed as a share of the peak).
    let lobes = [
        (0.3, 0.03, 0.05),
        (0.3, 0.035, 0.05),
        (0.3, 0.04, 0.05),
        (0.3, 0.05, 0.01),
        (0.3, 0.06, 0.01),
        (0.3, 0.08, 0.01),
        (0.5, 0.12, 0.01),
        (0.2, 0.2, 0.01),
    ];
    for (rho_d, alpha, allowed) in lobes {
        let ward = Ward::new(rho_d, 1.0 - rho_d, alpha).unwrap();
        let v: Vec<f32> = simulate_readings(&s.inst, &ward, false).iter().map(|x| *x as f32).collect();
        let corrected: Vec<f32> = v.iter().enumerate().map(|(i, x)| x / view.white(0, i)).collect();
        let rho = est.apply(&corrected).rho;
        let peak = rho.iter().copied().fold(0.0f32, f32::max);
        // Within three bins of the mirror bin, no bin lies below both its
        // neighbours by more than the share allowed of the peak.
        for j in mirror - 3..=mirror + 3 {
            let dip = rho[j - 1].min(rho[j + 1]) - rho[j];
            assert!(
                dip <= allowed * peak,
                "Ward({rho_d}, {alpha}): bin {j} dips {dip} below its neighbours (peak {peak}, {allowed} of it allowed): {rho:?}"
            );
        }
    }
}

#[test]
fn the_cluster_count_chosen_is_one_the_devices_slot_takes() {
    // The default calibration on the patent profile takes six clusters
    // (guarded by kinds of material held out); a device whose slot is a
    // byte too small for that blob gets fewer, chosen again among fewer,
    // and one that fits. A count fixed by hand is trained as asked
    // (provisioning refuses what does not fit).
    use host_tools::calibration::train::{TrainSpec, board_blob_capacity, train};
    let s = setup(&[]);
    let spec = s.spec();
    assert_eq!(spec.max_blob_len, board_blob_capacity());
    let full = train(&spec).unwrap();
    assert_eq!(full.clusters, 6, "the default's count on the patent profile");
    let room = full.blob.len() - 1;
    let fitted = train(&TrainSpec { max_blob_len: room, ..s.spec() }).unwrap();
    assert!(fitted.clusters < full.clusters && fitted.clusters >= 2, "{} clusters", fitted.clusters);
    assert!(fitted.blob.len() <= room, "{} bytes for {room}", fitted.blob.len());
    assert!(full.slot_refused.is_empty());
    assert_eq!(fitted.slot_refused.first(), Some(&(6, full.blob.len())), "the count the slot refused, said");
    let fixed = train(&TrainSpec { max_blob_len: room, clusters: Some(6), ..s.spec() }).unwrap();
    assert_eq!((fixed.clusters, fixed.blob.len()), (6, full.blob.len()));
}

#[test]
fn every_fold_keeps_the_black_glass_so_the_polished_standards_read_on_its_scale() {
    // The bare polished dielectrics have one grid vector (the mirror spike
    // is no part of it): told apart by their gloss readings, each is held
    // out alone, and the black glass, which sets the gloss scale, is in
    // every calibration. A fold without it misreads every surface by its
    // misreading of the glass (the polished standards by about half).
    let fams = vec![TestFamily::gloss_standards()];
    let r = evaluate(&[], &fams, 0.02);
    assert!(r.clusters.iter().all(|k| (2..=6).contains(k)), "piecewise, each its own count: {:?}", r.clusters);
    let n = fams[0].materials.len();
    assert_eq!(r.families[0].in_training, n - 1, "{}", r.families[0].protocol);
    assert!(r.families[0].protocol.contains("black glass"), "{}", r.families[0].protocol);
    let glass = r.materials.iter().find(|m| m.name == "standard:n=1.567,base=0").map(|m| m.fold);
    assert_eq!(glass, Some(None), "the black glass is read by the calibration on everything");
    for m in r.materials.iter().filter(|m| m.name.starts_with("standard:") && m.name.ends_with("base=0")) {
        let (g, e) = (m.readings_true[0], m.readings_estimator[0]);
        assert!((e - g).abs() < 0.05 * g, "{} (fold {:?}): {e:.1} GU, truth {g:.1} GU", m.name, m.fold);
        if !m.name.contains("1.567") {
            assert!(m.fold.is_some(), "{}: held out by a fold", m.name);
        }
    }
}

#[test]
fn the_stated_per_bin_uncertainty_holds_on_kinds_of_surface_the_calibration_never_saw() {
    // The default calibration's stated k = 2 band against the truth, bin by
    // bin, on each family held out. Training calibrates the band on folds
    // that hold out whole kinds of material (the prior grouped by the shape
    // of its readings); with random folds, which leave a near twin of every
    // held-out material in training, it covered 58 % of the Ward surfaces'
    // bins and 81 % of the GGX lobes'.
    let set = host_tools::forward::brdf::NbrdfSet::merl();
    let spectral = host_tools::forward::optics::Instrument::patent_profile().spectral_weights;
    let fams = vec![
        TestFamily::measured("merl", &set, spectral),
        TestFamily::ward(),
        TestFamily::ggx(),
        TestFamily::gloss_standards(),
    ];
    let r = evaluate(&[], &fams, 0.02);
    let coverage = |family: &str| row(&r, family, "estimator").bin_coverage.unwrap();
    // The target, 92-98 %, met by the measured materials and the polished
    // standards (90.7 % with the four clusters random folds picked before
    // the cluster count was guarded by kinds held out: the finishes' smooth
    // lobes shared the standards' clusters).
    for family in ["measured", "gloss standards"] {
        let c = coverage(family);
        assert!((0.92..=0.98).contains(&c), "{family}: {c}\n{}", r.tables());
    }
    // Short of it: the Ward surfaces just under (94.1 % with four clusters,
    // 88.6 % before the prior held its materials' rougher finishes: Ward's
    // round-topped lobes were read from cusps, high at the lobe's
    // shoulders, where no held-out kind erred so); the GGX lobes are
    // over-covered.
    assert!(coverage("ward") > 0.90, "{}", r.tables());
    assert!(coverage("ggx") > 0.92, "{}", r.tables());
    // The specular peak's stated height and width, over the peaks the
    // calibration resolves (an unresolved one states none), with the
    // factors training sets on held-out peaks
    // (`host_tools::calibration::peak_factors`): they hold on the smooth
    // lobes, and on the measured materials' resolved peaks the width is
    // inside the target and the height 90 % in this one draw (94.4 % over
    // `accuracy`'s 4; 61 % with `H rho` training). Without the factors the
    // width was covered 88.4 % over `accuracy`'s 4 draws and the height
    // 91.2 %.
    let peak = |family: &str| row(&r, family, "estimator").peak_height_coverage.unwrap();
    let width = |family: &str| row(&r, family, "estimator").peak_width_coverage.unwrap();
    assert!(peak("measured") >= 0.88, "{}", r.tables());
    assert!((0.92..=0.98).contains(&width("measured")), "{}", r.tables());
    assert!(peak("ward") > 0.85 && peak("ggx") > 0.75, "{}", r.tables());
    // The polished standards' mirror spikes come out at the calibration's
    // resolution, spread over three bins and 45 % low (no prior of the maps
    // holds a mirror): every one is read as not resolved, and the peaks
    // that are resolved, the tiles', are covered (33 % over all peaks
    // before unresolved ones stated no uncertainty). There are 8 of them in
    // this one draw: 7 covered since the broad lobes' band is their own
    // (`brdf_meter::band`; 8 before), 31 of 32 over `accuracy`'s 4 draws.
    let standards = row(&r, "gloss standards", "estimator");
    assert!(standards.peak_unresolved.is_some_and(|u| u > 0.6), "{}", r.tables());
    assert!(peak("gloss standards") > 0.85, "{}", r.tables());
    assert_eq!(row(&r, "ward", "estimator").peak_unresolved, Some(0.0), "{}", r.tables());
    // Not bought with a band of no use: at most a few times the error it
    // covers (Ward's is the widest, about 4x: wide at the peak, where the
    // held-out kinds of gloss disagree most, and narrow in the tails).
    for family in ["measured", "ward", "ggx", "gloss standards"] {
        let e = row(&r, family, "estimator");
        let band = e.band.unwrap().median;
        assert!(band < 5.0 * e.error.median, "{family}: band {band}, error {}\n{}", e.error.median, r.tables());
    }
}

#[test]
fn a_mirror_spike_is_read_as_not_resolved_and_a_broad_lobe_as_resolved() {
    use host_tools::forward::brdf::{Ggx, SmoothDielectric};
    // The calibration records its resolution: what it makes of the black glass.
    let s = setup(&[]);
    let trained = host_tools::calibration::train::train(&s.spec()).unwrap();
    let view = brdf_meter::blob::BlobView::parse(&trained.blob).unwrap();
    let res = view.peak_resolution_deg().expect("a calibration with a gloss section records its peak resolution");
    assert!((0.5..2.0).contains(&res), "{res} deg: a few bins, far below the LEDs' 4 deg spacing");
    // Polished dielectrics (mirror spikes, one bin wide) come out at the
    // resolution: not resolved, so no uncertainty is stated for the height
    // they are read too low by. A GGX lobe degrees wide is resolved.
    let spikes = TestFamily {
        name: "spikes".into(),
        source: "test".into(),
        materials: [(1.52, 0.0), (1.6, 0.4)]
            .iter()
            .map(|&(n, a)| {
                (
                    format!("dielectric {n} over {a}"),
                    Arc::new(SmoothDielectric::over_base(n, a).unwrap()) as Arc<dyn Brdf>,
                )
            })
            .collect(),
    };
    let lobes = TestFamily {
        name: "lobes".into(),
        source: "test".into(),
        materials: vec![("ggx 0.08".into(), Arc::new(Ggx::new(0.3, 1.0, 0.08, 0.04).unwrap()) as Arc<dyn Brdf>)],
    };
    let r = evaluate(&[], &[spikes, lobes], 0.0);
    let spike = row(&r, "spikes", "estimator");
    assert_eq!(spike.peak_unresolved, Some(1.0), "{}", r.tables());
    assert_eq!(spike.peak_height_coverage, None, "an unresolved peak states no uncertainty");
    assert!(spike.peak_height_rel.median > 0.2, "the spike's height is the prior's: {}", r.tables());
    let lobe = row(&r, "lobes", "estimator");
    assert_eq!(lobe.peak_unresolved, Some(0.0), "{}", r.tables());
    assert!(lobe.peak_height_coverage.is_some());
    assert_eq!(row(&r, "lobes", "interpolation").peak_unresolved, None, "interpolation states no resolution");
}

#[test]
fn the_surfaces_read_worst_are_listed_with_their_flags_and_interpolation() {
    // The patent's Table 5 Wiener misreads measured materials (a tenth of
    // their peak and more): the report names the ones it reads worst,
    // most bad draws first, beside interpolation's error on the same draws.
    use host_tools::evaluation::metrology::metrics::BAD_ERROR;
    use host_tools::evaluation::metrology::report::READ_WORST;
    let set = host_tools::forward::brdf::NbrdfSet::merl();
    let spectral = host_tools::forward::optics::Instrument::patent_profile().spectral_weights;
    let fams = vec![TestFamily::measured("merl", &set, spectral).at_most(12)];
    let r = evaluate(&["--patent"], &fams, 0.02);
    let bad =
        |m: &host_tools::evaluation::metrology::MaterialResult| m.draws.iter().filter(|d| d.error > BAD_ERROR).count();
    let mut worst: Vec<_> = r.materials.iter().filter(|m| bad(m) > 0).collect();
    assert!(worst.len() > 1, "the Table 5 Wiener misreads some of them");
    worst.sort_by(|a, b| bad(b).cmp(&bad(a)).then(b.error_estimator.total_cmp(&a.error_estimator)));
    let t = r.tables();
    let listed: Vec<&str> = t
        .lines()
        .skip_while(|l| !l.starts_with("Surfaces read worst"))
        .filter(|l| l.starts_with("| measured |"))
        .collect();
    assert_eq!(listed.len(), worst.len().min(READ_WORST) + usize::from(worst.len() > READ_WORST), "{t}");
    let first = worst[0];
    let row = format!("| measured | {} | {} of {} |", first.name, bad(first), first.draws.len());
    assert!(listed[0].starts_with(&row), "{} should lead: {t}", first.name);
    // Beside interpolation, the prior sample nearest it (a Table 5 Ward).
    let near = first.nearest_training.as_ref().expect("the prior's nearest sample");
    assert!(
        listed[0].ends_with(&format!(
            "| {:.4} | {:.4} | {} ({:.3}) |",
            first.error_estimator, first.error_interpolation, near.name, near.distance
        )),
        "{t}"
    );
}
