//! A blob's white reference rewritten, and its uncertainty stated: the
//! standardisation on a white tile (host-tools' `standardise`).
//!
//! The white reference is what every reading is divided by, so when the
//! LEDs age or the sensor's response drifts, rescaling it brings the
//! readings back to the scale training saw; the matrices, uncertainties,
//! gloss rows and every other section stay as trained, byte for byte.
//! [`rewrite_white`] changes only the white section and the CRC;
//! [`with_white_uncertainty`] adds (or replaces) the last section, the
//! white's relative standard uncertainty (flag bit 13). The result is a new
//! calibration: a new CRC, to be signed again.

use super::*;

/// How far a standardisation may rescale a white value (new over old):
/// LEDs that lost half their light or doubled it have not drifted but
/// failed, or the tile read was another one. Also what the host takes as a
/// standardised calibration of the same optics.
pub const WHITE_RATIO_RANGE: (f32, f32) = (0.5, 2.0);

/// The largest relative standard uncertainty a blob may state for its
/// white reference: a standardisation known no better than this is not one.
pub const MAX_WHITE_UNCERTAINTY: f32 = 0.1;

/// Writes `blob` (exactly one blob) into `out` stating `u_rel` as its white
/// reference's relative standard uncertainty (flag bit 13, the section
/// before the CRC: added, or replaced when the blob has it) and returns the
/// length written: 4 bytes more than `blob` when the section is new. A
/// format version 1 blob is written as version 2 (K = 1), the oldest that
/// carries flags beyond the far-field one; every other byte is kept.
///
/// Nothing is written unless `blob` parses, `u_rel` is finite and within
/// 0 to [`MAX_WHITE_UNCERTAINTY`], and `out` has room; the result is
/// parsed before this returns.
pub fn with_white_uncertainty(blob: &[u8], u_rel: f32, out: &mut [u8]) -> Result<usize, BlobError> {
    check_white_uncertainty(u_rel)?;
    let t = super::stated::Trailing { flag: FLAG_WHITE_UNCERTAINTY, section: Section::WhiteUncertainty };
    super::stated::with_trailing(blob, t, u_rel, out)
}

/// Replaces the white reference of the blob `bytes` (exactly one blob, no
/// signature trailer) with `white` (pixel-major, `P x m`, as
/// [`BlobView::white`] reads it) and seals it again with a new CRC.
///
/// Nothing is changed unless `bytes` parses, `white` has `P x m` values and
/// each is finite and within [`WHITE_RATIO_RANGE`] of the value it
/// replaces; the result is parsed once more before this returns.
pub fn rewrite_white(bytes: &mut [u8], white: &[f32]) -> Result<(), BlobError> {
    let (off, crc_at) = {
        let view = BlobView::parse(bytes)?;
        if bytes.len() != view.lay.total {
            return Err(BlobError::ContentMismatch { section: Section::White });
        }
        if white.len() != view.dims.pixels * view.dims.m {
            return Err(BlobError::ContentMismatch { section: Section::White });
        }
        if let Some(index) = white.iter().position(|x| !x.is_finite()) {
            return Err(BlobError::NonFinite { section: Section::White, index });
        }
        let (lo, hi) = WHITE_RATIO_RANGE;
        let m = view.dims.m;
        if let Some(index) = white.iter().enumerate().position(|(k, x)| {
            let was = view.white(k / m, k % m);
            !(*x >= lo * was && *x <= hi * was)
        }) {
            return Err(BlobError::OutOfRange { section: Section::White, index });
        }
        (view.lay.white, view.lay.crc)
    };
    super::stated::reseal(bytes, off, white, crc_at)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_blobs::test_blob;

    #[test]
    fn the_white_uncertainty_is_added_or_replaced_and_nothing_else_changes() {
        // Version 1 (a Wiener blob with nothing added) and a version 2 one.
        let v1 = test_blob(9, 7, 3, 16, 0.5);
        assert_eq!(BlobView::parse(&v1).unwrap().version(), FORMAT_VERSION_1);
        let parts = crate::test_blobs::TestBlobParts::new(9, 7, 3, 16, 0.5);
        let lin = crate::acquire::Linearity::new([1.0; crate::acquire::linearity::LINEARITY_KNOTS]).unwrap();
        let ex = BlobExtras { linearity: Some(lin), ..BlobExtras::NONE };
        let mut v2 = vec![0u8; parts.dims.blob_len_with(&ex)];
        write_blob_with(&parts.contents(), &ex, &mut v2).unwrap();
        for blob in [v1, v2] {
            let before = BlobView::parse(&blob).unwrap();
            assert_eq!(before.white_uncertainty(), 0.0);
            let mut out = vec![0u8; blob.len() + 4];
            let n = with_white_uncertainty(&blob, 0.004, &mut out).unwrap();
            assert_eq!(n, blob.len() + 4);
            let after = BlobView::parse(&out).unwrap();
            assert_eq!(after.white_uncertainty(), 0.004);
            assert_eq!(after.version(), before.version().max(FORMAT_VERSION_2));
            for p in 0..16 {
                for i in 0..7 {
                    assert_eq!(after.white(p, i), before.white(p, i));
                }
            }
            let (mut a, mut b) = (vec![0.0; 63], vec![0.0; 63]);
            for z in 0..3 {
                before.copy_matrix(z, &mut a);
                after.copy_matrix(z, &mut b);
                assert_eq!(a, b);
                assert_eq!(before.uncertainty(z, 4), after.uncertainty(z, 4));
            }
            assert_eq!(after.linearity(), before.linearity());
            // Stated again, it is replaced in place.
            let mut again = vec![0u8; n + 4];
            let m = with_white_uncertainty(&out[..n], 0.002, &mut again).unwrap();
            assert_eq!(m, n);
            assert_eq!(BlobView::parse(&again).unwrap().white_uncertainty(), 0.002);
            // The white rewritten keeps it.
            let white: Vec<f32> = (0..16 * 7).map(|k| after.white(k / 7, k % 7) * 1.2).collect();
            rewrite_white(&mut again[..m], &white).unwrap();
            assert_eq!(BlobView::parse(&again).unwrap().white_uncertainty(), 0.002);
            // What cannot be stated, or a buffer without room, writes nothing.
            let mut small = vec![0u8; n - 1];
            assert!(matches!(with_white_uncertainty(&blob, 0.004, &mut small), Err(BlobError::TooShort { .. })));
            for bad in [f32::NAN, -0.001, MAX_WHITE_UNCERTAINTY * 1.01] {
                let mut o = vec![0u8; n];
                assert!(with_white_uncertainty(&blob, bad, &mut o).is_err(), "{bad}");
                assert!(o.iter().all(|b| *b == 0));
            }
        }
    }

    #[test]
    fn only_the_white_section_and_the_crc_change() {
        let before = test_blob(9, 7, 3, 16, 0.5);
        let view = BlobView::parse(&before).unwrap();
        let white: Vec<f32> = (0..16 * 7).map(|k| view.white(k / 7, k % 7) * (0.6 + k as f32 / 100.0)).collect();
        let mut after = before.clone();
        rewrite_white(&mut after, &white).unwrap();
        let new = BlobView::parse(&after).unwrap();
        for p in 0..16 {
            for i in 0..7 {
                assert_eq!(new.white(p, i), white[p * 7 + i]);
            }
        }
        assert_ne!(new.crc(), view.crc());
        let (lo, hi) = (view.lay.white, view.lay.white + 4 * 16 * 7);
        let changed: Vec<usize> = (0..before.len()).filter(|&k| before[k] != after[k]).collect();
        assert!(changed.iter().all(|&k| (lo..hi).contains(&k) || k >= view.lay.crc), "{changed:?}");
        // Written back, the first white gives the first blob again, bit for bit.
        let first: Vec<f32> = (0..16 * 7).map(|k| view.white(k / 7, k % 7)).collect();
        rewrite_white(&mut after, &first).unwrap();
        assert_eq!(after, before);
    }

    #[test]
    fn a_bad_white_or_blob_changes_nothing() {
        let before = test_blob(9, 7, 3, 16, 0.5);
        let view = BlobView::parse(&before).unwrap();
        let good: Vec<f32> = (0..16 * 7).map(|k| view.white(k / 7, k % 7) * 1.1).collect();
        let mut b = before.clone();
        let short = &good[..16 * 7 - 1];
        assert_eq!(rewrite_white(&mut b, short), Err(BlobError::ContentMismatch { section: Section::White }));
        let mut bad = good.clone();
        bad[20] = f32::NAN;
        assert_eq!(rewrite_white(&mut b, &bad), Err(BlobError::NonFinite { section: Section::White, index: 20 }));
        for x in [0.0, view.white(2, 6) * 0.49, view.white(2, 6) * 2.01] {
            bad[20] = x;
            assert_eq!(rewrite_white(&mut b, &bad), Err(BlobError::OutOfRange { section: Section::White, index: 20 }));
        }
        assert_eq!(b, before);
        // A blob followed by anything (a signature trailer) is refused whole.
        let mut longer = before.clone();
        longer.extend_from_slice(&[0; 8]);
        assert!(rewrite_white(&mut longer, &good).is_err());
        assert_eq!(&longer[..before.len()], &before[..]);
        // Bytes that are not a blob are left as they are.
        let mut junk = vec![7u8; 100];
        assert!(rewrite_white(&mut junk, &good).is_err());
        assert_eq!(junk, vec![7u8; 100]);
    }
}
