//! The host's reference computation of the device: what the device must
//! answer for a point's readings or a line of raw frames, computed with the
//! library's own correction, kernels and rules, so a link test can demand
//! equality bit for bit, and `host-tools estimate` applies a calibration to
//! logged readings exactly as the instrument would.
//!
//! The device's rule is `brdf_meter::estimate::Calibration::estimate_pixel`
//! on fixed sizes; [`PointEstimator`] is the same rule on the shapes a blob
//! declares at run time: the same kernels (`mat_vec_f32_slice` and the
//! scale-free form, whose accumulation order is the device kernel's with
//! the last reading replaced by the scale), the same cluster selection, the
//! same out-of-prior statistic and flag rule, the same guard.
use anyhow::ensure;
use brdf_meter::acquire::{AcqConfig, Shorter, correct_point_into};
use brdf_meter::band::BandTable;
use brdf_meter::blob::{BlobView, EstimatorKind};
use brdf_meter::estimate::{guard_estimate, out_of_prior_flag};
use brdf_meter::kernel::scale_free::{
    OutOfPriorForm, estimate_scale_free, estimate_scale_free_root, flagged_sigma_scale, root_uncertainty, scale,
    scaled_uncertainty, whitening_len,
};
use brdf_meter::kernel::{mat_vec_f32_slice, select_cluster};
use brdf_meter::protocol::flags;
use brdf_meter::shape::READINGS;
use serde::Serialize;

/// One point's estimate, as the device computes it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PointEstimate {
    /// The n bin values.
    pub rho: Vec<f32>,
    /// Per-bin standard uncertainty (for the scale-free kinds scaled by the point).
    pub sigma: Vec<f32>,
    /// The gloss readings (`brdf_meter::gloss`: specular GU, haze HU,
    /// distinctness %; NaN, written as null, when the blob has none).
    pub readings: [f32; READINGS],
    /// Their standard uncertainties (k = 1).
    pub reading_sigma: [f32; READINGS],
    /// Flag names.
    pub flags: Vec<&'static str>,
    /// Flag bits as the device frames them.
    #[serde(skip)]
    pub flag_bits: u8,
    /// The cluster whose matrix was used (the frame's `cluster`).
    #[serde(skip)]
    pub cluster: u8,
    /// What the per-bin uncertainty was multiplied by (the frame's `sigma_scale`).
    #[serde(skip)]
    pub sigma_scale: f32,
    /// The out-of-prior statistic (NaN when the blob has no such data).
    #[serde(skip)]
    pub stat: f32,
}

/// Names of the flag bits, in bit order: what every output writes.
pub fn flag_names(bits: u8) -> Vec<&'static str> {
    flags::NAMES.into_iter().filter(|(b, _)| bits & b != 0).map(|(_, name)| name).collect()
}

/// One zone of a calibration, ready to apply to that zone's points.
pub struct PointEstimator<'a> {
    view: BlobView<'a>,
    zone: usize,
    mats: Vec<Vec<f32>>,
    /// Per table (sharp, broad: `brdf_meter::band`) and cluster, the
    /// per-bin uncertainty.
    sigma: [Vec<Vec<f32>>; 2],
    /// The grid (deg), which a point's table is decided on.
    bins: Vec<f32>,
    centroids: Vec<f32>,
    out_of_prior: Option<(Vec<f32>, Vec<f32>, f32, OutOfPriorForm)>,
    /// Per gloss cluster the gloss block, and the standard's assigned value.
    gloss: Option<(Vec<Vec<f32>>, f32)>,
    /// The gloss rows' own centroids (K_g x m), or empty: a point's gloss
    /// block is then its BRDF cluster's.
    gloss_centroids: Vec<f32>,
}

impl<'a> PointEstimator<'a> {
    /// Prepares zone `zone` of `view`. Refuses what the device refuses to
    /// run: a log-domain blob (no device form).
    pub fn new(view: BlobView<'a>, zone: usize) -> anyhow::Result<Self> {
        let d = view.dims();
        ensure!(zone < d.zones, "zone {zone}: the blob has {} zone(s)", d.zones);
        ensure!(
            view.estimator() != EstimatorKind::LogWiener,
            "a log-wiener blob cannot be applied (it has no device form)"
        );
        let k = view.clusters();
        let mats = (0..k)
            .map(|c| {
                let mut w = vec![0.0f32; d.n * d.m];
                view.copy_matrix_of(zone, c, &mut w);
                w
            })
            .collect();
        let table = |t| (0..k).map(|c| (0..d.n).map(|j| view.uncertainty_in(t, zone, c, j)).collect()).collect();
        let sigma = [table(BandTable::Sharp), table(BandTable::Broad)];
        let bins = (0..d.n).map(|j| view.grid_deg(j)).collect();
        let mut centroids = Vec::new();
        if view.estimator() == EstimatorKind::ScaleFreePiecewise {
            centroids = vec![0.0f32; k * d.m];
            view.copy_centroids(zone, &mut centroids);
        }
        let out_of_prior = view.out_of_prior_threshold().zip(view.out_of_prior_form()).map(|(t, form)| {
            let (mut mean, mut g) = (vec![0.0f32; d.m - 1], vec![0.0f32; whitening_len(d.m)]);
            view.copy_out_of_prior(zone, &mut mean, &mut g);
            (mean, g, t, form)
        });
        let kg = view.gloss_clusters();
        let mut gloss_centroids = vec![0.0f32; kg * d.m];
        if !view.copy_gloss_centroids(zone, &mut gloss_centroids) {
            gloss_centroids.clear();
        }
        let gloss = view.has_gloss().then(|| {
            let mut assigned = 0.0f32;
            let blocks = (0..kg)
                .map(|c| {
                    let mut b = vec![0.0f32; brdf_meter::gloss::block_len(d.m)];
                    assigned = view.copy_gloss(zone, c, &mut b).expect("the blob has the section").0;
                    b
                })
                .collect();
            (blocks, assigned)
        });
        Ok(Self { view, zone, mats, sigma, bins, centroids, out_of_prior, gloss, gloss_centroids })
    }

    /// The calibration it applies.
    pub fn view(&self) -> &BlobView<'a> {
        &self.view
    }

    /// Readings per point m.
    pub fn m(&self) -> usize {
        self.view.dims().m
    }

    /// The zone applied.
    pub fn zone(&self) -> usize {
        self.zone
    }

    /// Estimates one point of the zone's first pixel from its
    /// white-corrected readings, as the device does.
    pub fn apply(&self, v: &[f32]) -> PointEstimate {
        self.apply_pixel(self.view.zone_start(self.zone) as usize, v)
    }

    /// Estimates one point of pixel `p` (one of the zone's) from its
    /// white-corrected readings, as the device does: the gloss readings on
    /// the pixel's own reference.
    pub fn apply_pixel(&self, p: usize, v: &[f32]) -> PointEstimate {
        let n = self.view.dims().n;
        assert_eq!(v.len(), self.m());
        let mut rho = vec![0.0f32; n];
        let mut bits = 0u8;
        if v.iter().any(|x| !x.is_finite()) {
            bits |= flags::NON_FINITE;
        }
        let root = self.view.root_form();
        let mut sqrt_s = 0.0f32;
        let (s, sigma_scale, cluster) = match self.view.estimator() {
            EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise => {
                let c = if self.centroids.is_empty() { 0 } else { select_cluster(&self.centroids, v) };
                let s = if root {
                    let (s, r) = estimate_scale_free_root(&self.mats[c], v, &mut rho);
                    sqrt_s = r;
                    s
                } else {
                    estimate_scale_free(&self.mats[c], v, &mut rho)
                };
                (s, s, c as u8)
            }
            _ => {
                mat_vec_f32_slice(&self.mats[0], v, &mut rho);
                (scale(v), 1.0, 0)
            }
        };
        let mut stat = f32::NAN;
        if let Some((mean, g, t, form)) = &self.out_of_prior {
            stat = form.stat(g, mean, v, s);
            bits |= out_of_prior_flag(stat, *t);
        }
        // The per-bin uncertainty the frame states: from the point's scale,
        // which a flagged point's band factor widens, as the device does
        // (the gloss readings' own uncertainties keep the readings' scale).
        let band_factor = self.view.out_of_prior_band_factor();
        let readings_scale = sigma_scale;
        let sigma_scale = if bits & flags::OUT_OF_PRIOR != 0 && band_factor != 1.0 {
            flagged_sigma_scale(sigma_scale, band_factor, root)
        } else {
            sigma_scale
        };
        let table = self.view.band_table(&self.bins, &rho);
        let unit = &self.sigma[usize::from(table == BandTable::Broad)][cluster as usize];
        let mut sigma = vec![0.0f32; n];
        if root {
            for (j, o) in sigma.iter_mut().enumerate() {
                *o = root_uncertainty(unit[j], rho[j], sigma_scale);
            }
        } else {
            scaled_uncertainty(unit, sigma_scale, &mut sigma);
        }
        bits |= guard_estimate(&mut rho);
        let (mut readings, mut reading_sigma) = (brdf_meter::gloss::NO_READINGS, brdf_meter::gloss::NO_READINGS);
        if let Some((blocks, assigned)) = &self.gloss {
            // The device's operation, so the same bits.
            let q = *assigned / self.view.gloss_reference(p).expect("the blob has the section");
            // The gloss rows' cluster, from the same readings as the BRDF's.
            let gc = brdf_meter::gloss::cluster_of(&self.gloss_centroids, cluster as usize, v);
            // The kernel's input: the scale-free kinds replace the last reading by the scale.
            let mut x = v.to_vec();
            if matches!(self.view.estimator(), EstimatorKind::ScaleFree | EstimatorKind::ScaleFreePiecewise) {
                x[v.len() - 1] = s;
            }
            (readings, reading_sigma) = if root {
                brdf_meter::kernel::scale_input(&mut x, brdf_meter::kernel::root_scales(s).1);
                brdf_meter::gloss::readings_root(&blocks[gc], &x, q, sqrt_s, self.view.root_readings())
            } else {
                brdf_meter::gloss::readings(&blocks[gc], &x, q, readings_scale)
            };
        }
        if bits & flags::NON_FINITE != 0 {
            rho.fill(0.0);
            sigma.fill(0.0);
            (readings, reading_sigma) = (brdf_meter::gloss::NO_READINGS, brdf_meter::gloss::NO_READINGS);
        }
        PointEstimate {
            rho,
            sigma,
            readings,
            reading_sigma,
            flags: flag_names(bits),
            flag_bits: bits,
            cluster,
            sigma_scale,
            stat,
        }
    }
}

/// What the device streams for one point: zone, flags, the uncertainty's
/// scale, the gloss readings with their uncertainties and the n values.
#[derive(Clone, Debug, PartialEq)]
pub struct ExpectedPoint {
    /// The pixel's zone.
    pub zone: u16,
    /// Flag bits.
    pub flags: u8,
    /// The frame's `cluster`.
    pub cluster: u8,
    /// The frame's `sigma_scale`.
    pub sigma_scale: f32,
    /// The frame's `readings`.
    pub readings: [f32; READINGS],
    /// The frame's `reading_sigma`.
    pub reading_sigma: [f32; READINGS],
    /// The n values.
    pub values: Vec<f32>,
    /// The corrected readings the values were estimated from (in reading
    /// order): what the corrected-readings encoding sends.
    pub corrected: Vec<f32>,
}

/// The device's correction of one scene line (`frames` as
/// [`expected_line`] takes them): per pixel the corrected readings (reading
/// order) and their flags, by the library's own `correct_point_into`.
pub fn corrected_line(
    blob: &BlobView<'_>,
    frames: &[Vec<u16>],
    full_scale: u16,
    acq: &AcqConfig,
) -> Vec<(Vec<f32>, u8)> {
    let d = blob.dims();
    let order = blob.led_order();
    let levels = (frames.len() / (d.m + 1)).saturating_sub(1).min(acq.short_levels());
    let linearity = blob.linearity();
    (0..d.pixels)
        .map(|p| {
            let lit_at = |level: usize| -> Vec<u16> {
                order.iter().map(|&led| frames[level * (d.m + 1) + led as usize + 1][p]).collect()
            };
            let lit = lit_at(0);
            let short: Vec<Vec<u16>> = (1..=levels).map(lit_at).collect();
            let taken = vec![true; d.m];
            let shorter: Vec<Shorter<'_>> = (0..levels)
                .map(|l| Shorter {
                    dark: frames[(l + 1) * (d.m + 1)][p],
                    ratio: acq.ratio(l),
                    lit: &short[l],
                    taken: &taken,
                })
                .collect();
            let white: Vec<f32> = (0..d.m).map(|i| blob.white(p, i)).collect();
            let mut v = vec![0.0f32; d.m];
            let flags =
                correct_point_into(frames[0][p], &lit, &white, full_scale, &shorter, linearity.as_ref(), &mut v);
            (v, flags)
        })
        .collect()
}

/// What the device must send for one scene line, point by point, computed
/// with the library's own correction and the device's rule (so equality is
/// bit for bit). `frames` is the line as the simulated sensor serves it:
/// the dark frame and one per LED (physical order), then the same at each
/// shorter exposure of `acq` the scene has (`forward::scene::raw_frames`).
///
/// # Panics
/// If the blob is one the device refuses to run (see [`PointEstimator::new`]).
pub fn expected_line(blob: &BlobView<'_>, frames: &[Vec<u16>], full_scale: u16, acq: &AcqConfig) -> Vec<ExpectedPoint> {
    let zones: Vec<PointEstimator<'_>> =
        (0..blob.dims().zones).map(|z| PointEstimator::new(*blob, z).expect("a calibration the device runs")).collect();
    corrected_line(blob, frames, full_scale, acq)
        .into_iter()
        .enumerate()
        .map(|(p, (v, flags))| {
            let z = blob.zone_of_pixel(p);
            let e = zones[z].apply_pixel(p, &v);
            ExpectedPoint {
                zone: z as u16,
                cluster: e.cluster,
                flags: flags | e.flag_bits,
                sigma_scale: e.sigma_scale,
                readings: e.readings,
                reading_sigma: e.reading_sigma,
                values: e.rho,
                corrected: v,
            }
        })
        .collect()
}
