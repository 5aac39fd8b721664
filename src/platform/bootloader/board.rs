//! The board bootloader's flash: embassy-stm32's blocking flash driver,
//! shared by embassy-boot's three partitions (ACTIVE, DFU, STATE) as memory.x
//! places them (`from_linkerfile_blocking` reads its symbols). The chip is
//! left at its reset clock (MSI 4 MHz): the bootloader only reads and
//! programs flash, and the application sets its own clocks.
use core::cell::RefCell;
use embassy_boot::{BootError, BootLoaderConfig, State};
use embassy_stm32::flash::{Blocking, Flash};
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;

/// Runs the bootloader's part (swap or revert when the state asks for it).
pub fn prepare() -> Result<State, BootError> {
    let p = embassy_stm32::init(embassy_stm32::Config::default());
    let flash: Mutex<NoopRawMutex, RefCell<Flash<'_, Blocking>>> =
        Mutex::new(RefCell::new(Flash::new_blocking(p.FLASH)));
    let config = BootLoaderConfig::from_linkerfile_blocking(&flash, &flash, &flash);
    let mut buf = [0u8; crate::firmware::boot::SWAP_BUFFER];
    crate::firmware::boot::prepare(config.active, config.dfu, config.state, &mut buf)
}
