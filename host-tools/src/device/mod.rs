//! The device as the host sees it: the link (transports, client, QEMU
//! launcher), provisioning over USB and SWD, the board's memory map, the
//! host's reference computation of the device, a measurement as files,
//! its summary and its result with the uncertainty budget and its coverage
//! factor, the firmware budget, and the firmware's stack: each function's
//! frame and the high-water mark.
pub mod budget;
pub mod coverage_factor;
pub mod link;
pub mod measurement;
pub mod measurement_result;
pub mod measurement_summary;
pub mod memory_map;
pub mod provision;
pub mod qemu_demo;
pub mod reference;
pub mod stack_frames;
pub mod stack_use;
