//! Power cut during provisioning at every step of the flash mock (every byte
//! written, every page erase): after each, boot must find a whole valid
//! calibration, the old one or the new one, never a mix and never none.
use brdf_meter::blob::{BlobView, CRC32};
use brdf_meter::estimate::Calibration;
use brdf_meter::platform::host_sim::SimFlash;
use brdf_meter::store::Store;
use brdf_meter::test_blobs::signed_test_blob as test_blob;
use host_tools::device::link::Client;
use host_tools::device::reference::expected_line;
use host_tools::forward::scene::frames::analytic_scene;
use system_tests::sim::{FULL_SCALE, M, N, P, SLOT_LEN, SimDevice};

fn open(flash: SimFlash) -> Store<SimFlash> {
    Store::open(flash, SLOT_LEN, brdf_meter::test_blobs::dev_trusted(), |v| Calibration::<N, M, P>::check(v).is_ok())
}

/// Provisions `blob` through the store as the device does (chunks of 512).
fn provision(st: &mut Store<SimFlash>, blob: &[u8]) -> Result<(), brdf_meter::protocol::DeviceError> {
    st.begin(blob.len() as u32, CRC32.checksum(blob))?;
    let mut off = 0;
    for c in blob.chunks(512) {
        off = st.write_chunk(off, c)?;
    }
    st.commit(|v| Calibration::<N, M, P>::check(v)).map(|_| ()).map_err(Into::into)
}

/// A flash holding the `olds`, provisioned in turn.
fn image(olds: &[&[u8]]) -> SimFlash {
    let f = SimFlash::new(2 * SLOT_LEN as usize);
    let mut st = open(f.clone());
    for b in olds {
        provision(&mut st, b).unwrap();
    }
    f
}

/// Cuts the power at every step of provisioning `new` over `base`; checks what
/// boot finds. Returns the number of cut points tried.
fn cut_everywhere(base: &SimFlash, old: &[u8], new: &[u8]) -> usize {
    // How many steps a whole provisioning takes.
    let probe = base.reboot();
    let before = probe.steps();
    provision(&mut open(probe.clone()), new).unwrap();
    let total = probe.steps() - before;
    // The time goes into store opens (each checks a signature, milliseconds
    // on the host), one per cut point at least: spread them over the cores.
    let cuts: Vec<usize> = (0..=total).collect();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let (saw_old, saw_new) = std::thread::scope(|s| {
        let workers: Vec<_> = cuts
            .chunks(cuts.len().div_ceil(threads))
            .map(|part| s.spawn(move || cut_at(base, part, total, old, new)))
            .collect();
        workers
            .into_iter()
            .map(|w| w.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .fold((0, 0), |(o, n), (o2, n2)| (o + o2, n + n2))
    });
    // The new blob wins only once its header is whole: the last 32 steps are
    // the header bytes, so only the final cut point (no cut) sees it.
    assert_eq!(saw_new, 1, "the new blob must count only once completely written");
    assert_eq!(saw_old, total);
    total + 1
}

/// Provisions `new` over `base` with the power cut after each of `cuts` steps
/// (of `total`), boots each result; returns how many boots found the old blob
/// and how many the new one.
fn cut_at(base: &SimFlash, cuts: &[usize], total: usize, old: &[u8], new: &[u8]) -> (usize, usize) {
    // One store, opened on `base`, provisions at every cut point, its memory
    // restored to `base` before each: a failed provisioning leaves the store
    // as it opened (checked below), and opening a fresh one each time would
    // check the old blob's signature again, which doubled the test's time.
    let contents = base.contents();
    let f = base.reboot();
    let mut st = open(f.clone());
    let booted = st.active();
    let (mut saw_old, mut saw_new) = (0, 0);
    for &cut in cuts {
        f.restore(&contents);
        assert_eq!((st.active(), st.provisioning()), (booted, None), "the store before the cut at step {cut}");
        f.cut_after(cut);
        let r = provision(&mut st, new);
        assert_eq!(r.is_ok(), cut == total, "cut at step {cut} of {total}: {r:?}");
        let boot = open(f.reboot());
        let (_, view) = boot.active_blob().unwrap_or_else(|| panic!("no calibration after a cut at step {cut}"));
        // The view is the blob; `old` and `new` are signed calibrations.
        let got = view.as_bytes();
        let blob_of = |image: &[u8]| image.len() - brdf_meter::signed::TRAILER_LEN;
        if got == &old[..blob_of(old)] {
            saw_old += 1;
        } else if got == &new[..blob_of(new)] {
            saw_new += 1;
        } else {
            panic!("cut at step {cut}: boot found a blob that is neither the old nor the new one");
        }
    }
    (saw_old, saw_new)
}

#[test]
fn a_cut_at_any_step_leaves_the_old_or_the_new_calibration_whole() {
    let a = test_blob(N, M, 4, P, 1.0);
    let b = test_blob(N, M, 4, P, 2.0);
    let c = test_blob(N, M, 3, P, 3.0);
    // Target slot B, the active one A.
    let tried = cut_everywhere(&image(&[&a]), &a, &b);
    assert!(tried > a.len(), "every byte is a cut point ({tried})");
    // Target slot A holding an older valid blob, the active one B.
    cut_everywhere(&image(&[&a, &b]), &b, &c);
}

#[test]
fn a_cut_provisioning_never_writes_the_active_slot() {
    let a = test_blob(N, M, 4, P, 1.0);
    let b = test_blob(N, M, 4, P, 2.0);
    let base = image(&[&a]);
    let f = base.reboot();
    let before = f.log().len();
    provision(&mut open(f.clone()), &b).unwrap();
    for op in &f.log()[before..] {
        let at = match *op {
            brdf_meter::platform::host_sim::FlashOp::Erase(o)
            | brdf_meter::platform::host_sim::FlashOp::Write(o, _) => o,
        };
        assert!(at >= SLOT_LEN, "operation {op:?} touched the active slot A");
    }
}

#[test]
fn after_a_cut_the_application_boots_and_measures_with_the_surviving_calibration() {
    let a = test_blob(N, M, 4, P, 1.0);
    let b = test_blob(N, M, 4, P, 2.0);
    let base = image(&[&a]);
    let probe = base.reboot();
    let s0 = probe.steps();
    provision(&mut open(probe.clone()), &b).unwrap();
    let total = probe.steps() - s0;
    // A spread of cut points through the application (the store-level test
    // above covers every one).
    for cut in (0..=total).step_by(total / 7).chain([total - 1, total]) {
        let f = base.reboot();
        f.cut_after(cut);
        let _ = provision(&mut open(f.clone()), &b);
        let mut c = Client::new(SimDevice::boot(f.reboot(), 4)).unwrap();
        c.format = brdf_meter::protocol::StreamFormat::LOSSLESS;
        let cal = c.info().unwrap().calibration.expect("a calibration survives");
        let blob = if cal.blob_crc == BlobView::parse(&b).unwrap().crc() { &b } else { &a };
        assert_eq!(cal.blob_crc, BlobView::parse(blob).unwrap().crc());
        let view = BlobView::parse(blob).unwrap();
        let scene = analytic_scene(&view, 1, FULL_SCALE);
        c.load_scene(&scene).unwrap();
        let pts = c.measure(1).unwrap();
        let want = expected_line(&view, &scene[0], FULL_SCALE, &system_tests::sim::ACQ);
        for (p, w) in pts.iter().zip(&want) {
            assert_eq!(
                p.values.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                w.values.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
            );
        }
    }
}
