//! Reading a blob: [`BlobView::parse`] refuses anything malformed, naming
//! where, so the device keeps its last good calibration.

use super::*;
use crate::acquire::linearity::LinearityError;

impl<'a> BlobView<'a> {
    /// Validates `bytes` (exactly one blob, or a blob followed by unused bytes
    /// such as erased flash) and returns a view of it.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, BlobError> {
        if bytes.len() < HEADER_LEN {
            return Err(BlobError::TooShort { need: HEADER_LEN, got: bytes.len() });
        }
        if bytes[0..4] != MAGIC {
            return Err(BlobError::BadMagic);
        }
        let version = get_u16(bytes, 4);
        if !(FORMAT_VERSION_1..=FORMAT_VERSION).contains(&version) {
            return Err(BlobError::UnsupportedVersion(version));
        }
        let hl = get_u16(bytes, 6);
        if hl as usize != HEADER_LEN {
            return Err(BlobError::BadHeaderLen(hl));
        }
        let dims = Dims {
            n: get_u16(bytes, 8) as usize,
            m: get_u16(bytes, 10) as usize,
            zones: get_u16(bytes, 12) as usize,
            pixels: get_u16(bytes, 14) as usize,
        };
        dims.check()?;
        let flags = get_u16(bytes, 22);
        let code = get_u16(bytes, 20);
        let kind = EstimatorKind::from_code(code).ok_or(BlobError::UnknownEstimator(code))?;
        let ex = if version == FORMAT_VERSION_1 {
            if matches!(kind, EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise) {
                return Err(BlobError::UnknownEstimator(code));
            }
            Extras::NONE
        } else {
            let gloss = flags & FLAG_GLOSS != 0;
            Extras {
                clusters: get_u16(bytes, 48) as usize,
                piecewise: kind == EstimatorKind::ScaleFreePiecewise,
                out_of_prior: flags & FLAG_OUT_OF_PRIOR != 0,
                gloss,
                root_form: flags & FLAG_ROOT != 0,
                gloss_refs: match (gloss, version) {
                    (false, _) => 0,
                    (true, FORMAT_VERSION_3) => dims.zones,
                    (true, _) => dims.pixels,
                },
                peak_resolution: flags & FLAG_PEAK_RESOLUTION != 0,
                pixel_resolution: flags & FLAG_PIXEL_RESOLUTION != 0,
                broad_band: flags & FLAG_BROAD_BAND != 0,
                gloss_clusters: if flags & FLAG_GLOSS_CLUSTERS != 0 {
                    // Zero means "none" in `Extras`: with the bit it is a bad count.
                    match get_u16(bytes, 50) {
                        0 => return Err(BlobError::BadDimension { field: "gloss clusters", value: 0 }),
                        k => k as usize,
                    }
                } else {
                    0
                },
                deficit_readings: flags & FLAG_DEFICIT_READINGS != 0,
                linearity: flags & FLAG_LINEARITY != 0,
                peak_factors: flags & FLAG_PEAK_FACTORS != 0,
                white_uncertainty: flags & FLAG_WHITE_UNCERTAINTY != 0,
                gloss_uncertainty: flags & FLAG_GLOSS_UNCERTAINTY != 0,
            }
        };
        // Versions 3 and 4 exist for the gloss section: they carry it, 2 never does.
        if (version >= FORMAT_VERSION_3) != ex.gloss {
            return Err(BlobError::ReservedNotZero);
        }
        ex.check(kind)?;
        if ex.out_of_prior && dims.m < 2 {
            return Err(BlobError::BadDimension { field: "m", value: dims.m as u16 });
        }
        let lay = dims.layout_with(&ex);
        let declared = get_u32(bytes, 44) as usize;
        if declared != lay.total {
            return Err(BlobError::LengthMismatch { expected: lay.total, got: declared });
        }
        if bytes.len() < lay.total {
            return Err(BlobError::TooShort { need: lay.total, got: bytes.len() });
        }
        let bytes = &bytes[..lay.total];
        let stored = get_u32(bytes, lay.crc);
        let computed = CRC32.checksum(&bytes[..lay.crc]);
        if stored != computed {
            return Err(BlobError::CrcMismatch { stored, computed });
        }
        // Semantic checks: a blob with a valid CRC can still be wrong if the
        // host that wrote it was; the device must never run on such a blob.
        let reserved_ok = if version == FORMAT_VERSION_1 {
            bytes[48..64].iter().all(|b| *b == 0) && flags & !FLAG_FAR_FIELD == 0
        } else {
            let band = flags & FLAG_BAND_FACTOR != 0;
            let known = FLAG_FAR_FIELD
                | FLAG_OUT_OF_PRIOR
                | FLAG_GLOSS
                | FLAG_ROOT
                | FLAG_LOG_RATIO
                | FLAG_BAND_FACTOR
                | FLAG_PEAK_RESOLUTION
                | FLAG_PIXEL_RESOLUTION
                | FLAG_BROAD_BAND
                | FLAG_GLOSS_CLUSTERS
                | FLAG_DEFICIT_READINGS
                | FLAG_LINEARITY
                | FLAG_PEAK_FACTORS
                | FLAG_WHITE_UNCERTAINTY
                | FLAG_GLOSS_UNCERTAINTY;
            (ex.gloss_clusters > 0 || bytes[50..52].iter().all(|b| *b == 0))
                && (ex.peak_resolution || !(ex.pixel_resolution || ex.peak_factors))
                && (ex.gloss || !ex.gloss_uncertainty)
                && (band || get_u32(bytes, 56) == 0)
                && (ex.peak_resolution || get_u32(bytes, 60) == 0)
                && flags & !known == 0
                && (ex.out_of_prior || (get_u32(bytes, 52) == 0 && flags & (FLAG_LOG_RATIO | FLAG_BAND_FACTOR) == 0))
        };
        if !reserved_ok {
            return Err(BlobError::ReservedNotZero);
        }
        let view = Self { bytes, dims, lay };
        if ex.out_of_prior {
            let t = get_f32(bytes, 52);
            if !t.is_finite() {
                return Err(BlobError::NonFinite { section: Section::OutOfPrior, index: 0 });
            }
            if t <= 0.0 {
                return Err(BlobError::OutOfRange { section: Section::OutOfPrior, index: 0 });
            }
            let f = view.out_of_prior_band_factor();
            if !f.is_finite() {
                return Err(BlobError::NonFinite { section: Section::Header, index: 56 });
            }
            if f < 1.0 {
                return Err(BlobError::OutOfRange { section: Section::Header, index: 56 });
            }
        }
        if let Some(r) = view.peak_resolution_deg() {
            check_peak_resolution(r)?;
            if ex.pixel_resolution {
                for p in 0..dims.pixels {
                    check_pixel_resolution(get_f32(bytes, lay.pixel_resolution + 4 * p), r, p)?;
                }
            }
        }
        let noise = view.noise_rel();
        if !noise.is_finite() {
            return Err(BlobError::NonFinite { section: Section::Header, index: 16 });
        }
        if noise < 0.0 {
            return Err(BlobError::OutOfRange { section: Section::Header, index: 16 });
        }
        let mut prev = f32::NEG_INFINITY;
        for i in 0..dims.n {
            let g = view.grid_deg(i);
            if !g.is_finite() {
                return Err(BlobError::NonFinite { section: Section::Grid, index: i });
            }
            if !(-90.0..=90.0).contains(&g) {
                return Err(BlobError::OutOfRange { section: Section::Grid, index: i });
            }
            if g <= prev {
                return Err(BlobError::GridNotAscending { index: i });
            }
            prev = g;
        }
        let mut seen = 0u64;
        for (i, &led) in view.led_order().iter().enumerate() {
            if led as usize >= dims.m || seen & (1 << led) != 0 {
                return Err(BlobError::BadLedOrder { index: i });
            }
            seen |= 1 << led;
        }
        let mut prev_start = None;
        for i in 0..dims.zones {
            let s = view.zone_start(i);
            let ok = match prev_start {
                None => s == 0,
                Some(p) => s > p && (s as usize) < dims.pixels,
            };
            if !ok {
                return Err(BlobError::BadZoneMap { index: i });
            }
            prev_start = Some(s);
        }
        view.check_finite(Section::White, lay.white, dims.pixels * dims.m, true)?;
        let k = lay.clusters;
        view.check_finite(Section::Uncertainty, lay.uncertainty, dims.zones * k * dims.n, false)?;
        // The second table, its values indexed on from the first's.
        let first = dims.zones * k * dims.n;
        view.check_finite(
            Section::Uncertainty,
            lay.broad_uncertainty,
            (lay.linearity - lay.broad_uncertainty) / 4,
            false,
        )
        .map_err(|e| match e {
            BlobError::NonFinite { section, index } => BlobError::NonFinite { section, index: first + index },
            BlobError::OutOfRange { section, index } => BlobError::OutOfRange { section, index: first + index },
            e => e,
        })?;
        view.check_finite(Section::Matrices, lay.matrices, dims.zones * k * dims.n * dims.m, false)?;
        view.check_finite(Section::Centroids, lay.centroids, (lay.out_of_prior - lay.centroids) / 4, false)?;
        view.check_finite(Section::OutOfPrior, lay.out_of_prior, (lay.gloss - lay.out_of_prior) / 4, false)?;
        if ex.gloss {
            view.check_gloss()?;
        }
        if ex.linearity {
            view.check_linearity()?;
        }
        view.check_finite(
            Section::PeakFactors,
            lay.peak_factors,
            (lay.white_uncertainty - lay.peak_factors) / 4,
            true,
        )?;
        if ex.white_uncertainty {
            check_white_uncertainty(get_f32(bytes, lay.white_uncertainty))?;
        }
        if ex.gloss_uncertainty {
            check_gloss_uncertainty(get_f32(bytes, lay.gloss_uncertainty))?;
        }
        Ok(view)
    }

    /// The gloss section's rules: everything finite; the assigned value and
    /// the references > 0, the refractive index > 1, the covariances'
    /// diagonals and standard deviations >= 0; except a zone without a
    /// reading, whose references (its pixels' in version 4, its own in
    /// version 3) and every value of its blocks are NaN (no mix). Indices
    /// count f32 values from the section's start.
    fn check_gloss(&self) -> Result<(), BlobError> {
        let (z, k, m, refs) = (self.dims.zones, self.lay.gloss_clusters, self.dims.m, self.lay.gloss_refs);
        let block = crate::gloss::block_len(m);
        let rows = crate::gloss::LINEAR * m;
        let diag = [0, 1, 2, 3].map(|i| rows + crate::gloss::cov_index(i, i));
        let sd = [rows + crate::gloss::COV_LEN, rows + crate::gloss::COV_LEN + 1];
        // Zone `zz` without a reading: the first value of its first block is
        // NaN (and then all of its values and references must be).
        let first_block = GLOSS_HEAD + refs;
        let no_reading = |zz: usize| get_f32(self.bytes, self.lay.gloss + 4 * (first_block + zz * k * block)).is_nan();
        let zone_of_ref = |r: usize| if refs == z { r } else { self.zone_of_pixel(r) };
        for i in 0..gloss_len(refs, z, k, m) {
            let x = get_f32(self.bytes, self.lay.gloss + 4 * i);
            let zone = match i {
                _ if i < GLOSS_HEAD => None,
                _ if i < first_block => Some(zone_of_ref(i - GLOSS_HEAD)),
                _ => Some((i - first_block) / (k * block)),
            };
            if zone.is_some_and(no_reading) {
                if !x.is_nan() {
                    return Err(BlobError::OutOfRange { section: Section::Gloss, index: i });
                }
                continue;
            }
            if !x.is_finite() {
                return Err(BlobError::NonFinite { section: Section::Gloss, index: i });
            }
            let ok = match i {
                0 => x > 0.0,
                1 => x > 1.0,
                _ if i < first_block => x > 0.0,
                _ => {
                    let at = (i - first_block) % block;
                    !(diag.contains(&at) || sd.contains(&at)) || x >= 0.0
                }
            };
            if !ok {
                return Err(BlobError::OutOfRange { section: Section::Gloss, index: i });
            }
        }
        // The rows' own centroids, after the blocks: finite in every zone.
        let cents = if self.lay.gloss_centroids { z * k * m } else { 0 };
        let first_centroid = gloss_len(refs, z, k, m);
        for i in first_centroid..first_centroid + cents {
            if !get_f32(self.bytes, self.lay.gloss + 4 * i).is_finite() {
                return Err(BlobError::NonFinite { section: Section::Gloss, index: i });
            }
        }
        Ok(())
    }

    fn check_finite(&self, section: Section, off: usize, count: usize, positive: bool) -> Result<(), BlobError> {
        for i in 0..count {
            let x = get_f32(self.bytes, off + 4 * i);
            if !x.is_finite() {
                return Err(BlobError::NonFinite { section, index: i });
            }
            if (positive && x <= 0.0) || (section == Section::Uncertainty && x < 0.0) {
                return Err(BlobError::OutOfRange { section, index: i });
            }
        }
        Ok(())
    }

    /// The linearity section's rules ([`Linearity::new`]'s), knot by knot
    /// in place.
    fn check_linearity(&self) -> Result<(), BlobError> {
        let mut last = f32::NAN;
        for index in 0..(self.lay.peak_factors - self.lay.linearity) / 4 {
            let f = get_f32(self.bytes, self.lay.linearity + 4 * index);
            match crate::acquire::linearity::fault(index, f, last) {
                None => last = f,
                Some(_) if !f.is_finite() => return Err(BlobError::NonFinite { section: Section::Linearity, index }),
                Some(LinearityError::OutOfRange { index } | LinearityError::NotMonotone { index }) => {
                    return Err(BlobError::OutOfRange { section: Section::Linearity, index });
                }
            }
        }
        Ok(())
    }
}
