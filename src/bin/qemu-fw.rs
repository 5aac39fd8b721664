//! The instrument's firmware for QEMU's `b-l475e-iot01a` machine: the shared
//! application (`brdf_meter::app`) on the QEMU board layer (src/qemu/). This
//! file wires them with concrete types and the build-time sizes.
//!
//! Run it with `scripts/qemu-run.sh` (or `cargo qemu-run`), which exposes
//! USART1 as a TCP serial on 127.0.0.1; talk to it with
//! `host-tools info --tcp 127.0.0.1:PORT`.
#![no_std]
#![no_main]

#[path = "../qemu/mod.rs"]
mod qemu;

use brdf_meter::acquire::AcqConfig;
use brdf_meter::app::{self, LineBuf, Shared};
use embassy_executor::Executor;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex as Cs;
use embassy_sync::zerocopy_channel::{Channel, Receiver, Sender};
use qemu::flash::{Memory, RamFlash};
use qemu::leds::GpioLeds;
use qemu::sensor::{Scene, SceneIn, SimSensor};
use qemu::usart::{UsartRx, UsartTx};
use static_cell::StaticCell;

/// Angle bins (patent profile).
const N: usize = 81;
/// LEDs, readings per point (patent profile).
const M: usize = 7;
/// Pixels of the simulated line sensor.
const P: usize = 32;
/// Frames per line: dark + one per LED.
const F: usize = M + 1;
/// Scene lines the simulated sensor holds.
const SCENE_LINES: usize = 4;
/// Zones whose matrices are copied to RAM (9 KiB); larger calibrations run in
/// place from the (RAM-backed) slot.
const RAM_ZONES: usize = 4;
/// Calibration slot length: 8 pages of 2 KiB, room for a blob of 6 zones.
const SLOT_LEN: usize = 16 * 1024;
/// Simulated 16-bit converter (the scene simulator's counts reach ~48k).
const FULL_SCALE: u16 = u16::MAX;
/// Acquisition timing: short, it is a simulation.
const ACQ: AcqConfig = AcqConfig { exposure_us: 200, settle_us: 100, intensity: u16::MAX };

type Flash = RamFlash<{ 2 * SLOT_LEN }>;
type QemuShared = Shared<Flash, N, M, P>;

static FLASH_MEM: Memory<{ 2 * SLOT_LEN }> = Memory::new();
static SCENE: Scene<P, F, SCENE_LINES> = Scene::new();
static SHARED: StaticCell<QemuShared> = StaticCell::new();
static RAM: StaticCell<[[[f32; M]; N]; RAM_ZONES]> = StaticCell::new();
static LINES: StaticCell<[LineBuf<M, P>; 2]> = StaticCell::new();
static CHANNEL: StaticCell<Channel<'static, Cs, LineBuf<M, P>>> = StaticCell::new();
static EXECUTOR: StaticCell<Executor> = StaticCell::new();

#[embassy_executor::task]
async fn transport(shared: &'static QemuShared, rx: UsartRx, tx: UsartTx) -> ! {
    app::transport(shared, rx, tx, SceneIn(&SCENE)).await
}

#[embassy_executor::task]
async fn acquisition(shared: &'static QemuShared, lines: Sender<'static, Cs, LineBuf<M, P>>) -> ! {
    let sensor = SimSensor { scene: &SCENE, full_scale: FULL_SCALE, lit: qemu::leds::lit::<M> };
    app::acquisition(shared, GpioLeds::<M>::new(), sensor, lines).await
}

#[embassy_executor::task]
async fn estimation(shared: &'static QemuShared, lines: Receiver<'static, Cs, LineBuf<M, P>>) -> ! {
    app::estimation(shared, lines).await
}

#[cortex_m_rt::entry]
fn main() -> ! {
    let cp = cortex_m::Peripherals::take().expect("taken once");
    qemu::init();
    qemu::time_driver::init(cp.SYST);
    let ram = RAM.init([[[0.0; M]; N]; RAM_ZONES]);
    let flash = RamFlash::take(&FLASH_MEM);
    let shared: &'static QemuShared =
        SHARED.init(Shared::new(flash, SLOT_LEN as u32, ram, ACQ, FULL_SCALE, true));
    let channel = CHANNEL.init(Channel::new(LINES.init([LineBuf::new(), LineBuf::new()])));
    let (lines_tx, lines_rx) = channel.split();
    let (rx, tx) = qemu::usart::init();
    EXECUTOR.init(Executor::new()).run(|spawner| {
        spawner.spawn(transport(shared, rx, tx).expect("spawned once"));
        spawner.spawn(acquisition(shared, lines_tx).expect("spawned once"));
        spawner.spawn(estimation(shared, lines_rx).expect("spawned once"));
    })
}
