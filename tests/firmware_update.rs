//! Firmware updates on the host simulation: embassy-boot's own updater (in
//! the device's `firmware::update`) and bootloader (`firmware::boot`, what
//! the bootloader binaries run) on the NOR fake that can cut the power at
//! any byte written and any page erased.
//!
//! The simulated flash holds the boot state, the active image and the update
//! partition as the board's map orders them (smaller: 4 pages of image).
use brdf_meter::blob::CRC32;
use brdf_meter::firmware::boot;
use brdf_meter::firmware::image::{self, ImageFault, Target};
use brdf_meter::firmware::update::{FirmwareSlot, Updater};
use brdf_meter::platform::host_sim::SimFlash;
use brdf_meter::protocol::{BootState, DeviceError, UpdateFault};
use brdf_meter::shape::FLASH_PAGE;
use brdf_meter::signed::SignatureFault;
use brdf_meter::test_blobs::{DEV_SECRET, dev_trusted};
use core::cell::RefCell;
use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use system_tests::fw_sim::{app_image, which_image};

const STATE_LEN: u32 = 2 * FLASH_PAGE as u32;
const ACTIVE_LEN: u32 = 4 * FLASH_PAGE as u32;
const DFU_LEN: u32 = ACTIVE_LEN + FLASH_PAGE as u32;
const ACTIVE_AT: u32 = STATE_LEN;
const DFU_AT: u32 = ACTIVE_AT + ACTIVE_LEN;
const FLASH_LEN: usize = (DFU_AT + DFU_LEN) as usize;

type Part<'a> = BlockingPartition<'a, NoopRawMutex, SimFlash>;

/// A flash whose active region holds `active` (state erased: Boot).
fn factory(active: &[u8]) -> SimFlash {
    let mut mem = vec![0xFFu8; FLASH_LEN];
    mem[ACTIVE_AT as usize..ACTIVE_AT as usize + active.len()].copy_from_slice(active);
    SimFlash::with_contents(mem)
}

fn parts(m: &Mutex<NoopRawMutex, RefCell<SimFlash>>) -> (Part<'_>, Part<'_>, Part<'_>) {
    (
        BlockingPartition::new(m, ACTIVE_AT, ACTIVE_LEN),
        BlockingPartition::new(m, DFU_AT, DFU_LEN),
        BlockingPartition::new(m, 0, STATE_LEN),
    )
}

/// A reset: the bootloader's part on `flash`.
fn bootloader(flash: &SimFlash) -> Result<embassy_boot::State, embassy_boot::BootError> {
    let m = Mutex::new(RefCell::new(flash.clone()));
    let (active, dfu, state) = parts(&m);
    boot::prepare(active, dfu, state, &mut [0u8; boot::SWAP_BUFFER])
}

/// The running firmware's updater on `flash`, and what it does with it.
fn with_updater<R>(flash: &SimFlash, f: impl FnOnce(&mut dyn FirmwareSlot) -> R) -> R {
    let m = Mutex::new(RefCell::new(flash.clone()));
    let (_, dfu, state) = parts(&m);
    let mut aligned = [0u8; 8];
    let mut u = Updater::new(dfu, state, &mut aligned, ACTIVE_LEN, Target::Qemu, dev_trusted());
    f(&mut u)
}

/// Sends `image` as the link would (begin, 512-byte chunks, commit).
fn send(u: &mut dyn FirmwareSlot, image: &[u8]) -> Result<[u8; 3], DeviceError> {
    let mut off = u.begin(image.len() as u32, CRC32.checksum(image))?;
    while (off as usize) < image.len() {
        let end = (off as usize + 512).min(image.len());
        off = u.write(off, &image[off as usize..end])?;
    }
    u.commit()
}

fn active(flash: &SimFlash) -> Vec<u8> {
    flash.contents()[ACTIVE_AT as usize..(ACTIVE_AT + ACTIVE_LEN) as usize].to_vec()
}

/// Which image the active region holds, whole: 'A', 'B', or a panic.
fn which(flash: &SimFlash, a: &[u8], b: &[u8], context: &str) -> char {
    which_image(&active(flash), a, b, context)
}

#[test]
fn an_update_swaps_in_on_trial_and_stays_once_confirmed() {
    let (a, b) = (app_image(5000, 1, [1, 0, 0]), app_image(6000, 2, [1, 1, 0]));
    let f = factory(&a);
    assert_eq!(bootloader(&f), Ok(embassy_boot::State::Boot));
    assert_eq!(with_updater(&f, |u| u.boot_state()), BootState::Confirmed);
    assert_eq!(with_updater(&f, |u| send(u, &b)), Ok([1, 1, 0]));
    assert_eq!(which(&f, &a, &b, "before the reset"), 'A', "nothing changes before the reset");
    bootloader(&f).unwrap();
    assert_eq!(which(&f, &a, &b, "after the swap"), 'B');
    with_updater(&f, |u| {
        assert_eq!(u.boot_state(), BootState::Trial);
        assert_eq!(u.begin(b.len() as u32, 0), Err(DeviceError::Update(UpdateFault::TrialNotConfirmed)));
        u.confirm().unwrap();
        assert_eq!(u.boot_state(), BootState::Confirmed);
    });
    bootloader(&f).unwrap();
    assert_eq!(which(&f, &a, &b, "after the confirmed reset"), 'B');
    assert_eq!(with_updater(&f, |u| u.boot_state()), BootState::Confirmed);
}

#[test]
fn an_image_that_fails_its_self_test_is_reverted_at_the_next_reset() {
    let (a, b) = (app_image(5000, 1, [1, 0, 0]), app_image(7000, 2, [2, 0, 0]));
    let f = factory(&a);
    with_updater(&f, |u| send(u, &b)).unwrap();
    bootloader(&f).unwrap();
    assert_eq!(which(&f, &a, &b, "trial"), 'B');
    // B never confirms (its self-test failed, or it hung and the watchdog reset it).
    bootloader(&f).unwrap();
    assert_eq!(which(&f, &a, &b, "after the revert"), 'A');
    assert_eq!(with_updater(&f, |u| u.boot_state()), BootState::Reverted);
    bootloader(&f).unwrap();
    assert_eq!(which(&f, &a, &b, "after the next reset"), 'A', "a revert is final");
    // And the device takes an update again.
    assert_eq!(with_updater(&f, |u| send(u, &b)), Ok([2, 0, 0]));
}

#[test]
fn unsigned_tampered_foreign_and_wrong_target_images_are_refused_and_change_nothing() {
    let a = app_image(5000, 1, [1, 0, 0]);
    let b = app_image(6000, 2, [1, 1, 0]);
    let f = factory(&a);
    let trailer = image::FW_TRAILER_LEN;
    let unsigned = b[..b.len() - trailer].to_vec();
    let mut tampered = b.clone();
    tampered[100] ^= 1;
    let mut foreign = b[..b.len() - trailer].to_vec();
    foreign.truncate(6000);
    let foreign = image::sign(&foreign, Target::Qemu, [1, 1, 0], &[9u8; 32]);
    let board = image::sign(&b[..6000], Target::Board, [1, 1, 0], &DEV_SECRET);
    let mut raw = b[..6000].to_vec();
    raw[4..8].copy_from_slice(&0x0800_0001u32.to_le_bytes()); // reset handler in the bootloader
    let not_bootable = image::sign(&raw, Target::Qemu, [1, 1, 0], &DEV_SECRET);
    for (what, img, want) in [
        ("unsigned", &unsigned, DeviceError::FirmwareRejected(ImageFault::Unsigned)),
        ("tampered", &tampered, DeviceError::FirmwareRejected(ImageFault::Signature(SignatureFault::BadSignature))),
        ("foreign key", &foreign, DeviceError::FirmwareRejected(ImageFault::Signature(SignatureFault::UnknownKey))),
        ("board image", &board, DeviceError::FirmwareRejected(ImageFault::WrongTarget)),
        ("not bootable", &not_bootable, DeviceError::FirmwareRejected(ImageFault::NotBootable)),
    ] {
        let state_before = f.contents()[..STATE_LEN as usize].to_vec();
        assert_eq!(with_updater(&f, |u| send(u, img)), Err(want), "{what}");
        assert_eq!(f.contents()[..STATE_LEN as usize], state_before[..], "{what}: the boot state was touched");
        assert!(!want.to_string().is_empty());
        bootloader(&f).unwrap();
        assert_eq!(which(&f, &a, &b, what), 'A', "{what}: the running image must stay");
    }
    // Too large for the active region, and a corrupted transfer.
    let huge = app_image(ACTIVE_LEN as usize, 3, [9, 0, 0]);
    assert!(matches!(with_updater(&f, |u| send(u, &huge)), Err(DeviceError::Update(UpdateFault::TooLarge { .. }))));
    let crc_wrong = with_updater(&f, |u| {
        u.begin(b.len() as u32, CRC32.checksum(&b) ^ 1)?;
        let mut off = 0;
        while (off as usize) < b.len() {
            off = u.write(off, &b[off as usize..(off as usize + 512).min(b.len())])?;
        }
        u.commit()
    });
    assert!(matches!(crc_wrong, Err(DeviceError::CrcMismatch { .. })), "{crc_wrong:?}");
}

#[test]
fn a_transfer_resumes_where_the_link_dropped() {
    let (a, b) = (app_image(5000, 1, [1, 0, 0]), app_image(6000, 2, [1, 1, 0]));
    let f = factory(&a);
    with_updater(&f, |u| {
        let crc = CRC32.checksum(&b);
        assert_eq!(u.begin(b.len() as u32, crc), Ok(0));
        assert_eq!(u.write(0, &b[..512]), Ok(512));
        assert_eq!(u.write(1024, &b[1024..1536]), Err(DeviceError::OutOfOrder { expected: 512, got: 1024 }));
        // The link comes back: the same image resumes at 512.
        assert_eq!(u.begin(b.len() as u32, crc), Ok(512));
        assert_eq!(send(u, &b), Ok([1, 1, 0]));
        assert_eq!(u.begin(b.len() as u32, crc), Err(DeviceError::Update(UpdateFault::Pending)));
    });
}

/// The cut points of a run of `f` on `flash`: after every page erase and
/// every double word programmed (the STM32L4's program unit, atomic on the
/// chip), from the operations the run sent to the flash.
///
/// The NOR fake can also tear a double word byte by byte; embassy-boot's
/// progress words assume the program unit is atomic (a torn progress word
/// reads as not written and is then programmed again, which NOR refuses),
/// so those cuts are outside the model the chip gives. The calibration
/// store's own test (power_cut.rs) does cut inside double words.
fn cut_points(flash: &SimFlash, f: impl FnOnce(&SimFlash)) -> Vec<usize> {
    use brdf_meter::platform::host_sim::FlashOp;
    let before = flash.log().len();
    f(flash);
    let mut points = vec![0];
    let mut step = 0;
    for op in &flash.log()[before..] {
        match *op {
            FlashOp::Erase(_) => {
                step += 1;
                points.push(step);
            }
            FlashOp::Write(_, len) => {
                for _ in 0..len as usize / brdf_meter::shape::FLASH_WRITE {
                    step += brdf_meter::shape::FLASH_WRITE;
                    points.push(step);
                }
            }
        }
    }
    points
}

/// The whole update: transfer + commit, reset (swap), self-test passes
/// (confirm), reset. Each step stops at the first flash error (power lost).
fn whole_update(f: &SimFlash, b: &[u8]) {
    if with_updater(f, |u| send(u, b)).is_err() || bootloader(f).is_err() {
        return;
    }
    if with_updater(f, |u| u.confirm()).is_err() {
        return;
    }
    let _ = bootloader(f);
}

#[test]
fn a_power_cut_at_every_flash_step_of_an_update_leaves_a_whole_image_that_boots() {
    let (a, b) = (app_image(5000, 1, [1, 0, 0]), app_image(6000, 2, [1, 1, 0]));
    let base = factory(&a);
    let points = cut_points(&base.reboot(), |f| whole_update(f, &b));
    let total = *points.last().unwrap();
    let (mut saw_a, mut saw_b) = (0, 0);
    for &cut in &points {
        let f = base.reboot();
        f.cut_after(cut);
        whole_update(&f, &b);
        // Power back: the bootloader runs (and finishes a swap it was in).
        let f = f.reboot();
        bootloader(&f).unwrap_or_else(|e| panic!("cut at {cut}/{total}: the bootloader failed: {e:?}"));
        match which(&f, &a, &b, &format!("cut at step {cut} of {total}")) {
            'A' => saw_a += 1,
            _ => saw_b += 1,
        }
        // Whatever it holds runs: B on trial confirms, or A as it was; one
        // more reset keeps what is there (a trial not confirmed reverts to A).
        let state = with_updater(&f, |u| {
            let s = u.boot_state();
            u.confirm().unwrap();
            s
        });
        let held = which(&f, &a, &b, "before the next reset");
        bootloader(&f).unwrap();
        assert_eq!(which(&f, &a, &b, "after the next reset"), held, "cut at {cut}: state {state:?}");
    }
    println!(
        "{} cut points (every double word programmed and page erased, {total} flash steps): A whole {saw_a}, B whole {saw_b}",
        points.len()
    );
    assert!(saw_a > 0 && saw_b > 0, "the cuts must land both before and after the swap");
    assert_eq!(saw_a + saw_b, points.len());
}

#[test]
fn a_power_cut_at_every_flash_step_of_a_revert_leaves_the_previous_image_whole() {
    let (a, b) = (app_image(5000, 1, [1, 0, 0]), app_image(7000, 2, [2, 0, 0]));
    let base = factory(&a);
    with_updater(&base, |u| send(u, &b)).unwrap();
    bootloader(&base).unwrap();
    assert_eq!(which(&base, &a, &b, "trial"), 'B');
    // B does not confirm; the reset that reverts it loses power at each step.
    let points = cut_points(&base.reboot(), |f| {
        bootloader(f).unwrap();
    });
    let total = *points.last().unwrap();
    for &cut in &points {
        let f = base.reboot();
        f.cut_after(cut);
        let _ = bootloader(&f);
        let f = f.reboot();
        bootloader(&f).unwrap();
        assert_eq!(which(&f, &a, &b, &format!("revert cut at step {cut} of {total}")), 'A');
        // Reverted, or Confirmed when the cut fell between the state's erase
        // and its REVERT magic: either way A runs and is never swapped out.
        let state = with_updater(&f, |u| u.boot_state());
        assert!(matches!(state, BootState::Reverted | BootState::Confirmed), "cut at {cut}: {state:?}");
        bootloader(&f).unwrap();
        assert_eq!(which(&f, &a, &b, "the reset after"), 'A');
    }
    println!("{} cut points in the revert ({total} flash steps): A whole after each", points.len());
}

#[test]
fn an_update_never_touches_anything_but_the_update_and_state_partitions() {
    let (a, b) = (app_image(5000, 1, [1, 0, 0]), app_image(6000, 2, [1, 1, 0]));
    let f = factory(&a);
    let before = f.log().len();
    with_updater(&f, |u| send(u, &b)).unwrap();
    for op in &f.log()[before..] {
        let at = match op {
            brdf_meter::platform::host_sim::FlashOp::Erase(at)
            | brdf_meter::platform::host_sim::FlashOp::Write(at, _) => *at,
        };
        assert!(!(STATE_LEN..DFU_AT).contains(&at), "the transfer touched the active image at {at:#x}");
    }
}

/// Erases and double words programmed by the operations logged after `from`.
fn flash_work(flash: &SimFlash, from: usize) -> (usize, usize) {
    use brdf_meter::platform::host_sim::FlashOp;
    flash.log()[from..].iter().fold((0, 0), |(e, w), op| match *op {
        FlashOp::Erase(_) => (e + 1, w),
        FlashOp::Write(_, len) => (e, w + len as usize / brdf_meter::shape::FLASH_WRITE),
    })
}

/// The flash work of an update on the board's own partition sizes (80-page
/// active image, 82-page update partition, 2-page state), counted on the
/// NOR fake, priced with the STM32L475's datasheet times (page erase 22.02 ms,
/// double word 81.69 us, typical): the figures the firmware-updates guide's estimate of the
/// board's update time uses. embassy-boot swaps the whole active partition,
/// whatever the image's size.
#[test]
fn a_board_sized_update_s_flash_work() {
    use brdf_meter::shape::board::{ACTIVE_LEN, BOOT_STATE_LEN, DFU_LEN};
    let (active_at, dfu_at) = (BOOT_STATE_LEN, BOOT_STATE_LEN + ACTIVE_LEN);
    let flash_len = (dfu_at + DFU_LEN) as usize;
    let parts = |m| {
        (
            BlockingPartition::new(m, active_at, ACTIVE_LEN),
            BlockingPartition::new(m, dfu_at, DFU_LEN),
            BlockingPartition::new(m, 0, BOOT_STATE_LEN),
        )
    };
    // About today's board image (see the budget table in docs/guide/board.md).
    let (a, b) = (app_image(120 * 1024, 1, [1, 0, 0]), app_image(128 * 1024, 2, [2, 0, 0]));
    let mut mem = vec![0xFFu8; flash_len];
    mem[active_at as usize..active_at as usize + a.len()].copy_from_slice(&a);
    let f = SimFlash::with_contents(mem);
    let m: Mutex<NoopRawMutex, RefCell<SimFlash>> = Mutex::new(RefCell::new(f.clone()));
    let price = |(e, w): (usize, usize)| e as f64 * 22.02e-3 + w as f64 * 81.69e-6;

    let t0 = f.log().len();
    let (_, dfu, state) = parts(&m);
    let mut aligned = [0u8; 8];
    let mut u = Updater::new(dfu, state, &mut aligned, ACTIVE_LEN, Target::Qemu, dev_trusted());
    assert_eq!(send(&mut u, &b), Ok([2, 0, 0]));
    let transfer = flash_work(&f, t0);
    let t1 = f.log().len();
    let (active, dfu, state) = parts(&m);
    boot::prepare(active, dfu, state, &mut [0u8; boot::SWAP_BUFFER]).unwrap();
    let swap = flash_work(&f, t1);
    let act = f.contents()[active_at as usize..(active_at + ACTIVE_LEN) as usize].to_vec();
    assert_eq!(which_image(&act, &a, &b, "after the swap"), 'B');
    let t2 = f.log().len();
    let (active, dfu, state) = parts(&m);
    boot::prepare(active, dfu, state, &mut [0u8; boot::SWAP_BUFFER]).unwrap();
    let revert = flash_work(&f, t2);
    let act = f.contents()[active_at as usize..(active_at + ACTIVE_LEN) as usize].to_vec();
    assert_eq!(which_image(&act, &a, &b, "after the revert"), 'A');

    let pages = (ACTIVE_LEN / FLASH_PAGE as u32) as usize;
    let image_pages = b.len().div_ceil(FLASH_PAGE);
    // The transfer erases each page of the image once and programs it once.
    let state_pages = (BOOT_STATE_LEN / FLASH_PAGE as u32) as usize;
    assert_eq!(transfer.0, image_pages + state_pages, "the image's pages and the state the mark erases");
    assert!(transfer.1 >= b.len() / 8 && transfer.1 < b.len() / 8 + 8, "{transfer:?}");
    // The swap moves every page of the active partition both ways.
    assert!(swap.0 >= 2 * pages && swap.1 >= 2 * pages * FLASH_PAGE / 8, "{swap:?}");
    for (what, work) in [("transfer + commit", transfer), ("swap at the reset", swap), ("revert", revert)] {
        println!(
            "board-sized update, {what}: {} page erases, {} double words: {:.1} s of flash time (datasheet, typical)",
            work.0,
            work.1,
            price(work)
        );
    }
}
