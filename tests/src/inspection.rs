//! What the inspection tests on the host simulation and in QEMU share: a
//! calibration and a recipe taught by host-tools for the QEMU build's scene,
//! a scene with a scratch, and the host's reference verdicts.
use crate::sim::{ACQ, FULL_SCALE, P, RECIPE_SLOT_LEN};
use brdf_meter::inspect::{RecipeView, Verdict};
use host_tools::forward::brdf::BrdfSpec;
use host_tools::forward::scene::defects::{DefectScene, DefectSpec, Extent};
use host_tools::forward::scene::frames::patent_scene;
use host_tools::inspection::lines::{DeviceModel, HostInspector};
use host_tools::inspection::teach::{TeachSpec, Window, teach};

/// The signed calibration, the signed recipe and the scene with a scratch.
pub struct Fixture {
    /// The signed calibration.
    pub cal: Vec<u8>,
    /// The signed recipe.
    pub recipe: Vec<u8>,
    /// The scene with the scratch.
    pub scene: DefectScene,
}

/// A scale-free calibration for the QEMU build's scene (patent profile,
/// 32 pixels, 4 zones, the measured and the patent's prior), a recipe taught on 60 of its defect-free lines, and
/// the same scene with a 3-pixel scratch on lines 61 and 63.
pub fn fixture() -> Fixture {
    let scene = patent_scene(P);
    // The scene's surface is a Ward lobe: the measured prior alone flags
    // half of it out of prior (teach refuses such a reference), so the
    // calibration is trained on the measured prior mixed with the patent's.
    let prior = host_tools::calibration::demo::scene_prior(&scene, "merl@0.8+patent@0.2").unwrap();
    let cal = host_tools::calibration::demo::train_measured_for_scene(
        &scene,
        4,
        0.02,
        brdf_meter::blob::EstimatorKind::ScaleFree,
        &prior,
    )
    .unwrap();
    let clean = DefectScene::new("clean", scene.clone(), &[]).unwrap();
    let recipe = taught_recipe(&cal, &clean, &teach_spec());
    let scratch = |first_line| DefectSpec::Scratch {
        at: Extent { first_pixel: 10, pixels: 3, first_line, lines: 1 },
        brdf: BrdfSpec::Ward { rho_d: 0.9, rho_s: Some(0.05), alpha: 0.4 },
    };
    let scene = DefectScene::new("scratch", scene, &[scratch(61), scratch(63)]).unwrap();
    Fixture { cal: host_tools::calibration::signing::sign_with_dev_key(&cal), recipe, scene }
}

/// A recipe taught with `spec` on the first [`TEACH_LINES`] lines of
/// `scene` (defect-free there) through the calibration `cal` (unsigned),
/// signed with the development key.
pub fn taught_recipe(cal: &[u8], scene: &DefectScene, spec: &TeachSpec) -> Vec<u8> {
    let model = DeviceModel::new(brdf_meter::blob::BlobView::parse(cal).unwrap(), FULL_SCALE, ACQ).unwrap();
    let lines: Vec<_> = (0..TEACH_LINES).map(|l| model.correct(&scene.raw_frames_at(l as u64).unwrap())).collect();
    host_tools::calibration::signing::sign_with_dev_key(&teach(&model, &lines, spec).unwrap().bytes)
}

/// Lines the recipe is taught from (the scene's first).
pub const TEACH_LINES: usize = 60;

/// The recipe's settings.
pub fn teach_spec() -> TeachSpec {
    TeachSpec {
        max_bytes: RECIPE_SLOT_LEN as usize - brdf_meter::store::SLOT_HEADER_LEN - brdf_meter::signed::TRAILER_LEN,
        pulse_us: 20_000,
        // The patent scene's gloss (hundreds of GU, 2 % noise) spreads by
        // several GU per pixel: the distance alone decides here.
        windows: [Window::Off; 3],
        // The scratch is 3 pixels wide and its edge pixels see part of the
        // surface beside it: 2 adjacent pixels make a defect here.
        min_pixels: 2,
        ..TeachSpec::default()
    }
}

/// The scene lines the tests load (60..64: the scratch on the 2nd and 4th).
pub fn scene_lines(f: &Fixture) -> Vec<Vec<Vec<u16>>> {
    (60..64).map(|l| f.scene.raw_frames_at(l).unwrap()).collect()
}

/// The host's verdicts for `lines` lines of the loaded scene (cycled), one
/// inspection, with the points-follow bit a device asked for points sets.
pub fn host_verdicts(f: &Fixture, frames: &[Vec<Vec<u16>>], lines: usize, points: bool) -> Vec<Verdict> {
    let cal = brdf_meter::blob::BlobView::parse(&f.cal[..f.cal.len() - brdf_meter::signed::TRAILER_LEN]).unwrap();
    let model = DeviceModel::new(cal, FULL_SCALE, ACQ).unwrap();
    let recipe = RecipeView::parse(&f.recipe[..f.recipe.len() - brdf_meter::signed::TRAILER_LEN]).unwrap();
    let mut host = HostInspector::new(P).unwrap();
    (0..lines)
        .map(|k| {
            let mut v = host.line(&recipe, &model, k as u32, &model.correct(&frames[k % frames.len()]));
            if points && v.rejected() {
                v.flags |= brdf_meter::inspect::decide::verdict::POINTS_FOLLOW;
            }
            v
        })
        .collect()
}

/// A verdict's wire bytes (for comparing bit for bit, NaN included).
pub fn bytes(v: &Verdict) -> Vec<u8> {
    postcard::to_allocvec(v).unwrap()
}

/// The calibration CRC a signed recipe names.
pub fn recipe_cal(signed: &[u8]) -> u32 {
    RecipeView::parse(&signed[..signed.len() - brdf_meter::signed::TRAILER_LEN]).unwrap().settings().calibration_crc
}
