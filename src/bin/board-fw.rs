//! Board firmware for the B-L475E-IOT01A (STM32L475VG).
//!
//! The hardware layer is `brdf_meter::platform::board` (pin map, peripheral choices, drivers
//! for the library's traits). Everything above it is the shared library's
//! application (`brdf_meter::app`): the same transport, acquisition and
//! estimation tasks the QEMU firmware and the host simulation run. This file
//! only wires them to the board: it is the one place with concrete types.
#![no_std]
#![no_main]

use brdf_meter::acquire::AcqConfig;
use brdf_meter::app::{self, LineBuf, Shared};
use brdf_meter::firmware::image::Target;

/// The machine this image is for, as a named symbol of its ELF
/// ([`Target::declared`]).
#[unsafe(no_mangle)]
pub static BRDF_FIRMWARE_TARGET: u32 = Target::Board.code();
use brdf_meter::hw::NoFrameInput;
use brdf_meter::platform::board;
use brdf_meter::platform::watchdog_health::Health;
use brdf_meter::shape;
use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex as Cs;
use embassy_sync::zerocopy_channel::{Channel, Receiver, Sender};
use embassy_time::{Instant, Timer};
use embedded_storage::nor_flash::ReadNorFlash as _;
use nalgebra::SMatrix;
use panic_probe as _;
use static_cell::StaticCell;

use board::flash::{CalFlash, Part};
use board::leds::PwmLeds;
use board::sensor::Tsl1401;
use board::usb::{UsbRx, UsbTx};

const N: usize = shape::BINS;
const M: usize = shape::LEDS;
const P: usize = shape::board::PIXELS;
const RAM_ZONES: usize = shape::board::RAM_ZONES;

/// Acquisition settings: integration per frame and LED settling before it
/// (written down in `platform::timing`, where the host's line-rate
/// budget reads them too).
const ACQ: AcqConfig = brdf_meter::platform::timing::ACQUISITION;

type BoardShared = Shared<CalFlash, N, M, P>;
type Updater = brdf_meter::firmware::update::Updater<'static, Part, Part>;
type Dfu = embassy_usb::class::dfu::dfu_mode::DfuState<app::usb_dfu::UsbDfu<'static, CalFlash, N, M, P>>;

static SHARED: StaticCell<BoardShared> = StaticCell::new();

#[embassy_executor::task]
async fn transport(shared: &'static BoardShared, rx: UsbRx, tx: UsbTx) -> ! {
    app::transport(shared, rx, tx, NoFrameInput).await
}

#[embassy_executor::task]
async fn acquisition(
    shared: &'static BoardShared,
    leds: PwmLeds,
    sensor: Tsl1401,
    lines: Sender<'static, Cs, LineBuf<M, P>>,
) -> ! {
    app::acquisition(shared, leds, sensor, lines).await
}

/// Resets the chip when asked (a `Reboot` request, the end of a USB DFU
/// download): the bootloader then swaps in a committed update.
#[embassy_executor::task]
async fn reboot(shared: &'static BoardShared) -> ! {
    app::reboot(shared, || cortex_m::peripheral::SCB::sys_reset()).await
}

/// Drives the inspection's reject output (PA4) and reports each pulse.
#[embassy_executor::task]
async fn reject(shared: &'static BoardShared, pin: board::RejectPin) -> ! {
    app::reject_output(shared, pin).await
}

#[embassy_executor::task]
async fn estimation(shared: &'static BoardShared, lines: Receiver<'static, Cs, LineBuf<M, P>>) -> ! {
    app::estimation(shared, lines).await
}

/// Feeds the watchdog while the application is healthy (see
/// `board::watchdog`), and shows it on LED2.
#[embassy_executor::task]
async fn supervisor(shared: &'static BoardShared, mut led: embassy_stm32::gpio::Output<'static>) -> ! {
    let mut health = Health::default();
    loop {
        let st = shared.status();
        if health.observe(Instant::now().as_millis(), shared.measuring_lines(), st.lines_total) {
            board::watchdog::healthy();
            led.toggle();
        } else {
            defmt::error!("measurement stalled at line {}: the watchdog will reset", st.lines_total);
            led.set_low();
        }
        Timer::after_millis(250).await;
    }
}

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    defmt::info!("board-fw {} starting", env!("CARGO_PKG_VERSION"));
    let (b, iwdg) = board::Board::init();
    // From here a hang or a panic (panic-probe logs it, then faults) ends in
    // a watchdog reset: the supervisor below is the only thing that feeds it.
    board::watchdog::start(iwdg);

    static RAM: StaticCell<[SMatrix<f32, M, N>; RAM_ZONES]> = StaticCell::new();
    let ram = brdf_meter::estimate::zeroed_in_place(RAM.uninit());
    // One flash, two users: the calibration store and embassy-boot's
    // updater, each in its own window of it.
    let cal = board::flash::calibration(b.flash);
    let slot_len = cal.capacity() as u32 / 2;
    let (dfu, state) = board::flash::update_partitions(b.flash);
    static ALIGNED: StaticCell<embassy_boot::AlignedBuffer<{ shape::FLASH_WRITE }>> = StaticCell::new();
    static UPDATER: StaticCell<Updater> = StaticCell::new();
    let updater = UPDATER.init(Updater::new(
        dfu,
        state,
        &mut ALIGNED.init(embassy_boot::AlignedBuffer([0; shape::FLASH_WRITE])).0,
        shape::board::ACTIVE_LEN,
        Target::declared(&BRDF_FIRMWARE_TARGET),
        brdf_meter::signed::TRUSTED_KEYS,
    ));
    let shared: &'static BoardShared =
        Shared::init_in_place(SHARED.uninit(), cal, slot_len, ram, ACQ, board::sensor::FULL_SCALE, false);
    shared.set_firmware(updater);
    // The inspection recipes: a third window of the same flash.
    static RECIPES: StaticCell<brdf_meter::inspect::RecipeStore<Part>> = StaticCell::new();
    let recipe_flash = board::flash::recipes(b.flash);
    let recipe_slot = recipe_flash.capacity() as u32 / 2;
    shared.set_recipes(RECIPES.init(shared.open_recipes(recipe_flash, recipe_slot)));
    let fw = shared.firmware_info();
    defmt::info!("firmware {}: boot state {}", fw.version, fw.boot);
    match shared.status().calibration {
        Some(c) => defmt::info!(
            "calibration: slot {}, sequence {}, {} zones, matrices in {}",
            c.slot,
            c.sequence,
            c.zones,
            if c.in_ram { "RAM" } else { "flash (in place)" }
        ),
        None => defmt::warn!("no valid calibration for this build (n = {}, m = {}, P = {}): provision one", N, M, P),
    }

    static LINES: StaticCell<[LineBuf<M, P>; 2]> = StaticCell::new();
    static CHANNEL: StaticCell<Channel<'static, Cs, LineBuf<M, P>>> = StaticCell::new();
    let channel = CHANNEL.init(Channel::new(LineBuf::init_in_place(LINES.uninit())));
    let (lines_tx, lines_rx) = channel.split();

    // The USB device, now that the application that serves its DFU
    // interface exists.
    static DFU: StaticCell<Dfu> = StaticCell::new();
    let usb = board::usb::Usb::new(b.usb, DFU.init(app::usb_dfu::state(shared)));

    spawner.spawn(board::usb::run(usb.device).expect("spawned once"));
    spawner.spawn(transport(shared, usb.rx, usb.tx).expect("spawned once"));
    spawner.spawn(reboot(shared).expect("spawned once"));
    spawner.spawn(acquisition(shared, b.leds, b.sensor, lines_tx).expect("spawned once"));
    spawner.spawn(estimation(shared, lines_rx).expect("spawned once"));
    spawner.spawn(supervisor(shared, b.status_led).expect("spawned once"));
    spawner.spawn(reject(shared, b.reject).expect("spawned once"));
}
