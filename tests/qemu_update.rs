//! Firmware updates in QEMU, as far as its machine allows: the QEMU
//! bootloader starts the application (every QEMU test boots that way; this
//! one checks the boot state it reports), an update travels over the real
//! QEMU link into the QEMU build's RAM update partition (SRAM2, 32 KiB) and
//! is verified and marked there by the firmware on the emulated Cortex-M4,
//! a tampered one is refused, and `Reboot` resets the machine through the
//! bootloader. What QEMU cannot show: the swap and the revert (its flash is
//! read-only ROM, so the bootloader reads the state the factory image left,
//! never the RAM one), and today's image, which is larger than SRAM2.
use brdf_meter::firmware::image::Target;
use brdf_meter::protocol::{BootState, DeviceError, UpdateFault};
use host_tools::cli::update_firmware;
use host_tools::device::link::{Endpoint, LinkError};
use std::time::{Duration, Instant};
use system_tests::fw_sim::app_image;

#[test]
fn qemu_takes_a_signed_update_over_its_link_and_refuses_what_it_must() {
    let q = system_tests::qemu::start(Duration::from_secs(300));
    let mut c = q.connect().unwrap();
    c.timeout = Duration::from_secs(30);
    let fw = c.firmware_info().unwrap();
    assert_eq!((fw.target, fw.boot, fw.updates), (Target::Qemu, BootState::Confirmed, true), "{fw:?}");
    let partition = brdf_meter::shape::qemu::DFU_LEN;
    assert_eq!(fw.max_image, partition);
    let dev_key = brdf_meter::signed::key_id(&brdf_meter::test_blobs::dev_public_key());
    assert!(fw.trusts_development_key && fw.trusted[..fw.trusted_count as usize].contains(&dev_key));

    // Today's QEMU firmware, signed: larger than the RAM partition, refused
    // at once with the sizes.
    // Signed with the version the firmware reports (its ELF symbol), and
    // never with another.
    let elf = system_tests::qemu::firmware();
    let sign = |v| host_tools::cli::sign_firmware::sign_elf(&elf, Target::Qemu, v, &brdf_meter::test_blobs::DEV_SECRET);
    let today = sign(None).unwrap();
    let own = brdf_meter::app::FIRMWARE_VERSION;
    let trailer = today[today.len() - 96..].try_into().unwrap();
    assert_eq!(brdf_meter::firmware::image::decode_trailer(trailer, today.len() as u32).unwrap().0.version, own);
    assert_eq!(fw.version, own, "the device reports the version its image is signed with");
    let other = [own[0], own[1].wrapping_add(1), own[2]];
    let e = sign(Some(other)).unwrap_err().to_string();
    assert!(e.contains("a device would show another version"), "{e}");
    // Nor for the board: the ELF says which machine it is for.
    let e = host_tools::cli::sign_firmware::sign_elf(&elf, Target::Board, None, &brdf_meter::test_blobs::DEV_SECRET)
        .unwrap_err()
        .to_string();
    assert!(e.contains("built for Qemu, not Board"), "{e}");
    assert!(today.len() as u32 > partition);
    match c.update_firmware(&today, |_, _| {}) {
        Err(LinkError::Device(DeviceError::Update(UpdateFault::TooLarge { len, max }))) => {
            assert_eq!((len, max), (today.len() as u32, partition))
        }
        other => panic!("today's image in the RAM partition: {other:?}"),
    }

    // The largest signed image the partition takes, tampered: sent whole,
    // then refused by the signature check on the device.
    let image = app_image(partition as usize - 96, 9, [0, 2, 0]);
    assert_eq!(image.len() as u32, partition);
    let mut tampered = image.clone();
    tampered[4096] ^= 1;
    let e = match c.update_firmware(&tampered, |_, _| {}) {
        Err(LinkError::Device(e)) => e,
        other => panic!("a tampered image: {other:?}"),
    };
    assert!(matches!(e, DeviceError::FirmwareRejected(_)), "{e}");
    assert_eq!(c.firmware_info().unwrap().refused, Some(e));
    drop(c);

    // The same image intact, through `host-tools update-firmware` as a user
    // runs it (it prints the time), without the reset.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("b.fwu");
    std::fs::write(&path, &image).unwrap();
    let device = Endpoint { port: None, tcp: Some(q.addr.clone()) };
    let t0 = Instant::now();
    update_firmware::run(update_firmware::Args {
        device: device.clone(),
        image: Some(path),
        no_reboot: true,
        reboot_only: false,
    })
    .unwrap();
    let secs = t0.elapsed().as_secs_f64();
    println!(
        "QEMU link: {} bytes sent, verified (CRC, SHA-512, Ed25519) and marked in {secs:.2} s ({:.1} KiB/s)",
        image.len(),
        image.len() as f64 / 1024.0 / secs
    );
    let mut c = q.connect().unwrap();
    let fw = c.firmware_info().unwrap();
    assert_eq!((fw.pending, fw.refused, fw.boot), (Some([0, 2, 0]), None, BootState::Confirmed));
    drop(c);
    // Before the reset, which paints the stack again.
    system_tests::qemu::assert_stack_within_reserve(&q, "verifying and marking two signed updates");

    // The reset goes through the bootloader, which reads the boot state from
    // QEMU's read-only flash: no swap, the same image comes back confirmed.
    update_firmware::run(update_firmware::Args { device, image: None, no_reboot: false, reboot_only: true }).unwrap();
    // The reset is asynchronous to the reply: ask until the restarted
    // firmware answers (a loaded machine may take seconds to get there).
    let mut fw = None;
    for _ in 0..40 {
        std::thread::sleep(Duration::from_millis(500));
        if let Some(info) = q.connect().ok().and_then(|mut c| c.firmware_info().ok()) {
            let done = info.pending.is_none();
            fw = Some(info);
            if done {
                break;
            }
        }
    }
    let fw = fw.expect("the device answers after its reset");
    assert_eq!((fw.pending, fw.boot), (None, BootState::Confirmed), "QEMU cannot swap: the image is the same");
}
