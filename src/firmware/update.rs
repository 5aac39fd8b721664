//! Receiving an update over the instrument's link into the update partition
//! (DFU), on embassy-boot's own `BlockingFirmwareUpdater`, and the boot state
//! the bootloader left.
//!
//! An update is a session like a calibration's provisioning: `begin` (length
//! and CRC of the signed image), chunks in order, `commit`. The chunks go
//! straight to the DFU partition (each page erased as the first chunk reaches
//! it); nothing else is written until `commit` has checked, from the bytes in
//! flash, the CRC, the trailer, the target, the vector table and the
//! signature. Only then does it mark the update for the bootloader (the
//! state partition's SWAP magic): the one write that makes the next reset
//! swap. So a refused, interrupted or abandoned update changes nothing the
//! running firmware or the bootloader uses, and the calibration and recipe
//! slots are never in reach (the updater holds only DFU and STATE).
//!
//! Resuming: a `begin` with the length and CRC of the session in progress
//! continues it where it stopped (a link that dropped); a device reset
//! forgets the session and the host starts again from 0.
//!
//! USB DFU (`dfu-util -D`) sends no length or CRC first: its session is
//! opened with [`FirmwareSlot::begin_download`], takes blocks until the host
//! says it is done, and its commit checks the bytes received so far the same
//! way (trailer, target, vector table, signature; the USB transfer's own CRC
//! stands in for the CRC the link declares).
use super::image::{self, FW_TRAILER_LEN, ImageFault, ImageHasher, Target};
use crate::blob::CRC32;
use crate::protocol::{BootState, DeviceError, MAX_CHUNK, UpdateFault};
use crate::signed::PublicKeyBytes;
use embassy_boot::{BlockingFirmwareUpdater, FirmwareUpdaterConfig, FirmwareUpdaterError, State};
use embedded_storage::nor_flash::NorFlash;

/// What the application asks of the firmware updater; object safe, so the
/// application holds any platform's updater behind one reference.
pub trait FirmwareSlot {
    /// The boot state (as found at boot, then as changed by this firmware).
    fn boot_state(&self) -> BootState;
    /// Largest signed image the active region takes.
    fn max_image(&self) -> u32;
    /// Bytes received of the session in progress.
    fn receiving(&self) -> Option<u32>;
    /// The version of an update committed and waiting for a reset.
    fn pending(&self) -> Option<[u8; 3]>;
    /// Starts (or resumes) an update of `len` bytes with CRC-32 `crc`;
    /// returns the offset of the next chunk to send.
    fn begin(&mut self, len: u32, crc: u32) -> Result<u32, DeviceError>;
    /// Starts an update whose length is known only at its end (USB DFU);
    /// blocks follow in order from offset 0, and [`Self::commit`] takes the
    /// bytes received as the image.
    fn begin_download(&mut self) -> Result<(), DeviceError>;
    /// Writes the chunk at `offset`; returns the next offset.
    fn write(&mut self, offset: u32, data: &[u8]) -> Result<u32, DeviceError>;
    /// Checks the whole image and marks it for the bootloader; returns its
    /// version.
    fn commit(&mut self) -> Result<[u8; 3], DeviceError>;
    /// Abandons the session (the update partition is left as it is).
    fn abort(&mut self) -> Result<(), DeviceError>;
    /// Confirms the running image after its self-test: the bootloader will
    /// not revert it. Does nothing unless this boot is a trial.
    fn confirm(&mut self) -> Result<(), DeviceError>;
}

#[derive(Clone, Copy, Debug)]
struct Session {
    /// The declared length, or for a download of unknown length the most
    /// it may grow to.
    len: u32,
    /// The declared CRC; `None` for a download (USB DFU) of unknown length.
    crc: Option<u32>,
    received: u32,
}

/// The updater of one platform: embassy-boot's updater over the DFU and
/// STATE partitions, this build's target and trusted keys.
pub struct Updater<'d, DFU: NorFlash, STATE: NorFlash> {
    inner: BlockingFirmwareUpdater<'d, DFU, STATE>,
    max_image: u32,
    target: Target,
    trusted: &'static [PublicKeyBytes],
    boot: BootState,
    session: Option<Session>,
    pending: Option<[u8; 3]>,
}

fn flash_err(e: FirmwareUpdaterError) -> DeviceError {
    match e {
        FirmwareUpdaterError::BadState => DeviceError::Update(UpdateFault::TrialNotConfirmed),
        FirmwareUpdaterError::Flash(_) | FirmwareUpdaterError::Signature(_) => DeviceError::Storage,
    }
}

fn boot_state(s: State) -> BootState {
    match s {
        State::Boot => BootState::Confirmed,
        State::Swap => BootState::Trial,
        State::Revert => BootState::Reverted,
        State::DfuDetach => BootState::DfuRequested,
    }
}

impl<'d, DFU: NorFlash, STATE: NorFlash> Updater<'d, DFU, STATE> {
    /// The updater over `dfu` and `state` (`aligned`: one flash write unit
    /// of scratch, as embassy-boot asks); reads the boot state the
    /// bootloader left. `max_image` is the active region's length.
    pub fn new(
        dfu: DFU,
        state: STATE,
        aligned: &'d mut [u8],
        max_image: u32,
        target: Target,
        trusted: &'static [PublicKeyBytes],
    ) -> Self {
        assert!(max_image as usize <= dfu.capacity(), "the update partition is smaller than the active image");
        let mut inner = BlockingFirmwareUpdater::new(FirmwareUpdaterConfig { dfu, state }, aligned);
        // An unreadable state partition reads as a trial: the image is then
        // confirmed only by its self-test, never taken for granted.
        let boot = inner.get_state().map_or(BootState::Trial, boot_state);
        Self { inner, max_image, target, trusted, boot, session: None, pending: None }
    }

    /// Whether a new session may start: not while an update waits for its
    /// reset, nor while this image is itself on trial.
    fn may_begin(&self) -> Result<(), DeviceError> {
        if self.pending.is_some() {
            return Err(DeviceError::Update(UpdateFault::Pending));
        }
        if self.boot == BootState::Trial {
            return Err(DeviceError::Update(UpdateFault::TrialNotConfirmed));
        }
        Ok(())
    }

    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), DeviceError> {
        self.inner.read_dfu(offset, buf).map_err(flash_err)
    }

    /// Feeds the update partition's first `len` bytes to `f`, a small
    /// buffer at a time (the image is never whole in RAM).
    fn scan(&mut self, len: u32, mut f: impl FnMut(&[u8])) -> Result<(), DeviceError> {
        let mut buf = [0u8; 256];
        let mut offset = 0;
        while offset < len {
            let n = (len - offset).min(buf.len() as u32) as usize;
            self.read(offset, &mut buf[..n])?;
            f(&buf[..n]);
            offset += n as u32;
        }
        Ok(())
    }

    /// The CRC and the checks of the image now in the update partition.
    fn check_image(&mut self, s: Session) -> Result<[u8; 3], DeviceError> {
        let mut crc = CRC32.digest();
        self.scan(s.len, |b| crc.update(b))?;
        let computed = crc.finalize();
        if let Some(declared) = s.crc.filter(|d| *d != computed) {
            return Err(DeviceError::CrcMismatch { declared, computed });
        }
        let reject = |e: ImageFault| DeviceError::FirmwareRejected(e);
        let mut trailer = [0u8; FW_TRAILER_LEN];
        self.read(s.len - FW_TRAILER_LEN as u32, &mut trailer)?;
        let (manifest, signature) = image::decode_trailer(&trailer, s.len).map_err(reject)?;
        let mut hasher = ImageHasher::default();
        self.scan(manifest.image_len, |b| hasher.update(b))?;
        let mut first = [0u8; 8];
        self.read(0, &mut first)?;
        let words = [
            u32::from_le_bytes([first[0], first[1], first[2], first[3]]),
            u32::from_le_bytes([first[4], first[5], first[6], first[7]]),
        ];
        image::check(&manifest, &signature, &hasher.digest(&manifest), words, self.target, self.trusted)
            .map_err(reject)?;
        Ok(manifest.version)
    }
}

impl<DFU: NorFlash, STATE: NorFlash> FirmwareSlot for Updater<'_, DFU, STATE> {
    fn boot_state(&self) -> BootState {
        self.boot
    }

    fn max_image(&self) -> u32 {
        self.max_image
    }

    fn receiving(&self) -> Option<u32> {
        self.session.map(|s| s.received)
    }

    fn pending(&self) -> Option<[u8; 3]> {
        self.pending
    }

    fn begin(&mut self, len: u32, crc: u32) -> Result<u32, DeviceError> {
        self.may_begin()?;
        if let Some(s) = self.session.filter(|s| s.len == len && s.crc == Some(crc)) {
            return Ok(s.received);
        }
        if len > self.max_image {
            return Err(DeviceError::Update(UpdateFault::TooLarge { len, max: self.max_image }));
        }
        if len <= FW_TRAILER_LEN as u32 || !(len as usize).is_multiple_of(DFU::WRITE_SIZE) {
            return Err(DeviceError::FirmwareRejected(ImageFault::BadTrailer));
        }
        self.session = Some(Session { len, crc: Some(crc), received: 0 });
        Ok(0)
    }

    fn begin_download(&mut self) -> Result<(), DeviceError> {
        self.may_begin()?;
        self.session = Some(Session { len: self.max_image, crc: None, received: 0 });
        Ok(())
    }

    fn write(&mut self, offset: u32, data: &[u8]) -> Result<u32, DeviceError> {
        let mut s = self.session.ok_or(DeviceError::Update(UpdateFault::NotUpdating))?;
        if offset != s.received {
            return Err(DeviceError::OutOfOrder { expected: s.received, got: offset });
        }
        let end = offset.checked_add(data.len() as u32);
        if s.crc.is_none() && end.is_none_or(|e| e > s.len) {
            // A download (no declared length) grew past the partition.
            return Err(DeviceError::Update(UpdateFault::TooLarge { len: end.unwrap_or(u32::MAX), max: s.len }));
        }
        if data.len() > MAX_CHUNK || end.is_none_or(|e| e > s.len) || !data.len().is_multiple_of(DFU::WRITE_SIZE) {
            return Err(DeviceError::ChunkTooLarge { max: MAX_CHUNK as u32 });
        }
        self.inner.write_firmware(offset as usize, data).map_err(flash_err)?;
        s.received += data.len() as u32;
        self.session = Some(s);
        Ok(s.received)
    }

    fn commit(&mut self) -> Result<[u8; 3], DeviceError> {
        let mut s = self.session.ok_or(DeviceError::Update(UpdateFault::NotUpdating))?;
        if s.crc.is_none() {
            // A download ends where the host stopped sending.
            s.len = s.received;
            if s.len <= FW_TRAILER_LEN as u32 {
                self.session = None;
                return Err(DeviceError::FirmwareRejected(ImageFault::BadTrailer));
            }
        }
        if s.received != s.len {
            return Err(DeviceError::Incomplete { received: s.received, len: s.len });
        }
        // Whatever the verdict, this image is done with: a refused one is
        // sent again from the start.
        self.session = None;
        let version = self.check_image(s)?;
        self.inner.mark_updated().map_err(flash_err)?;
        self.pending = Some(version);
        Ok(version)
    }

    fn abort(&mut self) -> Result<(), DeviceError> {
        self.session.take().map(|_| ()).ok_or(DeviceError::Update(UpdateFault::NotUpdating))
    }

    fn confirm(&mut self) -> Result<(), DeviceError> {
        if self.boot == BootState::Trial {
            self.inner.mark_booted().map_err(flash_err)?;
            self.boot = BootState::Confirmed;
        }
        Ok(())
    }
}
