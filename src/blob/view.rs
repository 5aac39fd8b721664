//! A validated blob read in place: what the device runs on and the host
//! checks before it provisions.

use super::*;
use crate::acquire::linearity::{LINEARITY_KNOTS, Linearity};
use crate::kernel::scale_free::OutOfPriorForm;

/// A validated blob, read in place.
#[derive(Clone, Copy, Debug)]
pub struct BlobView<'a> {
    pub(super) bytes: &'a [u8],
    pub(super) dims: Dims,
    pub(super) lay: Layout,
}

impl<'a> BlobView<'a> {
    /// The sensor's linearity correction (flag bit 11), when the blob has one.
    pub fn linearity(&self) -> Option<Linearity> {
        (self.lay.peak_factors != self.lay.linearity).then(|| Linearity::validated(self.linearity_factors()))
    }

    fn linearity_factors(&self) -> [f32; LINEARITY_KNOTS] {
        let mut f = [0.0; LINEARITY_KNOTS];
        for (k, x) in f.iter_mut().enumerate() {
            *x = get_f32(self.bytes, self.lay.linearity + 4 * k);
        }
        f
    }

    /// The blob's bytes (exactly its length).
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }
    /// The blob's CRC, which also identifies it.
    pub fn crc(&self) -> u32 {
        get_u32(self.bytes, self.lay.crc)
    }
    /// Dimensions.
    pub fn dims(&self) -> Dims {
        self.dims
    }
    /// Relative noise level used in training.
    pub fn noise_rel(&self) -> f32 {
        get_f32(self.bytes, 16)
    }
    /// Estimator that produced the matrices.
    pub fn estimator(&self) -> EstimatorKind {
        // Checked in parse.
        EstimatorKind::from_code(get_u16(self.bytes, 20)).unwrap_or(EstimatorKind::Wiener)
    }
    /// Whether the optics were modelled far-field.
    pub fn far_field(&self) -> bool {
        get_u16(self.bytes, 22) & FLAG_FAR_FIELD != 0
    }
    /// Training summary.
    pub fn summary(&self) -> TrainingSummary {
        TrainingSummary {
            prior_samples: get_u32(self.bytes, 24),
            condition: get_f32(self.bytes, 28),
            regularisation: get_f32(self.bytes, 32),
            predicted_rmse: get_f32(self.bytes, 36),
            f32_rel_error: get_f32(self.bytes, 40),
        }
    }
    /// Angle of bin `i`, degrees.
    pub fn grid_deg(&self, i: usize) -> f32 {
        assert!(i < self.dims.n);
        get_f32(self.bytes, self.lay.grid + 4 * i)
    }
    /// The LED fired for each reading.
    pub fn led_order(&self) -> &'a [u8] {
        &self.bytes[self.lay.led_order..self.lay.led_order + self.dims.m]
    }
    /// First pixel of zone `z`.
    pub fn zone_start(&self, z: usize) -> u16 {
        assert!(z < self.dims.zones);
        get_u16(self.bytes, self.lay.zones + 2 * z)
    }
    /// Zone that pixel `p` belongs to.
    pub fn zone_of_pixel(&self, p: usize) -> usize {
        let mut z = 0;
        while z + 1 < self.dims.zones && (self.zone_start(z + 1) as usize) <= p {
            z += 1;
        }
        z
    }
    /// White reference of pixel `p` under reading `i`.
    pub fn white(&self, p: usize, i: usize) -> f32 {
        assert!(p < self.dims.pixels && i < self.dims.m);
        get_f32(self.bytes, self.lay.white + 4 * (p * self.dims.m + i))
    }
    /// Predicted standard uncertainty of zone `z`, bin `j` (cluster 0; for
    /// the scale-free kinds per unit scale).
    pub fn uncertainty(&self, z: usize, j: usize) -> f32 {
        self.uncertainty_of(z, 0, j)
    }
    /// Predicted standard uncertainty of zone `z`, cluster `c`, bin `j`.
    pub fn uncertainty_of(&self, z: usize, c: usize, j: usize) -> f32 {
        assert!(z < self.dims.zones && c < self.lay.clusters && j < self.dims.n);
        get_f32(self.bytes, self.lay.uncertainty + 4 * ((z * self.lay.clusters + c) * self.dims.n + j))
    }
    /// Whether the blob carries the second uncertainty table (flag bit 8).
    pub fn has_broad_band(&self) -> bool {
        self.lay.linearity != self.lay.broad_uncertainty
    }
    /// The table the point of estimate `rho` (on the angles `bins_deg`:
    /// the grid's, or the subset a frame carries) takes: [`crate::band`].
    pub fn band_table(&self, bins_deg: &[f32], rho: &[f32]) -> crate::band::BandTable {
        crate::band::table_of(self.has_broad_band(), bins_deg, rho)
    }
    /// Predicted standard uncertainty of zone `z`, cluster `c`, bin `j` in
    /// `table` (the first table when the blob has no second).
    pub fn uncertainty_in(&self, table: crate::band::BandTable, z: usize, c: usize, j: usize) -> f32 {
        match table {
            crate::band::BandTable::Broad if self.has_broad_band() => {
                assert!(z < self.dims.zones && c < self.lay.clusters && j < self.dims.n);
                get_f32(self.bytes, self.lay.broad_uncertainty + 4 * ((z * self.lay.clusters + c) * self.dims.n + j))
            }
            _ => self.uncertainty_of(z, c, j),
        }
    }
    /// A point's standard uncertainty of bin `j`, from the table it takes
    /// ([`Self::band_table`]), its zone `z`, cluster `c`, estimate `rho` of
    /// the bin and `sigma_scale` (the frame's): the table's uncertainty
    /// times `|sigma_scale|`, or in the root form
    /// [`crate::kernel::scale_free::root_uncertainty`], which follows the
    /// point's own estimate.
    pub fn point_uncertainty(
        &self,
        table: crate::band::BandTable,
        (z, c): (usize, usize),
        j: usize,
        rho: f32,
        sigma_scale: f32,
    ) -> f32 {
        let u = self.uncertainty_in(table, z, c, j);
        if self.root_form() {
            crate::kernel::scale_free::root_uncertainty(u, rho, sigma_scale)
        } else {
            u * sigma_scale.abs()
        }
    }
    /// Element (j, i) of zone `z`'s matrix (cluster 0).
    pub fn w(&self, z: usize, j: usize, i: usize) -> f32 {
        assert!(z < self.dims.zones && j < self.dims.n && i < self.dims.m);
        get_f32(self.bytes, self.matrix_offset(z, 0) + 4 * (j * self.dims.m + i))
    }
    fn matrix_offset(&self, z: usize, c: usize) -> usize {
        self.lay.matrices + 4 * (z * self.lay.clusters + c) * self.dims.n * self.dims.m
    }
    /// Copies zone `z`'s matrix (row-major n x m; cluster 0) into `out`.
    pub fn copy_matrix(&self, z: usize, out: &mut [f32]) {
        self.copy_matrix_of(z, 0, out)
    }
    /// Copies zone `z`'s matrix of cluster `c` (row-major n x m) into `out`.
    pub fn copy_matrix_of(&self, z: usize, c: usize, out: &mut [f32]) {
        let nm = self.dims.n * self.dims.m;
        assert!(z < self.dims.zones && c < self.lay.clusters && out.len() == nm);
        let off = self.matrix_offset(z, c);
        for (k, o) in out.iter_mut().enumerate() {
            *o = get_f32(self.bytes, off + 4 * k);
        }
    }
    /// Zone `z`'s matrix (cluster 0) as an `f32` slice in place, when the
    /// blob sits at a 4-byte aligned address (little-endian targets only).
    #[cfg(target_endian = "little")]
    pub fn matrix_in_place(&self, z: usize) -> Option<&'a [f32]> {
        let nm = self.dims.n * self.dims.m;
        let off = self.matrix_offset(z, 0);
        bytemuck::try_cast_slice(self.bytes.get(off..off + 4 * nm)?).ok()
    }
    /// All zones' centroids (Z x K x m) as an `f32` slice in place (piecewise
    /// blobs at a 4-byte aligned address); `None` otherwise.
    #[cfg(target_endian = "little")]
    pub fn centroids_in_place(&self) -> Option<&'a [f32]> {
        if self.lay.out_of_prior == self.lay.centroids {
            return None;
        }
        bytemuck::try_cast_slice(self.bytes.get(self.lay.centroids..self.lay.out_of_prior)?).ok()
    }
    /// All zones' out-of-prior data (per zone: the mean, m-1, then the packed
    /// whitening matrix, m(m-1)/2) as an `f32` slice in place, when the blob
    /// carries it and sits at a 4-byte aligned address; `None` otherwise.
    #[cfg(target_endian = "little")]
    pub fn out_of_prior_in_place(&self) -> Option<&'a [f32]> {
        self.out_of_prior_threshold()?;
        bytemuck::try_cast_slice(self.bytes.get(self.lay.out_of_prior..self.lay.gloss)?).ok()
    }
    /// All zones' per-bin standard uncertainties (Z x K x n) as an `f32`
    /// slice in place, when the blob sits at a 4-byte aligned address.
    #[cfg(target_endian = "little")]
    pub fn uncertainty_in_place(&self) -> Option<&'a [f32]> {
        let len = 4 * self.dims.zones * self.lay.clusters * self.dims.n;
        bytemuck::try_cast_slice(self.bytes.get(self.lay.uncertainty..self.lay.uncertainty + len)?).ok()
    }
    /// The gloss section (`crate::gloss`) in place, when the blob carries it
    /// and sits at a 4-byte aligned address: (assigned value, refractive
    /// index, the references, the blocks Z x K_g and the rows' own
    /// centroids).
    #[cfg(target_endian = "little")]
    pub fn gloss_in_place(&self) -> Option<GlossData<'a>> {
        if !self.has_gloss() {
            return None;
        }
        let all: &'a [f32] =
            bytemuck::try_cast_slice(self.bytes.get(self.lay.gloss..self.lay.pixel_resolution)?).ok()?;
        let r = self.lay.gloss_refs;
        let blocks = self.dims.zones * self.lay.gloss_clusters * crate::gloss::block_len(self.dims.m);
        Some(GlossData {
            assigned_gu: all[0],
            refractive_index: all[1],
            reference: &all[GLOSS_HEAD..GLOSS_HEAD + r],
            blocks: &all[GLOSS_HEAD + r..GLOSS_HEAD + r + blocks],
            centroids: &all[GLOSS_HEAD + r + blocks..],
            root_readings: self.root_readings(),
        })
    }
    /// How the gloss rows are read in the root form (flag bit 10):
    /// [`crate::gloss::readings_root`]'s `form`.
    pub fn root_readings(&self) -> crate::gloss::RootReadings {
        if self.dims_flags() & FLAG_DEFICIT_READINGS != 0 {
            crate::gloss::RootReadings::Deficit
        } else {
            crate::gloss::RootReadings::Shoulders
        }
    }
    /// Whether the calibration is in the root form (flag bit 3): the
    /// kernel's outputs are roots `t`, the estimate `t^2 / s`.
    pub fn root_form(&self) -> bool {
        self.dims_flags() & FLAG_ROOT != 0
    }
    fn dims_flags(&self) -> u16 {
        get_u16(self.bytes, 22)
    }
    /// Whether the blob carries the gloss section.
    pub fn has_gloss(&self) -> bool {
        self.lay.pixel_resolution != self.lay.gloss
    }
    /// The gloss section's values copied out (any alignment): assigned value,
    /// refractive index, then the reference of zone `z`'s first pixel and the
    /// block of gloss cluster `c` (< [`Self::gloss_clusters`]) into `block`;
    /// `None` when the blob has no gloss section.
    pub fn copy_gloss(&self, z: usize, c: usize, block: &mut [f32]) -> Option<(f32, f32, f32)> {
        if !self.has_gloss() {
            return None;
        }
        let (zones, k, m) = (self.dims.zones, self.lay.gloss_clusters, self.dims.m);
        let bl = crate::gloss::block_len(m);
        assert!(z < zones && c < k && block.len() == bl);
        let at = |i: usize| get_f32(self.bytes, self.lay.gloss + 4 * i);
        let off = GLOSS_HEAD + self.lay.gloss_refs + (z * k + c) * bl;
        for (i, b) in block.iter_mut().enumerate() {
            *b = at(off + i);
        }
        Some((at(0), at(1), self.gloss_reference(self.zone_start(z) as usize).expect("the blob has the section")))
    }

    /// The gloss rows' clusters per zone: K_g when they have their own
    /// (flag bit 9), else K (a point's gloss block is its BRDF cluster's).
    pub fn gloss_clusters(&self) -> usize {
        self.lay.gloss_clusters
    }
    /// Whether the gloss rows have clusters of their own (flag bit 9).
    pub fn has_gloss_centroids(&self) -> bool {
        self.lay.gloss_centroids
    }
    /// Copies zone `z`'s gloss centroids (K_g x m) into `out`, when the
    /// gloss rows have their own (flag bit 9): a point's gloss cluster is
    /// the one [`crate::kernel::select_cluster`] picks among them. `false`
    /// (nothing copied) when they have none: a point's gloss block is then
    /// its BRDF cluster's.
    pub fn copy_gloss_centroids(&self, z: usize, out: &mut [f32]) -> bool {
        if !self.lay.gloss_centroids {
            return false;
        }
        let (k, m) = (self.lay.gloss_clusters, self.dims.m);
        assert!(z < self.dims.zones && out.len() == k * m);
        let at = self.lay.gloss + 4 * (gloss_len(self.lay.gloss_refs, self.dims.zones, k, m) + z * k * m);
        for (i, o) in out.iter_mut().enumerate() {
            *o = get_f32(self.bytes, at + 4 * i);
        }
        true
    }
    /// The gloss reference pixel `p` is read with: its own (format version
    /// 4) or its zone's (version 3); `None` without a gloss section.
    pub fn gloss_reference(&self, p: usize) -> Option<f32> {
        if !self.has_gloss() {
            return None;
        }
        assert!(p < self.dims.pixels);
        let r = if self.lay.gloss_refs == self.dims.pixels { p } else { self.zone_of_pixel(p) };
        Some(get_f32(self.bytes, self.lay.gloss + 4 * (GLOSS_HEAD + r)))
    }
    /// Format version of this blob (1 to 4).
    pub fn version(&self) -> u16 {
        get_u16(self.bytes, 4)
    }
    /// K, matrices per zone (1 unless piecewise).
    pub fn clusters(&self) -> usize {
        self.lay.clusters
    }
    /// Copies zone `z`'s centroids (K x m) into `out` (piecewise blobs only).
    pub fn copy_centroids(&self, z: usize, out: &mut [f32]) {
        let km = self.lay.clusters * self.dims.m;
        assert!(
            z < self.dims.zones
                && out.len() == km
                && self.lay.out_of_prior - self.lay.centroids == 4 * self.dims.zones * km
        );
        for (k, o) in out.iter_mut().enumerate() {
            *o = get_f32(self.bytes, self.lay.centroids + 4 * (z * km + k));
        }
    }
    /// The out-of-prior threshold, when the blob carries the section.
    pub fn out_of_prior_threshold(&self) -> Option<f32> {
        (get_u16(self.bytes, 22) & FLAG_OUT_OF_PRIOR != 0).then(|| get_f32(self.bytes, 52))
    }
    /// What a flagged point's per-bin unit uncertainty is multiplied by
    /// (header offset 56 with flag bit 5; 1 without): the band of a point
    /// the out-of-prior flag raised, as training measured it on held-out
    /// kinds of material the flag raised
    /// ([`crate::kernel::scale_free::flagged_sigma_scale`]).
    pub fn out_of_prior_band_factor(&self) -> f32 {
        if get_u16(self.bytes, 22) & FLAG_BAND_FACTOR != 0 { get_f32(self.bytes, 56) } else { 1.0 }
    }
    /// The peak resolution (deg; header offset 60 with flag bit 6), when
    /// the blob carries it: the module docs.
    pub fn peak_resolution_deg(&self) -> Option<f32> {
        (get_u16(self.bytes, 22) & FLAG_PEAK_RESOLUTION != 0).then(|| get_f32(self.bytes, 60))
    }

    /// The specular peak's uncertainty factors (flag bit 12), when the blob
    /// has them.
    pub fn peak_factors(&self) -> Option<PeakFactors> {
        let at = |i: usize| get_f32(self.bytes, self.lay.peak_factors + 4 * i);
        (self.lay.white_uncertainty != self.lay.peak_factors).then(|| PeakFactors { height: at(0), width: at(1) })
    }

    /// The white reference's relative standard uncertainty (flag bit 13):
    /// a standardised calibration's; 0 when the blob states none.
    pub fn white_uncertainty(&self) -> f32 {
        if self.lay.gloss_uncertainty != self.lay.white_uncertainty {
            get_f32(self.bytes, self.lay.white_uncertainty)
        } else {
            0.0
        }
    }

    /// The gloss scale's relative standard uncertainty (flag bit 14): a
    /// calibration standardised on the black glass; 0 when the blob states
    /// none.
    pub fn gloss_uncertainty(&self) -> f32 {
        if self.lay.crc != self.lay.gloss_uncertainty { get_f32(self.bytes, self.lay.gloss_uncertainty) } else { 0.0 }
    }

    /// How many gloss references the blob holds: one per pixel (format
    /// version 4) or per zone (version 3); 0 without a gloss section.
    pub fn gloss_reference_count(&self) -> usize {
        self.lay.gloss_refs
    }

    /// Which gloss reference pixel `p` is read with (its own, or its
    /// zone's; `None` without a gloss section).
    pub fn gloss_reference_index(&self, p: usize) -> Option<usize> {
        self.has_gloss().then(|| if self.lay.gloss_refs == self.dims.pixels { p } else { self.zone_of_pixel(p) })
    }

    /// Pixel `p`'s peak resolution (deg): its own (flag bit 7) when it has
    /// one, else the calibration's ([`Self::peak_resolution_deg`]).
    pub fn peak_resolution_at(&self, p: usize) -> Option<f32> {
        let own = (get_u16(self.bytes, 22) & FLAG_PIXEL_RESOLUTION != 0 && p < self.dims.pixels)
            .then(|| get_f32(self.bytes, self.lay.pixel_resolution + 4 * p))
            .filter(|r| !r.is_nan());
        own.or_else(|| self.peak_resolution_deg())
    }
    /// Which statistic the out-of-prior section is for, when the blob
    /// carries one.
    pub fn out_of_prior_form(&self) -> Option<OutOfPriorForm> {
        let flags = get_u16(self.bytes, 22);
        (flags & FLAG_OUT_OF_PRIOR != 0).then_some(if flags & FLAG_LOG_RATIO != 0 {
            OutOfPriorForm::LogRatio
        } else {
            OutOfPriorForm::Linear
        })
    }
    /// Copies zone `z`'s out-of-prior mean (m-1) and packed whitening matrix
    /// (m(m-1)/2); false when the blob carries no such section.
    pub fn copy_out_of_prior(&self, z: usize, mean: &mut [f32], g: &mut [f32]) -> bool {
        let m = self.dims.m;
        if self.out_of_prior_threshold().is_none() {
            return false;
        }
        assert!(z < self.dims.zones && mean.len() == m - 1 && g.len() == m * (m - 1) / 2);
        let off = self.lay.out_of_prior + 4 * z * out_of_prior_len(m);
        for (k, o) in mean.iter_mut().chain(g.iter_mut()).enumerate() {
            *o = get_f32(self.bytes, off + 4 * k);
        }
        true
    }
}
