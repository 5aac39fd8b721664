//! The client's side of firmware updates: the running firmware's state, a
//! signed image sent in chunks (resumed where the device says), reboot.
use super::Transport;
use super::client::{Client, LinkError};
use brdf_meter::protocol::{FirmwareInfo, Request, Response};

impl<T: Transport> Client<T> {
    /// The running firmware's version, boot state, self-test and keys.
    pub fn firmware_info(&mut self) -> Result<FirmwareInfo, LinkError> {
        match self.request(&Request::FirmwareInfo)? {
            Response::Firmware(f) => Ok(f),
            r => Err(LinkError::Unexpected(format!("{r:?} to FirmwareInfo"))),
        }
    }

    /// Sends the signed firmware `image` and commits it; returns the version
    /// the device verified. A device that already holds part of this image
    /// (an earlier call broke off) continues from where it stopped, so
    /// calling this again after a link failure resumes the transfer.
    /// `progress(done, total)` reports bytes the device has.
    pub fn update_firmware(
        &mut self,
        image: &[u8],
        mut progress: impl FnMut(usize, usize),
    ) -> Result<[u8; 3], LinkError> {
        let crc = brdf_meter::blob::CRC32.checksum(image);
        let (mut offset, max_chunk) = match self.request(&Request::UpdateBegin { len: image.len() as u32, crc })? {
            Response::UpdateReady { next_offset, max_chunk } => (next_offset as usize, max_chunk as usize),
            r => return Err(LinkError::Unexpected(format!("{r:?} to UpdateBegin"))),
        };
        if offset > image.len() {
            return Err(LinkError::Unexpected(format!("resume at {offset}, past the image's {} bytes", image.len())));
        }
        progress(offset, image.len());
        // Whole write units per chunk: the device writes each chunk as it comes.
        let step = (max_chunk / brdf_meter::shape::FLASH_WRITE * brdf_meter::shape::FLASH_WRITE).max(8);
        while offset < image.len() {
            let chunk = &image[offset..(offset + step).min(image.len())];
            match self.request(&Request::UpdateChunk { offset: offset as u32, data: chunk })? {
                Response::ChunkAck { next_offset } if next_offset as usize == offset + chunk.len() => {}
                r => return Err(LinkError::Unexpected(format!("{r:?} to the update chunk at {offset}"))),
            }
            offset += chunk.len();
            progress(offset, image.len());
        }
        match self.request(&Request::UpdateCommit)? {
            Response::UpdateCommitted { version } => Ok(version),
            r => Err(LinkError::Unexpected(format!("{r:?} to UpdateCommit"))),
        }
    }

    /// Asks the device to reset (into a committed update, on trial).
    pub fn reboot(&mut self) -> Result<(), LinkError> {
        match self.request(&Request::Reboot)? {
            Response::Rebooting => Ok(()),
            r => Err(LinkError::Unexpected(format!("{r:?} to Reboot"))),
        }
    }
}
