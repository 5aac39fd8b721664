//! Inspection on the host simulation of the firmware: a recipe taught by
//! host-tools is provisioned over the link (refused for another
//! calibration, unsigned, or malformed; power cuts leave the old or the new
//! recipe whole), the device inspects a scene with a scratch and sends one
//! verdict per line, bit for bit the host's reference, drives its reject
//! output, and a defect-free line costs at most 64 link bytes. A recipe
//! taught on the device, from the lines it measures, is the recipe taught
//! from the host's simulation of the same lines, byte for byte.
use brdf_meter::blob::CRC32;
use brdf_meter::inspect::RecipeStore;
use brdf_meter::platform::host_sim::SimFlash;
use brdf_meter::protocol::{DeviceError, Response};
use host_tools::device::link::{Client, LinkError, frame_len};
use host_tools::inspection::teach::TeachSpec;
use system_tests::inspection::{
    TEACH_LINES, bytes, fixture, host_verdicts, recipe_cal, scene_lines, taught_recipe, teach_spec,
};
use system_tests::sim::{ACQ, FULL_SCALE, P, RECIPE_SLOT_LEN, SLOT_LEN, SimDevice};

fn device_error<T: std::fmt::Debug>(r: Result<T, LinkError>) -> DeviceError {
    match r {
        Err(LinkError::Device(e)) => e,
        other => panic!("expected a device error, got {other:?}"),
    }
}

/// A host-simulated device inspecting the fixture's scene (lines 60..64)
/// with its calibration and a recipe taught with `spec`.
fn inspecting(spec: TeachSpec) -> Client<SimDevice> {
    let f = fixture();
    let unsigned = &f.cal[..f.cal.len() - brdf_meter::signed::TRAILER_LEN];
    let recipe = taught_recipe(unsigned, &f.scene, &spec);
    let mut c = Client::new(SimDevice::boot_with_recipes(
        SimFlash::new(2 * SLOT_LEN as usize),
        SimFlash::new(2 * RECIPE_SLOT_LEN as usize),
        4,
    ))
    .unwrap();
    c.provision(&f.cal, |_, _| {}).unwrap();
    c.provision_recipe(&recipe, |_, _| {}).unwrap();
    c.load_scene(&scene_lines(&f)).unwrap();
    c.set_calibration(&f.cal).unwrap();
    c
}

#[test]
fn a_taught_recipe_inspects_bit_for_bit_as_the_host_and_drives_the_reject_output() {
    let f = fixture();
    let mut c = Client::new(SimDevice::boot_with_recipes(
        SimFlash::new(2 * SLOT_LEN as usize),
        SimFlash::new(2 * RECIPE_SLOT_LEN as usize),
        4,
    ))
    .unwrap();
    // No calibration yet: a recipe taught with one is refused.
    assert_eq!(
        device_error(c.provision_recipe(&f.recipe, |_, _| {})),
        DeviceError::RecipeForOtherCalibration { recipe: recipe_cal(&f.recipe), active: 0 }
    );
    c.provision(&f.cal, |_, _| {}).unwrap();
    assert_eq!(device_error(c.inspect(1, false, &mut |_| {})), DeviceError::NoRecipe);
    // Unsigned and malformed recipes are refused; the device keeps none.
    let unsigned = &f.recipe[..f.recipe.len() - brdf_meter::signed::TRAILER_LEN];
    // The refusal is the recipe's, in what the user reads too: the
    // device's error is the store's, which names the calibration.
    match c.provision_recipe(unsigned, |_, _| {}) {
        Err(e @ LinkError::RecipeSignature(brdf_meter::signed::SignatureFault::Unsigned)) => {
            let text = e.to_string();
            assert!(text.contains("refused the recipe") && text.contains("previous recipe is kept"), "{text}");
            assert!(!text.contains("calibration"), "{text}");
        }
        other => panic!("expected the recipe's signature refused, got {other:?}"),
    }
    let foreign = host_tools::calibration::signing::sign_blob(unsigned, &[9; 32]);
    assert!(matches!(
        c.provision_recipe(&foreign, |_, _| {}),
        Err(LinkError::RecipeSignature(brdf_meter::signed::SignatureFault::UnknownKey))
    ));
    let mut bad = unsigned.to_vec();
    bad[16] = 7; // pixels: 7 (CRC made right, then signed): another device's shape
    let n = bad.len();
    let crc = CRC32.checksum(&bad[..n - 4]);
    bad[n - 4..].copy_from_slice(&crc.to_le_bytes());
    let bad = host_tools::calibration::signing::sign_with_dev_key(&bad);
    assert!(matches!(device_error(c.provision_recipe(&bad, |_, _| {})), DeviceError::RecipeRejected(_)));
    let info = c.provision_recipe(&f.recipe, |_, _| {}).unwrap();
    assert_eq!(info.calibration_crc, recipe_cal(&f.recipe));

    // The scene: lines 60..64, the scratch on the 2nd and 4th; 8 lines cycle it twice.
    let frames = scene_lines(&f);
    c.load_scene(&frames).unwrap();
    c.set_calibration(&f.cal).unwrap();
    let run = c.inspect(8, true, &mut |_| {}).unwrap();
    assert_eq!(run.verdicts.len(), 8);
    // The host's reference, line after line with the same state.
    for (k, (got, want)) in run.verdicts.iter().zip(host_verdicts(&f, &frames, 8, true)).enumerate() {
        assert_eq!(bytes(got), bytes(&want), "line {k}: device {got:?}, host {want:?}");
    }
    let rejected: Vec<u32> = run.verdicts.iter().filter(|v| v.rejected()).map(|v| v.line).collect();
    assert_eq!(rejected, [1, 3, 5, 7], "the scratch lines, and only them");
    // Every point's first part was worked out while its line's last frame
    // integrated: after it, only the rest (and the verdicts are still the
    // host's, which works each point out whole).
    let early = c.transport().shared.core.lock(|c| c.borrow().early_points);
    assert_eq!(early as usize, 8 * P);
    for v in run.verdicts.iter().filter(|v| v.rejected()) {
        let r = v.runs.as_slice();
        assert!(
            r.iter().any(|r| r.first <= 12 && r.first + r.len >= 10),
            "line {}: defects {r:?} miss pixels 10..12",
            v.line
        );
    }
    // The points of the rejected lines followed their verdicts.
    assert_eq!(run.points.len(), 4 * P);
    // Defect-free lines: one verdict frame each, at most 64 bytes.
    for v in run.verdicts.iter().filter(|v| !v.rejected()) {
        let n = frame_len(7, &Response::Verdict(*v));
        assert!(n <= 64, "a defect-free line's verdict frame is {n} bytes");
    }
    // Reject pulses: reported on the link and seen on the output, 20 ms each.
    let status = c.inspect_status().unwrap();
    assert_eq!(status.counters.rejected, 4);
    let edges = c.transport().reject.edges();
    let highs: Vec<(u64, u64)> =
        edges.windows(2).filter(|w| w[0].1 && !w[1].1).map(|w| (w[0].0, w[1].0 - w[0].0)).collect();
    assert!(!highs.is_empty() && highs.len() == run.pulses.len(), "edges {edges:?}, pulses {:?}", run.pulses);
    for ((start, len), p) in highs.iter().zip(&run.pulses) {
        assert_eq!((*start, *len), (p.start_us, p.len_us as u64));
        assert!(*len >= 20_000, "a pulse a PLC scanning every 10 ms cannot miss");
    }
    // The run ended after its pulses: the last one reported is the last
    // rejected line's (a merged pulse names the last line it took in).
    assert_eq!(run.pulses.last().map(|p| p.line), rejected.last().copied(), "pulses {:?}", run.pulses);
}

/// A delay in lines: each rejected line pulses when the line that many
/// lines later is read, and the one whose delay outlasts the run pulses at
/// its end, before the run's `MeasureDone`.
#[test]
fn a_delay_in_lines_pulses_later_and_the_run_ends_after_the_lines_it_still_held() {
    use brdf_meter::inspect::recipe::DelayUnit;
    let mut c = inspecting(TeachSpec { delay: (2, DelayUnit::Lines), ..teach_spec() });
    // Lines 1, 3 and 5 pulse at the verdicts of 3, 5 and 7; nothing counts
    // line 7's delay down, so it pulses as the run ends.
    let run = c.inspect(8, false, &mut |_| {}).unwrap();
    let rejected: Vec<u32> = run.verdicts.iter().filter(|v| v.rejected()).map(|v| v.line).collect();
    assert_eq!(rejected, [1, 3, 5, 7]);
    assert_eq!(run.pulses.last().map(|p| p.line), Some(7), "pulses {:?}", run.pulses);
    let status = c.inspect_status().unwrap();
    assert_eq!(status.counters.pulses as usize, run.pulses.len());
    let edges = c.transport().reject.edges();
    assert_eq!(edges.windows(2).filter(|w| w[0].1 && !w[1].1).count(), run.pulses.len(), "edges {edges:?}");
    // Every pulse names a rejected line, and the next run starts with
    // nothing held over.
    assert!(run.pulses.iter().all(|p| rejected.contains(&p.line)), "{:?}", run.pulses);
    let again = c.inspect(1, false, &mut |_| {}).unwrap();
    assert!(again.pulses.is_empty(), "{:?}", again.pulses);
}

/// A delay in time keeps a run open past its last line, until its pulse is
/// over: the device stays busy meanwhile, and the board's watchdog rule,
/// fed what `measuring_lines` says, does not take the wait for a stall
/// (fed the plain "measuring" it would reset the board mid-run).
#[test]
fn a_run_waiting_for_a_late_pulse_is_busy_but_not_stalled() {
    use brdf_meter::inspect::recipe::DelayUnit;
    use brdf_meter::platform::watchdog_health::{Health, STALL_LIMIT_MS};
    use brdf_meter::protocol::Request;
    use host_tools::device::link::Reply;
    let delay_us = 4_000_000; // longer than the stall limit
    assert!(delay_us / 1000 > STALL_LIMIT_MS as u32);
    let mut c = inspecting(TeachSpec { delay: (delay_us, DelayUnit::Micros), ..teach_spec() });
    // Two lines, the second with the scratch: its pulse starts 4 s after its verdict.
    let seq = c.send(&Request::Inspect { lines: 2, defect_points: false, format: c.format }).unwrap();
    let (mut plain, mut watched) = (Health::default(), Health::default());
    let (mut plain_stalled, mut waited_ms) = (false, 0u64);
    for _ in 0..(2 * delay_us / 1000 / 10) {
        let dev = c.transport();
        dev.advance_us(10_000);
        let (st, lines) = (dev.shared.status(), dev.shared.measuring_lines());
        if !st.measuring {
            break;
        }
        waited_ms += u64::from(st.measuring && !lines) * 10;
        let now = embassy_time::Instant::now().as_millis();
        plain_stalled |= !plain.observe(now, st.measuring, st.lines_total);
        assert!(watched.observe(now, lines, st.lines_total), "a stall seen at {now} ms");
    }
    assert!(!c.transport().shared.status().measuring, "the run never ended");
    assert!(waited_ms >= u64::from(delay_us) / 1000 - 100, "waited {waited_ms} ms for the pulse");
    assert!(plain_stalled, "without measuring_lines the wait would have looked like a stall");
    // On the link: the verdicts, the pulse, then the run's end.
    let mut order = Vec::new();
    while let Ok(fr) = c.next_frame(std::time::Duration::from_millis(1)) {
        match fr.reply {
            Reply::Msg(Response::Verdict(v)) if fr.seq == seq => order.push(format!("verdict {}", v.line)),
            Reply::Msg(Response::RejectPulse { line, .. }) => order.push(format!("pulse {line}")),
            Reply::Msg(Response::MeasureDone { lines_done }) => order.push(format!("done {lines_done}")),
            _ => {}
        }
    }
    assert_eq!(order, ["verdict 0", "verdict 1", "pulse 1", "done 2"]);
}

/// A delay in time schedules pulses ahead of their start: each rejected
/// line's pulse is its own, as long as the recipe says, where pulses do
/// not overlap (a pulse driven while the next was already scheduled once
/// stretched to that one's end, holding the ejector through the good parts
/// between).
#[test]
fn pulses_scheduled_ahead_by_a_delay_in_time_stay_apart() {
    use brdf_meter::inspect::recipe::DelayUnit;
    let mut c = inspecting(TeachSpec { pulse_us: 1_000, delay: (50_000, DelayUnit::Micros), ..teach_spec() });
    let run = c.inspect(8, false, &mut |_| {}).unwrap();
    let rejected: Vec<u32> = run.verdicts.iter().filter(|v| v.rejected()).map(|v| v.line).collect();
    assert_eq!(rejected, [1, 3, 5, 7]);
    // Two lines apart is several milliseconds (a line is 7 exposures):
    // 1 ms pulses 50 ms late never overlap.
    let lines: Vec<u32> = run.pulses.iter().map(|p| p.line).collect();
    assert_eq!(lines, rejected, "pulses {:?}", run.pulses);
    assert!(run.pulses.iter().all(|p| p.len_us == 1_000), "pulses {:?}", run.pulses);
    assert!(run.pulses.windows(2).all(|w| w[1].start_us > w[0].start_us + 1_000), "{:?}", run.pulses);
    let edges = c.transport().reject.edges();
    let highs: Vec<(u64, u64)> =
        edges.windows(2).filter(|w| w[0].1 && !w[1].1).map(|w| (w[0].0, w[1].0 - w[0].0)).collect();
    assert_eq!(highs, run.pulses.iter().map(|p| (p.start_us, u64::from(p.len_us))).collect::<Vec<_>>());
}

#[test]
fn a_power_cut_while_provisioning_a_recipe_leaves_the_old_or_the_new_whole() {
    let f = fixture();
    let old = f.recipe.clone();
    let mut new_body = old[..old.len() - brdf_meter::signed::TRAILER_LEN].to_vec();
    new_body[24] ^= 1; // another version number
    let n = new_body.len();
    let crc = CRC32.checksum(&new_body[..n - 4]);
    new_body[n - 4..].copy_from_slice(&crc.to_le_bytes());
    let new = host_tools::calibration::signing::sign_with_dev_key(&new_body);
    let keys = brdf_meter::test_blobs::dev_trusted();
    let open = |fl: SimFlash| RecipeStore::open(fl, RECIPE_SLOT_LEN, keys, |_| true);
    let base = SimFlash::new(2 * RECIPE_SLOT_LEN as usize);
    let provision = |st: &mut RecipeStore<SimFlash>, image: &[u8]| -> Result<(), ()> {
        st.begin(image.len() as u32, CRC32.checksum(image)).map_err(|_| ())?;
        let mut off = 0;
        for c in image.chunks(512) {
            off = st.write_chunk(off, c).map_err(|_| ())?;
        }
        st.commit(|_| Ok(())).map(|_| ()).map_err(|_| ())
    };
    provision(&mut open(base.clone()), &old).unwrap();
    let whole = |fl: SimFlash| open(fl.reboot()).active_blob().map(|(_, v)| v.as_bytes().to_vec());
    let (old_body, new_body) = (old[..old.len() - 80].to_vec(), new_body);
    let mut cuts = 0;
    for k in 0.. {
        let fl = SimFlash::with_contents(base.contents());
        let mut st = open(fl.clone());
        fl.cut_after(k);
        let done = provision(&mut st, &new).is_ok();
        let found = whole(fl).expect("a whole recipe after every cut");
        assert!(found == old_body || found == new_body, "cut after {k} steps");
        if done {
            assert_eq!(found, new_body);
            break;
        }
        cuts += 1;
    }
    assert!(cuts > 100, "cut at every step ({cuts})");
}

#[test]
fn a_recipe_taught_on_the_device_is_the_one_taught_from_its_simulation() {
    let f = fixture();
    let mut c = Client::new(SimDevice::boot(SimFlash::new(2 * SLOT_LEN as usize), 4)).unwrap();
    c.provision(&f.cal, |_, _| {}).unwrap();
    c.set_calibration(&f.cal).unwrap();
    // The scene's first lines (the scratch comes later), fed to the
    // simulated sensor a few at a time and measured in the corrected encoding.
    let mut done = Vec::new();
    let lines =
        host_tools::inspection::measured::measure_reference(&mut c, P, TEACH_LINES, Some((&f.scene, 0)), &mut |n| {
            done.push(n)
        })
        .unwrap();
    assert_eq!(done.last(), Some(&TEACH_LINES));
    assert_eq!(c.format.encoding, brdf_meter::protocol::Encoding::Sigma16, "the client's format is given back");
    let cal = brdf_meter::blob::BlobView::parse(&f.cal[..f.cal.len() - brdf_meter::signed::TRAILER_LEN]).unwrap();
    let model = host_tools::inspection::lines::DeviceModel::new(cal, FULL_SCALE, ACQ).unwrap();
    // Each line as the device measured it is the host's correction of it, bit for bit ...
    for (l, line) in lines.iter().enumerate() {
        let host = model.correct(&f.scene.raw_frames_at(l as u64).unwrap());
        let bits = |l: &host_tools::inspection::lines::Line| {
            l.v.iter().flat_map(|x| x.iter().map(|y| y.to_bits())).collect::<Vec<_>>()
        };
        assert_eq!((bits(line), &line.flags), (bits(&host), &host.flags), "line {l}");
    }
    // ... so the recipe taught from them is the one the fixture taught on the host.
    let taught = host_tools::inspection::teach::teach(&model, &lines, &teach_spec()).unwrap();
    assert_eq!(host_tools::calibration::signing::sign_with_dev_key(&taught.bytes), f.recipe);
}
