//! The two-slot store on a NOR flash: slots A and B, each holding one slot
//! header and one signed image. The calibrations live in one ([`Store`]),
//! the inspection recipes in another (`crate::inspect::RecipeStore`): the
//! same slot logic, power-cut rules and signature check, told apart only by
//! what a slot's content must parse as ([`SlotContent`]).
//!
//! # Slot layout (slot format version 1)
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `b"BRDS"` |
//! | 4 | 2 | slot format version (1) |
//! | 6 | 2 | header length (32) |
//! | 8 | 4 | sequence number (higher = newer, wrapping) |
//! | 12 | 4 | blob length (the signed content: blob or recipe, and signature trailer) |
//! | 16 | 4 | blob CRC-32 over all its bytes (trailer included) |
//! | 20 | 8 | reserved, 0 |
//! | 28 | 4 | CRC-32 of bytes 0..28 |
//! | 32 | .. | the blob (4-byte aligned, so its matrices can be read in place) |
//!
//! # Why a power cut never loses the last good calibration
//! - A new blob is always written into the slot that is *not* active.
//! - Its header is written last, after every blob byte; a slot counts only if
//!   its header CRC, its blob CRC, its signature by a trusted key
//!   ([`crate::signed`]) and the blob's own checks all pass. So an
//!   interrupted write leaves at worst an invalid slot, and the active slot,
//!   never touched, is what boot finds.
//! - Boot takes the valid slot with the newest sequence number.
//! - The target slot's first page (its header) is erased before anything is
//!   written there, so a half-rewritten slot can never show an old valid
//!   header over new bytes.
//!
//! The test `tests/power_cut.rs` cuts the power at every byte written and at
//! every page erase of a provisioning and checks that boot then finds the old
//! or the new blob, whole.
use crate::blob::{BlobError, BlobView, CRC32};
use crate::hw::MappedFlash;
use crate::protocol::DeviceError;
use crate::signed::{PublicKeyBytes, SignatureFault};
use embedded_storage::nor_flash::{NorFlashError, NorFlashErrorKind};

/// First bytes of a valid slot.
pub const SLOT_MAGIC: [u8; 4] = *b"BRDS";
/// Slot format version.
pub const SLOT_VERSION: u16 = 1;
/// Slot header length; the blob follows.
pub const SLOT_HEADER_LEN: usize = 32;
/// Largest flash write granularity the store supports.
const MAX_WRITE: usize = 32;

/// Why the store did not do what was asked. `E` is the flash's own error,
/// kept whole (its [`NorFlashErrorKind`] through [`StoreError::flash_kind`]);
/// what travels to the host is the [`DeviceError`] it converts into.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StoreError<E> {
    /// The flash failed an erase or a write.
    Flash(E),
    /// A header just written did not read back valid.
    ReadBack,
    /// The request was refused (bad order, size, CRC, blob...): the reason
    /// travels to the host as it is.
    Refused(DeviceError),
}

impl<E: NorFlashError> StoreError<E> {
    /// The flash error's kind, when the flash failed.
    pub fn flash_kind(&self) -> Option<NorFlashErrorKind> {
        match self {
            Self::Flash(e) => Some(e.kind()),
            _ => None,
        }
    }
}

impl<E> From<DeviceError> for StoreError<E> {
    fn from(e: DeviceError) -> Self {
        Self::Refused(e)
    }
}

impl<E> From<SignatureFault> for StoreError<E> {
    fn from(e: SignatureFault) -> Self {
        Self::Refused(e.into())
    }
}

impl<E> From<BlobError> for StoreError<E> {
    fn from(e: BlobError) -> Self {
        Self::Refused(e.into())
    }
}

/// On the wire a flash failure is [`DeviceError::Storage`] (the previous
/// calibration is kept); a refusal is its own reason.
impl<E> From<StoreError<E>> for DeviceError {
    fn from(e: StoreError<E>) -> Self {
        match e {
            StoreError::Flash(_) | StoreError::ReadBack => DeviceError::Storage,
            StoreError::Refused(d) => d,
        }
    }
}

/// A valid slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlotInfo {
    /// 0 = A, 1 = B.
    pub slot: u8,
    /// Sequence number.
    pub sequence: u32,
    /// Blob length.
    pub blob_len: u32,
    /// Blob CRC over all its bytes.
    pub blob_crc: u32,
}

/// The slot header for a blob of `blob_len` bytes with CRC `blob_crc`: what
/// the store writes after the blob, and what factory provisioning over SWD
/// writes in front of one. The one encoder of the layout in the module docs.
pub fn encode_slot_header(sequence: u32, blob_len: u32, blob_crc: u32) -> [u8; SLOT_HEADER_LEN] {
    let mut h = [0u8; SLOT_HEADER_LEN];
    h[0..4].copy_from_slice(&SLOT_MAGIC);
    h[4..6].copy_from_slice(&SLOT_VERSION.to_le_bytes());
    h[6..8].copy_from_slice(&(SLOT_HEADER_LEN as u16).to_le_bytes());
    h[8..12].copy_from_slice(&sequence.to_le_bytes());
    h[12..16].copy_from_slice(&blob_len.to_le_bytes());
    h[16..20].copy_from_slice(&blob_crc.to_le_bytes());
    let hcrc = CRC32.checksum(&h[..28]);
    h[28..32].copy_from_slice(&hcrc.to_le_bytes());
    h
}

/// Decodes the header of slot `slot`: `None` unless magic, version, header
/// length and header CRC hold. The blob's own CRC is the caller's to check.
pub fn decode_slot_header(slot: u8, h: &[u8]) -> Option<SlotInfo> {
    if h.len() < SLOT_HEADER_LEN {
        return None;
    }
    let u16_at = |o: usize| u16::from_le_bytes([h[o], h[o + 1]]);
    let u32_at = |o: usize| u32::from_le_bytes([h[o], h[o + 1], h[o + 2], h[o + 3]]);
    if h[0..4] != SLOT_MAGIC
        || u16_at(4) != SLOT_VERSION
        || u16_at(6) as usize != SLOT_HEADER_LEN
        || CRC32.checksum(&h[..28]) != u32_at(28)
    {
        return None;
    }
    Some(SlotInfo { slot, sequence: u32_at(8), blob_len: u32_at(12), blob_crc: u32_at(16) })
}

/// What a store's slots hold: how a verified (signed) slot's content is
/// parsed, and which whole, signed content this firmware keeps but cannot
/// read.
pub trait SlotContent {
    /// The parsed content, read in place from the slot.
    type View: Copy;
    /// Parses the content (signature already verified and removed); also
    /// checks that it fills exactly the bytes given.
    fn parse(bytes: &'static [u8]) -> Result<Self::View, DeviceError>;
    /// The reason a whole, signed content that fails [`Self::parse`] is kept
    /// but not used, when it is a format this firmware does not read;
    /// `None` for any other failure.
    fn unreadable(_bytes: &'static [u8]) -> Option<DeviceError> {
        None
    }
}

/// The calibrations: blobs ([`crate::blob`]).
pub struct Calibrations;

impl SlotContent for Calibrations {
    type View = BlobView<'static>;

    fn parse(bytes: &'static [u8]) -> Result<Self::View, DeviceError> {
        let view = BlobView::parse(bytes)?;
        if view.as_bytes().len() != bytes.len() {
            return Err(BlobError::LengthMismatch { expected: view.as_bytes().len(), got: bytes.len() }.into());
        }
        Ok(view)
    }

    fn unreadable(bytes: &'static [u8]) -> Option<DeviceError> {
        match BlobView::parse(bytes) {
            // Whole, signed, but a format this build cannot read (written
            // by another firmware): said so, never misread.
            Err(BlobError::UnsupportedVersion(format)) => Some(DeviceError::CalibrationUnsupported {
                format,
                oldest: crate::blob::FORMAT_VERSION_1,
                newest: crate::blob::FORMAT_VERSION,
            }),
            _ => None,
        }
    }
}

/// A provisioning in progress.
#[derive(Clone, Copy, Debug)]
struct Session {
    slot: u8,
    len: u32,
    crc: u32,
    /// Blob bytes accepted (written or in `carry`).
    received: u32,
    /// Slot bytes erased so far (from the slot start).
    erased_to: u32,
    /// Bytes waiting for a whole write unit.
    carry: [u8; MAX_WRITE],
    carry_len: usize,
}

/// A provisioning's image written and checked: the session, the signed
/// content's bytes (without the trailer) and the image's CRC.
type Finished = (Session, &'static [u8], u32);

/// The two-slot store of content `K`: the slot logic (`Slots`, the same
/// code whatever the content, so a firmware with two stores on one kind of
/// flash carries it once) and what its content parses as.
pub struct SlotStore<F, K: SlotContent> {
    s: Slots<F>,
    content: core::marker::PhantomData<K>,
}

/// The slots, whatever they hold: headers, sessions, power-cut rules,
/// signatures.
struct Slots<F> {
    flash: F,
    slot_len: u32,
    /// The keys a slot's signature must verify against.
    trusted: &'static [PublicKeyBytes],
    active: Option<SlotInfo>,
    session: Option<Session>,
    /// See [`SlotStore::unreadable`].
    unreadable: Option<DeviceError>,
}

/// The two-slot calibration store.
pub type Store<F> = SlotStore<F, Calibrations>;

/// Whether sequence `a` is newer than `b` (wrapping).
/// Whether sequence `a` is newer than `b` (wrapping comparison, so the
/// sequence number may roll over).
pub fn newer(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

impl<F: MappedFlash, K: SlotContent> SlotStore<F, K> {
    /// Opens the store on `flash`, whose first `2 * slot_len` bytes are slots
    /// A and B, and finds the newest valid slot signed by one of the
    /// `trusted` keys (a slot whose signature fails is passed over).
    ///
    /// `accept` is asked about each valid blob, newest first; the first it
    /// accepts becomes active (so a blob made for another build is skipped in
    /// favour of an older one that fits).
    ///
    /// # Panics
    /// If `slot_len` is not a multiple of the erase size, the flash is smaller
    /// than two slots, or the write size is above 32 bytes (build-time errors).
    pub fn open(
        flash: F,
        slot_len: u32,
        trusted: &'static [PublicKeyBytes],
        mut accept: impl FnMut(&K::View) -> bool,
    ) -> Self {
        assert!((slot_len as usize).is_multiple_of(F::ERASE_SIZE), "slot length must be whole erase pages");
        assert!(F::WRITE_SIZE <= MAX_WRITE && SLOT_HEADER_LEN.is_multiple_of(F::WRITE_SIZE));
        assert!(flash.capacity() >= 2 * slot_len as usize, "flash smaller than two slots");
        let mut s = Slots { flash, slot_len, trusted, active: None, session: None, unreadable: None };
        let (a, b) = (s.scan(0), s.scan(1));
        let newest_first = match (a, b) {
            (Some(x), Some(y)) if newer(y.sequence, x.sequence) => [b, a],
            _ => [a, b],
        };
        for info in newest_first.into_iter().flatten() {
            if !s.signed_by_trusted(info) {
                continue;
            }
            let image = s.image(info.slot, info.blob_len);
            let bytes = &image[..image.len() - crate::signed::TRAILER_LEN];
            match K::parse(bytes) {
                Ok(view) if accept(&view) => {
                    s.active = Some(info);
                    break;
                }
                Ok(_) => {}
                Err(_) if s.unreadable.is_none() => s.unreadable = K::unreadable(bytes),
                Err(_) => {}
            }
        }
        Self { s, content: core::marker::PhantomData }
    }

    /// Why the newest whole, signed content was passed over at boot, when
    /// it is one this firmware cannot read (a blob format newer or older
    /// than it reads); `None` when every such slot was readable.
    pub fn unreadable(&self) -> Option<DeviceError> {
        self.s.unreadable
    }

    /// The active slot.
    pub fn active(&self) -> Option<SlotInfo> {
        self.s.active
    }

    /// The active content (blob or recipe), read in place.
    pub fn active_blob(&self) -> Option<(SlotInfo, K::View)> {
        let info = self.s.active?;
        let image = self.s.image(info.slot, info.blob_len);
        Some((info, K::parse(image.get(..image.len().checked_sub(crate::signed::TRAILER_LEN)?)?).ok()?))
    }

    /// Largest blob a slot holds.
    pub fn max_blob(&self) -> u32 {
        self.s.max_blob()
    }

    /// Bytes received by the provisioning in progress.
    pub fn provisioning(&self) -> Option<u32> {
        self.s.session.map(|s| s.received)
    }

    /// The flash (for tests).
    pub fn flash(&self) -> &F {
        &self.s.flash
    }

    /// Gives the flash back, dropping everything the store knew (the board
    /// tests reopen the store on it, as a reboot would).
    pub fn into_flash(self) -> F {
        self.s.flash
    }

    /// Starts writing a blob of `len` bytes (CRC `crc`) into the inactive slot;
    /// returns that slot. Cancels any provisioning in progress.
    pub fn begin(&mut self, len: u32, crc: u32) -> Result<u8, StoreError<F::Error>> {
        self.s.begin(len, crc)
    }

    /// Writes the blob bytes at `offset`; returns the next expected offset.
    pub fn write_chunk(&mut self, offset: u32, data: &[u8]) -> Result<u32, StoreError<F::Error>> {
        self.s.write_chunk(offset, data)
    }

    /// Verifies the written signed content (CRC over all of it against
    /// the one declared at begin, the signature by a trusted key, the
    /// content's own checks, then `accept`) and, only if all pass,
    /// writes the slot header that makes it the active one.
    ///
    /// On error the provisioning is over and the previous content stays
    /// active.
    pub fn commit(
        &mut self,
        accept: impl FnOnce(&K::View) -> Result<(), DeviceError>,
    ) -> Result<SlotInfo, StoreError<F::Error>> {
        let (session, blob, crc) = self.s.finish()?;
        // Nothing is parsed before the signature holds (`finish`).
        accept(&K::parse(blob)?)?;
        self.s.activate(session, crc)
    }

    /// Abandons the provisioning in progress (the target slot stays invalid).
    pub fn abort(&mut self) -> Result<(), StoreError<F::Error>> {
        self.s.session.take().map(|_| ()).ok_or(StoreError::Refused(DeviceError::NotProvisioning))
    }
}

impl<F: MappedFlash> Slots<F> {
    fn max_blob(&self) -> u32 {
        self.slot_len - SLOT_HEADER_LEN as u32
    }

    fn base(&self, slot: u8) -> u32 {
        slot as u32 * self.slot_len
    }

    /// The bytes of slot `slot`'s image of `len` bytes, read in place.
    fn image(&self, slot: u8, len: u32) -> &'static [u8] {
        self.flash.mapped(self.base(slot) + SLOT_HEADER_LEN as u32, len as usize)
    }

    /// Whether the slot's signed content verifies against the trusted keys.
    fn signed_by_trusted(&self, info: SlotInfo) -> bool {
        crate::signed::verify(self.image(info.slot, info.blob_len), self.trusted).is_ok()
    }

    /// Validates slot `slot`'s header and blob CRC.
    fn scan(&self, slot: u8) -> Option<SlotInfo> {
        let info = decode_slot_header(slot, self.flash.mapped(self.base(slot), SLOT_HEADER_LEN))?;
        if info.blob_len > self.max_blob() {
            return None;
        }
        (CRC32.checksum(self.image(slot, info.blob_len)) == info.blob_crc).then_some(info)
    }

    fn begin(&mut self, len: u32, crc: u32) -> Result<u8, StoreError<F::Error>> {
        self.session = None;
        if len > self.max_blob() {
            return Err(DeviceError::BlobTooLarge { len, max: self.max_blob() }.into());
        }
        if len == 0 {
            return Err(BlobError::TooShort { need: crate::blob::HEADER_LEN, got: 0 }.into());
        }
        let slot = match self.active {
            Some(a) => 1 - a.slot,
            None => 0,
        };
        // Invalidate the target's header first: from here on the slot is not
        // valid until commit writes a new header.
        let base = self.base(slot);
        self.flash.erase(base, base + F::ERASE_SIZE as u32).map_err(StoreError::Flash)?;
        self.session = Some(Session {
            slot,
            len,
            crc,
            received: 0,
            erased_to: F::ERASE_SIZE as u32,
            carry: [0xFF; MAX_WRITE],
            carry_len: 0,
        });
        Ok(slot)
    }

    /// Writes the blob bytes at `offset`; returns the next expected offset.
    fn write_chunk(&mut self, offset: u32, data: &[u8]) -> Result<u32, StoreError<F::Error>> {
        let mut s = self.session.ok_or(DeviceError::NotProvisioning)?;
        if offset != s.received {
            return Err(DeviceError::OutOfOrder { expected: s.received, got: offset }.into());
        }
        if data.len() > crate::protocol::MAX_CHUNK || s.received as usize + data.len() > s.len as usize {
            let max = (s.len - s.received).min(crate::protocol::MAX_CHUNK as u32);
            return Err(DeviceError::ChunkTooLarge { max }.into());
        }
        let w = F::WRITE_SIZE;
        let mut rest = data;
        while !rest.is_empty() {
            let take = (w - s.carry_len).min(rest.len());
            s.carry[s.carry_len..s.carry_len + take].copy_from_slice(&rest[..take]);
            s.carry_len += take;
            s.received += take as u32;
            rest = &rest[take..];
            if s.carry_len == w {
                let at = SLOT_HEADER_LEN as u32 + s.received - w as u32;
                if let Err(e) = self.program(&mut s, at) {
                    self.session = None;
                    return Err(e);
                }
            }
        }
        self.session = Some(s);
        Ok(s.received)
    }

    /// Writes `s.carry` (one write unit) at slot offset `at`, erasing ahead.
    fn program(&mut self, s: &mut Session, at: u32) -> Result<(), StoreError<F::Error>> {
        let w = F::WRITE_SIZE;
        let base = self.base(s.slot);
        while s.erased_to < at + w as u32 {
            let p = base + s.erased_to;
            self.flash.erase(p, p + F::ERASE_SIZE as u32).map_err(StoreError::Flash)?;
            s.erased_to += F::ERASE_SIZE as u32;
        }
        self.flash.write(base + at, &s.carry[..w]).map_err(StoreError::Flash)?;
        s.carry = [0xFF; MAX_WRITE];
        s.carry_len = 0;
        Ok(())
    }

    /// The first half of a commit: the last write unit programmed, the CRC
    /// over all the image against the one declared at begin, the signature
    /// by a trusted key. Returns the session, the signed content's bytes
    /// (without the trailer) and the CRC.
    fn finish(&mut self) -> Result<Finished, StoreError<F::Error>> {
        let mut s = self.session.take().ok_or(DeviceError::NotProvisioning)?;
        if s.received != s.len {
            return Err(DeviceError::Incomplete { received: s.received, len: s.len }.into());
        }
        if s.carry_len > 0 {
            let at = SLOT_HEADER_LEN as u32 + s.received - s.carry_len as u32;
            self.program(&mut s, at)?;
        }
        let image = self.image(s.slot, s.len);
        let computed = CRC32.checksum(image);
        if computed != s.crc {
            return Err(DeviceError::CrcMismatch { declared: s.crc, computed }.into());
        }
        let blob = crate::signed::verify(image, self.trusted)?;
        Ok((s, blob, computed))
    }

    /// The second half: the slot header that makes the slot active, trusted
    /// only once it reads back.
    fn activate(&mut self, s: Session, crc: u32) -> Result<SlotInfo, StoreError<F::Error>> {
        let sequence = self.active.map_or(1, |a| a.sequence.wrapping_add(1));
        let h = encode_slot_header(sequence, s.len, crc);
        let base = self.base(s.slot);
        self.flash.write(base, &h).map_err(StoreError::Flash)?;
        let info = self.scan(s.slot).ok_or(StoreError::ReadBack)?;
        self.active = Some(info);
        self.unreadable = None;
        Ok(info)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::platform::host_sim::{NorFault, SimFlash};

    type Error = StoreError<NorFault>;

    fn blob(seed: f32) -> Vec<u8> {
        crate::test_blobs::signed_test_blob(5, 3, 2, 4, seed)
    }

    fn unsigned(image: &[u8]) -> &[u8] {
        &image[..image.len() - crate::signed::TRAILER_LEN]
    }

    fn open(flash: SimFlash) -> Store<SimFlash> {
        Store::open(flash, 4096, crate::test_blobs::dev_trusted(), |_| true)
    }

    fn provision(st: &mut Store<SimFlash>, b: &[u8], chunk: usize) -> Result<SlotInfo, Error> {
        st.begin(b.len() as u32, CRC32.checksum(b))?;
        let mut off = 0;
        for c in b.chunks(chunk) {
            off = st.write_chunk(off, c)?;
        }
        st.commit(|_| Ok(()))
    }

    #[test]
    fn alternates_slots_and_keeps_the_previous_blob() {
        let flash = SimFlash::new(4 * 2048);
        let mut st = open(flash.clone());
        assert_eq!(st.active(), None);
        let (a, b, c) = (blob(1.0), blob(2.0), blob(3.0));
        let i1 = provision(&mut st, &a, 7).unwrap();
        let i2 = provision(&mut st, &b, 64).unwrap();
        assert_eq!((i1.slot, i1.sequence, i2.slot, i2.sequence), (0, 1, 1, 2));
        let st2 = open(flash.clone());
        assert_eq!(st2.active_blob().unwrap().1.as_bytes(), unsigned(&b));
        // A failed provisioning leaves the active blob in place.
        let mut st = st2;
        st.begin(c.len() as u32, 0xBAD).unwrap();
        st.write_chunk(0, &c).unwrap();
        assert!(matches!(st.commit(|_| Ok(())), Err(Error::Refused(DeviceError::CrcMismatch { .. }))));
        assert_eq!(st.active_blob().unwrap().1.as_bytes(), unsigned(&b));
        let st3 = open(flash);
        assert_eq!(st3.active_blob().unwrap().1.as_bytes(), unsigned(&b));
    }

    #[test]
    fn unsigned_tampered_and_foreign_calibrations_are_refused_and_the_previous_stays() {
        let flash = SimFlash::new(4 * 2048);
        let mut st = open(flash.clone());
        let good = blob(1.0);
        provision(&mut st, &good, 64).unwrap();
        let plain = crate::test_blobs::test_blob(5, 3, 2, 4, 2.0);
        let mut tampered = blob(2.0);
        tampered[70] ^= 4;
        let mut foreign = plain.clone();
        foreign.extend_from_slice(&crate::signed::sign(&plain, &[9; 32]));
        for (bad, fault) in [
            (&plain, SignatureFault::Unsigned),
            (&tampered, SignatureFault::BadSignature),
            (&foreign, SignatureFault::UnknownKey),
        ] {
            assert_eq!(provision(&mut st, bad, 64), Err(Error::Refused(DeviceError::SignatureRejected(fault))));
            assert_eq!(st.active_blob().unwrap().1.as_bytes(), unsigned(&good));
        }
        assert_eq!(open(flash).active_blob().unwrap().1.as_bytes(), unsigned(&good));
    }

    #[test]
    fn boot_passes_over_a_slot_whose_signature_fails() {
        // Slot B holds a newer calibration with a valid header and CRC but a
        // foreign signature (as SWD could write it): boot takes slot A.
        let flash = SimFlash::new(4 * 2048);
        let good = blob(1.0);
        provision(&mut open(flash.clone()), &good, 64).unwrap();
        let plain = crate::test_blobs::test_blob(5, 3, 2, 4, 2.0);
        let mut foreign = plain.clone();
        foreign.extend_from_slice(&crate::signed::sign(&plain, &[9; 32]));
        let mut raw = flash.clone();
        let mut image = encode_slot_header(2, foreign.len() as u32, CRC32.checksum(&foreign)).to_vec();
        image.extend_from_slice(&foreign);
        image.resize(image.len().next_multiple_of(8), 0xFF);
        embedded_storage::nor_flash::NorFlash::erase(&mut raw, 4096, 8192).unwrap();
        embedded_storage::nor_flash::NorFlash::write(&mut raw, 4096, &image).unwrap();
        let st = open(flash.clone());
        assert_eq!(st.active().map(|a| (a.slot, a.sequence)), Some((0, 1)));
        // Trusting the foreign key instead, the newer slot B is taken.
        let foreign_key: &'static [PublicKeyBytes] = Box::leak(Box::new([crate::signed::public_key(&[9; 32])]));
        let st = Store::open(flash, 4096, foreign_key, |_| true);
        assert_eq!(st.active().map(|a| (a.slot, a.sequence)), Some((1, 2)));
    }

    #[test]
    fn out_of_order_and_oversized_chunks_are_refused() {
        let mut st = open(SimFlash::new(4 * 2048));
        let a = blob(1.0);
        assert_eq!(st.write_chunk(0, &a[..8]), Err(Error::Refused(DeviceError::NotProvisioning)));
        st.begin(a.len() as u32, CRC32.checksum(&a)).unwrap();
        st.write_chunk(0, &a[..10]).unwrap();
        assert_eq!(
            st.write_chunk(20, &a[20..30]),
            Err(Error::Refused(DeviceError::OutOfOrder { expected: 10, got: 20 }))
        );
        assert!(matches!(
            st.write_chunk(10, &vec![0; a.len()]),
            Err(Error::Refused(DeviceError::ChunkTooLarge { .. }))
        ));
        assert!(matches!(st.commit(|_| Ok(())), Err(Error::Refused(DeviceError::Incomplete { received: 10, .. }))));
        assert_eq!(st.begin(5000, 0), Err(Error::Refused(DeviceError::BlobTooLarge { len: 5000, max: 4096 - 32 })));
    }

    #[test]
    fn a_flash_failure_keeps_its_kind_and_travels_as_storage() {
        let flash = SimFlash::new(4 * 2048);
        let mut st = open(flash.clone());
        let a = blob(1.0);
        flash.cut_after(0);
        let e = st.begin(a.len() as u32, CRC32.checksum(&a)).unwrap_err();
        assert_eq!(e, Error::Flash(NorFault::PowerCut));
        assert_eq!(e.flash_kind(), Some(NorFlashErrorKind::Other));
        assert_eq!(DeviceError::from(e), DeviceError::Storage);
        // A misaligned write keeps the driver's own kind.
        let mut raw = SimFlash::new(2048);
        let e: Error =
            StoreError::Flash(embedded_storage::nor_flash::NorFlash::write(&mut raw, 3, &[0; 8]).unwrap_err());
        assert_eq!(e.flash_kind(), Some(NorFlashErrorKind::NotAligned));
        // A refusal travels as its own reason.
        assert_eq!(DeviceError::from(Error::Refused(DeviceError::NotProvisioning)), DeviceError::NotProvisioning);
    }

    #[test]
    fn wrapping_sequence_numbers_order_correctly() {
        assert!(newer(0, u32::MAX));
        assert!(newer(5, 4));
        assert!(!newer(4, 5));
    }
}
