//! Board firmware for the B-L475E-IOT01A (STM32L475VG). The hardware layer is
//! src/board/ (pin map and peripheral choices); everything above it is the
//! shared library's application, the same the QEMU build runs.
#![no_std]
#![no_main]

#[path = "../board/mod.rs"]
mod board;

use brdf_meter::hw::{Leds, LineSensor};
use defmt_rtt as _;
use embassy_executor::Spawner;
use panic_probe as _;

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    defmt::info!("board-fw {} starting", env!("CARGO_PKG_VERSION"));
    let (mut b, iwdg) = board::Board::init();
    spawner.spawn(board::usb::run(b.usb.device).expect("usb task spawns once"));
    board::watchdog::start(iwdg);
    let mut frame = [0u16; board::sensor::PIXELS];
    loop {
        b.leds.set(None, 0).await;
        let r = b.sensor.read_frame(1000, &mut frame).await;
        defmt::info!("dark frame: {}", r);
        board::watchdog::healthy();
    }
}
