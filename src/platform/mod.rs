//! The platforms the application runs on, each behind its feature; the
//! firmware binaries (src/bin/) wire one of them to `crate::app`.
//!
//! - `board` (feature `board`, bare-metal target only): the B-L475E-IOT01A
//!   board layer on embassy-stm32.
//! - `qemu` (feature `qemu`, bare-metal target only): the board layer for
//!   QEMU's b-l475e-iot01a machine, written against the registers QEMU emulates.
//! - `bootloader` (feature `bootloader-board` / `bootloader-qemu`, bare-metal
//!   target only): the bootloader's flash and the jump into the active image.
//! - [`host_sim`] (feature `sim`): the host simulation's fakes (power-cut
//!   flash, in-memory link, simulated optics), used by tests/.
//! - [`nor_fake`]: the NOR flash rules both flash fakes share.
//! - `watchdog_health`: the board's watchdog rule, pure logic tested on the host.
//! - [`timing`]: the board's acquisition settings and sensor timing
//!   (not gated: the host's line-rate budget derives from them).
#[cfg(all(feature = "board", target_os = "none"))]
pub mod board;
#[cfg(all(feature = "bootloader", target_os = "none"))]
pub mod bootloader;
#[cfg(feature = "app")]
pub mod flash_window;
#[cfg(any(test, feature = "sim"))]
pub mod host_sim;
#[cfg(any(test, feature = "sim", all(feature = "qemu", target_os = "none")))]
pub mod nor_fake;
#[cfg(all(feature = "qemu", target_os = "none"))]
pub mod qemu;
pub mod timing;
#[cfg(any(test, feature = "sim", all(feature = "board", target_os = "none")))]
pub mod watchdog_health;
