//! USB DFU 1.1 download into the update partition, beside the CDC-ACM link on
//! the same USB device: standard `dfu-util -D image.fwu` sends a signed image
//! (`host-tools sign-firmware`) and the device handles it exactly as an
//! update over the link: blocks into the DFU partition through the same
//! updater, and on the host's final empty block the same check (trailer,
//! target, vector table, Ed25519 signature by a trusted key) before the SWAP
//! mark is written; then it resets into the new image, on trial.
//!
//! The protocol's state machine is embassy-usb's (`class::dfu::dfu_mode`,
//! which embassy-usb-dfu also wraps); this file is only its `Handler`.
//! embassy-usb-dfu's own handler is not used because it checks embassy-boot's
//! bare 64-byte signature with one key, not this product's signed image.
//! The interface is in DFU mode (not the runtime interface that asks a USB
//! bootloader to take over): the application itself receives the image, so
//! the bootloader stays without a USB stack and within its 24 KiB.
//!
//! A refused image ends the download in DFU's error state with the closest
//! DFU status (`errTARGET` for another machine's image, `errFILE` for an
//! unsigned, tampered or foreign-key one, `errADDRESS` for one too large),
//! which dfu-util prints; the device's own reason is in `host-tools info`
//! (`FirmwareInfo::refused`). The running firmware keeps running.
use super::Shared;
use crate::firmware::image::ImageFault;
use crate::hw::MappedFlash;
use crate::protocol::{DeviceError, UpdateFault};
use embassy_usb::class::dfu::consts::{DfuAttributes, Status};
use embassy_usb::class::dfu::dfu_mode::{DfuState, Handler};

/// Largest DFU block (`wTransferSize`): the USB device's control buffer
/// must hold one. A multiple of the flash's program unit, so every block
/// but the image's last (itself a multiple of 8) is written as it comes.
pub const BLOCK: usize = 256;
const _: () = assert!(BLOCK.is_multiple_of(crate::shape::FLASH_WRITE) && BLOCK <= crate::protocol::MAX_CHUNK);

/// What the DFU interface can do: download (no upload: the active image is
/// not handed out), and reset by itself once the image is marked.
pub const ATTRIBUTES: DfuAttributes = DfuAttributes::CAN_DOWNLOAD.union(DfuAttributes::WILL_DETACH);

/// The DFU handler: the application's updater behind its shared state.
pub struct UsbDfu<'a, F, const N: usize, const M: usize, const P: usize> {
    shared: &'a Shared<F, N, M, P>,
}

/// The DFU interface's state, for `embassy_usb::class::dfu::dfu_mode::usb_dfu`.
pub fn state<F: MappedFlash, const N: usize, const M: usize, const P: usize>(
    shared: &Shared<F, N, M, P>,
) -> DfuState<UsbDfu<'_, F, N, M, P>> {
    DfuState::new(UsbDfu { shared }, ATTRIBUTES)
}

/// The DFU status closest to why the device refused.
pub fn status(e: DeviceError) -> Status {
    match e {
        DeviceError::FirmwareRejected(ImageFault::WrongTarget) => Status::ErrTarget,
        DeviceError::FirmwareRejected(_) | DeviceError::CrcMismatch { .. } => Status::ErrFile,
        DeviceError::Update(UpdateFault::TooLarge { .. }) | DeviceError::ChunkTooLarge { .. } => Status::ErrAddress,
        DeviceError::Storage => Status::ErrWrite,
        DeviceError::Incomplete { .. } => Status::ErrNotDone,
        // Busy measuring, on trial, an update already pending, no updater:
        // the reason is the device's own (`host-tools info`).
        _ => Status::ErrVendor,
    }
}

impl<F: MappedFlash, const N: usize, const M: usize, const P: usize> Handler for UsbDfu<'_, F, N, M, P> {
    fn start(&mut self) -> Result<(), Status> {
        self.shared.firmware_update(true, |fw| fw.begin_download()).map_err(status)
    }

    fn write(&mut self, data: &[u8]) -> Result<(), Status> {
        self.shared
            .firmware_update(false, |fw| {
                let at = fw.receiving().ok_or(DeviceError::Update(UpdateFault::NotUpdating))?;
                fw.write(at, data)
            })
            .map(|_| ())
            .map_err(status)
    }

    fn finish(&mut self) -> Result<(), Status> {
        self.shared.firmware_update(true, |fw| fw.commit()).map(|_| ()).map_err(status)
    }

    fn system_reset(&mut self) {
        // The platform's reboot task resets once the last status has left.
        self.shared.reboot.signal(());
    }
}
