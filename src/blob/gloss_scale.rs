//! A blob's gloss scale standardised on a certified black-glass standard
//! (host-tools' `standardise --black-glass-gu`), as ISO 2813 instruments
//! are: each gloss reference (what the standard's assigned value is
//! divided by, `crate::gloss`'s `S`) rescaled so the standard reads its
//! certified value, and the scale's uncertainty stated.
//!
//! A white standardisation corrects drift; what is left between the
//! model's reading of the black glass and the glass itself is the
//! calibration's own error of the gloss scale, small and stable, which
//! this corrects. Hence its narrow range ([`GLOSS_RATIO_RANGE`]): a black
//! glass that reads further off is not drift to correct here (standardise
//! the white first) or not the standard certified.
//! [`rewrite_gloss_references`] changes only the references and the CRC;
//! [`with_gloss_uncertainty`] adds (or replaces) the last section, the
//! scale's relative standard uncertainty (flag bit 14).

use super::*;

/// How far a gloss standardisation may rescale a gloss reference (new over
/// old, the black glass's reading over its certified value).
pub const GLOSS_RATIO_RANGE: (f32, f32) = (0.9, 1.1);

/// The largest relative standard uncertainty a blob may state for its gloss
/// scale.
pub const MAX_GLOSS_UNCERTAINTY: f32 = 0.1;

/// Writes `blob` (exactly one blob, with a gloss section) into `out`
/// stating `u_rel` as its gloss scale's relative standard uncertainty
/// (flag bit 14, the section before the CRC: added, or replaced) and
/// returns the length written. Nothing is written unless `blob` parses and
/// carries gloss readings, `u_rel` is finite and within 0 to
/// [`MAX_GLOSS_UNCERTAINTY`], and `out` has room.
pub fn with_gloss_uncertainty(blob: &[u8], u_rel: f32, out: &mut [u8]) -> Result<usize, BlobError> {
    check_gloss_uncertainty(u_rel)?;
    if !BlobView::parse(blob)?.has_gloss() {
        return Err(BlobError::ContentMismatch { section: Section::GlossUncertainty });
    }
    let t = super::stated::Trailing { flag: FLAG_GLOSS_UNCERTAINTY, section: Section::GlossUncertainty };
    super::stated::with_trailing(blob, t, u_rel, out)
}

/// Replaces the gloss references of the blob `bytes` (exactly one blob, no
/// signature trailer) with `refs` ([`BlobView::gloss_reference_count`]
/// values, in the blob's order: per pixel or per zone) and seals it again
/// with a new CRC.
///
/// Nothing is changed unless `bytes` parses and has a gloss section, and
/// each value is NaN where the blob's is (a zone that reads no gloss) and
/// elsewhere finite and within [`GLOSS_RATIO_RANGE`] of the value it
/// replaces; the result is parsed once more before this returns.
pub fn rewrite_gloss_references(bytes: &mut [u8], refs: &[f32]) -> Result<(), BlobError> {
    let (off, crc_at) = {
        let view = BlobView::parse(bytes)?;
        if bytes.len() != view.lay.total || !view.has_gloss() || refs.len() != view.lay.gloss_refs {
            return Err(BlobError::ContentMismatch { section: Section::Gloss });
        }
        let off = view.lay.gloss + 4 * GLOSS_HEAD;
        let (lo, hi) = GLOSS_RATIO_RANGE;
        for (r, x) in refs.iter().enumerate() {
            let was = get_f32(bytes, off + 4 * r);
            let ok = if was.is_nan() { x.is_nan() } else { *x >= lo * was && *x <= hi * was };
            if !ok {
                let index = GLOSS_HEAD + r;
                return Err(if x.is_finite() || was.is_nan() {
                    BlobError::OutOfRange { section: Section::Gloss, index }
                } else {
                    BlobError::NonFinite { section: Section::Gloss, index }
                });
            }
        }
        (off, view.lay.crc)
    };
    super::stated::reseal(bytes, off, refs, crc_at)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A version 4 blob with a gloss section (per-pixel references), and
    /// one whose second zone (pixels 4-7) reads no gloss.
    fn glossy(no_reading_zone: bool) -> Vec<u8> {
        crate::test_blobs::test_blob_with_gloss(9, 5, 2, 8, 0.5, no_reading_zone.then_some(1))
    }

    #[test]
    fn only_the_gloss_references_and_the_crc_change() {
        for no_reading in [false, true] {
            let before = glossy(no_reading);
            let view = BlobView::parse(&before).unwrap();
            assert_eq!(view.gloss_reference_count(), 8);
            let old: Vec<f32> = (0..8).map(|p| view.gloss_reference(p).unwrap()).collect();
            let new: Vec<f32> = old.iter().enumerate().map(|(p, x)| x * (0.95 + 0.01 * p as f32)).collect();
            let mut after = before.clone();
            rewrite_gloss_references(&mut after, &new).unwrap();
            let v = BlobView::parse(&after).unwrap();
            for (p, x) in new.iter().enumerate() {
                assert_eq!(v.gloss_reference(p).unwrap().to_bits(), x.to_bits());
                assert_eq!(v.gloss_reference_index(p), Some(p));
            }
            let lo = view.lay.gloss + 4 * GLOSS_HEAD;
            let changed: Vec<usize> = (0..before.len()).filter(|&k| before[k] != after[k]).collect();
            assert!(changed.iter().all(|&k| (lo..lo + 32).contains(&k) || k >= view.lay.crc), "{changed:?}");
            rewrite_gloss_references(&mut after, &old).unwrap();
            assert_eq!(after, before, "written back, the first blob again");
        }
    }

    #[test]
    fn a_reference_off_its_range_or_its_kind_changes_nothing() {
        let before = glossy(true);
        let view = BlobView::parse(&before).unwrap();
        let good: Vec<f32> = (0..8).map(|p| view.gloss_reference(p).unwrap() * 1.05).collect();
        let mut b = before.clone();
        let gloss = |index| BlobError::OutOfRange { section: Section::Gloss, index };
        let mut bad = good.clone();
        bad[1] *= 1.1;
        assert_eq!(rewrite_gloss_references(&mut b, &bad), Err(gloss(GLOSS_HEAD + 1)));
        bad = good.clone();
        bad[5] = 0.04; // a zone that reads no gloss keeps no reference
        assert_eq!(rewrite_gloss_references(&mut b, &bad), Err(gloss(GLOSS_HEAD + 5)));
        bad = good.clone();
        bad[2] = f32::INFINITY;
        assert_eq!(
            rewrite_gloss_references(&mut b, &bad),
            Err(BlobError::NonFinite { section: Section::Gloss, index: GLOSS_HEAD + 2 })
        );
        assert!(rewrite_gloss_references(&mut b, &good[..7]).is_err());
        assert_eq!(b, before);
        // A blob without a gloss section has nothing to standardise.
        let mut plain = crate::test_blobs::test_blob(9, 5, 2, 8, 0.5);
        let was = plain.clone();
        assert!(rewrite_gloss_references(&mut plain, &good).is_err());
        assert_eq!(plain, was);
    }

    /// `blob` with `value` appended as the gloss scale's uncertainty by
    /// hand, its flag, length and CRC set: what the writers never write.
    fn by_hand(blob: &[u8], value: f32) -> Vec<u8> {
        let mut b = blob[..blob.len() - 4].to_vec();
        b.extend_from_slice(&value.to_le_bytes());
        put_u16(&mut b, 22, get_u16(blob, 22) | FLAG_GLOSS_UNCERTAINTY);
        let total = b.len() + 4;
        put_u32(&mut b, 44, total as u32);
        let crc = CRC32.checksum(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        b
    }

    #[test]
    fn the_parser_refuses_a_gloss_uncertainty_it_cannot_take() {
        let ok = by_hand(&glossy(false), 0.01);
        assert_eq!(BlobView::parse(&ok).unwrap().gloss_uncertainty(), 0.01);
        let section = Section::GlossUncertainty;
        let nan = by_hand(&glossy(false), f32::NAN);
        assert_eq!(BlobView::parse(&nan).unwrap_err(), BlobError::NonFinite { section, index: 0 });
        let big = by_hand(&glossy(false), MAX_GLOSS_UNCERTAINTY * 1.5);
        assert_eq!(BlobView::parse(&big).unwrap_err(), BlobError::OutOfRange { section, index: 0 });
        // A blob without gloss readings has no gloss scale (format 2).
        let plain = crate::test_blobs::test_blob(9, 5, 2, 8, 0.5);
        let mut v2 = vec![0u8; plain.len() + 4];
        let n = with_white_uncertainty(&plain, 0.001, &mut v2).unwrap();
        assert_eq!(BlobView::parse(&by_hand(&v2[..n], 0.01)).unwrap_err(), BlobError::ReservedNotZero);
    }

    #[test]
    fn the_gloss_uncertainty_keeps_the_white_one_and_needs_a_gloss_section() {
        let blob = glossy(false);
        let mut with_white = vec![0u8; blob.len() + 4];
        let n = with_white_uncertainty(&blob, 0.003, &mut with_white).unwrap();
        let mut both = vec![0u8; n + 4];
        let m = with_gloss_uncertainty(&with_white[..n], 0.005, &mut both).unwrap();
        assert_eq!(m, blob.len() + 8);
        let v = BlobView::parse(&both[..m]).unwrap();
        assert_eq!((v.white_uncertainty(), v.gloss_uncertainty()), (0.003, 0.005));
        // Either stated again is replaced in place, the other kept.
        let mut again = vec![0u8; m];
        assert_eq!(with_white_uncertainty(&both[..m], 0.004, &mut again), Ok(m));
        let v = BlobView::parse(&again).unwrap();
        assert_eq!((v.white_uncertainty(), v.gloss_uncertainty()), (0.004, 0.005));
        let mut third = vec![0u8; m];
        assert_eq!(with_gloss_uncertainty(&again, 0.002, &mut third), Ok(m));
        let v = BlobView::parse(&third).unwrap();
        assert_eq!((v.white_uncertainty(), v.gloss_uncertainty()), (0.004, 0.002));
        // The white stated on a blob with only the gloss one goes before it.
        let mut gloss_only = vec![0u8; blob.len() + 4];
        let k = with_gloss_uncertainty(&blob, 0.006, &mut gloss_only).unwrap();
        let mut then_white = vec![0u8; k + 4];
        with_white_uncertainty(&gloss_only[..k], 0.001, &mut then_white).unwrap();
        let v = BlobView::parse(&then_white).unwrap();
        assert_eq!((v.white_uncertainty(), v.gloss_uncertainty()), (0.001, 0.006));
        // Bad values, and a blob without gloss readings, write nothing.
        for bad in [f32::NAN, -0.001, MAX_GLOSS_UNCERTAINTY * 1.01] {
            let mut o = vec![0u8; m];
            assert!(with_gloss_uncertainty(&blob, bad, &mut o).is_err(), "{bad}");
            assert!(o.iter().all(|b| *b == 0));
        }
        let plain = crate::test_blobs::test_blob(9, 5, 2, 8, 0.5);
        let mut o = vec![0u8; plain.len() + 4];
        assert_eq!(
            with_gloss_uncertainty(&plain, 0.01, &mut o),
            Err(BlobError::ContentMismatch { section: Section::GlossUncertainty })
        );
    }
}
