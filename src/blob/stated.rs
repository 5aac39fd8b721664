//! What a standardisation changes in a blob: values rewritten in place and
//! the blob sealed again ([`reseal`]), and the trailing one-value sections
//! it states (the white reference's uncertainty, flag bit 13; the gloss
//! scale's, flag bit 14), added or replaced, every other byte kept.

use super::*;

/// One of the trailing one-value sections.
#[derive(Clone, Copy)]
pub(super) struct Trailing {
    /// Its flag bit.
    pub(super) flag: u16,
    /// Where it is refused.
    pub(super) section: Section,
}

impl Trailing {
    /// Its offset in a blob laid out as `lay`, and whether it is there.
    fn at(self, lay: &Layout) -> (usize, bool) {
        match self.flag {
            FLAG_WHITE_UNCERTAINTY => (lay.white_uncertainty, lay.gloss_uncertainty != lay.white_uncertainty),
            _ => (lay.gloss_uncertainty, lay.crc != lay.gloss_uncertainty),
        }
    }
}

/// Writes `blob` (exactly one blob) into `out` with `value` as section `t`
/// (added, or replaced when the blob has it) and returns the length
/// written. A format version 1 blob is written as version 2 (K = 1), the
/// oldest that carries flags beyond the far-field one; every other byte is
/// kept, the sections after `t` included. `value` has been checked by the
/// caller; the result is parsed before this returns.
pub(super) fn with_trailing(blob: &[u8], t: Trailing, value: f32, out: &mut [u8]) -> Result<usize, BlobError> {
    let view = BlobView::parse(blob)?;
    if blob.len() != view.lay.total {
        return Err(BlobError::ContentMismatch { section: t.section });
    }
    let (at, present) = t.at(&view.lay);
    let rest = (at + if present { 4 } else { 0 })..view.lay.crc;
    let total = at + 4 + rest.len() + 4;
    if out.len() < total {
        return Err(BlobError::TooShort { need: total, got: out.len() });
    }
    out[..at].copy_from_slice(&blob[..at]);
    out[at + 4..total - 4].copy_from_slice(&blob[rest]);
    if view.version() == FORMAT_VERSION_1 {
        put_u16(out, 4, FORMAT_VERSION_2);
        put_u16(out, 48, 1);
    }
    put_u16(out, 22, get_u16(blob, 22) | t.flag);
    put_u32(out, 44, total as u32);
    put_f32(out, at, value);
    let crc = CRC32.checksum(&out[..total - 4]);
    put_u32(out, total - 4, crc);
    BlobView::parse(&out[..total])?;
    Ok(total)
}

/// Writes `values` into the blob `bytes` from byte `off` on (checked by the
/// caller), seals it with a new CRC at `crc_at` and parses it again.
pub(super) fn reseal(bytes: &mut [u8], off: usize, values: &[f32], crc_at: usize) -> Result<(), BlobError> {
    for (i, x) in values.iter().enumerate() {
        put_f32(bytes, off + 4 * i, *x);
    }
    let crc = CRC32.checksum(&bytes[..crc_at]);
    put_u32(bytes, crc_at, crc);
    BlobView::parse(bytes)?;
    Ok(())
}
