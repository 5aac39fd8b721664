//! The instrument's firmware for QEMU's `b-l475e-iot01a` machine: the shared
//! application (`brdf_meter::app`) on the QEMU platform layer
//! (`brdf_meter::platform::qemu`). This file wires them with concrete types
//! and the build-time sizes (`brdf_meter::shape`).
//!
//! Run it with `scripts/qemu-run.sh` (or `cargo qemu-run`), which exposes
//! USART1 as a TCP serial on 127.0.0.1; talk to it with
//! `host-tools info --tcp 127.0.0.1:PORT`.
#![no_std]
#![no_main]

use brdf_meter::acquire::AcqConfig;
use brdf_meter::app::{self, LineBuf, Shared};
use brdf_meter::platform::qemu;
use brdf_meter::shape;

/// The machine this image is for, as a named symbol of its ELF
/// (`Target::declared`).
#[unsafe(no_mangle)]
pub static BRDF_FIRMWARE_TARGET: u32 = brdf_meter::firmware::image::Target::Qemu.code();
use core::fmt::Write as _;
use embassy_executor::Executor;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex as Cs;
use embassy_sync::zerocopy_channel::{Channel, Receiver, Sender};
use nalgebra::SMatrix;
use qemu::flash::{Memory, RamFlash};
use qemu::leds::GpioLeds;
use qemu::reject::GpioReject;
use qemu::sensor::{FrameSensor, Frames, FramesIn};
use qemu::usart::{UsartRx, UsartTx};
use static_cell::StaticCell;

const N: usize = shape::BINS;
const M: usize = shape::LEDS;
const P: usize = shape::qemu::PIXELS;
const F: usize = shape::FRAMES_PER_LINE;
const FRAME_LINES: usize = shape::qemu::FRAME_LINES;
const RAM_ZONES: usize = shape::qemu::RAM_ZONES;
const SLOT_LEN: usize = shape::qemu::SLOT_LEN as usize;
const RECIPE_SLOT_LEN: usize = shape::qemu::RECIPE_SLOT_LEN as usize;
/// The simulated converter's full scale: the board's (`shape::qemu`).
const FULL_SCALE: u16 = shape::qemu::FULL_SCALE;
/// Acquisition timing: short, it is a simulation (`platform::timing`).
const ACQ: AcqConfig = brdf_meter::platform::timing::QEMU_ACQUISITION;

/// The RAM update partition and the boot state beside it (see below).
const DFU_LEN: usize = shape::qemu::DFU_LEN as usize;
const STATE_LEN: usize = shape::board::BOOT_STATE_LEN as usize;

type Flash = RamFlash<{ 2 * SLOT_LEN }>;
type RecipeFlash = RamFlash<{ 2 * RECIPE_SLOT_LEN }>;
type QemuShared = Shared<Flash, N, M, P>;
type Updater = brdf_meter::firmware::update::Updater<'static, RamFlash<DFU_LEN>, RamFlash<STATE_LEN>>;

static FLASH_MEM: Memory<{ 2 * SLOT_LEN }> = Memory::new();
/// The inspection recipe slots, in RAM as the calibration's (in SRAM2,
/// beside the update partition: SRAM1 keeps its room for the stack).
#[unsafe(link_section = ".sram2")]
static RECIPE_MEM: Memory<{ 2 * RECIPE_SLOT_LEN }> = Memory::new();
static RECIPES: StaticCell<brdf_meter::inspect::RecipeStore<RecipeFlash>> = StaticCell::new();
/// The update partition, in SRAM2 (the RAM the rest leaves): updates are
/// received, verified and marked as on the board, but the bootloader reads
/// its state from the read-only flash, so no swap follows.
#[unsafe(link_section = ".sram2")]
static DFU_MEM: Memory<DFU_LEN> = Memory::new();
static STATE_MEM: Memory<STATE_LEN> = Memory::new();
static UPDATER: StaticCell<Updater> = StaticCell::new();
static ALIGNED: StaticCell<embassy_boot::AlignedBuffer<{ shape::FLASH_WRITE }>> = StaticCell::new();
static FRAMES: Frames<P, F, FRAME_LINES> = Frames::new();
static SHARED: StaticCell<QemuShared> = StaticCell::new();
static RAM: StaticCell<[SMatrix<f32, M, N>; RAM_ZONES]> = StaticCell::new();
static LINES: StaticCell<[LineBuf<M, P>; 2]> = StaticCell::new();
static CHANNEL: StaticCell<Channel<'static, Cs, LineBuf<M, P>>> = StaticCell::new();
static EXECUTOR: StaticCell<Executor> = StaticCell::new();

#[embassy_executor::task]
async fn transport(shared: &'static QemuShared, rx: UsartRx, tx: UsartTx) -> ! {
    app::transport(shared, rx, tx, FramesIn(&FRAMES)).await
}

#[embassy_executor::task]
async fn acquisition(shared: &'static QemuShared, lines: Sender<'static, Cs, LineBuf<M, P>>) -> ! {
    let sensor = FrameSensor { frames: &FRAMES, full_scale: FULL_SCALE, lit: qemu::leds::lit::<M>, acq: ACQ };
    app::acquisition(shared, GpioLeds::<M>::configure(), sensor, lines).await
}

#[embassy_executor::task]
async fn estimation(shared: &'static QemuShared, lines: Receiver<'static, Cs, LineBuf<M, P>>) -> ! {
    app::estimation(shared, lines).await
}

/// Drives the inspection's reject output (PA4) and reports each pulse.
#[embassy_executor::task]
async fn reject(shared: &'static QemuShared) -> ! {
    app::reject_output(shared, GpioReject::configure()).await
}

/// Resets the machine on a `Reboot` request (through the bootloader again).
#[embassy_executor::task]
async fn reboot(shared: &'static QemuShared) -> ! {
    app::reboot(shared, || cortex_m::peripheral::SCB::sys_reset()).await
}

#[cortex_m_rt::entry]
fn main() -> ! {
    let cp = cortex_m::Peripherals::take().expect("taken once");
    qemu::init();
    qemu::time_driver::init(cp.SYST);
    let ram = brdf_meter::estimate::zeroed_in_place(RAM.uninit());
    let flash = qemu::flash::take(&FLASH_MEM);
    let updater = UPDATER.init(Updater::new(
        qemu::flash::take(&DFU_MEM),
        qemu::flash::take(&STATE_MEM),
        &mut ALIGNED.init(embassy_boot::AlignedBuffer([0; shape::FLASH_WRITE])).0,
        DFU_LEN as u32,
        brdf_meter::firmware::image::Target::declared(&BRDF_FIRMWARE_TARGET),
        brdf_meter::signed::TRUSTED_KEYS,
    ));
    let shared: &'static QemuShared =
        Shared::init_in_place(SHARED.uninit(), flash, SLOT_LEN as u32, ram, ACQ, FULL_SCALE, true);
    shared.set_firmware(updater);
    shared.set_recipes(RECIPES.init(shared.open_recipes(qemu::flash::take(&RECIPE_MEM), RECIPE_SLOT_LEN as u32)));
    let channel = CHANNEL.init(Channel::new(LineBuf::init_in_place(LINES.uninit())));
    let (lines_tx, lines_rx) = channel.split();
    let (rx, tx) = qemu::usart::init();
    EXECUTOR.init(Executor::new()).run(|spawner| {
        spawner.spawn(transport(shared, rx, tx).expect("spawned once"));
        spawner.spawn(acquisition(shared, lines_tx).expect("spawned once"));
        spawner.spawn(estimation(shared, lines_rx).expect("spawned once"));
        spawner.spawn(reboot(shared).expect("spawned once"));
        spawner.spawn(reject(shared).expect("spawned once"));
    })
}

/// A panic prints its message on QEMU's stderr and ends QEMU with a failure
/// exit code (semihosting), so a firmware panic fails the test that ran it
/// instead of hanging it.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m::interrupt::disable();
    if let Ok(mut err) = cortex_m_semihosting::hio::hstderr() {
        let _ = writeln!(err, "qemu-fw panic: {info}");
    }
    cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
