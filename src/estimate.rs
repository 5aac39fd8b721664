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
use crate::blob::BlobView;
use crate::protocol::{CalInfo, DeviceError, SizeField};
use crate::store::SlotInfo;
use nalgebra::{SMatrix, SMatrixView, SVector};

/// One zone's matrix as the kernel takes it: `W` transposed, M x N.
pub type ZoneMatrix<const N: usize, const M: usize> = SMatrix<f32, M, N>;

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
    /// White reference per pixel and reading.
    pub white: [[f32; M]; P],
    /// Zone of each pixel.
    pub zone_of: [u16; P],
    zones: usize,
    home: MatrixHome,
    /// The blob's matrices in flash (Z x n x m f32), when read in place.
    in_place: &'static [f32],
}

/// The calibration holder: the RAM budget buffer and the active calibration.
pub struct Calibration<const N: usize, const M: usize, const P: usize> {
    ram: &'static mut [ZoneMatrix<N, M>],
    active: Option<Active<N, M, P>>,
}

impl<const N: usize, const M: usize, const P: usize> Calibration<N, M, P> {
    /// A holder whose RAM budget is `ram` (room for `ram.len()` zones).
    pub fn new(ram: &'static mut [ZoneMatrix<N, M>]) -> Self {
        Self { ram, active: None }
    }

    /// RAM budget in f32 words.
    pub fn ram_words(&self) -> usize {
        self.ram.len() * N * M
    }

    /// Whether `view` was made for this build (n, m, P).
    pub fn check(view: &BlobView<'_>) -> Result<(), DeviceError> {
        let d = view.dims();
        for (field, device, blob) in [(SizeField::Bins, N, d.n), (SizeField::Leds, M, d.m), (SizeField::Pixels, P, d.pixels)] {
            if device != blob {
                return Err(DeviceError::Mismatch { field, device: device as u16, blob: blob.min(65535) as u16 });
            }
        }
        Ok(())
    }

    /// Makes `view` (a validated blob in slot `slot`) the active calibration.
    /// Nothing changes on error.
    pub fn load(&mut self, view: &BlobView<'static>, slot: SlotInfo) -> Result<(), DeviceError> {
        Self::check(view)?;
        let z = view.dims().zones;
        let bytes = view.as_bytes();
        // W is the last section before the CRC (blob.rs layout table).
        let w_len = 4 * z * N * M;
        let w_off = bytes.len() - 4 - w_len;
        let in_ram = z <= self.ram.len();
        let in_place: &'static [f32] = if in_ram {
            &[]
        } else {
            // A slot that is not 4-byte aligned is a build error.
            bytemuck::try_cast_slice(&bytes[w_off..w_off + w_len]).map_err(|_| DeviceError::Storage)?
        };
        let mut white = [[0.0f32; M]; P];
        for (p, wp) in white.iter_mut().enumerate() {
            for (i, x) in wp.iter_mut().enumerate() {
                *x = view.white(p, i);
            }
        }
        let zone_of = core::array::from_fn(|p| view.zone_of_pixel(p) as u16);
        let led_order = core::array::from_fn(|i| view.led_order()[i]);
        if in_ram {
            for (zi, dst) in self.ram[..z].iter_mut().enumerate() {
                view.copy_matrix(zi, dst.as_mut_slice());
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
            white,
            zone_of,
            zones: z,
            home: if in_ram { MatrixHome::Ram } else { MatrixHome::InPlace },
            in_place,
        });
        Ok(())
    }

    /// The active calibration.
    pub fn active(&self) -> Option<&Active<N, M, P>> {
        self.active.as_ref()
    }

    /// Zone `z`'s matrix, wherever it lives.
    ///
    /// # Panics
    /// If there is no active calibration or `z` is not one of its zones.
    pub fn matrix(&self, z: usize) -> SMatrixView<'_, f32, M, N> {
        let a = self.active.as_ref().expect("no active calibration");
        assert!(z < a.zones);
        match a.home {
            MatrixHome::Ram => self.ram[z].as_view(),
            MatrixHome::InPlace => SMatrixView::from_slice(&a.in_place[z * N * M..(z + 1) * N * M]),
        }
    }

    /// Where the matrices are read from.
    pub fn home(&self) -> Option<MatrixHome> {
        self.active.as_ref().map(|a| a.home)
    }

    /// Estimates pixel `p`'s BRDF from its corrected readings with its
    /// zone's matrix; returns the zone.
    pub fn estimate_pixel(&self, p: usize, v: &SVector<f32, M>, out: &mut SVector<f32, N>) -> u16 {
        let z = self.active.as_ref().expect("no active calibration").zone_of[p];
        point_kernel(self.matrix(z as usize), v, out);
        z
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
            let za = ram.estimate_pixel(p, &v, &mut a);
            let zb = flash.estimate_pixel(p, &v, &mut b);
            assert_eq!(za, zb);
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
