//! The host simulation's platform (feature `sim`, and this crate's own unit
//! tests): an in-memory NOR flash that can lose power at any byte, an
//! in-memory transport, simulated LEDs and line sensor. tests/ runs the
//! application on them. Nothing here is built into firmware.
mod flash;
#[cfg(feature = "app")]
mod io;
#[cfg(feature = "app")]
mod reject;
#[cfg(feature = "app")]
mod sensor;

pub use crate::platform::nor_fake::{FlashOp, NorFault};
pub use flash::{PowerCutMemory, SimFlash};
#[cfg(feature = "app")]
pub use io::{Pipe, PipeEnd, pipe};
#[cfg(feature = "app")]
pub use reject::SimReject;
#[cfg(feature = "app")]
pub use sensor::{SIM_LINES, SimFrames, SimLeds, SimSensor, sim_optics};
