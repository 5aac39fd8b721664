//! The specular peaks of the map's held-out points (`crate::output::peak`,
//! as `measure` writes them): each point's peak against its truth's at the
//! pixel's own view, the height's relative error over every point with a
//! peak, the share the calibration does not resolve, and the k = 2
//! coverage of the heights and widths it does (an unresolved peak states no
//! uncertainty); linear interpolation's peak heights on the same points
//! beside them.
use crate::device::reference::ExpectedPoint;
use crate::evaluation::metrology::metrics::K;
use crate::evaluation::pixel_error::quantiles;
use crate::output::peak::{Peak, specular_peak};
use serde::Serialize;

fn share(within: usize, of: usize) -> f64 {
    if of > 0 { within as f64 / of as f64 } else { f64::NAN }
}

/// The running count, mergeable over materials.
#[derive(Clone, Debug, Default)]
pub struct PeakTally {
    height_rel: Vec<f64>,
    resolved_height_rel: Vec<f64>,
    interpolation_height_rel: Vec<f64>,
    resolved: usize,
    resolved_within: usize,
    /// Resolved peaks whose width and the truth's are both defined, and
    /// those within k = 2.
    widths: usize,
    widths_within: usize,
    unresolved: usize,
    missed: usize,
}

/// What the map reports of the peaks.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PeakSummary {
    /// Points whose truth has a peak.
    pub points: usize,
    /// Height relative error, median and 90th percentile, over the points
    /// whose estimate has a peak (resolved or not).
    pub height_rel: [f64; 2],
    /// The same over the resolved peaks.
    pub resolved_height_rel: [f64; 2],
    /// Linear interpolation's, over the points whose profile has a peak.
    pub interpolation_height_rel: [f64; 2],
    /// Share of the estimates' peaks the calibration does not resolve.
    pub unresolved: f64,
    /// Share of the resolved peaks' heights within k = 2 of their stated
    /// uncertainty.
    pub resolved_coverage: f64,
    /// Share of the resolved peaks' widths within k = 2 of theirs (where
    /// the estimate and the truth both have a width).
    pub width_coverage: f64,
    /// Points without a peak where the truth has one.
    pub missed: usize,
}

/// How a pixel reads a peak: about its own view's mirror incidence, at its
/// own peak resolution (`brdf_meter::blob::BlobView::peak_resolution_at`;
/// `None`: the calibration records none).
#[derive(Clone, Copy, Debug)]
pub struct PixelPeaks {
    /// The pixel's view, deg.
    pub view_deg: f64,
    /// The pixel's peak resolution, deg.
    pub resolution_deg: Option<f64>,
    /// The calibration's factors on a resolved peak's uncertainties.
    pub factors: Option<crate::output::peak::PeakFactors>,
}

impl PeakTally {
    /// Adds point `pt` with the per-bin uncertainty `u` its frame
    /// states, and interpolation's `profile` of the same readings, against
    /// the truth's bins `truth` (on `bins_deg`), read as `pixel` reads it.
    /// Returns whether the point's peak is not resolved (`None`: the truth
    /// has no peak, or the estimate none where it has one).
    pub fn add(
        &mut self,
        bins_deg: &[f32],
        truth: &[f32],
        pt: &ExpectedPoint,
        u: &[f32],
        profile: &[f32],
        pixel: PixelPeaks,
    ) -> Option<bool> {
        let view_deg = pixel.view_deg;
        let none = vec![0.0; truth.len()];
        let t = specular_peak(bins_deg, truth, &none, view_deg);
        if !t.rf.is_finite() {
            return None;
        }
        let i = specular_peak(bins_deg, profile, &none, view_deg);
        if i.rf.is_finite() {
            self.interpolation_height_rel.push((i.rf - t.rf).abs() / t.rf);
        }
        let e: Peak = specular_peak(bins_deg, &pt.values, u, view_deg).stated(pixel.resolution_deg, pixel.factors);
        if !e.rf.is_finite() {
            self.missed += 1;
            return None;
        }
        let err = (e.rf - t.rf).abs();
        self.height_rel.push(err / t.rf);
        if e.resolved == Some(false) {
            self.unresolved += 1;
        } else if e.u_rf.is_finite() {
            self.resolved += 1;
            self.resolved_height_rel.push(err / t.rf);
            self.resolved_within += usize::from(err <= K * e.u_rf);
            if e.u_width_deg.is_finite() && t.width_deg.is_finite() {
                self.widths += 1;
                self.widths_within += usize::from((e.width_deg - t.width_deg).abs() <= K * e.u_width_deg);
            }
        }
        Some(e.resolved == Some(false))
    }

    /// Both counts together.
    pub fn merged(mut self, o: Self) -> Self {
        self.height_rel.extend(o.height_rel);
        self.resolved_height_rel.extend(o.resolved_height_rel);
        self.interpolation_height_rel.extend(o.interpolation_height_rel);
        self.resolved += o.resolved;
        self.resolved_within += o.resolved_within;
        self.widths += o.widths;
        self.widths_within += o.widths_within;
        self.unresolved += o.unresolved;
        self.missed += o.missed;
        self
    }

    /// The figures.
    pub fn summary(&self) -> PeakSummary {
        let q = quantiles(&self.height_rel);
        let qr = quantiles(&self.resolved_height_rel);
        let qi = quantiles(&self.interpolation_height_rel);
        let with_peak = self.height_rel.len();
        PeakSummary {
            points: with_peak + self.missed,
            height_rel: [q[0], q[1]],
            resolved_height_rel: [qr[0], qr[1]],
            interpolation_height_rel: [qi[0], qi[1]],
            unresolved: self.unresolved as f64 / with_peak.max(1) as f64,
            resolved_coverage: share(self.resolved_within, self.resolved),
            width_coverage: share(self.widths_within, self.widths),
            missed: self.missed,
        }
    }
}
