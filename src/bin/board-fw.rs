//! Board firmware for the B-L475E-IOT01A (STM32L475VG). See src/board/.
#![no_std]
#![no_main]

use defmt_rtt as _;
use panic_probe as _;

#[embassy_executor::main]
async fn main(_spawner: embassy_executor::Spawner) {
    let _p = embassy_stm32::init(Default::default());
    defmt::info!("board-fw up");
    loop {
        embassy_time::Timer::after_secs(1).await;
    }
}
