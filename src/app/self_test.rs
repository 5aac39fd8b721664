//! The self-test that decides whether a new firmware image stays: a trial
//! boot (the bootloader just swapped an update in) is confirmed only when
//! the calibration store was read, the sensor delivered a frame and a valid
//! request arrived over the link. Until then the image is not confirmed, and
//! a reset (the watchdog's, a power cut's, the user's) makes the bootloader
//! swap the previous image back.
use super::Shared;
use crate::hw::MappedFlash;
use crate::protocol::{BootState, SelfTest};

/// One part of the self-test.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Check {
    /// The sensor delivered a frame.
    Sensor,
    /// A valid request arrived over the link.
    Link,
}

impl<F: MappedFlash, const N: usize, const M: usize, const P: usize> Shared<F, N, M, P> {
    /// Records a passed part of the self-test; once all have passed, a
    /// trial image confirms itself with the bootloader.
    pub fn passed(&self, check: Check) {
        self.core.lock(|c| {
            let mut c = c.borrow_mut();
            let t: &mut SelfTest = &mut c.self_test;
            match check {
                Check::Sensor => t.sensor = true,
                Check::Link => t.link = true,
            }
            if c.self_test.passed()
                && let Some(fw) = c.firmware.as_mut()
                && fw.boot_state() == BootState::Trial
            {
                // A failed write leaves the image unconfirmed: the next
                // check tries again, and a reset reverts, which is safe.
                let _ = fw.confirm();
            }
        });
    }

    /// Whether this boot is a trial not yet confirmed (the acquisition task
    /// then reads one dark frame at start for the self-test).
    pub fn on_trial(&self) -> bool {
        self.core.lock(|c| c.borrow().firmware.as_ref().is_some_and(|f| f.boot_state() == BootState::Trial))
    }
}
