//! Estimation: the calibration the device runs on (white reference, LED order,
//! zone map, one W per zone) and `rho = W_zone v` for each point.
//!
//! # Where the matrices live: [`MatrixHome`]
//! At boot (and after each provisioning) the matrices are copied to a RAM
//! buffer whose size is fixed at build time (the *RAM budget*), when they fit;
//! otherwise they are read in place from the memory-mapped, CRC-validated
//! calibration slot, which the store never writes while it is active. Both
//! cases give the kernel the same nalgebra view of `W`'s transpose
//! (`SMatrixView<f32, M, N>`, the blob's row-major n x m in memory) per zone,
//! through the one method [`Calibration::matrix`]: there is one estimation
//! code path.
//!
//! The board's full calibration (Z = 128 zones of 81 x 7 f32, about 290 KiB)
//! cannot be copied into its 128 KiB of RAM and runs in place; the QEMU build
//! and the host simulation copy to RAM (and the host simulation tests the
//! in-place case too, with a small budget).
use crate::blob::{BlobView, EstimatorKind, GlossData};
use crate::kernel::scale_free::{OutOfPriorForm, scale, whitening_len};
use crate::protocol::{CalInfo, DeviceError, SizeField};
use crate::store::SlotInfo;
use nalgebra::{SMatrix, SMatrixView, SVector};

/// One zone's matrix as the kernel takes it: `W` transposed, M x N.
pub type ZoneMatrix<const N: usize, const M: usize> = SMatrix<f32, M, N>;

/// Fills `slot` with `Z` zero matrices in place and returns them: the
/// firmware's RAM copy of the matrices (18 KB on the board), which built
/// on the stack and moved into its static, as `StaticCell::init` would,
/// would take that much stack for good (the firmware's `main` never
/// returns).
pub fn zeroed_in_place<const N: usize, const M: usize, const Z: usize>(
    slot: &mut core::mem::MaybeUninit<[ZoneMatrix<N, M>; Z]>,
) -> &mut [ZoneMatrix<N, M>; Z] {
    // SAFETY: a matrix is `f32`s only, and zero bytes are 0.0.
    unsafe { crate::in_place::zeroed(slot) }
}

/// Where the active matrices are read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MatrixHome {
    /// Copied into the RAM budget buffer.
    Ram,
    /// Read in place from the flash slot.
    InPlace,
}

/// The active calibration, ready to run.
pub struct Active<const N: usize, const M: usize, const P: usize> {
    /// Identity, for replies.
    pub info: CalInfo,
    /// LED fired for reading i.
    pub led_order: [u8; M],
    /// The sensor's linearity correction, when the calibration has one.
    pub linearity: Option<crate::acquire::Linearity>,
    zones: usize,
    home: MatrixHome,
    /// The blob's matrices in flash (Z x K x n x m f32), when read in place.
    in_place: &'static [f32],
    /// Which rule turns readings into an estimate.
    kind: EstimatorKind,
    /// The root form: the kernel's outputs are roots (`crate::blob`).
    root: bool,
    /// K, matrices per zone (piecewise: one per cluster of readings).
    clusters: usize,
    /// Piecewise: the blob's centroids in flash, Z x K x m.
    centroids: &'static [f32],
    /// The blob's out-of-prior data in flash (per zone: mean m-1, then the
    /// packed whitening), with its threshold; empty when it has none.
    out_of_prior: &'static [f32],
    out_of_prior_threshold: f32,
    /// What a flagged point's unit uncertainty is multiplied by (1 without).
    band_factor: f32,
    /// Which statistic the out-of-prior data is for.
    out_of_prior_form: OutOfPriorForm,
    /// The blob's per-bin uncertainties in flash, Z x K x n (what the
    /// Sigma16 stream encoding scales its steps by).
    uncertainty: &'static [f32],
    /// The blob's gloss section in flash, when it carries one.
    gloss: Option<GlossData<'static>>,
    /// The gloss rows' clusters per zone (K unless they have their own).
    gloss_clusters: usize,
}

/// What the active calibration says of each pixel, kept beside [`Active`]
/// rather than in it, and uninitialised until the first load: `load` writes
/// these tables where they live, while a new `Active` is built as a value
/// and moved into place (with the tables in it, that value took 3.8 KB of
/// the board's stack, P = 128), and a holder that started with them zeroed
/// built the zeros as a value too (4 KB more in the board's main task,
/// which never returns).
pub struct PixelTables<const M: usize, const P: usize> {
    /// White reference per pixel and reading.
    pub white: [[f32; M]; P],
    /// Zone of each pixel.
    pub zone_of: [u16; P],
    /// Per pixel, its zone's gloss scale `assigned / S_z` (`crate::gloss`),
    /// divided once at load rather than per point.
    gloss_q: [f32; P],
}

/// What one point's estimate adds to its frame besides the values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointMeta {
    /// The pixel's zone (selects the matrices).
    pub zone: u16,
    /// The cluster whose matrix was used (piecewise kinds; 0 otherwise).
    pub cluster: u8,
    /// [`crate::protocol::flags`] raised by the estimate itself
    /// (`OUT_OF_PRIOR`); the caller adds the readings' and the guard's.
    pub flags: u8,
    /// What the calibration's per-bin uncertainty is multiplied by for this
    /// point: the readings' scale for the scale-free kinds, 1 otherwise.
    pub sigma_scale: f32,
    /// The point's gloss readings ([`crate::gloss`]); NaN when the
    /// calibration carries none.
    pub readings: [f32; crate::shape::READINGS],
    /// Their standard uncertainties, NaN with the readings.
    pub reading_sigma: [f32; crate::shape::READINGS],
}

/// The calibration holder: the RAM budget buffer and the active calibration.
pub struct Calibration<const N: usize, const M: usize, const P: usize> {
    ram: &'static mut [ZoneMatrix<N, M>],
    active: Option<Active<N, M, P>>,
    /// The active calibration's per-pixel tables: written in full by
    /// `load` before it sets `active`, so initialised whenever `active` is
    /// `Some` ([`Self::loaded`]).
    pixels: core::mem::MaybeUninit<PixelTables<M, P>>,
}

impl<const N: usize, const M: usize, const P: usize> Calibration<N, M, P> {
    /// A holder whose RAM budget is `ram` (room for `ram.len()` zones).
    pub fn new(ram: &'static mut [ZoneMatrix<N, M>]) -> Self {
        Self { ram, active: None, pixels: core::mem::MaybeUninit::uninit() }
    }

    /// RAM budget in f32 words.
    pub fn ram_words(&self) -> usize {
        self.ram.len() * N * M
    }

    /// Whether `view` was made for this build (n, m, P).
    pub fn check(view: &BlobView<'_>) -> Result<(), DeviceError> {
        let d = view.dims();
        for (field, device, blob) in
            [(SizeField::Bins, N, d.n), (SizeField::Leds, M, d.m), (SizeField::Pixels, P, d.pixels)]
        {
            if device != blob {
                return Err(DeviceError::Mismatch { field, device: device as u16, blob: blob.min(65535) as u16 });
            }
        }
        Ok(())
    }

    /// Whether the estimator runs on this device: a log-domain blob has no
    /// device form (its estimate is not `W v`); the scale-free kinds need
    /// m >= 2 (the last reading's place carries the scale). The parser has
    /// already checked every other rule of the kind.
    fn check_kind(view: &BlobView<'_>) -> Result<(), DeviceError> {
        if view.estimator() == EstimatorKind::LogWiener {
            return Err(DeviceError::BlobRejected {
                fault: crate::protocol::BlobFault::UnknownEstimator,
                section: Some(crate::blob::Section::Header),
                detail: EstimatorKind::LogWiener as u32,
            });
        }
        let scale_free = matches!(view.estimator(), EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise);
        if (scale_free || view.out_of_prior_threshold().is_some()) && M < 2 {
            return Err(DeviceError::Mismatch { field: SizeField::Leds, device: M as u16, blob: view.dims().m as u16 });
        }
        Ok(())
    }

    /// Makes `view` (a validated blob in slot `slot`) the active calibration.
    /// Nothing changes on error.
    pub fn load(&mut self, view: &BlobView<'static>, slot: SlotInfo) -> Result<(), DeviceError> {
        Self::check(view)?;
        Self::check_kind(view)?;
        let z = view.dims().zones;
        let k = view.clusters();
        let bytes = view.as_bytes();
        let in_ram = z * k <= self.ram.len();
        // A slot that is not 4-byte aligned is a build error.
        let in_place: &'static [f32] = if in_ram {
            &[]
        } else {
            let first = view.matrix_in_place(0).ok_or(DeviceError::Storage)?;
            // The Z x K matrices are contiguous from zone 0's first.
            let start = first.as_ptr() as usize - bytes.as_ptr() as usize;
            bytemuck::try_cast_slice(&bytes[start..start + 4 * z * k * N * M]).map_err(|_| DeviceError::Storage)?
        };
        let centroids: &'static [f32] = if view.estimator() == EstimatorKind::ScaleFreePiecewise {
            view.centroids_in_place().ok_or(DeviceError::Storage)?
        } else {
            &[]
        };
        let (out_of_prior, out_of_prior_threshold): (&'static [f32], f32) = match view.out_of_prior_threshold() {
            Some(t) => (view.out_of_prior_in_place().ok_or(DeviceError::Storage)?, t),
            None => (&[], f32::INFINITY),
        };
        let out_of_prior_form = view.out_of_prior_form().unwrap_or(OutOfPriorForm::Linear);
        let uncertainty = view.uncertainty_in_place().ok_or(DeviceError::Storage)?;
        let gloss = if view.has_gloss() { Some(view.gloss_in_place().ok_or(DeviceError::Storage)?) } else { None };
        let led_order = core::array::from_fn(|i| view.led_order()[i]);
        if in_ram {
            for (i, dst) in self.ram[..z * k].iter_mut().enumerate() {
                view.copy_matrix_of(i / k, i % k, dst.as_mut_slice());
            }
        }
        let t = self.pixels.as_mut_ptr();
        for p in 0..P {
            let zone = view.zone_of_pixel(p);
            let q = gloss.map_or(0.0, |g| g.assigned_gu / g.reference_for(p, zone, P));
            // SAFETY: `t` points to this holder's own tables, borrowed
            // mutably through `self`; each write is of a plain value into
            // an element of an array (place projections, no reference to
            // memory that may be uninitialised). Every element is written.
            unsafe {
                for i in 0..M {
                    core::ptr::addr_of_mut!((*t).white[p][i]).write(view.white(p, i));
                }
                core::ptr::addr_of_mut!((*t).zone_of[p]).write(zone as u16);
                core::ptr::addr_of_mut!((*t).gloss_q[p]).write(q);
            }
        }
        self.active = Some(Active {
            info: CalInfo {
                slot: slot.slot,
                sequence: slot.sequence,
                blob_crc: view.crc(),
                blob_len: bytes.len() as u32,
                zones: z as u16,
                in_ram,
            },
            led_order,
            linearity: view.linearity(),
            zones: z,
            home: if in_ram { MatrixHome::Ram } else { MatrixHome::InPlace },
            in_place,
            kind: view.estimator(),
            root: view.root_form(),
            clusters: k,
            centroids,
            out_of_prior,
            out_of_prior_threshold,
            band_factor: view.out_of_prior_band_factor(),
            out_of_prior_form,
            uncertainty,
            gloss,
            gloss_clusters: view.gloss_clusters(),
        });
        Ok(())
    }

    /// The active calibration.
    pub fn active(&self) -> Option<&Active<N, M, P>> {
        self.active.as_ref()
    }

    /// The active calibration with its per-pixel tables.
    pub fn loaded(&self) -> Option<(&Active<N, M, P>, &PixelTables<M, P>)> {
        let a = self.active.as_ref()?;
        // SAFETY: `load` writes every element of the tables before it sets
        // `active`, and nothing unsets `active` or writes them otherwise.
        Some((a, unsafe { self.pixels.assume_init_ref() }))
    }

    /// Zone `z`'s matrix (cluster 0), wherever it lives.
    ///
    /// # Panics
    /// If there is no active calibration or `z` is not one of its zones.
    pub fn matrix(&self, z: usize) -> SMatrixView<'_, f32, M, N> {
        self.matrix_of(z, 0)
    }

    /// Zone `z`'s matrix for cluster `c`, wherever it lives.
    ///
    /// # Panics
    /// If there is no active calibration or `(z, c)` is not one of its matrices.
    pub fn matrix_of(&self, z: usize, c: usize) -> SMatrixView<'_, f32, M, N> {
        let a = self.active.as_ref().expect("no active calibration");
        assert!(z < a.zones && c < a.clusters);
        let i = z * a.clusters + c;
        match a.home {
            MatrixHome::Ram => self.ram[i].as_view(),
            MatrixHome::InPlace => SMatrixView::from_slice(&a.in_place[i * N * M..(i + 1) * N * M]),
        }
    }

    /// The blob's per-bin standard uncertainty of zone `z`, cluster `c` (n
    /// values; for the scale-free kinds per unit scale).
    ///
    /// # Panics
    /// If there is no active calibration or `(z, c)` is not one of its matrices.
    pub fn uncertainty(&self, z: usize, c: usize) -> &[f32] {
        let a = self.active.as_ref().expect("no active calibration");
        assert!(z < a.zones && c < a.clusters);
        let i = z * a.clusters + c;
        &a.uncertainty[i * N..(i + 1) * N]
    }

    /// One point as the device streams it: [`Self::estimate_pixel`], then
    /// [`guard_estimate`], with every flag in the returned meta: the
    /// readings' own (`reading_flags`, from the correction), the estimate's
    /// and the guard's. A point whose estimate is not finite has no gloss
    /// readings either (NaN).
    pub fn estimate_point(
        &self,
        p: usize,
        v: &SVector<f32, M>,
        reading_flags: u8,
        out: &mut SVector<f32, N>,
    ) -> PointMeta {
        let mut meta = self.estimate_pixel(p, v, out);
        meta.flags |= reading_flags | guard_estimate(out.as_mut_slice());
        if meta.flags & crate::protocol::flags::NON_FINITE != 0 {
            meta.readings = crate::gloss::NO_READINGS;
            meta.reading_sigma = crate::gloss::NO_READINGS;
        }
        meta
    }

    /// Where the matrices are read from.
    pub fn home(&self) -> Option<MatrixHome> {
        self.active.as_ref().map(|a| a.home)
    }

    /// Estimates pixel `p`'s BRDF from its corrected readings with its
    /// zone's matrix, by the calibration's rule:
    /// - the linear kinds: `rho = W v`;
    /// - scale-free: `rho = [W' | b] [v_0 .. v_{m-2}, s]` with `s = sum v`
    ///   (`crate::kernel::scale_free`: the same kernel, its last reading
    ///   replaced by the scale, so no extra multiply-adds);
    /// - scale-free piecewise: the same with the matrix of the cluster
    ///   [`crate::kernel::select_cluster`] picks from the zone's centroids;
    /// - in the root form (the scale-free kinds, `crate::blob`): the kernel's
    ///   input over the square root of the scale, its outputs squared (never
    ///   negative);
    ///
    /// and, when the blob carries out-of-prior data, flags the point whose
    /// statistic is above the threshold (or not a number); and, when it
    /// carries the gloss section, computes the point's gloss readings and
    /// their uncertainties from the same kernel input ([`crate::gloss`]:
    /// 4 x m multiply-adds more, and the choice of the gloss rows' own
    /// cluster when they have one: `crate::blob`, flag bit 9), else leaves
    /// them NaN.
    ///
    /// Not inlined, so the firmware has one symbol for the whole per-point
    /// path, whose instructions scripts/qemu-icount.sh counts with those of
    /// the functions it calls.
    #[inline(never)]
    pub fn estimate_pixel(&self, p: usize, v: &SVector<f32, M>, out: &mut SVector<f32, N>) -> PointMeta {
        let (a, t) = self.loaded().expect("no active calibration");
        let z = t.zone_of[p] as usize;
        // Built in locals and written once at the end (the frame's fields
        // are not stored twice per point).
        let (mut cluster, mut flags, mut sigma_scale) = (0u8, 0u8, 1.0f32);
        // The root form's sqrt(s), for the gloss readings.
        let mut root_sqrt_s = 0.0f32;
        // The kernel's input: the readings, or (scale-free) a copy whose last is the scale.
        let mut vs;
        let mut x = v;
        let (s, c) = match a.kind {
            EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise => {
                let s = scale(v.as_slice());
                let c = if a.centroids.is_empty() {
                    0
                } else {
                    let km = a.clusters * M;
                    crate::kernel::select_cluster(&a.centroids[z * km..(z + 1) * km], v.as_slice())
                };
                vs = *v;
                vs[M - 1] = s;
                if a.root {
                    let (sqrt_s, r) = crate::kernel::root_scales(s);
                    crate::kernel::scale_input(vs.as_mut_slice(), r);
                    root_sqrt_s = sqrt_s;
                }
                x = &vs;
                point_kernel(self.matrix_of(z, c), x, out);
                if a.root {
                    crate::kernel::square_in_place(out.as_mut_slice());
                }
                cluster = c as u8;
                sigma_scale = s;
                (s, c)
            }
            _ => {
                point_kernel(self.matrix(z), v, out);
                (if a.out_of_prior.is_empty() { 0.0 } else { scale(v.as_slice()) }, 0)
            }
        };
        if !a.out_of_prior.is_empty() {
            let per = M - 1 + whitening_len(M);
            let data = &a.out_of_prior[z * per..(z + 1) * per];
            let stat = a.out_of_prior_form.stat(&data[M - 1..], &data[..M - 1], v.as_slice(), s);
            flags |= out_of_prior_flag(stat, a.out_of_prior_threshold);
        }
        let (readings, reading_sigma) = match &a.gloss {
            Some(g) => {
                let block = g.block(z, c, a.gloss_clusters, v.as_slice());
                if a.root {
                    crate::gloss::readings_root(block, x.as_slice(), t.gloss_q[p], root_sqrt_s, g.root_readings)
                } else {
                    crate::gloss::readings(block, x.as_slice(), t.gloss_q[p], sigma_scale)
                }
            }
            None => (crate::gloss::NO_READINGS, crate::gloss::NO_READINGS),
        };
        // A flagged point's band is wider (the readings' own uncertainties
        // are calibrated per cluster on their own and keep theirs).
        if flags & crate::protocol::flags::OUT_OF_PRIOR != 0 && a.band_factor != 1.0 {
            sigma_scale = crate::kernel::scale_free::flagged_sigma_scale(sigma_scale, a.band_factor, a.root);
        }
        PointMeta { zone: z as u16, cluster, flags, sigma_scale, readings, reading_sigma }
    }
}

/// Makes one point's estimate safe to stream, and says so in its flags.
///
/// If any value is NaN or infinite - corrected readings that were not finite
/// (a white reference so small that the division overflowed), or `W v`
/// overflowing f32 because W itself is huge - every value of the point is set
/// to 0 and [`crate::protocol::flags::NON_FINITE`] is returned; otherwise the
/// values are untouched and 0 is returned. The whole point is zeroed, not just
/// the bad bins: its other bins come from the same readings and matrix and
/// cannot be trusted either, and a host that ignores flags then sees a flat
/// zero curve rather than a wild one. The device applies this to every point
/// before it is framed, so no NaN or infinity is ever streamed; the host's
/// reproduction of the device (`host_tools::device::reference::expected_line`) calls
/// the same function.
pub fn guard_estimate(rho: &mut [f32]) -> u8 {
    if rho.iter().all(|x| x.is_finite()) {
        return 0;
    }
    rho.fill(0.0);
    crate::protocol::flags::NON_FINITE
}

/// The out-of-prior rule, once for device and host: a statistic above the
/// calibration's threshold, or not a number, raises
/// [`crate::protocol::flags::OUT_OF_PRIOR`] (NaN is not "within the prior").
#[inline]
pub fn out_of_prior_flag(stat: f32, threshold: f32) -> u8 {
    if stat.is_nan() || stat > threshold { crate::protocol::flags::OUT_OF_PRIOR } else { 0 }
}

/// `out = W v` for one point, with the shared kernel (`wt` is W's
/// transpose). Not inlined, so the firmware has one symbol whose instructions
/// can be counted in QEMU (scripts/qemu-icount.sh looks for its name).
#[inline(never)]
pub fn point_kernel<const N: usize, const M: usize>(
    wt: SMatrixView<'_, f32, M, N>,
    v: &SVector<f32, M>,
    out: &mut SVector<f32, N>,
) {
    crate::kernel::mat_vec_f32_into(wt, v, out);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blob::BlobView;

    fn leak<T>(x: T) -> &'static mut T {
        Box::leak(Box::new(x))
    }

    #[test]
    fn ram_and_in_place_give_identical_results() {
        let bytes = crate::test_blobs::test_blob(9, 3, 3, 6, 0.5);
        // 4-byte aligned copy with 'static life, as a flash slot is.
        let words: &'static mut [u32] = Box::leak(vec![0u32; bytes.len().div_ceil(4)].into_boxed_slice());
        bytemuck::cast_slice_mut::<u32, u8>(words)[..bytes.len()].copy_from_slice(&bytes);
        let aligned: &'static [u8] = &bytemuck::cast_slice::<u32, u8>(words)[..bytes.len()];
        let view = BlobView::parse(aligned).unwrap();
        let slot = SlotInfo { slot: 0, sequence: 1, blob_len: bytes.len() as u32, blob_crc: 0 };
        let mut ram = Calibration::<9, 3, 6>::new(leak([SMatrix::zeros(); 3]));
        let mut flash = Calibration::<9, 3, 6>::new(leak([SMatrix::zeros(); 1]));
        ram.load(&view, slot).unwrap();
        flash.load(&view, slot).unwrap();
        assert_eq!(ram.home(), Some(MatrixHome::Ram));
        assert_eq!(flash.home(), Some(MatrixHome::InPlace));
        for p in 0..6 {
            let v = SVector::from([0.3f32 + p as f32, -1.25, 7.5]);
            let (mut a, mut b) = (SVector::zeros(), SVector::zeros());
            let ma = ram.estimate_pixel(p, &v, &mut a);
            let mb = flash.estimate_pixel(p, &v, &mut b);
            let bits = |m: PointMeta| {
                (
                    m.zone,
                    m.cluster,
                    m.flags,
                    m.sigma_scale.to_bits(),
                    m.readings.map(f32::to_bits),
                    m.reading_sigma.map(f32::to_bits),
                )
            };
            assert_eq!(bits(ma), bits(mb));
            // A linear calibration without out-of-prior data: no flag, unscaled uncertainty.
            assert_eq!((ma.flags, ma.sigma_scale), (0, 1.0));
            let za = ma.zone;
            assert_eq!(za as usize, view.zone_of_pixel(p));
            assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits));
            // And against the blob's own accessor.
            for (j, aj) in a.iter().enumerate() {
                let mut acc = 0.0f32;
                for (i, vi) in v.iter().enumerate() {
                    acc += view.w(za as usize, j, i) * vi;
                }
                assert_eq!(aj.to_bits(), acc.to_bits());
            }
        }
    }

    #[test]
    fn a_blob_for_another_build_is_refused_and_nothing_changes() {
        let good = crate::test_blobs::test_blob(9, 3, 2, 6, 0.5);
        let other = crate::test_blobs::test_blob(9, 3, 2, 8, 0.5);
        let slot = SlotInfo { slot: 0, sequence: 1, blob_len: 0, blob_crc: 0 };
        let mut c = Calibration::<9, 3, 6>::new(leak([SMatrix::zeros(); 2]));
        let g: &'static [u8] = Box::leak(good.into_boxed_slice());
        let o: &'static [u8] = Box::leak(other.into_boxed_slice());
        c.load(&BlobView::parse(g).unwrap(), slot).unwrap();
        let before = c.matrix(1).clone_owned();
        assert_eq!(
            c.load(&BlobView::parse(o).unwrap(), slot),
            Err(DeviceError::Mismatch { field: SizeField::Pixels, device: 6, blob: 8 })
        );
        assert_eq!(c.matrix(1).clone_owned(), before);
    }
}
