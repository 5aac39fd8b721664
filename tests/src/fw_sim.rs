//! A simulated chip laid out as the board's flash map, with smaller images:
//! boot state, active image, update (DFU) partition, two recipe slots, two
//! calibration slots; one NOR fake shared by the calibration store and the
//! updater through the library's flash windows (`platform::flash_window`),
//! as the board shares its flash; embassy-boot's bootloader on it; and the
//! application booted on whatever image the bootloader left active.
use crate::sim::{SLOT_LEN, SimDevice};
use brdf_meter::firmware::boot;
use brdf_meter::firmware::image::{self, FW_TRAILER_LEN, Target};
use brdf_meter::firmware::update::Updater;
use brdf_meter::platform::flash_window::{SharedFlash, Window};
use brdf_meter::platform::host_sim::SimFlash;
use brdf_meter::shape::FLASH_PAGE;
use brdf_meter::test_blobs::DEV_SECRET;
use core::cell::RefCell;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex as Cs;

const PAGE: u32 = FLASH_PAGE as u32;
/// embassy-boot's state partition (two pages, as on the board).
pub const STATE: u32 = 0;
/// Its length.
pub const STATE_LEN: u32 = 2 * PAGE;
/// The active image.
pub const ACTIVE: u32 = STATE + STATE_LEN;
/// Its length (the board's is 80 pages).
pub const ACTIVE_LEN: u32 = 8 * PAGE;
/// The update partition: the active image's length and two pages, as on
/// the board.
pub const DFU: u32 = ACTIVE + ACTIVE_LEN;
/// Its length.
pub const DFU_LEN: u32 = ACTIVE_LEN + 2 * PAGE;
/// The two inspection-recipe slots, one page each here.
pub const RECIPES: u32 = DFU + DFU_LEN;
/// Their length.
pub const RECIPES_LEN: u32 = 2 * PAGE;
/// The two calibration slots (the simulated build's slot length).
pub const CAL: u32 = RECIPES + RECIPES_LEN;
/// Their length.
pub const CAL_LEN: u32 = 2 * SLOT_LEN;
/// The whole simulated chip.
pub const CHIP_LEN: u32 = CAL + CAL_LEN;

/// A window of the simulated chip.
pub type Part = Window<'static, Cs, SimFlash>;
/// The application with an updater, its store on a window of the chip.
pub type FwDevice = SimDevice<Part>;

/// A plausible application image of `len` bytes (vector table for the
/// active region, then bytes that tell `seed`'s image from another's),
/// signed with the development key for the simulated (QEMU) target.
pub fn app_image(len: usize, seed: u8, version: [u8; 3]) -> Vec<u8> {
    let mut raw: Vec<u8> = (0..len).map(|i| (i as u8).wrapping_mul(31).wrapping_add(seed)).collect();
    // The initial stack pointer: the top of the stack, below the statics.
    let sp = brdf_meter::shape::board::RAM_ORIGIN + brdf_meter::shape::board::STACK_LEN;
    raw[0..4].copy_from_slice(&sp.to_le_bytes());
    raw[4..8].copy_from_slice(&(brdf_meter::shape::board::ACTIVE + 0x401).to_le_bytes());
    image::sign(&raw, Target::Qemu, version, &DEV_SECRET)
}

/// A chip as the factory leaves it: image `active` in ACTIVE, `recipes` at
/// the start of the recipe slots, everything else erased.
pub fn factory(active: &[u8], recipes: &[u8]) -> SimFlash {
    let mut mem = vec![0xFFu8; CHIP_LEN as usize];
    mem[ACTIVE as usize..ACTIVE as usize + active.len()].copy_from_slice(active);
    mem[RECIPES as usize..RECIPES as usize + recipes.len()].copy_from_slice(recipes);
    SimFlash::with_contents(mem)
}

fn share(chip: &SimFlash) -> &'static SharedFlash<Cs, SimFlash> {
    // One per boot, as the firmware's static: leaked, the test is short.
    Box::leak(Box::new(Mutex::new(RefCell::new(chip.clone()))))
}

/// A reset's first half: the bootloader (`firmware::boot::prepare`, what
/// the bootloader binaries run) on the chip.
pub fn bootloader(chip: &SimFlash) -> Result<embassy_boot::State, embassy_boot::BootError> {
    let shared = share(chip);
    let part = |at, len| Window::new(shared, at, len);
    boot::prepare(part(ACTIVE, ACTIVE_LEN), part(DFU, DFU_LEN), part(STATE, STATE_LEN), &mut [0; boot::SWAP_BUFFER])
}

/// The version in the signed trailer of the image in ACTIVE: the image the
/// simulated device is running (a signed image keeps its trailer after the
/// swap, at the end of its bytes, followed by erased flash).
pub fn running_version(chip: &SimFlash) -> Option<[u8; 3]> {
    let active = &chip.contents()[ACTIVE as usize..(ACTIVE + ACTIVE_LEN) as usize];
    // The first trailer that signs the bytes before it as its image (pages
    // after the image may still hold an older, longer image's end).
    (0..=active.len() - FW_TRAILER_LEN).step_by(8).find_map(|at| {
        let t: &[u8; FW_TRAILER_LEN] = active[at..at + FW_TRAILER_LEN].try_into().unwrap();
        image::decode_trailer(t, (at + FW_TRAILER_LEN) as u32).ok().map(|(m, _)| m.version)
    })
}

/// A reset's second half: the application starts on the image the
/// bootloader left active, its calibration store on the calibration slots
/// and its updater on DFU and STATE, all windows of the one chip.
pub fn boot(chip: &SimFlash) -> FwDevice {
    let version = running_version(chip).expect("the active image carries its signed trailer");
    let shared = share(chip);
    let part = |at, len| Window::new(shared, at, len);
    let aligned: &'static mut [u8] = Box::leak(Box::new([0u8; brdf_meter::shape::FLASH_WRITE]));
    let updater = Box::leak(Box::new(Updater::new(
        part(DFU, DFU_LEN),
        part(STATE, STATE_LEN),
        aligned,
        ACTIVE_LEN,
        Target::Qemu,
        brdf_meter::signed::TRUSTED_KEYS,
    )));
    SimDevice::boot_on(part(CAL, CAL_LEN), chip.clone(), 4, |dev| {
        dev.set_firmware(updater);
        // One build runs as image A and image B of an update.
        dev.version = version;
    })
}

/// The bytes of the regions an update must never touch: the recipe slots
/// and the calibration slots.
pub fn slots(chip: &SimFlash) -> Vec<u8> {
    chip.contents()[RECIPES as usize..CHIP_LEN as usize].to_vec()
}

/// Which image the simulated chip's active region holds: see [`which_image`].
pub fn which(chip: &SimFlash, a: &[u8], b: &[u8], context: &str) -> char {
    which_image(&chip.contents()[ACTIVE as usize..(ACTIVE + ACTIVE_LEN) as usize], a, b, context)
}

/// Which image an active region `act` holds, whole: 'A', 'B', or a panic.
pub fn which_image(act: &[u8], a: &[u8], b: &[u8], context: &str) -> char {
    if act[..a.len()] == *a {
        'A'
    } else if act[..b.len()] == *b {
        'B'
    } else {
        panic!("{context}: the active region holds neither image whole")
    }
}
