//! The signed firmware image: what `host-tools sign-firmware` writes, what
//! travels in an update and what the update partition (DFU) holds, byte for
//! byte, until the bootloader swaps it in.
//!
//! # Layout
//! The application's flash image (from the start of the active region, its
//! vector table first), zero-padded to a multiple of 8 bytes (the flash's
//! program unit), then a 96-byte trailer:
//!
//! | offset in the trailer | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `b"BRDU"` |
//! | 4 | 2 | trailer format version (1) |
//! | 6 | 2 | trailer length (96) |
//! | 8 | 4 | image length: the bytes before the trailer |
//! | 12 | 4 | target the image is built for ([`Target`]) |
//! | 16 | 3 | firmware version, major / minor / patch |
//! | 19 | 5 | reserved, 0 |
//! | 24 | 8 | key id: the first 8 bytes of the signer's public key |
//! | 32 | 64 | Ed25519 signature over SHA-512(image, trailer bytes 0..32) |
//!
//! The signature covers every image byte and every trailer field before it.
//! It signs the 64-byte SHA-512 digest rather than the bytes themselves (as
//! embassy-boot's own `verify_and_mark_updated` does), so the device hashes
//! the update partition page by page and never needs the image in RAM or
//! mapped. A calibration's signature (over a blob, [`crate::signed`]) can
//! never pass for a firmware's: a blob is longer than 64 bytes.
//! The keys are the calibrations' ([`crate::signed::TRUSTED_KEYS`]), and so
//! is the verifier ([`crate::signed::verify_message`]).
use crate::signed::{KeyId, PublicKeyBytes, SignatureFault, Trailer};

/// First four bytes of a firmware trailer.
pub const FW_MAGIC: [u8; 4] = *b"BRDU";
/// The trailer format version this library writes and reads.
pub const FW_TRAILER_VERSION: u16 = 1;
/// Length of the trailer.
pub const FW_TRAILER_LEN: usize = 96;
/// Bytes of the trailer the signature covers (all before the key id).
const SIGNED_TRAILER_LEN: usize = 24;

/// Which machine an image is built for: an image for another is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Target {
    /// The B-L475E-IOT01A board firmware (`board-fw`).
    Board,
    /// The QEMU firmware (`qemu-fw`) and the host simulation of it.
    Qemu,
}

impl Target {
    /// The trailer's code for it.
    pub const fn code(self) -> u32 {
        match self {
            Self::Board => 1,
            Self::Qemu => 2,
        }
    }
    /// The target of a trailer code.
    pub fn from_code(code: u32) -> Option<Self> {
        [Self::Board, Self::Qemu].into_iter().find(|t| t.code() == code)
    }

    /// The target a firmware binary declares in its `BRDF_FIRMWARE_TARGET`
    /// symbol (a `#[no_mangle]` static holding [`Self::code`]), read so the
    /// linker keeps the symbol: `host-tools sign-firmware` reads it from the
    /// ELF and refuses to sign the image for another machine.
    ///
    /// # Panics
    /// If `declared` holds no target's code (a build error, not a runtime one).
    pub fn declared(declared: &'static u32) -> Self {
        // SAFETY: a valid, aligned, immutable static; volatile only so the
        // read, and with it the symbol, is not optimised away.
        let code = unsafe { core::ptr::read_volatile(declared) };
        match Self::from_code(code) {
            Some(t) => t,
            None => panic!("BRDF_FIRMWARE_TARGET holds no target's code"),
        }
    }
}

/// What the trailer says about the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Manifest {
    /// Image bytes before the trailer.
    pub image_len: u32,
    /// The machine it is built for.
    pub target: Target,
    /// Firmware version, major / minor / patch.
    pub version: [u8; 3],
}

/// Why a firmware image was refused. Travels in the wire protocol's
/// `DeviceError::FirmwareRejected`: never reorder the variants.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImageFault {
    /// No firmware trailer: an unsigned image (sign it with `host-tools sign-firmware`).
    Unsigned,
    /// A trailer is there but its version, length or image length is not this format's.
    BadTrailer,
    /// Built for another machine (a board image on QEMU or the reverse).
    WrongTarget,
    /// The image does not start with a vector table for the active region
    /// (initial stack in RAM, reset handler in the active image): it would
    /// not start.
    NotBootable,
    /// The signature was refused.
    Signature(SignatureFault),
}

impl core::fmt::Display for ImageFault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Unsigned => f.write_str("the firmware image is not signed (sign it with `host-tools sign-firmware`)"),
            Self::BadTrailer => f.write_str("the firmware image's trailer is malformed"),
            Self::WrongTarget => f.write_str("the firmware image is built for another machine (board / QEMU)"),
            Self::NotBootable => {
                f.write_str("the firmware image does not start with a vector table for the active image region")
            }
            Self::Signature(SignatureFault::UnknownKey) => {
                f.write_str("the firmware image is signed by a key this firmware does not trust")
            }
            Self::Signature(SignatureFault::BadSignature) => {
                f.write_str("the firmware image's signature does not verify (the image or its trailer was changed)")
            }
            Self::Signature(e) => write!(f, "{e}"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for ImageFault {}

impl From<SignatureFault> for ImageFault {
    fn from(e: SignatureFault) -> Self {
        Self::Signature(e)
    }
}

/// Encodes the signed part of a trailer (bytes 0..24).
fn signed_fields(m: &Manifest) -> [u8; SIGNED_TRAILER_LEN] {
    let mut t = [0u8; SIGNED_TRAILER_LEN];
    t[0..4].copy_from_slice(&FW_MAGIC);
    t[4..6].copy_from_slice(&FW_TRAILER_VERSION.to_le_bytes());
    t[6..8].copy_from_slice(&(FW_TRAILER_LEN as u16).to_le_bytes());
    t[8..12].copy_from_slice(&m.image_len.to_le_bytes());
    t[12..16].copy_from_slice(&m.target.code().to_le_bytes());
    t[16..19].copy_from_slice(&m.version);
    t
}

/// Decodes a trailer (nothing verified yet). `total_len` is the length of
/// the whole signed image the trailer ends.
pub fn decode_trailer(t: &[u8; FW_TRAILER_LEN], total_len: u32) -> Result<(Manifest, Trailer), ImageFault> {
    if t[0..4] != FW_MAGIC {
        return Err(ImageFault::Unsigned);
    }
    let u32_at = |o: usize| u32::from_le_bytes([t[o], t[o + 1], t[o + 2], t[o + 3]]);
    let image_len = u32_at(8);
    if u16::from_le_bytes([t[4], t[5]]) != FW_TRAILER_VERSION
        || u16::from_le_bytes([t[6], t[7]]) as usize != FW_TRAILER_LEN
        || image_len.checked_add(FW_TRAILER_LEN as u32) != Some(total_len)
        || !(image_len as usize).is_multiple_of(crate::shape::FLASH_WRITE)
        || t[19..24] != [0; 5]
    {
        return Err(ImageFault::BadTrailer);
    }
    let target = Target::from_code(u32_at(12)).ok_or(ImageFault::WrongTarget)?;
    let mut key_id: KeyId = [0; 8];
    key_id.copy_from_slice(&t[24..32]);
    let mut signature = [0u8; 64];
    signature.copy_from_slice(&t[32..96]);
    Ok((Manifest { image_len, target, version: [t[16], t[17], t[18]] }, Trailer { key_id, signature }))
}

/// Incremental SHA-512 of a signed image: feed it the image bytes (in any
/// chunks), then [`ImageHasher::digest`] adds the trailer's signed fields.
pub struct ImageHasher(salty::Sha512);

impl Default for ImageHasher {
    fn default() -> Self {
        Self(salty::Sha512::new())
    }
}

impl ImageHasher {
    /// Hashes the next image bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        self.0.update(bytes);
    }
    /// The digest the signature is made over.
    pub fn digest(mut self, m: &Manifest) -> [u8; 64] {
        self.0.update(&signed_fields(m));
        self.0.finalize()
    }
}

/// Checks a decoded image: its target, its vector table (`first_words`: the
/// image's first two words, initial stack pointer and reset handler), and
/// the signature over `digest` by one of the `trusted` keys.
pub fn check(
    m: &Manifest,
    t: &Trailer,
    digest: &[u8; 64],
    first_words: [u32; 2],
    target: Target,
    trusted: &[PublicKeyBytes],
) -> Result<(), ImageFault> {
    if m.target != target {
        return Err(ImageFault::WrongTarget);
    }
    // The signature first: an unsigned or foreign image says so, whatever
    // else is wrong with it.
    crate::signed::verify_message(digest, t, trusted)?;
    if !vector_table_fits(first_words, m.image_len) {
        return Err(ImageFault::NotBootable);
    }
    Ok(())
}

/// Whether an image's first two words are a vector table for the active
/// region: the initial stack pointer inside RAM (or at its end), the reset
/// handler a Thumb address inside the image.
pub fn vector_table_fits([sp, reset]: [u32; 2], image_len: u32) -> bool {
    use crate::shape::board::{ACTIVE, RAM_LEN, RAM_ORIGIN};
    let sp_ok = sp > RAM_ORIGIN && sp <= RAM_ORIGIN + RAM_LEN && sp.is_multiple_of(8);
    let reset_ok = reset & 1 == 1 && (ACTIVE..ACTIVE + image_len).contains(&(reset & !1));
    sp_ok && reset_ok
}

/// A signed image of `image` (the host's side): pads it to the program unit,
/// appends the trailer signed with the secret seed `seed`.
#[cfg(feature = "std")]
pub fn sign(image: &[u8], target: Target, version: [u8; 3], seed: &[u8; 32]) -> std::vec::Vec<u8> {
    let mut out = image.to_vec();
    out.resize(image.len().next_multiple_of(crate::shape::FLASH_WRITE), 0);
    let m = Manifest { image_len: out.len() as u32, target, version };
    let mut h = ImageHasher::default();
    h.update(&out);
    let t = crate::signed::sign_message(&h.digest(&m), seed);
    out.extend_from_slice(&signed_fields(&m));
    out.extend_from_slice(&t.key_id);
    out.extend_from_slice(&t.signature);
    out
}
