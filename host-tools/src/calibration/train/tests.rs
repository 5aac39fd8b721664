use super::gloss::chosen_gloss_clusters;
use super::*;
use crate::forward::grid::AngleGrid;
use crate::forward::optics::{Instrument, system_matrix};
use crate::forward::prior_measured::PriorMix;
use crate::forward::reading_noise::ReadingNoise;
use crate::forward::zone_optics::uniform_zones;

/// The gloss rows take clusters of their own only when those leave at
/// most three quarters of the maps' error, summed over the zones the
/// maps' rows read; a zone without a reading decides nothing.
#[test]
fn the_gloss_rows_own_clusters_are_taken_only_when_clearly_better_where_rows_read() {
    let options = [None, Some(2), Some(3), Some(4)];
    let inf = f64::INFINITY;
    // Clearly better: the best count of their own; at a tie, the fewest.
    let e = [vec![1.0, 1.0], vec![1.2, 1.0], vec![0.5, 0.4], vec![0.4, 0.5]];
    assert_eq!(chosen_gloss_clusters(&options, &e), Some(3));
    // Better, but not by a quarter: the maps'.
    let e = [vec![1.0, 1.0], vec![0.8, 0.8], vec![0.9, 0.9], vec![1.0, 1.0]];
    assert_eq!(chosen_gloss_clusters(&options, &e), None);
    // A zone without a reading (infinite under every option) is left
    // out of every sum; before, it made every sum infinite and
    // `inf <= 0.75 inf` took the first count of their own.
    let e = [vec![1.0, inf], vec![1.0, inf], vec![0.9, inf], vec![1.1, inf]];
    assert_eq!(chosen_gloss_clusters(&options, &e), None);
    let e = [vec![1.0, inf], vec![1.0, inf], vec![0.5, inf], vec![1.1, inf]];
    assert_eq!(chosen_gloss_clusters(&options, &e), Some(3));
    // A count of their own that reads a zone the maps' read not at all
    // is no better there; one that fails where the maps' read loses.
    let e = [vec![1.0, 1.0], vec![0.1, inf], vec![1.0, 1.0], vec![1.0, 1.0]];
    assert_eq!(chosen_gloss_clusters(&options, &e), None);
    // No zone read at all: the maps'.
    let e = [vec![inf, inf], vec![0.1, 0.1], vec![0.1, 0.1], vec![0.1, 0.1]];
    assert_eq!(chosen_gloss_clusters(&options, &e), None);
}

/// A form's name in reports is the one `--form` takes.
#[test]
fn a_forms_name_is_the_one_the_command_line_takes() {
    for f in [Form::Root, Form::Linear] {
        let value = clap::ValueEnum::to_possible_value(&f).unwrap();
        assert_eq!(value.get_name(), f.name());
        assert_eq!(Form::of_root(f == Form::Root), f);
    }
}

fn patent_spec(
    prior: &PriorModels,
    grid: &AngleGrid,
    zones: usize,
    pixels: usize,
    kind: EstimatorKind,
) -> TrainSpec<'static> {
    let inst = Instrument::patent_profile();
    let zs = uniform_zones(&inst, grid, zones, pixels, false, 0.02).unwrap();
    let bins: &'static [f64] = Box::leak(grid.bins_deg().to_vec().into_boxed_slice());
    let prior: &'static PriorModels = Box::leak(Box::new(prior.clone()));
    TrainSpec::new(bins, zs, pixels, inst.view_deg, prior, 0.02, kind)
}

fn patent_prior(grid: &AngleGrid) -> PriorModels {
    PriorMix::parse("patent").unwrap().models(grid, 45.0, crate::forward::brdf::nbrdf::LUMINANCE).unwrap()
}

#[test]
fn blob_carries_the_trained_matrices_and_round_trips() {
    let grid = AngleGrid::patent();
    let prior = patent_prior(&grid);
    let t = train(&patent_spec(&prior, &grid, 4, 128, EstimatorKind::Wiener)).unwrap();
    let v = BlobView::parse(&t.blob).unwrap();
    assert_eq!(v.dims(), Dims { n: 81, m: 7, zones: 4, pixels: 128 });
    assert_eq!(v.estimator(), EstimatorKind::Wiener);
    assert_eq!(v.noise_rel(), 0.02f32);
    assert_eq!(v.zone_start(3), 96);
    assert_eq!(v.summary().prior_samples, 16);
    assert!(v.summary().predicted_rmse > 0.0);
    assert!(v.summary().f32_rel_error < 1e-4, "{}", v.summary().f32_rel_error);
    for z in 0..4 {
        let mut w = vec![0.0; 81 * 7];
        v.copy_matrix(z, &mut w);
        let e = t.zones[z].linear().unwrap();
        assert_eq!(w, e.w_f32_row_major());
        assert_eq!(v.uncertainty(z, 40), e.uncertainty[40] as f32);
    }
    assert_eq!(v.grid_deg(80), 65.0);
    assert_eq!(v.white(127, 6), 1.0);
    let j = t.to_json();
    assert_eq!(j["bins_deg"].as_array().unwrap().len(), 81);
    assert_eq!(j["H"].as_array().unwrap().len(), 7);
    assert_eq!(j["H"][0].as_array().unwrap().len(), 81);
    assert_eq!(j["W"].as_array().unwrap().len(), 81);
    assert_eq!(j["W"][0].as_array().unwrap().len(), 7);
    assert_eq!(j["uncertainty"].as_array().unwrap().len(), 81);
    assert_eq!(j["peak_resolution_deg"].as_f64().map(|x| x as f32), v.peak_resolution_deg());
    // Every pixel alike (the same in-plane optics): each takes the calibration's.
    assert_eq!(j["pixel_peak_resolution_deg"], serde_json::json!(vec![v.peak_resolution_deg(); 128]));
}

#[test]
fn every_estimator_trains_on_the_patent_profile_except_the_square_inverse() {
    let grid = AngleGrid::patent();
    let prior = patent_prior(&grid);
    for kind in [
        EstimatorKind::Wiener,
        EstimatorKind::WienerNoiseFree,
        EstimatorKind::PseudoInverse,
        EstimatorKind::Interpolation,
    ] {
        let t = train(&patent_spec(&prior, &grid, 1, 16, kind)).unwrap();
        assert_eq!(BlobView::parse(&t.blob).unwrap().estimator(), kind);
    }
    let e = train(&patent_spec(&prior, &grid, 1, 16, EstimatorKind::Inverse)).unwrap_err();
    assert!(format!("{e:#}").contains("square"), "{e:#}");
}

#[test]
fn the_patent_profiles_wiener_is_eq_22_of_the_table_5_prior() {
    // Pairs with the patent's plain criterion on in-plane optics give
    // the H-based W (so the reproduction and its Table 6 stand).
    let grid = AngleGrid::patent();
    let inst = Instrument::patent_profile();
    let t = train(&patent_spec(&patent_prior(&grid), &grid, 1, 1, EstimatorKind::Wiener)).unwrap();
    let h = system_matrix(&inst, &grid, false).unwrap();
    let prior = crate::forward::prior::PriorSpec::patent().build(&grid, 45.0, std::path::Path::new(".")).unwrap();
    let inputs = EstimatorInputs {
        h: &h,
        r_pp: &prior.r_pp,
        prior_samples: 16,
        noise: NoiseModel::Relative(0.02),
        bins_deg: grid.bins_deg(),
        centres_deg: &inst.centre_angles_deg(),
    };
    let classic = estimators::build(EstimatorKind::Wiener, &inputs).unwrap();
    let w = &t.zones[0].linear().unwrap().w;
    let d = (w - &classic.w).amax() / classic.w.amax();
    assert!(d < 1e-9, "{d:e}");
}

#[test]
fn zones_take_their_own_h() {
    let grid = AngleGrid::patent();
    let prior = patent_prior(&grid);
    let mut spec = patent_spec(&prior, &grid, 2, 8, EstimatorKind::Wiener);
    // Zone 1 sees the far-field optics: its W must differ.
    let inst = Instrument::patent_profile();
    let far = system_matrix(&inst, &grid, true).unwrap();
    spec.zones[1] = ZoneOptics::from_h(4, far, inst.centre_angles_deg(), 45.0, &grid, ReadingNoise::relative(0.02, 7));
    let t = train(&spec).unwrap();
    let d = (&t.zones[0].linear().unwrap().w - &t.zones[1].linear().unwrap().w).amax();
    assert!(d > 1e-3, "{d}");
    assert!(uniform_zones(&inst, &grid, 9, 8, false, 0.02).is_err());
}
