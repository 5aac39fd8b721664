use super::*;
use crate::acquire::linearity::{LINEARITY_KNOTS, Linearity};
use crate::kernel::scale_free::OutOfPriorForm;

// The one test-blob builder's owned parts, changed one at a time below.
use crate::test_blobs::TestBlobParts as Owned;

fn sample(n: usize, m: usize, zones: usize, pixels: usize) -> Owned {
    Owned::new(n, m, zones, pixels, 0.0)
}

fn contents(o: &Owned) -> BlobContents<'_> {
    o.contents()
}

fn encode(o: &Owned) -> Vec<u8> {
    let buf = o.encode();
    assert_eq!(buf.len(), o.dims.blob_len());
    buf
}

#[test]
fn round_trip_preserves_every_field() {
    let o = sample(9, 7, 3, 16);
    let buf = encode(&o);
    let v = BlobView::parse(&buf).unwrap();
    assert_eq!(v.dims(), o.dims);
    assert_eq!(v.noise_rel(), 0.02);
    assert_eq!(v.estimator(), EstimatorKind::Wiener);
    assert!(!v.far_field());
    assert_eq!(v.summary(), contents(&o).summary);
    assert_eq!(v.led_order(), &o.order[..]);
    for i in 0..9 {
        assert_eq!(v.grid_deg(i), o.grid[i]);
    }
    for z in 0..3 {
        assert_eq!(v.zone_start(z), o.zones[z]);
        let mut w = vec![0.0; 63];
        v.copy_matrix(z, &mut w);
        assert_eq!(w, o.mats[z * 63..(z + 1) * 63]);
        assert_eq!(v.w(z, 4, 2), o.mats[z * 63 + 4 * 7 + 2]);
        assert_eq!(v.uncertainty(z, 5), o.unc[z * 9 + 5]);
    }
    assert_eq!(v.white(15, 6), o.white[15 * 7 + 6]);
    assert_eq!(v.zone_of_pixel(0), 0);
    assert_eq!(v.zone_of_pixel(4), 0);
    assert_eq!(v.zone_of_pixel(5), 1);
    assert_eq!(v.zone_of_pixel(15), 2);
}

#[test]
fn trailing_erased_flash_is_ignored() {
    let o = sample(4, 3, 1, 2);
    let mut buf = encode(&o);
    let len = buf.len();
    buf.extend_from_slice(&[0xFF; 37]);
    assert_eq!(BlobView::parse(&buf).unwrap().as_bytes().len(), len);
}

#[test]
fn every_single_byte_corruption_is_rejected() {
    let o = sample(6, 4, 2, 5);
    let buf = encode(&o);
    for pos in 0..buf.len() {
        for flip in [0x01u8, 0x80, 0xFF, 0x5A] {
            let mut bad = buf.clone();
            bad[pos] ^= flip;
            assert!(BlobView::parse(&bad).is_err(), "corruption at byte {pos} (xor {flip:#x}) accepted");
        }
    }
}

#[test]
fn every_truncation_is_rejected() {
    let o = sample(5, 3, 2, 4);
    let buf = encode(&o);
    for len in 0..buf.len() {
        assert!(BlobView::parse(&buf[..len]).is_err(), "truncation to {len} accepted");
    }
}

#[test]
fn semantic_errors_are_refused_even_with_a_good_crc() {
    let mut o = sample(4, 3, 2, 4);
    o.grid[2] = o.grid[1];
    let mut buf = vec![0u8; o.dims.blob_len()];
    assert_eq!(write_blob(&contents(&o), &mut buf), Err(BlobError::GridNotAscending { index: 2 }));
    let mut o = sample(4, 3, 2, 4);
    o.order[1] = o.order[0];
    assert_eq!(write_blob(&contents(&o), &mut buf), Err(BlobError::BadLedOrder { index: 1 }));
    let mut o = sample(4, 3, 2, 4);
    o.mats[7] = f32::NAN;
    assert_eq!(write_blob(&contents(&o), &mut buf), Err(BlobError::NonFinite { section: Section::Matrices, index: 7 }));
    let mut o = sample(4, 3, 2, 4);
    o.zones[1] = 9;
    assert_eq!(write_blob(&contents(&o), &mut buf), Err(BlobError::BadZoneMap { index: 1 }));
    let mut o = sample(4, 3, 2, 4);
    o.white[0] = 0.0;
    assert_eq!(write_blob(&contents(&o), &mut buf), Err(BlobError::OutOfRange { section: Section::White, index: 0 }));
}

#[test]
fn content_of_the_wrong_size_is_refused() {
    let o = sample(4, 3, 2, 4);
    let mut c = contents(&o);
    c.matrices = &o.mats[1..];
    let mut buf = vec![0u8; o.dims.blob_len()];
    assert_eq!(write_blob(&c, &mut buf), Err(BlobError::ContentMismatch { section: Section::Matrices }));
    let mut small = vec![0u8; 10];
    assert_eq!(write_blob(&contents(&o), &mut small), Err(BlobError::BufferTooSmall { need: o.dims.blob_len() }));
}

#[test]
fn in_place_matrix_matches_copy_when_aligned() {
    let o = sample(8, 7, 2, 4);
    let buf = encode(&o);
    // Copy into an f32-aligned buffer.
    let mut aligned = vec![0u32; buf.len() / 4];
    bytemuck::cast_slice_mut::<u32, u8>(&mut aligned).copy_from_slice(&buf);
    let v = BlobView::parse(bytemuck::cast_slice(&aligned)).unwrap();
    let w = v.matrix_in_place(1).unwrap();
    assert_eq!(w, &o.mats[56..112]);
}

/// `b` edited by `edit`, its CRC set again, parsed.
fn resealed(mut b: Vec<u8>, edit: &dyn Fn(&mut Vec<u8>)) -> Result<(), BlobError> {
    edit(&mut b);
    let at = b.len() - 4;
    let crc = CRC32.checksum(&b[..at]);
    put_u32(&mut b, at, crc);
    BlobView::parse(&b).map(|_| ())
}

/// A piecewise blob (K = 3) with the out-of-prior section in `form`
/// and `band_factor`.
fn out_of_prior_blob(form: OutOfPriorForm, band_factor: f32) -> Vec<u8> {
    let o = sample(6, 4, 2, 5);
    let (unc, mats, cents, oop) = v2_extras(&o, 3);
    let mut c = contents(&o);
    c.estimator = EstimatorKind::ScaleFreePiecewise;
    c.uncertainty = &unc;
    c.matrices = &mats;
    let ex = BlobExtras {
        clusters: 3,
        centroids: &cents,
        out_of_prior: Some(OutOfPriorData { threshold: 12.5, form, data: &oop, band_factor }),
        ..BlobExtras::NONE
    };
    let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
    assert_eq!(write_blob_with(&c, &ex, &mut buf), Ok(buf.len()));
    buf
}

/// The same sample as [`out_of_prior_blob`], scale-free without the section.
fn bare_scale_free_blob() -> Vec<u8> {
    let o = sample(6, 4, 2, 5);
    let mut bare = vec![0u8; o.dims.blob_len()];
    let mut cs = contents(&o);
    cs.estimator = EstimatorKind::ScaleFree;
    write_blob(&cs, &mut bare).unwrap();
    bare
}

fn v2_extras(o: &Owned, k: usize) -> (Vec<f32>, Vec<f32>, Vec<f32>, Vec<f32>) {
    let d = o.dims;
    let unc = (0..d.zones * k * d.n).map(|x| 0.001 * x as f32).collect();
    let mats = (0..d.zones * k * d.n * d.m).map(|x| (x as f32).cos()).collect();
    let cents = (0..d.zones * k * d.m).map(|x| 0.1 * x as f32).collect();
    let oop = (0..d.zones * out_of_prior_len(d.m)).map(|x| 1.0 + x as f32).collect();
    (unc, mats, cents, oop)
}

#[test]
fn version_2_round_trips_piecewise_matrices_centroids_and_out_of_prior_data() {
    let o = sample(6, 4, 2, 5);
    let (unc, mats, cents, oop) = v2_extras(&o, 3);
    let buf = out_of_prior_blob(OutOfPriorForm::Linear, 1.0);
    let v = BlobView::parse(&buf).unwrap();
    assert_eq!((v.version(), v.clusters(), v.estimator()), (2, 3, EstimatorKind::ScaleFreePiecewise));
    assert_eq!(v.out_of_prior_threshold(), Some(12.5));
    let mut w = vec![0.0; 24];
    v.copy_matrix_of(1, 2, &mut w);
    assert_eq!(w, mats[(3 + 2) * 24..(3 + 3) * 24]);
    assert_eq!(v.uncertainty_of(1, 2, 5), unc[(3 + 2) * 6 + 5]);
    let mut ce = vec![0.0; 12];
    v.copy_centroids(1, &mut ce);
    assert_eq!(ce, cents[12..24]);
    let (mut mean, mut g) = (vec![0.0; 3], vec![0.0; 6]);
    assert!(v.copy_out_of_prior(1, &mut mean, &mut g));
    assert_eq!(mean, oop[9..12]);
    assert_eq!(g, oop[12..18]);
    for pos in 0..buf.len() {
        let mut bad = buf.clone();
        bad[pos] ^= 0x5A;
        assert!(BlobView::parse(&bad).is_err(), "corruption at byte {pos} accepted");
    }
    // Scale-free with one matrix per zone and no out-of-prior data.
    let buf = bare_scale_free_blob();
    let v = BlobView::parse(&buf).unwrap();
    assert_eq!((v.version(), v.clusters(), v.out_of_prior_threshold()), (2, 1, None));
    assert!(!v.copy_out_of_prior(0, &mut mean, &mut g));
    assert_eq!(v.out_of_prior_form(), None);
}

#[test]
fn the_log_ratio_form_is_flag_bit_4_and_only_with_the_section() {
    let linear = out_of_prior_blob(OutOfPriorForm::Linear, 1.0);
    let log_ratio = out_of_prior_blob(OutOfPriorForm::LogRatio, 1.0);
    // The same bytes but the flag (and so the CRC).
    let differ: Vec<usize> = (0..linear.len()).filter(|i| linear[*i] != log_ratio[*i]).collect();
    assert!(differ.iter().all(|i| *i == 22 || *i >= linear.len() - 4), "{differ:?}");
    assert_eq!(get_u16(&log_ratio, 22) & !get_u16(&linear, 22), FLAG_LOG_RATIO);
    assert_eq!(BlobView::parse(&linear).unwrap().out_of_prior_form(), Some(OutOfPriorForm::Linear));
    assert_eq!(BlobView::parse(&log_ratio).unwrap().out_of_prior_form(), Some(OutOfPriorForm::LogRatio));
    // The form bit without the section is refused, with a good CRC.
    let bare = bare_scale_free_blob();
    let flags = get_u16(&bare, 22) | FLAG_LOG_RATIO;
    assert_eq!(resealed(bare, &|b| put_u16(b, 22, flags)), Err(BlobError::ReservedNotZero));
}

#[test]
fn the_band_factor_is_flag_bit_5_at_offset_56_and_only_with_the_section() {
    let none = out_of_prior_blob(OutOfPriorForm::LogRatio, 1.0);
    let wide = out_of_prior_blob(OutOfPriorForm::LogRatio, 2.5);
    // A factor of 1 writes the blob as before: no flag, offset 56 zero.
    assert_eq!((get_u16(&none, 22) & FLAG_BAND_FACTOR, get_u32(&none, 56)), (0, 0));
    assert_eq!(BlobView::parse(&none).unwrap().out_of_prior_band_factor(), 1.0);
    // Otherwise the flag and the value, and nothing else but the CRC.
    let differ: Vec<usize> = (0..none.len()).filter(|i| none[*i] != wide[*i]).collect();
    assert!(differ.iter().all(|i| *i == 22 || (56..60).contains(i) || *i >= none.len() - 4), "{differ:?}");
    assert_eq!(get_u16(&wide, 22) & !get_u16(&none, 22), FLAG_BAND_FACTOR);
    assert_eq!(BlobView::parse(&wide).unwrap().out_of_prior_band_factor(), 2.5);
    // A factor below 1 or not finite is refused, with a good CRC.
    let bad = |x: f32| resealed(wide.clone(), &|b| put_f32(b, 56, x));
    assert_eq!(bad(0.5), Err(BlobError::OutOfRange { section: Section::Header, index: 56 }));
    assert_eq!(bad(f32::NAN), Err(BlobError::NonFinite { section: Section::Header, index: 56 }));
    assert_eq!(bad(1.0), Ok(()));
    // A value without the flag, or the flag without the section, is refused.
    assert_eq!(resealed(none, &|b| put_f32(b, 56, 2.0)), Err(BlobError::ReservedNotZero));
    let bare = bare_scale_free_blob();
    let flags = get_u16(&bare, 22) | FLAG_BAND_FACTOR;
    assert_eq!(resealed(bare, &|b| put_u16(b, 22, flags)), Err(BlobError::ReservedNotZero));
}

#[test]
fn the_peak_resolution_is_flag_bit_6_at_offset_60_and_is_checked() {
    let o = sample(6, 4, 2, 5);
    let with = |r: Option<f32>| {
        let ex = BlobExtras { peak_resolution_deg: r, ..BlobExtras::NONE };
        let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
        write_blob_with(&contents(&o), &ex, &mut buf).map(|n| {
            buf.truncate(n);
            buf
        })
    };
    // None writes version 1 as before; a value writes version 2, the
    // flag and the value, and it reads back.
    let (bare, res) = (with(None).unwrap(), with(Some(0.75)).unwrap());
    assert_eq!((get_u16(&bare, 4), BlobView::parse(&bare).unwrap().peak_resolution_deg()), (FORMAT_VERSION_1, None));
    assert_eq!(get_u16(&res, 4), FORMAT_VERSION_2);
    assert_eq!(get_u16(&res, 22) & FLAG_PEAK_RESOLUTION, FLAG_PEAK_RESOLUTION);
    assert_eq!(BlobView::parse(&res).unwrap().peak_resolution_deg(), Some(0.75));
    // The writer refuses what the parser would.
    assert_eq!(with(Some(0.0)), Err(BlobError::OutOfRange { section: Section::Header, index: 60 }));
    assert_eq!(with(Some(f32::NAN)), Err(BlobError::NonFinite { section: Section::Header, index: 60 }));
    // So does the parser, with a good CRC: a bad value, a value without
    // the flag, the flag in a version 1 blob.
    let bad = |x: f32| resealed(res.clone(), &|b| put_f32(b, 60, x));
    assert_eq!(bad(-1.0), Err(BlobError::OutOfRange { section: Section::Header, index: 60 }));
    assert_eq!(bad(f32::INFINITY), Err(BlobError::NonFinite { section: Section::Header, index: 60 }));
    let flags = get_u16(&res, 22) & !FLAG_PEAK_RESOLUTION;
    assert_eq!(resealed(res.clone(), &|b| put_u16(b, 22, flags)), Err(BlobError::ReservedNotZero));
    let v1_flags = get_u16(&bare, 22) | FLAG_PEAK_RESOLUTION;
    assert_eq!(resealed(bare, &|b| put_u16(b, 22, v1_flags)), Err(BlobError::ReservedNotZero));
}

#[test]
fn each_pixels_peak_resolution_is_flag_bit_7_after_the_last_section_and_is_checked() {
    let o = sample(6, 4, 2, 5);
    let with = |widest: Option<f32>, own: &[f32]| {
        let ex = BlobExtras { peak_resolution_deg: widest, pixel_peak_resolution_deg: own, ..BlobExtras::NONE };
        let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
        write_blob_with(&contents(&o), &ex, &mut buf).map(|n| {
            buf.truncate(n);
            buf
        })
    };
    let own = [0.5, f32::NAN, 0.75, 0.6, 0.7];
    let (bare, res) = (with(Some(0.75), &[]).unwrap(), with(Some(0.75), &own).unwrap());
    // The section is P values just before the CRC; nothing before it moves.
    assert_eq!(res.len(), bare.len() + 4 * 5);
    assert_eq!(res[64..bare.len() - 4], bare[64..bare.len() - 4]);
    assert_eq!(get_u16(&res, 22) & FLAG_PIXEL_RESOLUTION, FLAG_PIXEL_RESOLUTION);
    let v = BlobView::parse(&res).unwrap();
    // A pixel without its own (NaN) and one past the line take the header's.
    let at: Vec<Option<f32>> = (0..6).map(|p| v.peak_resolution_at(p)).collect();
    assert_eq!(at, [Some(0.5), Some(0.75), Some(0.75), Some(0.6), Some(0.7), Some(0.75)]);
    let b = BlobView::parse(&bare).unwrap();
    assert!((0..5).all(|p| b.peak_resolution_at(p) == Some(0.75)));
    // The writer refuses what the parser would: a width wider than the
    // calibration's, zero, infinite, the wrong count, no header value.
    let oor = |p| BlobError::OutOfRange { section: Section::PeakResolution, index: p };
    assert_eq!(with(Some(0.75), &[0.5, 0.5, 0.8, 0.5, 0.5]), Err(oor(2)));
    assert_eq!(with(Some(0.75), &[0.5, 0.0, 0.5, 0.5, 0.5]), Err(oor(1)));
    assert_eq!(
        with(Some(0.75), &[0.5, 0.5, 0.5, f32::INFINITY, 0.5]),
        Err(BlobError::NonFinite { section: Section::PeakResolution, index: 3 })
    );
    let mismatch = Err(BlobError::ContentMismatch { section: Section::PeakResolution });
    assert_eq!(with(Some(0.75), &own[..4]), mismatch);
    assert_eq!(with(None, &own), mismatch);
    // So does the parser, with a good CRC: a bad value, the section's
    // flag without the header's.
    let at_p = |p: usize| res.len() - 4 - 4 * (5 - p);
    assert_eq!(resealed(res.clone(), &|b| put_f32(b, at_p(4), 0.9)), Err(oor(4)));
    assert_eq!(resealed(res.clone(), &|b| put_f32(b, at_p(0), -0.1)), Err(oor(0)));
    let flags = get_u16(&res, 22) & !FLAG_PEAK_RESOLUTION;
    assert_eq!(
        resealed(res.clone(), &|b| {
            put_u16(b, 22, flags);
            put_f32(b, 60, 0.0)
        }),
        Err(BlobError::ReservedNotZero)
    );
}

#[test]
fn the_second_uncertainty_table_is_flag_bit_8_before_the_crc_and_is_checked() {
    use crate::band::BandTable;
    let o = sample(6, 4, 2, 5);
    let broad: Vec<f32> = (0..12).map(|i| 0.01 * i as f32).collect();
    let with = |table: &[f32]| {
        let ex = BlobExtras { broad_uncertainty: table, ..BlobExtras::NONE };
        let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
        write_blob_with(&contents(&o), &ex, &mut buf).map(|n| {
            buf.truncate(n);
            buf
        })
    };
    let (bare, two) = (with(&[]).unwrap(), with(&broad).unwrap());
    // Version 2, the flag, Z x K x n values just before the CRC; nothing
    // before them moves.
    assert_eq!((get_u16(&bare, 4), get_u16(&two, 4)), (FORMAT_VERSION_1, FORMAT_VERSION_2));
    assert_eq!(get_u16(&two, 22) & FLAG_BROAD_BAND, FLAG_BROAD_BAND);
    assert_eq!(two.len(), bare.len() + 4 * 12);
    assert_eq!(two[64..bare.len() - 4], bare[64..bare.len() - 4]);
    let (v, b) = (BlobView::parse(&two).unwrap(), BlobView::parse(&bare).unwrap());
    assert!(v.has_broad_band() && !b.has_broad_band());
    // A broad point takes the second table, a sharp one the first; a
    // blob without the second gives every point the first.
    assert_eq!(v.uncertainty_in(BandTable::Broad, 1, 0, 2), broad[6 + 2]);
    assert_eq!(v.uncertainty_in(BandTable::Sharp, 1, 0, 2), v.uncertainty_of(1, 0, 2));
    assert_eq!(b.uncertainty_in(BandTable::Broad, 1, 0, 2), b.uncertainty_of(1, 0, 2));
    assert_eq!(v.point_uncertainty(BandTable::Broad, (1, 0), 2, 0.5, -3.0), 3.0 * broad[8]);
    // Bins 1 deg apart: a flat estimate is broad, a one-bin spike sharp.
    let grid: Vec<f32> = (0..6).map(|i| 40.0 + i as f32).collect();
    let flat = [1.0f32; 6];
    let spike = [0.0f32, 0.0, 1.0, 0.0, 0.0, 0.0];
    assert_eq!(v.band_table(&grid, &flat), BandTable::Broad);
    assert_eq!(v.band_table(&grid, &spike), BandTable::Sharp);
    assert_eq!(b.band_table(&grid, &flat), BandTable::Sharp);
    // The writer refuses the wrong count; the parser, with a good CRC,
    // a negative or non-finite value, indexed on from the first table.
    assert_eq!(with(&broad[..11]), Err(BlobError::ContentMismatch { section: Section::Uncertainty }));
    let at = |i: usize| two.len() - 4 - 4 * (12 - i);
    assert_eq!(
        resealed(two.clone(), &|b| put_f32(b, at(3), -0.5)),
        Err(BlobError::OutOfRange { section: Section::Uncertainty, index: 12 + 3 })
    );
    assert_eq!(
        resealed(two.clone(), &|b| put_f32(b, at(0), f32::NAN)),
        Err(BlobError::NonFinite { section: Section::Uncertainty, index: 12 })
    );
    // The flag without its table is a length mismatch; in a version 1
    // blob, a reserved flag.
    let flags = get_u16(&two, 22) & !FLAG_BROAD_BAND;
    assert!(matches!(resealed(two.clone(), &|b| put_u16(b, 22, flags)), Err(BlobError::LengthMismatch { .. })));
    let v1_flags = get_u16(&bare, 22) | FLAG_BROAD_BAND;
    assert_eq!(resealed(bare, &|b| put_u16(b, 22, v1_flags)), Err(BlobError::ReservedNotZero));
}

#[test]
fn version_1_is_still_written_and_read_as_before_and_v2_rules_hold() {
    let o = sample(6, 4, 2, 5);
    let buf = encode(&o);
    assert_eq!(get_u16(&buf, 4), FORMAT_VERSION_1);
    assert_eq!(BlobView::parse(&buf).unwrap().version(), 1);
    // A version 1 blob cannot carry a scale-free kind.
    let mut bad = buf.clone();
    put_u16(&mut bad, 20, EstimatorKind::ScaleFree as u16);
    let crc_at = bad.len() - 4;
    let crc = CRC32.checksum(&bad[..crc_at]);
    put_u32(&mut bad, crc_at, crc);
    assert_eq!(BlobView::parse(&bad).unwrap_err(), BlobError::UnknownEstimator(6));
    // Piecewise needs K >= 2; other kinds K = 1.
    let (unc, mats, cents, _) = v2_extras(&o, 1);
    let mut c = contents(&o);
    c.estimator = EstimatorKind::ScaleFreePiecewise;
    c.uncertainty = &unc;
    c.matrices = &mats;
    let ex = BlobExtras { clusters: 1, centroids: &cents, out_of_prior: None, ..BlobExtras::NONE };
    let mut out = vec![0u8; 4096];
    assert!(matches!(write_blob_with(&c, &ex, &mut out), Err(BlobError::BadDimension { field: "clusters", .. })));
    // The threshold must be positive.
    let oop = vec![0.5; 2 * out_of_prior_len(4)];
    let c = contents(&o);
    let ex = BlobExtras {
        clusters: 1,
        centroids: &[],
        out_of_prior: Some(OutOfPriorData {
            threshold: 0.0,
            form: OutOfPriorForm::Linear,
            data: &oop,
            band_factor: 1.0,
        }),
        ..BlobExtras::NONE
    };
    assert_eq!(
        write_blob_with(&c, &ex, &mut out),
        Err(BlobError::OutOfRange { section: Section::OutOfPrior, index: 0 })
    );
    let ex = BlobExtras {
        clusters: 1,
        centroids: &[],
        out_of_prior: Some(OutOfPriorData {
            threshold: 3.0,
            form: OutOfPriorForm::Linear,
            data: &oop[1..],
            band_factor: 1.0,
        }),
        ..BlobExtras::NONE
    };
    assert_eq!(write_blob_with(&c, &ex, &mut out), Err(BlobError::ContentMismatch { section: Section::OutOfPrior }));
}

#[test]
fn a_zone_without_a_gloss_reading_is_all_nan_and_nothing_else_is() {
    let o = sample(6, 4, 3, 5);
    let (unc, mats, cents, oop) = v2_extras(&o, 2);
    let (mut reference, mut blocks) = gloss_parts(&o, 2);
    let bl = crate::gloss::block_len(4);
    // Zone 1 cannot see the standard.
    reference[1] = f32::NAN;
    blocks[2 * bl..4 * bl].fill(f32::NAN);
    let mut c = contents(&o);
    c.estimator = EstimatorKind::ScaleFreePiecewise;
    c.uncertainty = &unc;
    c.matrices = &mats;
    let g = gloss_data(&reference, &blocks, &[]);
    let ex = BlobExtras {
        clusters: 2,
        centroids: &cents,
        out_of_prior: Some(OutOfPriorData {
            threshold: 2.0,
            form: OutOfPriorForm::Linear,
            data: &oop,
            band_factor: 1.0,
        }),
        gloss: Some(g),
        ..BlobExtras::NONE
    };
    let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
    write_blob_with(&c, &ex, &mut buf).unwrap();
    let v = BlobView::parse(&buf).unwrap();
    let mut block = vec![0.0; bl];
    let (_, _, s) = v.copy_gloss(1, 1, &mut block).unwrap();
    assert!(s.is_nan() && block.iter().all(|x| x.is_nan()));
    assert_eq!(v.copy_gloss(2, 0, &mut block), Some((100.0, 1.567, 82.0)));
    assert!(block.iter().all(|x| x.is_finite()));
    let lay = o.dims.layout_with(&Extras::of(&ex, EstimatorKind::ScaleFreePiecewise, &o.dims));
    let resealed = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = buf.clone();
        f(&mut b);
        let at = b.len() - 4;
        let crc = CRC32.checksum(&b[..at]);
        put_u32(&mut b, at, crc);
        BlobView::parse(&b).map(|_| ())
    };
    let head = 2 + 3;
    // A finite value in the marked zone's blocks, a NaN in another zone's,
    // a NaN reference over finite blocks: all refused.
    let in_zone1 = head + 2 * bl + 7;
    assert_eq!(
        resealed(&|b| put_f32(b, lay.gloss + 4 * in_zone1, 0.5)),
        Err(BlobError::OutOfRange { section: Section::Gloss, index: in_zone1 })
    );
    let in_zone2 = head + 4 * bl + 3;
    assert_eq!(
        resealed(&|b| put_f32(b, lay.gloss + 4 * in_zone2, f32::NAN)),
        Err(BlobError::NonFinite { section: Section::Gloss, index: in_zone2 })
    );
    assert_eq!(
        resealed(&|b| put_f32(b, lay.gloss + 4 * 2, f32::NAN)),
        Err(BlobError::NonFinite { section: Section::Gloss, index: 2 })
    );
    // The assigned value is never NaN.
    assert_eq!(
        resealed(&|b| put_f32(b, lay.gloss, f32::NAN)),
        Err(BlobError::NonFinite { section: Section::Gloss, index: 0 })
    );
}

/// A gloss section on the black glass (100 GU, n = 1.567).
fn gloss_data<'a>(reference: &'a [f32], blocks: &'a [f32], centroids: &'a [f32]) -> GlossData<'a> {
    GlossData {
        assigned_gu: 100.0,
        refractive_index: 1.567,
        reference,
        blocks,
        centroids,
        root_readings: crate::gloss::RootReadings::Shoulders,
    }
}

/// A version 3 blob's gloss section for `o` with K clusters.
fn gloss_parts(o: &Owned, k: usize) -> (Vec<f32>, Vec<f32>) {
    let d = o.dims;
    let reference = (0..d.zones).map(|z| 80.0 + z as f32).collect();
    let bl = crate::gloss::block_len(d.m);
    let blocks = (0..d.zones * k * bl)
        .map(|i| if (i % bl) >= crate::gloss::LINEAR * d.m { 0.25 } else { (i as f32 * 0.3).sin() })
        .collect();
    (reference, blocks)
}

/// A piecewise blob (K = 3) with a version 4 gloss section whose rows
/// have `kg` clusters of their own (`kg = 0`: the maps').
fn gloss_clusters_blob(kg: usize, centroids: &[f32]) -> Result<Vec<u8>, BlobError> {
    gloss_clusters_blob_of(EstimatorKind::ScaleFreePiecewise, kg, centroids)
}

/// [`gloss_clusters_blob`] labelled as estimator `kind`.
fn gloss_clusters_blob_of(kind: EstimatorKind, kg: usize, centroids: &[f32]) -> Result<Vec<u8>, BlobError> {
    gloss_blob(kind, kg, centroids, false, crate::gloss::RootReadings::Shoulders)
}

/// A K = 3 blob of estimator `kind` with a version 4 gloss section whose
/// rows have `kg` clusters of their own (`kg = 0`: the maps'), in the
/// root form or not, its rows read in `form`.
fn gloss_blob(
    kind: EstimatorKind,
    kg: usize,
    centroids: &[f32],
    root_form: bool,
    form: crate::gloss::RootReadings,
) -> Result<Vec<u8>, BlobError> {
    let o = sample(6, 4, 2, 5);
    let (unc, mats, cents, _) = v2_extras(&o, 3);
    let (_, blocks) = gloss_parts(&o, if kg == 0 { 3 } else { kg });
    let reference: Vec<f32> = (0..o.dims.pixels).map(|p| 90.0 + p as f32).collect();
    let mut c = contents(&o);
    c.estimator = kind;
    c.uncertainty = &unc;
    c.matrices = &mats;
    let g = GlossData { root_readings: form, ..gloss_data(&reference, &blocks, centroids) };
    let ex = BlobExtras { clusters: 3, centroids: &cents, gloss: Some(g), root_form, ..BlobExtras::NONE };
    let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
    write_blob_with(&c, &ex, &mut buf).map(|n| {
        buf.truncate(n);
        buf
    })
}

#[test]
fn the_gloss_rows_own_clusters_are_flag_bit_9_with_k_g_at_offset_50_and_are_checked() {
    let (z, m, kg) = (2, 4, 5);
    // Each centroid a distinct point of the shares' simplex.
    let cents: Vec<f32> = (0..z * kg)
        .flat_map(|c| {
            let v: Vec<f32> = (0..m).map(|i| 1.0 + ((7 * c + 3 * i) % 11) as f32).collect();
            let s: f32 = v.iter().sum();
            v.into_iter().map(move |x| x / s)
        })
        .collect();
    let (maps, own) = (gloss_clusters_blob(0, &[]).unwrap(), gloss_clusters_blob(kg, &cents).unwrap());
    // Without the bit: K blocks per zone, offset 50 zero, a point's
    // block its BRDF cluster's.
    let v0 = BlobView::parse(&maps).unwrap();
    assert_eq!((v0.gloss_clusters(), v0.has_gloss_centroids(), get_u16(&maps, 50)), (3, false, 0));
    assert!(!v0.copy_gloss_centroids(1, &mut [0.0; 12]));
    // With it: K_g in the header, K_g blocks per zone, then the centroids.
    let v = BlobView::parse(&own).unwrap();
    assert_eq!(get_u16(&own, 22) & FLAG_GLOSS_CLUSTERS, FLAG_GLOSS_CLUSTERS);
    assert_eq!((v.gloss_clusters(), v.clusters(), get_u16(&own, 50)), (kg, 3, kg as u16));
    let bl = crate::gloss::block_len(m);
    assert_eq!(own.len(), maps.len() + 4 * (z * (kg - 3) * bl + z * kg * m));
    let mut got = vec![0.0; kg * m];
    assert!(v.copy_gloss_centroids(1, &mut got));
    assert_eq!(got, cents[kg * m..]);
    let (_, blocks) = gloss_parts(&sample(6, 4, 2, 5), kg);
    let mut block = vec![0.0; bl];
    v.copy_gloss(1, 4, &mut block).unwrap();
    assert_eq!(block, blocks[(kg + 4) * bl..(kg + 5) * bl]);
    // In place, a point's block is the one its readings select among its
    // zone's gloss centroids, whatever its BRDF cluster.
    let aligned: Vec<u32> = own.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect();
    let bytes: &[u8] = bytemuck::cast_slice(&aligned);
    let g = BlobView::parse(bytes).unwrap().gloss_in_place().unwrap();
    assert_eq!(g.centroids, &cents[..]);
    let near_3 = &cents[(kg + 3) * m..(kg + 4) * m];
    let pick = crate::kernel::select_cluster(&cents[kg * m..], near_3);
    assert_eq!(pick, 3);
    assert_eq!(g.block(1, 0, kg, near_3), &blocks[(kg + 3) * bl..(kg + 4) * bl]);
    // The writer refuses centroids that are not Z x K_g x m (one too
    // many: K_g still matches the blocks; one too few: it does not); a
    // count of 1 or over the limit; the rows' clusters without the
    // piecewise kind.
    let mismatch = Err(BlobError::ContentMismatch { section: Section::Gloss });
    let one_more: Vec<f32> = cents.iter().copied().chain([0.25]).collect();
    assert_eq!(gloss_clusters_blob(kg, &one_more), mismatch);
    assert_eq!(gloss_clusters_blob(kg, &cents[1..]), mismatch);
    assert!(matches!(
        gloss_clusters_blob(1, &cents[..z * m]),
        Err(BlobError::BadDimension { field: "gloss clusters", value: 1 })
    ));
    let over = MAX_CLUSTERS + 1;
    let many: Vec<f32> = (0..z * over * m).map(|i| 0.25 + (i % 7) as f32 * 0.01).collect();
    assert!(matches!(
        gloss_clusters_blob(over, &many),
        Err(BlobError::BadDimension { field: "gloss clusters", value }) if usize::from(value) == over
    ));
    assert!(matches!(
        gloss_clusters_blob_of(EstimatorKind::ScaleFree, kg, &cents),
        Err(BlobError::BadDimension { field: "gloss clusters", .. })
    ));
    // The parser: a non-finite centroid, K_g 0 or over the limit, the
    // bit on another kind, the bit without the gloss section, offset
    // 50 set without the bit.
    let first_centroid = own.len() - 4 - 4 * z * kg * m;
    assert_eq!(
        resealed(own.clone(), &|b| put_f32(b, first_centroid + 4, f32::INFINITY)),
        Err(BlobError::NonFinite { section: Section::Gloss, index: gloss_len(5, z, kg, m) + 1 })
    );
    assert_eq!(
        resealed(own.clone(), &|b| put_u16(b, 50, 0)),
        Err(BlobError::BadDimension { field: "gloss clusters", value: 0 })
    );
    assert_eq!(
        resealed(own.clone(), &|b| put_u16(b, 50, over as u16)),
        Err(BlobError::BadDimension { field: "gloss clusters", value: over as u16 })
    );
    let scale_free = EstimatorKind::ScaleFree as u16;
    assert_eq!(
        resealed(own.clone(), &|b| put_u16(b, 20, scale_free)),
        Err(BlobError::BadDimension { field: "gloss clusters", value: kg as u16 })
    );
    let bare = out_of_prior_blob(OutOfPriorForm::Linear, 1.0);
    let flags = get_u16(&bare, 22) | FLAG_GLOSS_CLUSTERS;
    assert!(matches!(
        resealed(bare.clone(), &|b| {
            put_u16(b, 22, flags);
            put_u16(b, 50, 4);
        }),
        Err(BlobError::BadDimension { field: "gloss clusters", .. })
    ));
    assert_eq!(resealed(maps, &|b| put_u16(b, 50, 4)), Err(BlobError::ReservedNotZero));
}

/// A piecewise blob with a version 4 gloss section (the maps'
/// clusters), in the root form or not, its rows read in `form`.
fn deficit_readings_blob(root_form: bool, form: crate::gloss::RootReadings) -> Result<Vec<u8>, BlobError> {
    gloss_blob(EstimatorKind::ScaleFreePiecewise, 0, &[], root_form, form)
}

#[test]
fn the_deficit_readings_are_flag_bit_10_of_the_root_forms_gloss_rows() {
    use crate::gloss::RootReadings::{Deficit, Shoulders};
    let shoulders = deficit_readings_blob(true, Shoulders).unwrap();
    let deficit = deficit_readings_blob(true, Deficit).unwrap();
    // Same layout and values; only the flag differs (and the CRC).
    assert_eq!(shoulders.len(), deficit.len());
    assert_eq!(get_u16(&deficit, 22), get_u16(&shoulders, 22) | FLAG_DEFICIT_READINGS);
    assert_eq!(shoulders[24..shoulders.len() - 4], deficit[24..deficit.len() - 4]);
    // The view and the in-place section say which row the device reads.
    assert_eq!(BlobView::parse(&shoulders).unwrap().root_readings(), Shoulders);
    let v = BlobView::parse(&deficit).unwrap();
    assert_eq!(v.root_readings(), Deficit);
    let aligned: Vec<u32> = deficit.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect();
    let bytes: &[u8] = bytemuck::cast_slice(&aligned);
    assert_eq!(BlobView::parse(bytes).unwrap().gloss_in_place().unwrap().root_readings, Deficit);
    // The deficit is a root: the writer refuses it outside the root
    // form, and the parser refuses the bit there or without the gloss
    // section.
    assert_eq!(deficit_readings_blob(false, Deficit), Err(BlobError::ReservedNotZero));
    let linear = deficit_readings_blob(false, Shoulders).unwrap();
    let flags = get_u16(&linear, 22) | FLAG_DEFICIT_READINGS;
    assert_eq!(resealed(linear, &|b| put_u16(b, 22, flags)), Err(BlobError::ReservedNotZero));
    let bare = out_of_prior_blob(OutOfPriorForm::Linear, 1.0);
    let flags = get_u16(&bare, 22) | FLAG_ROOT | FLAG_DEFICIT_READINGS;
    assert_eq!(resealed(bare, &|b| put_u16(b, 22, flags)), Err(BlobError::ReservedNotZero));
}

#[test]
fn the_sensors_linearity_is_flag_bit_11_and_its_factors_before_the_crc() {
    let o = sample(6, 4, 2, 5);
    let c = contents(&o);
    let factors: [f32; LINEARITY_KNOTS] = core::array::from_fn(|k| 1.04 - 0.0025 * k as f32);
    let lin = Linearity::new(factors).unwrap();
    let ex = BlobExtras { linearity: Some(lin), ..BlobExtras::NONE };
    let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
    assert_eq!(write_blob_with(&c, &ex, &mut buf), Ok(buf.len()));
    assert_eq!(buf.len(), o.dims.blob_len() + 4 * LINEARITY_KNOTS);
    let v = BlobView::parse(&buf).unwrap();
    // A version 1 blob's kind, but the flag needs version 2's header.
    assert_eq!((v.version(), get_u16(&buf, 22)), (FORMAT_VERSION_2, FLAG_LINEARITY));
    assert_eq!(v.linearity(), Some(lin));
    // Everything else reads as the blob without it (no second table).
    assert!(!v.has_broad_band());
    let plain = encode(&o);
    assert_eq!(BlobView::parse(&plain).unwrap().linearity(), None);
    assert_eq!(buf[64..plain.len() - 4], plain[64..plain.len() - 4]);
    // A factor out of range, not finite, or a falling response: refused,
    // naming the knot.
    let at = buf.len() - 4 - 4 * LINEARITY_KNOTS;
    let edit = |k: usize, x: f32| resealed(buf.clone(), &move |b| put_f32(b, at + 4 * k, x));
    let section = Section::Linearity;
    assert_eq!(edit(5, 9.0), Err(BlobError::OutOfRange { section, index: 5 }));
    assert_eq!(edit(16, f32::NAN), Err(BlobError::NonFinite { section, index: 16 }));
    assert_eq!(edit(9, 0.6), Err(BlobError::OutOfRange { section, index: 8 }));
    // The bit in a version 1 header is reserved.
    let flagged = resealed(plain, &|b| put_u16(b, 22, FLAG_LINEARITY));
    assert_eq!(flagged, Err(BlobError::ReservedNotZero));
}

#[test]
fn the_peaks_uncertainty_factors_are_flag_bit_12_after_the_linearity() {
    let o = sample(6, 4, 2, 5);
    let c = contents(&o);
    let lin = Linearity::new([1.0; LINEARITY_KNOTS]).unwrap();
    let factors = PeakFactors { height: 1.25, width: 0.8 };
    let ex = BlobExtras {
        peak_resolution_deg: Some(0.9),
        linearity: Some(lin),
        peak_factors: Some(factors),
        ..BlobExtras::NONE
    };
    let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
    assert_eq!(write_blob_with(&c, &ex, &mut buf), Ok(buf.len()));
    assert_eq!(buf.len(), o.dims.blob_len() + 4 * LINEARITY_KNOTS + 8);
    let v = BlobView::parse(&buf).unwrap();
    assert_eq!(get_u16(&buf, 22), FLAG_PEAK_RESOLUTION | FLAG_LINEARITY | FLAG_PEAK_FACTORS);
    assert_eq!((v.peak_factors(), v.linearity()), (Some(factors), Some(lin)));
    assert_eq!(get_f32(&buf, buf.len() - 12), 1.25, "height, then width, just before the CRC");
    // Without them the blob reads as before.
    let without = BlobExtras { peak_factors: None, ..ex };
    let mut plain = vec![0u8; o.dims.blob_len_with(&without)];
    write_blob_with(&c, &without, &mut plain).unwrap();
    assert_eq!(BlobView::parse(&plain).unwrap().peak_factors(), None);
    assert_eq!(buf[64..plain.len() - 4], plain[64..plain.len() - 4]);
    // A factor not finite or not above zero: refused, naming it.
    let section = Section::PeakFactors;
    let at = buf.len() - 12;
    let edit = |k: usize, x: f32| resealed(buf.clone(), &move |b| put_f32(b, at + 4 * k, x));
    assert_eq!(edit(1, f32::INFINITY), Err(BlobError::NonFinite { section, index: 1 }));
    assert_eq!(edit(0, 0.0), Err(BlobError::OutOfRange { section, index: 0 }));
    // Only with the peak resolution they scale the peaks of: the writer
    // refuses them without it, and so does the parser.
    let alone = BlobExtras { peak_resolution_deg: None, ..ex };
    let mut out = vec![0u8; o.dims.blob_len_with(&alone)];
    assert_eq!(write_blob_with(&c, &alone, &mut out), Err(BlobError::ContentMismatch { section }));
    let flags = FLAG_LINEARITY | FLAG_PEAK_FACTORS;
    assert_eq!(
        resealed(buf.clone(), &move |b| {
            put_u16(b, 22, flags);
            put_u32(b, 60, 0);
        }),
        Err(BlobError::ReservedNotZero)
    );
}

#[test]
fn version_4_carries_one_gloss_reference_per_pixel() {
    let o = sample(6, 4, 2, 5);
    let (_, blocks) = gloss_parts(&o, 1);
    let d = o.dims;
    let reference: Vec<f32> = (0..d.pixels).map(|p| 90.0 + p as f32).collect();
    let c = contents(&o);
    let g = gloss_data(&reference, &blocks, &[]);
    let ex = BlobExtras { gloss: Some(g), ..BlobExtras::NONE };
    let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
    assert_eq!(write_blob_with(&c, &ex, &mut buf), Ok(buf.len()));
    assert_eq!(buf.len(), o.dims.blob_len() + 4 * gloss_len(d.pixels, d.zones, 1, 4));
    let v = BlobView::parse(&buf).unwrap();
    assert_eq!(v.version(), 4);
    for p in 0..d.pixels {
        assert_eq!(v.gloss_reference(p), Some(90.0 + p as f32));
        assert_eq!(g.reference_for(p, v.zone_of_pixel(p), d.pixels), 90.0 + p as f32);
    }
    // copy_gloss gives the zone's first pixel's reference.
    let mut block = vec![0.0; crate::gloss::block_len(4)];
    assert_eq!(v.copy_gloss(1, 0, &mut block).unwrap().2, 90.0 + v.zone_start(1) as f32);
    // A zone without a reading: NaN at each of its pixels and in its blocks, or refused.
    let z1 = v.zone_start(1) as usize;
    let mut r2 = reference.clone();
    let mut b2 = blocks.clone();
    let bl = crate::gloss::block_len(4);
    r2[z1..].fill(f32::NAN);
    b2[bl..].fill(f32::NAN);
    let g2 = GlossData { reference: &r2, blocks: &b2, ..g };
    let ex2 = BlobExtras { gloss: Some(g2), ..BlobExtras::NONE };
    assert_eq!(write_blob_with(&c, &ex2, &mut buf), Ok(buf.len()));
    r2[z1] = 95.0;
    let g3 = GlossData { reference: &r2, blocks: &b2, ..g };
    let ex3 = BlobExtras { gloss: Some(g3), ..BlobExtras::NONE };
    assert!(write_blob_with(&c, &ex3, &mut buf).is_err(), "a reading pixel in a zone without a reading");
}

#[test]
fn version_3_carries_the_gloss_section_and_its_rules_hold() {
    let o = sample(6, 4, 2, 5);
    let (reference, blocks) = gloss_parts(&o, 1);
    let c = contents(&o);
    let g = gloss_data(&reference, &blocks, &[]);
    let ex = BlobExtras { gloss: Some(g), ..BlobExtras::NONE };
    let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
    assert_eq!(write_blob_with(&c, &ex, &mut buf), Ok(buf.len()));
    assert_eq!(buf.len(), o.dims.blob_len() + 4 * gloss_len(2, 2, 1, 4));
    let v = BlobView::parse(&buf).unwrap();
    assert_eq!((v.version(), v.clusters(), v.estimator(), v.has_gloss()), (3, 1, EstimatorKind::Wiener, true));
    let mut block = vec![0.0; crate::gloss::block_len(4)];
    assert_eq!(v.copy_gloss(1, 0, &mut block), Some((100.0, 1.567, 81.0)));
    assert_eq!(block, blocks[block.len()..]);
    let mut aligned = vec![0u32; buf.len() / 4];
    bytemuck::cast_slice_mut::<u32, u8>(&mut aligned).copy_from_slice(&buf);
    let va = BlobView::parse(bytemuck::cast_slice(&aligned)).unwrap();
    assert_eq!(va.gloss_in_place(), Some(g));
    for pos in 0..buf.len() {
        let mut bad = buf.clone();
        bad[pos] ^= 0x5A;
        assert!(BlobView::parse(&bad).is_err(), "corruption at byte {pos} accepted");
    }
    // A blob without the section: as before, and no readings.
    let old = encode(&o);
    let vo = BlobView::parse(&old).unwrap();
    assert_eq!((vo.version(), vo.has_gloss(), vo.copy_gloss(0, 0, &mut block)), (1, false, None));
    // The flag bit and the version go together, with a good CRC.
    assert_eq!(resealed(buf.clone(), &|b| put_u16(b, 4, 2)), Err(BlobError::ReservedNotZero));
    assert_eq!(resealed(old.clone(), &|b| put_u16(b, 22, 4)), Err(BlobError::ReservedNotZero));
    assert_eq!(resealed(buf.clone(), &|b| put_u16(b, 4, 5)), Err(BlobError::UnsupportedVersion(5)));
    // Relabelled version 4, it would need one reference per pixel.
    assert!(matches!(resealed(buf.clone(), &|b| put_u16(b, 4, 4)), Err(BlobError::LengthMismatch { .. })));
    // Every malformed value is named by its index in the section.
    let lay = o.dims.layout_with(&Extras::of(&ex, EstimatorKind::Wiener, &o.dims));
    let bl = crate::gloss::block_len(4);
    let cov00 = 2 + 2 + 4 * 4;
    for (i, x, want) in [
        (0, 0.0, BlobError::OutOfRange { section: Section::Gloss, index: 0 }),
        (1, 1.0, BlobError::OutOfRange { section: Section::Gloss, index: 1 }),
        (3, -1.0, BlobError::OutOfRange { section: Section::Gloss, index: 3 }),
        (5, f32::NAN, BlobError::NonFinite { section: Section::Gloss, index: 5 }),
        (cov00 + bl, -0.5, BlobError::OutOfRange { section: Section::Gloss, index: cov00 + bl }),
    ] {
        assert_eq!(resealed(buf.clone(), &|b| put_f32(b, lay.gloss + 4 * i, x)), Err(want), "index {i}");
    }
    // An off-diagonal covariance and a row may be negative.
    assert_eq!(resealed(buf.clone(), &|b| put_f32(b, lay.gloss + 4 * (cov00 + 1), -0.5)), Ok(()));
    assert_eq!(resealed(buf.clone(), &|b| put_f32(b, lay.gloss + 4 * 4, -7.0)), Ok(()));
    // The writer checks the section's size.
    let short = GlossData { blocks: &blocks[1..], ..g };
    let ex = BlobExtras { gloss: Some(short), ..BlobExtras::NONE };
    assert_eq!(write_blob_with(&c, &ex, &mut buf), Err(BlobError::ContentMismatch { section: Section::Gloss }));
    // With K clusters (piecewise scale-free), blocks per zone and cluster.
    let (unc, mats, cents, oop) = v2_extras(&o, 3);
    let (reference, blocks) = gloss_parts(&o, 3);
    let mut c = contents(&o);
    c.estimator = EstimatorKind::ScaleFreePiecewise;
    c.uncertainty = &unc;
    c.matrices = &mats;
    let ex = BlobExtras {
        clusters: 3,
        centroids: &cents,
        out_of_prior: Some(OutOfPriorData {
            threshold: 2.0,
            form: OutOfPriorForm::Linear,
            data: &oop,
            band_factor: 1.0,
        }),
        gloss: Some(GlossData { reference: &reference, blocks: &blocks, ..g }),
        ..BlobExtras::NONE
    };
    let mut buf = vec![0u8; o.dims.blob_len_with(&ex)];
    write_blob_with(&c, &ex, &mut buf).unwrap();
    let v = BlobView::parse(&buf).unwrap();
    assert_eq!(v.copy_gloss(1, 2, &mut block), Some((100.0, 1.567, 81.0)));
    assert_eq!(block, blocks[5 * bl..6 * bl]);
    let (mut mean, mut gg) = (vec![0.0; 3], vec![0.0; 6]);
    assert!(v.copy_out_of_prior(1, &mut mean, &mut gg));
    assert_eq!(mean, oop[9..12]);
}
