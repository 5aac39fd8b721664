//! Where each section starts: the byte offsets that the dimensions and the
//! optional sections (the extras) imply, computed one way for the writer and
//! the parser.

use super::*;
use crate::acquire::linearity::LINEARITY_KNOTS;

/// Dimensions of a blob.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Dims {
    /// Angle bins.
    pub n: usize,
    /// LEDs, readings per point.
    pub m: usize,
    /// Zones of pixels.
    pub zones: usize,
    /// Pixels of the line sensor.
    pub pixels: usize,
}

/// Byte offsets of the sections, derived from the dimensions alone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Layout {
    pub(super) grid: usize,
    pub(super) led_order: usize,
    pub(super) zones: usize,
    pub(super) white: usize,
    pub(super) uncertainty: usize,
    pub(super) matrices: usize,
    pub(super) centroids: usize,
    pub(super) out_of_prior: usize,
    pub(super) gloss: usize,
    /// The per-pixel peak resolutions (as long as the pixels, or empty).
    pub(super) pixel_resolution: usize,
    /// The second uncertainty table (as long as the first, or empty).
    pub(super) broad_uncertainty: usize,
    /// The linearity correction (its knots, or empty).
    pub(super) linearity: usize,
    /// The peak's uncertainty factors (two, or empty).
    pub(super) peak_factors: usize,
    pub(super) white_uncertainty: usize,
    /// The gloss scale's uncertainty (one value, or empty).
    pub(super) gloss_uncertainty: usize,
    pub(super) crc: usize,
    pub(super) total: usize,
    pub(super) clusters: usize,
    /// References in the gloss section.
    pub(super) gloss_refs: usize,
    /// The gloss rows' clusters per zone (K without flag bit 9).
    pub(super) gloss_clusters: usize,
    /// Whether the gloss section ends with its own centroids (flag bit 9).
    pub(super) gloss_centroids: bool,
}

pub(super) const fn pad4(x: usize) -> usize {
    (x + 3) & !3
}

impl Dims {
    pub(super) fn layout(&self) -> Layout {
        self.layout_with(&Extras::NONE)
    }

    pub(super) fn layout_with(&self, x: &Extras) -> Layout {
        let k = x.clusters.max(1);
        let grid = HEADER_LEN;
        let led_order = grid + 4 * self.n;
        let zones = led_order + pad4(self.m);
        let white = zones + pad4(2 * self.zones);
        let uncertainty = white + 4 * self.pixels * self.m;
        let matrices = uncertainty + 4 * self.zones * k * self.n;
        let centroids = matrices + 4 * self.zones * k * self.n * self.m;
        let out_of_prior = centroids + if x.piecewise { 4 * self.zones * k * self.m } else { 0 };
        let gloss = out_of_prior + if x.out_of_prior { 4 * self.zones * out_of_prior_len(self.m) } else { 0 };
        let kg = if x.gloss_clusters > 0 { x.gloss_clusters } else { k };
        let pixel_resolution = gloss
            + if x.gloss {
                4 * (gloss_len(x.gloss_refs, self.zones, kg, self.m)
                    + if x.gloss_clusters > 0 { self.zones * kg * self.m } else { 0 })
            } else {
                0
            };
        let broad_uncertainty = pixel_resolution + if x.pixel_resolution { 4 * self.pixels } else { 0 };
        let linearity = broad_uncertainty + if x.broad_band { 4 * self.zones * k * self.n } else { 0 };
        let peak_factors = linearity + if x.linearity { 4 * LINEARITY_KNOTS } else { 0 };
        let white_uncertainty = peak_factors + if x.peak_factors { 8 } else { 0 };
        let gloss_uncertainty = white_uncertainty + if x.white_uncertainty { 4 } else { 0 };
        let crc = gloss_uncertainty + if x.gloss_uncertainty { 4 } else { 0 };
        Layout {
            grid,
            led_order,
            zones,
            white,
            uncertainty,
            matrices,
            centroids,
            out_of_prior,
            gloss,
            pixel_resolution,
            broad_uncertainty,
            linearity,
            peak_factors,
            white_uncertainty,
            gloss_uncertainty,
            crc,
            total: crc + 4,
            clusters: k,
            gloss_refs: if x.gloss { x.gloss_refs } else { 0 },
            gloss_clusters: kg,
            gloss_centroids: x.gloss && x.gloss_clusters > 0,
        }
    }

    /// Total length in bytes of a version 1 blob with these dimensions.
    pub fn blob_len(&self) -> usize {
        self.layout().total
    }

    /// Total length in bytes of a blob with these dimensions and `extras`.
    pub fn blob_len_with(&self, extras: &BlobExtras<'_>) -> usize {
        self.layout_with(&Extras::of(extras, EstimatorKind::Wiener, self)).total
    }

    pub(super) fn check(&self) -> Result<(), BlobError> {
        let lim = |field, value: usize, max: usize| {
            if value == 0 || value > max {
                Err(BlobError::BadDimension { field, value: value.min(u16::MAX as usize) as u16 })
            } else {
                Ok(())
            }
        };
        lim("n", self.n, MAX_BINS)?;
        lim("m", self.m, MAX_LEDS)?;
        lim("pixels", self.pixels, MAX_PIXELS)?;
        lim("zones", self.zones, self.pixels)
    }
}

/// Largest number of clusters (matrices per zone) a blob may carry.
pub const MAX_CLUSTERS: usize = 64;

/// Values per zone of the out-of-prior section for m readings: the mean of
/// `u'` (m-1) and the packed whitening matrix (m(m-1)/2).
pub const fn out_of_prior_len(m: usize) -> usize {
    (m - 1) + m * (m - 1) / 2
}

/// Values of the gloss section for `refs` references (Z in format version
/// 3, P in version 4), Z zones, K clusters and m readings.
pub const fn gloss_len(refs: usize, zones: usize, clusters: usize, m: usize) -> usize {
    GLOSS_HEAD + refs + zones * clusters * crate::gloss::block_len(m)
}

/// The layout-relevant part of the extras.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Extras {
    pub(super) clusters: usize,
    pub(super) piecewise: bool,
    pub(super) out_of_prior: bool,
    pub(super) gloss: bool,
    pub(super) root_form: bool,
    /// References in the gloss section (P in version 4, Z in version 3).
    pub(super) gloss_refs: usize,
    /// The header holds the peak resolution.
    pub(super) peak_resolution: bool,
    /// The per-pixel resolutions follow.
    pub(super) pixel_resolution: bool,
    /// The second uncertainty table follows.
    pub(super) broad_band: bool,
    /// The gloss rows' own clusters per zone, K_g (flag bit 9), or 0.
    pub(super) gloss_clusters: usize,
    /// The root form's fourth gloss row is the peak's deficit (flag bit 10).
    pub(super) deficit_readings: bool,
    /// The sensor's linearity correction follows (flag bit 11).
    pub(super) linearity: bool,
    /// The peak's uncertainty factors follow (flag bit 12).
    pub(super) peak_factors: bool,
    /// The white reference's uncertainty follows (flag bit 13).
    pub(super) white_uncertainty: bool,
    /// The gloss scale's uncertainty follows (flag bit 14, with the gloss
    /// section only).
    pub(super) gloss_uncertainty: bool,
}

impl Extras {
    pub(super) const NONE: Extras = Extras {
        clusters: 1,
        piecewise: false,
        out_of_prior: false,
        gloss: false,
        root_form: false,
        gloss_refs: 0,
        peak_resolution: false,
        pixel_resolution: false,
        broad_band: false,
        gloss_clusters: 0,
        deficit_readings: false,
        linearity: false,
        peak_factors: false,
        white_uncertainty: false,
        gloss_uncertainty: false,
    };

    pub(super) fn of(x: &BlobExtras<'_>, kind: EstimatorKind, d: &Dims) -> Self {
        Extras {
            clusters: x.clusters,
            piecewise: kind == EstimatorKind::ScaleFreePiecewise || !x.centroids.is_empty(),
            out_of_prior: x.out_of_prior.is_some(),
            gloss: x.gloss.is_some(),
            root_form: x.root_form,
            gloss_refs: x.gloss.map_or(0, |g| g.reference.len()),
            peak_resolution: x.peak_resolution_deg.is_some(),
            pixel_resolution: !x.pixel_peak_resolution_deg.is_empty(),
            broad_band: !x.broad_uncertainty.is_empty(),
            gloss_clusters: x.gloss.map_or(0, |g| g.centroids.len() / (d.zones * d.m).max(1)),
            deficit_readings: x.gloss.is_some_and(|g| g.root_readings == crate::gloss::RootReadings::Deficit),
            linearity: x.linearity.is_some(),
            peak_factors: x.peak_factors.is_some(),
            white_uncertainty: x.white_uncertainty.is_some(),
            gloss_uncertainty: x.gloss_uncertainty.is_some(),
        }
    }

    pub(super) fn needs_v2(&self, kind: EstimatorKind) -> bool {
        self.clusters != 1
            || self.piecewise
            || self.out_of_prior
            || self.root_form
            || self.peak_resolution
            || self.broad_band
            || self.linearity
            || self.peak_factors
            || self.white_uncertainty
            || matches!(kind, EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise)
    }

    /// K agrees with the kind: >= 2 for the piecewise kind, 1 otherwise.
    pub(super) fn check(&self, kind: EstimatorKind) -> Result<(), BlobError> {
        let k = self.clusters;
        let ok = if kind == EstimatorKind::ScaleFreePiecewise {
            (2..=MAX_CLUSTERS).contains(&k)
        } else {
            k == 1 && !self.piecewise
        };
        if self.root_form && !matches!(kind, EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise) {
            return Err(BlobError::ReservedNotZero);
        }
        // The deficit row is a root: only the root form's gloss rows have it.
        if self.deficit_readings && !(self.gloss && self.root_form) {
            return Err(BlobError::ReservedNotZero);
        }
        if self.gloss_clusters != 0
            && (!self.gloss
                || kind != EstimatorKind::ScaleFreePiecewise
                || !(2..=MAX_CLUSTERS).contains(&self.gloss_clusters))
        {
            return Err(BlobError::BadDimension {
                field: "gloss clusters",
                value: self.gloss_clusters.min(u16::MAX as usize) as u16,
            });
        }
        if ok {
            Ok(())
        } else {
            Err(BlobError::BadDimension { field: "clusters", value: k.min(u16::MAX as usize) as u16 })
        }
    }
}
