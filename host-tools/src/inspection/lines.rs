//! Lines as the device decides them, on the host: the device's correction
//! (`device::reference::corrected_line`), its out-of-prior rule
//! (`PointEstimator`) and the library's own decision
//! (`brdf_meter::inspect::Inspector`), so the host's verdicts are the
//! device's bit for bit.
use crate::device::reference::{PointEstimator, corrected_line};
use brdf_meter::acquire::AcqConfig;
use brdf_meter::blob::BlobView;
use brdf_meter::inspect::{Inspector, RecipeView, Verdict};
use brdf_meter::protocol::flags;
use brdf_meter::shape::LEDS as M;
use nalgebra::SVector;

/// One line's corrected readings and flags, as the device has them.
#[derive(Clone, Debug)]
pub struct Line {
    /// Per pixel, the corrected readings (reading order).
    pub v: Vec<SVector<f32, M>>,
    /// Per pixel, the correction's flags.
    pub flags: Vec<u8>,
}

/// A calibration, ready to correct lines and answer the out-of-prior question.
pub struct DeviceModel<'a> {
    blob: BlobView<'a>,
    zones: Vec<PointEstimator<'a>>,
    full_scale: u16,
    acq: AcqConfig,
}

impl<'a> DeviceModel<'a> {
    /// The device running `blob` with the sensor's `full_scale` and `acq`.
    pub fn new(blob: BlobView<'a>, full_scale: u16, acq: AcqConfig) -> anyhow::Result<Self> {
        anyhow::ensure!(
            blob.dims().m == M,
            "the calibration has m = {} readings per point; this build inspects m = {M}",
            blob.dims().m
        );
        let zones = (0..blob.dims().zones).map(|z| PointEstimator::new(blob, z)).collect::<anyhow::Result<_>>()?;
        Ok(Self { blob, zones, full_scale, acq })
    }

    /// The calibration.
    pub fn blob(&self) -> &BlobView<'a> {
        &self.blob
    }

    /// Pixels P.
    pub fn pixels(&self) -> usize {
        self.blob.dims().pixels
    }

    /// The device's correction of raw frames (`forward::scene::raw_frames`' layout).
    pub fn correct(&self, frames: &[Vec<u16>]) -> Line {
        let (v, flags) = corrected_line(&self.blob, frames, self.full_scale, &self.acq)
            .into_iter()
            .map(|(v, f)| (SVector::<f32, M>::from_column_slice(&v), f))
            .unzip();
        Line { v, flags }
    }

    /// The point's estimate as the device makes it (readings, flags).
    pub fn estimate(&self, p: usize, v: &SVector<f32, M>) -> crate::device::reference::PointEstimate {
        self.zones[self.blob.zone_of_pixel(p)].apply(v.as_slice())
    }

    /// Whether the calibration flags the point out of its prior.
    pub fn out_of_prior(&self, p: usize, v: &SVector<f32, M>) -> bool {
        self.estimate(p, v).flag_bits & flags::OUT_OF_PRIOR != 0
    }
}

/// The device's decision over lines, for a sensor of any of this project's
/// pixel counts (the library's inspector is sized at build time).
pub enum HostInspector {
    /// The board (P = 128).
    Board(Box<Inspector<{ brdf_meter::shape::board::PIXELS }>>),
    /// The QEMU build (P = 32).
    Qemu(Box<Inspector<{ brdf_meter::shape::qemu::PIXELS }>>),
}

impl HostInspector {
    /// A fresh inspection for `pixels` pixels.
    pub fn new(pixels: usize) -> anyhow::Result<Self> {
        Ok(match pixels {
            brdf_meter::shape::board::PIXELS => Self::Board(Box::default()),
            brdf_meter::shape::qemu::PIXELS => Self::Qemu(Box::default()),
            p => anyhow::bail!(
                "no device build has {p} pixels (the board has {}, QEMU {})",
                brdf_meter::shape::board::PIXELS,
                brdf_meter::shape::qemu::PIXELS
            ),
        })
    }

    /// Decides `line` exactly as the device does.
    pub fn line(&mut self, recipe: &RecipeView<'_>, model: &DeviceModel<'_>, n: u32, line: &Line) -> Verdict {
        let oop = |p: usize| model.out_of_prior(p, &line.v[p]);
        match self {
            Self::Board(i) => i.line(recipe, n, &line.v, &line.flags, oop),
            Self::Qemu(i) => i.line(recipe, n, &line.v, &line.flags, oop),
        }
    }

    /// The counters.
    pub fn counters(&self) -> brdf_meter::inspect::InspectCounters {
        match self {
            Self::Board(i) => i.counters(),
            Self::Qemu(i) => i.counters(),
        }
    }
}
