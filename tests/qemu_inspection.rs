//! Inspection end to end in QEMU: the QEMU firmware on QEMU's
//! b-l475e-iot01a measures the reference a recipe is taught from (the
//! recipe byte for byte the one taught from the host's simulation), takes
//! the recipe (its RAM recipe slots, refused for another calibration),
//! inspects a scene with a scratch
//! and sends one verdict per line, bit for bit the host's reference, drives
//! its reject output (PA4, which QEMU cannot show the host) and reports each
//! pulse on the link; a defect-free line costs one verdict frame.
use brdf_meter::protocol::{DeviceError, Response};
use host_tools::device::link::{LinkError, frame_len};
use std::time::Duration;
use system_tests::inspection::{TEACH_LINES, bytes, fixture, host_verdicts, recipe_cal, scene_lines, teach_spec};
use system_tests::qemu::start;
use system_tests::sim::{ACQ, FULL_SCALE, P};

#[test]
fn qemu_inspects_bit_for_bit_as_the_host_and_reports_its_reject_pulses() {
    let f = fixture();
    let q = start(Duration::from_secs(300));
    let mut c = q.connect().unwrap();
    c.timeout = Duration::from_secs(20);
    // Without a calibration the recipe is for another one.
    match c.provision_recipe(&f.recipe, |_, _| {}) {
        Err(LinkError::Device(DeviceError::RecipeForOtherCalibration { recipe, active: 0 })) => {
            assert_eq!(recipe, recipe_cal(&f.recipe))
        }
        other => panic!("expected RecipeForOtherCalibration, got {other:?}"),
    }
    c.provision(&f.cal, |_, _| {}).unwrap();
    // Taught on the device: the reference's lines fed to its sensor and
    // measured in the corrected encoding give the host's recipe, byte for byte.
    c.set_calibration(&f.cal).unwrap();
    let reference =
        host_tools::inspection::measured::measure_reference(&mut c, P, TEACH_LINES, Some((&f.scene, 0)), &mut |_| {})
            .unwrap();
    let cal = brdf_meter::blob::BlobView::parse(&f.cal[..f.cal.len() - brdf_meter::signed::TRAILER_LEN]).unwrap();
    let model = host_tools::inspection::lines::DeviceModel::new(cal, FULL_SCALE, ACQ).unwrap();
    let taught = host_tools::inspection::teach::teach(&model, &reference, &teach_spec()).unwrap();
    assert!(
        host_tools::calibration::signing::sign_with_dev_key(&taught.bytes) == f.recipe,
        "the recipe taught in QEMU"
    );
    let info = c.provision_recipe(&f.recipe, |_, _| {}).unwrap();
    assert_eq!(info.calibration_crc, recipe_cal(&f.recipe));
    let frames = scene_lines(&f);
    c.load_scene(&frames).unwrap();
    c.set_calibration(&f.cal).unwrap();
    let lines = 12;
    let run = c.inspect(lines as u32, true, &mut |_| {}).unwrap();
    assert_eq!(run.verdicts.len(), lines);
    for (k, (got, want)) in run.verdicts.iter().zip(host_verdicts(&f, &frames, lines, true)).enumerate() {
        assert_eq!(bytes(got), bytes(&want), "line {k}: QEMU {got:?}, host {want:?}");
    }
    let rejected: Vec<u32> = run.verdicts.iter().filter(|v| v.rejected()).map(|v| v.line).collect();
    assert_eq!(rejected, [1, 3, 5, 7, 9, 11], "the scratch lines, and only them");
    assert_eq!(run.points.len(), rejected.len() * brdf_meter::shape::qemu::PIXELS, "the rejected lines' points");
    for v in run.verdicts.iter().filter(|v| !v.rejected()) {
        assert!(frame_len(1, &Response::Verdict(*v)) <= 64, "a defect-free line's frame");
    }
    // Reject pulses: merged where the lines come faster than a pulse lasts,
    // each at least the recipe's 20 ms, counted by the device.
    assert!(!run.pulses.is_empty());
    for p in &run.pulses {
        assert!(p.len_us >= 20_000, "pulse {p:?}");
    }
    // The run ended after its pulses (the device's MeasureDone waits for
    // them; the client no longer waits its timeout out where they merged):
    // the last one reported is the last rejected line's, and the device
    // counted no pulse the run did not report.
    assert_eq!(run.pulses.last().map(|p| p.line), rejected.last().copied(), "pulses {:?}", run.pulses);
    let status = c.inspect_status().unwrap();
    assert_eq!((status.counters.lines, status.counters.rejected), (lines as u32, rejected.len() as u32));
    assert_eq!(status.counters.pulses as usize, run.pulses.len());
    eprintln!(
        "QEMU: {lines} lines, rejected {rejected:?}, {} reject pulse(s) {:?}, {} link bytes of verdicts and pulses",
        run.pulses.len(),
        run.pulses,
        run.link_bytes
    );
    system_tests::qemu::assert_stack_within_reserve(&q, "teaching a recipe and inspecting");
}
