//! Firmware update requests, from the link (`UpdateBegin`/`Chunk`/`Commit`,
//! see `handler`) and from USB DFU (`usb_dfu`): both reach the platform's
//! updater through here, so both are refused while measuring and both leave
//! their refusal where `FirmwareInfo` reports it.
use super::{Core, Shared};
use crate::firmware::update::FirmwareSlot;
use crate::hw::MappedFlash;
use crate::protocol::{DeviceError, UpdateFault};

impl<F, const N: usize, const M: usize, const P: usize> Core<F, N, M, P> {
    /// Runs `step` on the updater (or says there is none), recording a
    /// refusal for `FirmwareInfo` and clearing it once an update commits.
    pub(super) fn update<R>(
        &mut self,
        step: impl FnOnce(&mut (dyn FirmwareSlot + Send)) -> Result<R, DeviceError>,
    ) -> Result<R, DeviceError> {
        let r = match self.firmware.as_mut() {
            Some(fw) => step(&mut **fw),
            None => Err(DeviceError::Update(UpdateFault::Unsupported)),
        };
        match &r {
            Err(e) => self.update_refused = Some(*e),
            Ok(_) if self.firmware.as_ref().is_some_and(|f| f.pending().is_some()) => self.update_refused = None,
            Ok(_) => {}
        }
        r
    }
}

impl<F: MappedFlash, const N: usize, const M: usize, const P: usize> Shared<F, N, M, P> {
    /// One step of an update from outside the request handler (USB DFU's
    /// control requests): as the link's, refused while a measurement runs
    /// when it `starts` or commits an update, and counted when refused.
    pub fn firmware_update<R>(
        &self,
        starts: bool,
        step: impl FnOnce(&mut (dyn FirmwareSlot + Send)) -> Result<R, DeviceError>,
    ) -> Result<R, DeviceError> {
        self.core.lock(|c| {
            let c = &mut *c.borrow_mut();
            let r = if starts && c.status.measuring { Err(DeviceError::Busy) } else { c.update(step) };
            if r.is_err() {
                c.status.refused = c.status.refused.wrapping_add(1);
            }
            r
        })
    }
}
