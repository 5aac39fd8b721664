//! Signed calibrations on the host simulation of the instrument: an unsigned
//! blob, a tampered one (a blob byte changed and its CRC fixed up; a
//! signature byte changed) and one signed by a foreign key are each refused
//! with the typed error, and the previous calibration keeps measuring bit for
//! bit, before and after a reboot. A slot holding a newer calibration with a
//! valid CRC but a foreign signature (as SWD could write one) is passed over
//! at boot.
use brdf_meter::blob::{BlobView, CRC32};
use brdf_meter::platform::host_sim::SimFlash;
use brdf_meter::protocol::DeviceError;
use brdf_meter::signed::{SignatureFault, TRAILER_LEN, sign};
use brdf_meter::store::{SLOT_HEADER_LEN, encode_slot_header};
use brdf_meter::test_blobs::{sign_for_tests, test_blob};
use embedded_storage::nor_flash::NorFlash;
use host_tools::device::link::{Client, LinkError};
use host_tools::device::reference::expected_line;
use host_tools::forward::scene::frames::analytic_scene;
use system_tests::sim::{FULL_SCALE, M, N, P, SLOT_LEN, SimDevice};

const ZONES: usize = 4;

fn device_error<T: std::fmt::Debug>(r: Result<T, LinkError>) -> DeviceError {
    match r {
        Err(LinkError::Device(e)) => e,
        other => panic!("expected a device error, got {other:?}"),
    }
}

/// Measures one line of `blob`'s analytic scene and checks it bit for bit
/// against the host's computation with `blob`.
fn measures_with(c: &mut Client<SimDevice>, blob: &[u8]) {
    let view = BlobView::parse(blob).unwrap();
    let scene = analytic_scene(&view, 1, FULL_SCALE);
    c.load_scene(&scene).unwrap();
    c.format = brdf_meter::protocol::StreamFormat::LOSSLESS;
    let pts = c.measure(1).unwrap();
    let want = expected_line(&view, &scene[0], FULL_SCALE, &system_tests::sim::ACQ);
    assert_eq!(pts.len(), P);
    for (p, w) in pts.iter().zip(&want) {
        assert_eq!(system_tests::meta_bits(p), system_tests::expected_meta_bits(w));
        let got: Vec<u32> = p.values.iter().map(|x| x.to_bits()).collect();
        let exp: Vec<u32> = w.values.iter().map(|x| x.to_bits()).collect();
        assert_eq!(got, exp);
    }
}

/// `blob` with one byte changed and its own CRC fixed up, so only the
/// signature can tell.
fn tampered_with_crc_fixed(blob: &[u8]) -> Vec<u8> {
    let mut t = blob.to_vec();
    let crc_at = t.len() - 4;
    t[crc_at / 2] ^= 0x10;
    let crc = CRC32.checksum(&t[..crc_at]);
    t[crc_at..].copy_from_slice(&crc.to_le_bytes());
    assert!(BlobView::parse(&t).is_ok(), "the tampered blob is itself valid");
    t
}

#[test]
fn unsigned_tampered_and_foreign_calibrations_are_refused_and_the_previous_keeps_measuring() {
    let flash = SimFlash::new(2 * SLOT_LEN as usize);
    let mut c = Client::new(SimDevice::boot(flash.clone(), ZONES)).unwrap();
    let good = sign_for_tests(&test_blob(N, M, ZONES, P, 1.0));
    let cal = c.provision(&good, |_, _| {}).unwrap();
    measures_with(&mut c, &good);

    let newer = test_blob(N, M, ZONES, P, 2.0);
    // The blob changed after signing, CRC fixed up: the old signature fails.
    let mut blob_changed = tampered_with_crc_fixed(&newer);
    blob_changed.extend_from_slice(&sign(&newer, &brdf_meter::test_blobs::DEV_SECRET));
    // One signature byte changed.
    let mut sig_changed = sign_for_tests(&newer);
    let last = sig_changed.len() - 1;
    sig_changed[last - 20] ^= 0x01;
    // Signed by a key the firmware does not trust.
    let mut foreign = newer.clone();
    foreign.extend_from_slice(&sign(&newer, &[0xA5; 32]));
    // A trailer of another format version.
    let mut bad_trailer = sign_for_tests(&newer);
    let v = newer.len() + 4;
    bad_trailer[v] = 9;
    let cases = [
        (newer.clone(), SignatureFault::Unsigned),
        (blob_changed, SignatureFault::BadSignature),
        (sig_changed, SignatureFault::BadSignature),
        (foreign, SignatureFault::UnknownKey),
        (bad_trailer, SignatureFault::BadTrailer),
    ];
    for (image, fault) in &cases {
        assert_eq!(device_error(c.provision(image, |_, _| {})), DeviceError::SignatureRejected(*fault));
        assert_eq!(c.info().unwrap().calibration, Some(cal), "{fault:?}");
        measures_with(&mut c, &good);
    }
    assert!(c.status().unwrap().refused >= cases.len() as u32);

    // After a reboot, still the first calibration (one simulated device at
    // a time: they share the mock clock).
    drop(c);
    let mut c = Client::new(SimDevice::boot(flash.reboot(), ZONES)).unwrap();
    assert_eq!(c.info().unwrap().calibration, Some(cal));
    measures_with(&mut c, &good);
    // And a correctly signed newer one is accepted.
    let signed = sign_for_tests(&newer);
    let cal2 = c.provision(&signed, |_, _| {}).unwrap();
    assert_eq!((cal2.slot, cal2.blob_crc), (1 - cal.slot, BlobView::parse(&newer).unwrap().crc()));
    measures_with(&mut c, &signed);
}

#[test]
fn boot_passes_over_a_newer_slot_with_a_foreign_signature() {
    let flash = SimFlash::new(2 * SLOT_LEN as usize);
    let mut c = Client::new(SimDevice::boot(flash.clone(), ZONES)).unwrap();
    let good = sign_for_tests(&test_blob(N, M, ZONES, P, 1.0));
    let cal = c.provision(&good, |_, _| {}).unwrap();
    assert_eq!(cal.slot, 0);
    drop(c);
    // Slot B written directly (as SWD would, bypassing the device's checks):
    // a newer sequence number, valid header and CRC, foreign signature.
    let newer = test_blob(N, M, ZONES, P, 2.0);
    let mut foreign = newer.clone();
    foreign.extend_from_slice(&sign(&newer, &[0xA5; 32]));
    assert_eq!(foreign.len(), newer.len() + TRAILER_LEN);
    let mut image = encode_slot_header(2, foreign.len() as u32, CRC32.checksum(&foreign)).to_vec();
    image.extend_from_slice(&foreign);
    image.resize(image.len().next_multiple_of(brdf_meter::shape::FLASH_WRITE), 0xFF);
    assert!(image.len() - SLOT_HEADER_LEN <= SLOT_LEN as usize);
    let mut raw = flash.reboot();
    raw.erase(SLOT_LEN, 2 * SLOT_LEN).unwrap();
    raw.write(SLOT_LEN, &image).unwrap();
    let mut c = Client::new(SimDevice::boot(raw.reboot(), ZONES)).unwrap();
    assert_eq!(c.info().unwrap().calibration, Some(cal), "the foreign-signed slot B must not be activated");
    measures_with(&mut c, &good);
}
