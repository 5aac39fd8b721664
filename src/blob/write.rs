//! Writing a blob: the oldest format version it fits, checked by the one
//! parser before it leaves the host.

use super::*;
use crate::kernel::scale_free::OutOfPriorForm;

/// Writes `c` into `out` and returns the number of bytes written.
///
/// The result always parses: the same checks [`BlobView::parse`] applies are
/// applied here before anything is written.
pub fn write_blob(c: &BlobContents<'_>, out: &mut [u8]) -> Result<usize, BlobError> {
    write_blob_with(c, &BlobExtras::NONE, out)
}

/// [`write_blob`] with the sections of format version 2 (written as version
/// 1 when `extras` adds nothing and the estimator kind is a version 1 kind).
/// For K > 1, `c.uncertainty` is Z x K x n and `c.matrices` Z x K x n x m.
pub fn write_blob_with(c: &BlobContents<'_>, extras: &BlobExtras<'_>, out: &mut [u8]) -> Result<usize, BlobError> {
    let d = c.dims;
    d.check()?;
    let ex = Extras::of(extras, c.estimator, &d);
    ex.check(c.estimator)?;
    let v2 = ex.needs_v2(c.estimator);
    let lay = d.layout_with(&ex);
    let k = lay.clusters;
    let sized = |ok: bool, section| if ok { Ok(()) } else { Err(BlobError::ContentMismatch { section }) };
    sized(c.grid_deg.len() == d.n, Section::Grid)?;
    sized(c.led_order.len() == d.m, Section::LedOrder)?;
    sized(c.zone_start.len() == d.zones, Section::Zones)?;
    sized(c.white.len() == d.pixels * d.m, Section::White)?;
    sized(c.uncertainty.len() == d.zones * k * d.n, Section::Uncertainty)?;
    sized(!ex.broad_band || extras.broad_uncertainty.len() == d.zones * k * d.n, Section::Uncertainty)?;
    sized(c.matrices.len() == d.zones * k * d.n * d.m, Section::Matrices)?;
    sized(extras.centroids.len() == if ex.piecewise { d.zones * k * d.m } else { 0 }, Section::Centroids)?;
    if let Some(o) = &extras.out_of_prior {
        sized(d.m >= 2 && o.data.len() == d.zones * out_of_prior_len(d.m), Section::OutOfPrior)?;
    }
    if let Some(g) = &extras.gloss {
        let kg = lay.gloss_clusters;
        sized(
            (g.reference.len() == d.pixels || g.reference.len() == d.zones)
                && g.blocks.len() == d.zones * kg * crate::gloss::block_len(d.m)
                && g.centroids.len() == if ex.gloss_clusters > 0 { d.zones * kg * d.m } else { 0 },
            Section::Gloss,
        )?;
    }
    if let Some(r) = extras.peak_resolution_deg {
        check_peak_resolution(r)?;
    }
    if ex.pixel_resolution {
        sized(extras.pixel_peak_resolution_deg.len() == d.pixels, Section::PeakResolution)?;
        let widest =
            extras.peak_resolution_deg.ok_or(BlobError::ContentMismatch { section: Section::PeakResolution })?;
        for (p, r) in extras.pixel_peak_resolution_deg.iter().enumerate() {
            check_pixel_resolution(*r, widest, p)?;
        }
    }
    if let Some(u) = extras.white_uncertainty {
        check_white_uncertainty(u)?;
    }
    if let Some(u) = extras.gloss_uncertainty {
        check_gloss_uncertainty(u)?;
        if !ex.gloss {
            return Err(BlobError::ContentMismatch { section: Section::GlossUncertainty });
        }
    }
    if ex.peak_factors && !ex.peak_resolution {
        return Err(BlobError::ContentMismatch { section: Section::PeakFactors });
    }
    if out.len() < lay.total {
        return Err(BlobError::BufferTooSmall { need: lay.total });
    }
    let out = &mut out[..lay.total];
    out.fill(0);
    out[0..4].copy_from_slice(&MAGIC);
    let version = if ex.gloss && ex.gloss_refs == d.pixels {
        FORMAT_VERSION
    } else if ex.gloss {
        FORMAT_VERSION_3
    } else if v2 {
        FORMAT_VERSION_2
    } else {
        FORMAT_VERSION_1
    };
    let v2 = v2 || ex.gloss;
    put_u16(out, 4, version);
    put_u16(out, 6, HEADER_LEN as u16);
    put_u16(out, 8, d.n as u16);
    put_u16(out, 10, d.m as u16);
    put_u16(out, 12, d.zones as u16);
    put_u16(out, 14, d.pixels as u16);
    put_f32(out, 16, c.noise_rel);
    put_u16(out, 20, c.estimator as u16);
    let oop_flag = match extras.out_of_prior {
        Some(OutOfPriorData { form: OutOfPriorForm::LogRatio, .. }) => FLAG_OUT_OF_PRIOR | FLAG_LOG_RATIO,
        Some(_) => FLAG_OUT_OF_PRIOR,
        None => 0,
    } | match extras.out_of_prior {
        Some(o) if o.band_factor != 1.0 => FLAG_BAND_FACTOR,
        _ => 0,
    };
    let gloss_flag = if ex.gloss { FLAG_GLOSS } else { 0 };
    let root_flag = if ex.root_form { FLAG_ROOT } else { 0 };
    let resolution_flag = if ex.peak_resolution { FLAG_PEAK_RESOLUTION } else { 0 }
        | if ex.pixel_resolution { FLAG_PIXEL_RESOLUTION } else { 0 }
        | if ex.broad_band { FLAG_BROAD_BAND } else { 0 }
        | if ex.gloss_clusters > 0 { FLAG_GLOSS_CLUSTERS } else { 0 }
        | if ex.deficit_readings { FLAG_DEFICIT_READINGS } else { 0 }
        | if ex.linearity { FLAG_LINEARITY } else { 0 }
        | if ex.peak_factors { FLAG_PEAK_FACTORS } else { 0 }
        | if ex.white_uncertainty { FLAG_WHITE_UNCERTAINTY } else { 0 }
        | if ex.gloss_uncertainty { FLAG_GLOSS_UNCERTAINTY } else { 0 };
    put_u16(
        out,
        22,
        if c.far_field { FLAG_FAR_FIELD } else { 0 } | oop_flag | gloss_flag | root_flag | resolution_flag,
    );
    if v2 {
        put_u16(out, 48, k as u16);
        put_u16(out, 50, ex.gloss_clusters as u16);
        put_f32(out, 52, extras.out_of_prior.map_or(0.0, |o| o.threshold));
        if let Some(o) = extras.out_of_prior.filter(|o| o.band_factor != 1.0) {
            put_f32(out, 56, o.band_factor);
        }
        if let Some(r) = extras.peak_resolution_deg {
            put_f32(out, 60, r);
        }
    }
    put_u32(out, 24, c.summary.prior_samples);
    put_f32(out, 28, c.summary.condition);
    put_f32(out, 32, c.summary.regularisation);
    put_f32(out, 36, c.summary.predicted_rmse);
    put_f32(out, 40, c.summary.f32_rel_error);
    put_u32(out, 44, lay.total as u32);
    for (i, x) in c.grid_deg.iter().enumerate() {
        put_f32(out, lay.grid + 4 * i, *x);
    }
    out[lay.led_order..lay.led_order + d.m].copy_from_slice(c.led_order);
    for (i, z) in c.zone_start.iter().enumerate() {
        put_u16(out, lay.zones + 2 * i, *z);
    }
    let oop: &[f32] = extras.out_of_prior.map_or(&[], |o| o.data);
    let peak_factors = extras.peak_factors.map_or([0.0; 2], |f| [f.height, f.width]);
    if let Some(g) = &extras.gloss {
        put_f32(out, lay.gloss, g.assigned_gu);
        put_f32(out, lay.gloss + 4, g.refractive_index);
    }
    let (gref, gblocks, gcents): (&[f32], &[f32], &[f32]) =
        extras.gloss.map_or((&[], &[], &[]), |g| (g.reference, g.blocks, g.centroids));
    for (off, xs) in [
        (lay.gloss + 4 * GLOSS_HEAD, gref),
        (lay.gloss + 4 * (GLOSS_HEAD + lay.gloss_refs), gblocks),
        (lay.gloss + 4 * (GLOSS_HEAD + lay.gloss_refs + gblocks.len()), gcents),
        (lay.white, c.white),
        (lay.uncertainty, c.uncertainty),
        (lay.matrices, c.matrices),
        (lay.centroids, extras.centroids),
        (lay.out_of_prior, oop),
        (lay.pixel_resolution, extras.pixel_peak_resolution_deg),
        (lay.broad_uncertainty, extras.broad_uncertainty),
        (lay.linearity, extras.linearity.as_ref().map_or(&[][..], |l| &l.factors()[..])),
        (lay.peak_factors, &peak_factors[..if ex.peak_factors { 2 } else { 0 }]),
        (lay.white_uncertainty, extras.white_uncertainty.as_slice()),
        (lay.gloss_uncertainty, extras.gloss_uncertainty.as_slice()),
    ] {
        for (i, x) in xs.iter().enumerate() {
            put_f32(out, off + 4 * i, *x);
        }
    }
    let crc = CRC32.checksum(&out[..lay.crc]);
    put_u32(out, lay.crc, crc);
    // Validate what we wrote with the one parser, so a blob that would be
    // refused on the device is refused here, before it leaves the host.
    BlobView::parse(out)?;
    Ok(lay.total)
}
