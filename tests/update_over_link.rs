//! Firmware updates end to end on the host simulation: the application (its
//! request handler and tasks, over the in-memory link) on a simulated chip
//! laid out as the board's flash map, its calibration store and embassy-boot's
//! updater sharing that one flash through the library's windows; host-tools'
//! own client sends the update (`update-firmware`'s library call) or drives
//! the USB DFU interface as dfu-util does; the bootloader (`firmware::boot`)
//! runs at every reset; the application boots on whatever image it left.
use brdf_meter::blob::BlobView;
use brdf_meter::firmware::image::{self, ImageFault, Target};
use brdf_meter::platform::host_sim::SimFlash;
use brdf_meter::protocol::{BootState, DeviceError, FirmwareInfo, UpdateFault};
use brdf_meter::signed::SignatureFault;
use brdf_meter::test_blobs::{DEV_SECRET, signed_test_blob};
use embassy_usb::control::{Recipient, Request, RequestType};
use embassy_usb::driver::Direction;
use host_tools::device::link::{Client, LinkError};
use host_tools::forward::scene::frames::analytic_scene;
use system_tests::fw_sim::{self, FwDevice, app_image, bootloader, slots, which};
use system_tests::sim::{FULL_SCALE, M, N, P};

/// Recipe bytes the factory wrote: an update must leave them as they are.
const RECIPES: &[u8] = b"recipe slot A: gloss 60 deg, haze, DOI; recipe slot B: spare";

fn a() -> Vec<u8> {
    app_image(5000, 1, [1, 0, 0])
}

fn b() -> Vec<u8> {
    app_image(9000, 2, [2, 0, 0])
}

/// The application booted on the chip as it is, and a client (f32 values,
/// so a measurement needs no blob on the host).
fn client(chip: &SimFlash) -> Client<FwDevice> {
    let mut c = Client::new(fw_sim::boot(chip)).unwrap();
    c.format = brdf_meter::protocol::StreamFormat::LOSSLESS;
    c
}

/// A chip with A active, a calibration provisioned by A, and A's client.
fn provisioned() -> (SimFlash, Client<FwDevice>, Vec<u8>) {
    let chip = fw_sim::factory(&a(), RECIPES);
    assert_eq!(bootloader(&chip), Ok(embassy_boot::State::Boot));
    let mut c = client(&chip);
    let cal = signed_test_blob(N, M, 4, P, 3.0);
    c.provision(&cal, |_, _| {}).unwrap();
    (chip, c, cal)
}

/// A reset: the bootloader, then the application on the image it left.
fn reset(chip: &SimFlash) -> Client<FwDevice> {
    bootloader(chip).expect("the bootloader prepares");
    client(chip)
}

fn device_error<T: std::fmt::Debug>(r: Result<T, LinkError>) -> DeviceError {
    match r {
        Err(LinkError::Device(e)) => e,
        other => panic!("expected a device error, got {other:?}"),
    }
}

/// Measures one line of a scene made for `cal`: the sensor delivers a frame,
/// the self-test's last part.
fn measure_a_line(c: &mut Client<FwDevice>, cal: &[u8]) {
    let scene = analytic_scene(&BlobView::parse(cal).unwrap(), 1, FULL_SCALE);
    c.load_scene(&scene).unwrap();
    assert_eq!(c.measure(1).unwrap().len(), P, "the calibration measures");
}

fn info(c: &mut Client<FwDevice>) -> FirmwareInfo {
    c.firmware_info().unwrap()
}

#[test]
fn an_update_over_the_link_boots_b_on_trial_and_b_confirms_after_its_self_test() {
    let (chip, mut c, cal) = provisioned();
    let before = slots(&chip);
    let fw = info(&mut c);
    assert_eq!((fw.version, fw.boot, fw.updates, fw.pending), ([1, 0, 0], BootState::Confirmed, true, None));

    let b = b();
    let mut seen = Vec::new();
    assert_eq!(c.update_firmware(&b, |done, total| seen.push((done, total))).unwrap(), [2, 0, 0]);
    assert_eq!(seen.last(), Some(&(b.len(), b.len())));
    assert_eq!(info(&mut c).pending, Some([2, 0, 0]));
    c.reboot().unwrap();
    assert!(c.transport().shared.reboot.signaled(), "Reboot asks the platform to reset");
    assert_eq!(which(&chip, &a(), &b, "before the reset"), 'A', "A runs until the reset");
    drop(c);

    let mut c = reset(&chip);
    assert_eq!(which(&chip, &a(), &b, "after the swap"), 'B');
    let fw = info(&mut c);
    assert_eq!((fw.version, fw.boot), ([2, 0, 0], BootState::Trial));
    // Store read and a request answered, but no sensor frame yet (no scene).
    assert!(fw.self_test.store && fw.self_test.link && !fw.self_test.sensor, "{:?}", fw.self_test);
    assert_eq!(device_error(c.update_firmware(&a(), |_, _| {})), DeviceError::Update(UpdateFault::TrialNotConfirmed));
    measure_a_line(&mut c, &cal);
    let fw = info(&mut c);
    assert_eq!((fw.boot, fw.self_test.passed()), (BootState::Confirmed, true));
    drop(c);

    let mut c = reset(&chip);
    assert_eq!(which(&chip, &a(), &b, "after the confirmed reset"), 'B', "a confirmed image stays");
    assert_eq!((info(&mut c).version, info(&mut c).boot), ([2, 0, 0], BootState::Confirmed));
    assert_eq!(slots(&chip), before, "the calibration and recipe slots are byte for byte as they were");
    measure_a_line(&mut c, &cal);
}

#[test]
fn a_new_image_that_fails_its_self_test_is_reverted_at_the_next_reset() {
    let (chip, mut c, cal) = provisioned();
    let before = slots(&chip);
    let b = b();
    c.update_firmware(&b, |_, _| {}).unwrap();
    drop(c);

    let mut c = reset(&chip);
    assert_eq!(which(&chip, &a(), &b, "trial"), 'B');
    // B answers over the link, but its sensor never delivers a frame (no
    // scene in the simulation: the sensor's read fails), so it never
    // confirms; the watchdog or the user resets it.
    assert_eq!(device_error(c.measure(1)), DeviceError::Sensor(brdf_meter::hw::SensorError::NoData));
    let fw = info(&mut c);
    assert_eq!((fw.version, fw.boot, fw.self_test.sensor), ([2, 0, 0], BootState::Trial, false));
    drop(c);

    let mut c = reset(&chip);
    assert_eq!(which(&chip, &a(), &b, "after the revert"), 'A');
    let fw = info(&mut c);
    assert_eq!((fw.version, fw.boot), ([1, 0, 0], BootState::Reverted));
    assert_eq!(slots(&chip), before, "the calibration and recipe slots are byte for byte as they were");
    measure_a_line(&mut c, &cal);
    drop(c);
    let _ = reset(&chip);
    assert_eq!(which(&chip, &a(), &b, "the reset after"), 'A', "a revert is final");
}

#[test]
fn a_refused_image_says_why_and_the_running_firmware_keeps_running() {
    let (chip, mut c, cal) = provisioned();
    let b = b();
    let mut tampered = b.clone();
    tampered[700] ^= 0x40;
    let foreign = image::sign(&b[..9000], Target::Qemu, [2, 0, 0], &[7; 32]);
    let board = image::sign(&b[..9000], Target::Board, [2, 0, 0], &DEV_SECRET);
    for (what, img, want) in [
        ("tampered", &tampered, ImageFault::Signature(SignatureFault::BadSignature)),
        ("foreign key", &foreign, ImageFault::Signature(SignatureFault::UnknownKey)),
        ("another machine's", &board, ImageFault::WrongTarget),
    ] {
        let e = device_error(c.update_firmware(img, |_, _| {}));
        assert_eq!(e, DeviceError::FirmwareRejected(want), "{what}");
        assert!(e.to_string().contains("the running firmware keeps running"), "{e}");
        let fw = info(&mut c);
        assert_eq!((fw.refused, fw.pending, fw.boot), (Some(e), None, BootState::Confirmed), "{what}");
    }
    measure_a_line(&mut c, &cal);
    drop(c);
    let mut c = reset(&chip);
    assert_eq!(which(&chip, &a(), &b, "after refusals"), 'A');
    assert_eq!(info(&mut c).boot, BootState::Confirmed);
}

/// One USB control request to the DFU interface (0), as the host sends it.
fn dfu_request(direction: Direction, request: u8, value: u16, length: u16) -> Request {
    Request {
        direction,
        request_type: RequestType::Class,
        recipient: Recipient::Interface,
        request,
        value,
        index: 0,
        length,
    }
}

/// DFU_DNLOAD block `n` (an empty one ends the download).
fn dnload<H: embassy_usb::Handler>(dfu: &mut H, n: u16, data: &[u8]) {
    let r = dfu.control_out(dfu_request(Direction::Out, 1, n, data.len() as u16), data);
    assert!(matches!(r, Some(embassy_usb::control::OutResponse::Accepted)), "DNLOAD {n} refused");
}

/// DFU_GETSTATUS: (bStatus, bState).
fn get_status<H: embassy_usb::Handler>(dfu: &mut H) -> (u8, u8) {
    let mut buf = [0u8; 64];
    match dfu.control_in(dfu_request(Direction::In, 3, 0, 6), &mut buf) {
        Some(embassy_usb::control::InResponse::Accepted(s)) => (s[0], s[4]),
        _ => panic!("GETSTATUS refused"),
    }
}

const DFU_DNLOAD_IDLE: u8 = 5;
const DFU_MANIFEST: u8 = 7;
const DFU_ERROR: u8 = 10;

/// What dfu-util -D does: blocks of wTransferSize, a GETSTATUS after each,
/// an empty block, GETSTATUS until it leaves the manifest phase. Returns the
/// last (status, state).
fn dfu_util_download(c: &mut Client<FwDevice>, img: &[u8]) -> (u8, u8) {
    let shared = c.transport().shared;
    let mut dfu = brdf_meter::app::usb_dfu::state(shared);
    for (n, block) in img.chunks(brdf_meter::app::usb_dfu::BLOCK).enumerate() {
        dnload(&mut dfu, n as u16, block);
        let (status, state) = get_status(&mut dfu);
        if state != DFU_DNLOAD_IDLE {
            return (status, state);
        }
    }
    dnload(&mut dfu, img.len().div_ceil(brdf_meter::app::usb_dfu::BLOCK) as u16, &[]);
    get_status(&mut dfu)
}

#[test]
fn dfu_util_s_download_writes_a_signed_image_that_the_next_reset_swaps_in() {
    let (chip, mut c, cal) = provisioned();
    let before = slots(&chip);
    let b = b();
    // Manifestation: the image checked and marked, then the device resets
    // by itself (bitWillDetach).
    assert_eq!(dfu_util_download(&mut c, &b), (0, DFU_MANIFEST));
    assert!(c.transport().shared.reboot.signaled(), "the end of the download resets the device");
    assert_eq!(info(&mut c).pending, Some([2, 0, 0]));
    drop(c);
    let mut c = reset(&chip);
    assert_eq!(which(&chip, &a(), &b, "after a DFU update"), 'B');
    assert_eq!((info(&mut c).version, info(&mut c).boot), ([2, 0, 0], BootState::Trial));
    measure_a_line(&mut c, &cal);
    assert_eq!(info(&mut c).boot, BootState::Confirmed);
    assert_eq!(slots(&chip), before, "the calibration and recipe slots are byte for byte as they were");
}

#[test]
fn dfu_util_gets_an_error_status_for_a_refused_image_and_info_says_why() {
    let (chip, mut c, _) = provisioned();
    let b = b();
    let unsigned = b[..9000].to_vec();
    let foreign = image::sign(&b[..9000], Target::Qemu, [2, 0, 0], &[7; 32]);
    let board = image::sign(&b[..9000], Target::Board, [2, 0, 0], &DEV_SECRET);
    const ERR_TARGET: u8 = 0x01;
    const ERR_FILE: u8 = 0x02;
    const ERR_ADDRESS: u8 = 0x08;
    let too_large = app_image(fw_sim::ACTIVE_LEN as usize, 3, [3, 0, 0]);
    for (what, img, status, why) in [
        ("unsigned", &unsigned, ERR_FILE, DeviceError::FirmwareRejected(ImageFault::Unsigned)),
        (
            "foreign key",
            &foreign,
            ERR_FILE,
            DeviceError::FirmwareRejected(ImageFault::Signature(SignatureFault::UnknownKey)),
        ),
        ("another machine's", &board, ERR_TARGET, DeviceError::FirmwareRejected(ImageFault::WrongTarget)),
    ] {
        assert_eq!(dfu_util_download(&mut c, img), (status, DFU_ERROR), "{what}");
        let fw = info(&mut c);
        assert_eq!((fw.refused, fw.pending, fw.boot), (Some(why), None, BootState::Confirmed), "{what}");
    }
    let (status, state) = dfu_util_download(&mut c, &too_large);
    assert_eq!((status, state), (ERR_ADDRESS, DFU_ERROR), "an image larger than the partition");
    assert!(matches!(info(&mut c).refused, Some(DeviceError::Update(UpdateFault::TooLarge { .. }))));
    assert!(!c.transport().shared.reboot.signaled(), "a refused download does not reset the device");
    drop(c);
    let _ = reset(&chip);
    assert_eq!(which(&chip, &a(), &b, "after refused downloads"), 'A');
}
