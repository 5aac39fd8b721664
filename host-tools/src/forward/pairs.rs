//! Sample pairs: for every prior sample, its truth at a pixel's own view and
//! what the instrument reads of it there (the patent's eq. 16-18 train the
//! estimation matrix from such pairs, `R_pv = <rho v^T>`, `R_vv = <v v^T>`,
//! noise included; eq. 20/22 are the special case `v = H rho`).
//!
//! [`PixelOptics`] is one pixel's geometry as training sees it: its view,
//! the rays of every LED at its point, the in-plane system matrix H there
//! and its readings' noise model. The readings of a sample are
//!
//! - by its rays, when the sample is a reflection model and the optics are
//!   known ray by ray: `v_i = sum_r w_r R(ray r, view)` with LED i's ray
//!   weights normalised to 1 (a perfect diffuser reads 1), exactly what the
//!   scene simulator computes before its sensor stages and what the
//!   instrument reads. In-plane optics too: `H rho` splits each ray between
//!   the two bins beside it and each bin is an average over its width, so
//!   for a lobe narrower than the rays' spacing (the measured prior's
//!   specular materials) `H rho` is a blurred reading the instrument never
//!   takes, and a map trained on it overshoots such a lobe's peak
//!   (`host-tools accuracy`: on held-out measured materials the peak bin
//!   read 0.18 of the peak high on average, the peak height 60 % off at the
//!   90th percentile; 0.00 and 14 % with the rays);
//! - `H rho` for a profile, known only in-plane on the grid at the nominal
//!   view, for optics known only by their H, and for in-plane optics
//!   training asks to read by H ([`PixelOptics::read_by_h_in_plane`]: the
//!   patent's estimators, defined by H, whose pairs then give eq. 20/22 on
//!   the Table 5 prior).
//!
//! The truth is the sample's binned reflectance factor at the pixel's own
//! view (a mirror spike projected onto its bins): what the user gets.
use crate::forward::brdf::{binned_reflectance_at, ray_reflectance};
use crate::forward::grid::AngleGrid;
use crate::forward::optics::{Optics, OpticsError, Ray, system_matrix_at};
use crate::forward::prior_models::{PriorModels, SampleModel};
use crate::forward::reading_noise::ReadingNoise;
use nalgebra::{DMatrix, DVector, Vector3};
use rayon::prelude::*;

/// Rays whose direction leaves the plane of incidence by less than this
/// (the y component of a unit vector) count as in-plane.
const IN_PLANE_TOLERANCE: f64 = 1e-12;

/// One pixel's optics as training and evaluation see them.
#[derive(Clone, Debug)]
pub struct PixelOptics {
    /// The (possibly fractional) pixel.
    pub pixel: f64,
    /// Its view direction, surface frame (unit).
    pub view: Vector3<f64>,
    /// The view's polar angle: the specular incidence of its gloss readings.
    pub theta_o_deg: f64,
    /// The in-plane system matrix at its point (m x n, rows summing to 1).
    pub h: DMatrix<f64>,
    /// Incidence of each LED's centre ray at its point, degrees (m).
    pub centres_deg: Vec<f64>,
    /// Its readings' noise.
    pub noise: ReadingNoise,
    /// The black-glass standard's readings as the instrument measures it
    /// here (the scene's whole pipeline without noise: its sensor effects
    /// and shorter exposures too), when known: what calibrating on the
    /// standard reads. `None`: its sample-pair readings.
    pub standard: Option<DVector<f64>>,
    /// Each LED's rays, weights normalised to sum to 1; `None` for optics
    /// known only by their H.
    rays: Option<Vec<Vec<Ray>>>,
    /// Whether every ray and the view lie in the plane of incidence.
    planar: bool,
    bins: Vec<f64>,
    step_deg: f64,
}

impl PixelOptics {
    /// The optics of `point` (cm, instrument frame) seen along `view`
    /// (surface frame) through prepared `optics`.
    pub fn new(
        optics: &Optics,
        grid: &AngleGrid,
        pixel: f64,
        point: &Vector3<f64>,
        view: Vector3<f64>,
        centres_deg: Vec<f64>,
        noise: ReadingNoise,
    ) -> Result<Self, OpticsError> {
        let h = system_matrix_at(optics, grid, point)?;
        let mut rays = Vec::with_capacity(optics.m());
        let mut planar = view.y.abs() < IN_PLANE_TOLERANCE;
        for led in 0..optics.m() {
            let mut r: Vec<Ray> = Vec::new();
            optics.for_each_ray(led, point, |ray| {
                if ray.weight > 0.0 {
                    planar &= ray.dir.y.abs() < IN_PLANE_TOLERANCE;
                    r.push(ray);
                }
            });
            let total: f64 = r.iter().map(|x| x.weight).sum();
            if total <= 0.0 || !total.is_finite() {
                return Err(OpticsError::NoLight { led });
            }
            r.iter_mut().for_each(|x| x.weight /= total);
            rays.push(r);
        }
        Ok(Self { rays: Some(rays), planar, ..Self::from_h(pixel, h, view, centres_deg, noise, grid) })
    }

    /// In-plane optics known only by their system matrix `h` (m x n on
    /// `grid`): readings `H rho`.
    pub fn from_h(
        pixel: f64,
        h: DMatrix<f64>,
        view: Vector3<f64>,
        centres_deg: Vec<f64>,
        noise: ReadingNoise,
        grid: &AngleGrid,
    ) -> Self {
        Self {
            pixel,
            theta_o_deg: view.z.clamp(-1.0, 1.0).acos().to_degrees(),
            view,
            h,
            centres_deg,
            noise,
            standard: None,
            rays: None,
            planar: true,
            bins: grid.bins_deg().to_vec(),
            step_deg: grid.step_deg(),
        }
    }

    /// Whether every ray and the view lie in the plane of incidence (the
    /// in-plane model `H rho` then describes the optics, up to its bins).
    pub fn in_plane(&self) -> bool {
        self.planar
    }

    /// The same optics, read by the in-plane model `H rho` when they are
    /// in-plane (the patent's estimators, defined by H); unchanged
    /// otherwise.
    pub fn read_by_h_in_plane(&self) -> Self {
        let rays = if self.planar { None } else { self.rays.clone() };
        Self { rays, ..self.clone() }
    }

    /// LEDs m.
    pub fn m(&self) -> usize {
        self.h.nrows()
    }

    /// The grid's bin centres, degrees.
    pub fn bins(&self) -> &[f64] {
        &self.bins
    }

    /// The sample's truth at this pixel's view (n).
    pub fn truth(&self, model: &SampleModel) -> DVector<f64> {
        match model {
            SampleModel::Brdf(b) => DVector::from_iterator(
                self.bins.len(),
                self.bins.iter().map(|t| binned_reflectance_at(b.as_ref(), *t, &self.view, self.step_deg)),
            ),
            SampleModel::Profile(p) => p.clone(),
        }
    }

    /// The sample's gloss readings' linear readings by their definitions at
    /// this pixel's view, on the black glass's scale there (`100 L /
    /// L_0,bg`, `crate::forward::gloss`): in three dimensions for a model,
    /// in-plane for a profile (`None` when the grid does not cover its
    /// specular aperture).
    pub fn gloss_target(&self, model: &SampleModel, truth: &DVector<f64>) -> Option<[f64; brdf_meter::gloss::LINEAR]> {
        use crate::forward::gloss::{ASSIGNED_GU, black_glass_flux, model_linear_readings, profile_scaled_readings};
        match model {
            SampleModel::Brdf(b) => {
                let q = ASSIGNED_GU / black_glass_flux(self.theta_o_deg);
                Some(model_linear_readings(b.as_ref(), &self.view).map(|x| x * q))
            }
            SampleModel::Profile(_) => profile_scaled_readings(truth, &self.bins, self.theta_o_deg),
        }
    }

    /// The sample's noise-free readings (m), given its truth here.
    pub fn readings(&self, model: &SampleModel, truth: &DVector<f64>) -> DVector<f64> {
        match (model, &self.rays) {
            (SampleModel::Brdf(b), Some(rays)) => DVector::from_iterator(
                rays.len(),
                rays.iter().map(|led| {
                    led.iter()
                        .map(|r| {
                            r.weight
                                * ray_reflectance(
                                    b.as_ref(),
                                    &r.dir,
                                    &self.view,
                                    r.theta_deg,
                                    self.theta_o_deg,
                                    self.step_deg,
                                )
                        })
                        .sum::<f64>()
                }),
            ),
            _ => &self.h * truth,
        }
    }
}

/// How the pairs are weighted: the error the training minimises.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Criterion {
    /// The prior's weights: the mean squared error over the ensemble (the
    /// patent's criterion; materials with large values decide).
    Plain,
    /// Each pair's weight divided by its truth's squared peak: the mean
    /// squared error relative to each sample's peak, the error a user
    /// judges an estimate by (a dark matt sample counts as much as a metal).
    #[default]
    PeakRelative,
    /// Each pair's weight divided by its readings' squared scale (their
    /// sum): the error relative to how bright the sample reads, which the
    /// scale-free estimators minimise by construction.
    ScaleRelative,
}

/// Sample pairs over one or more pixels.
#[derive(Clone, Debug)]
pub struct Pairs {
    /// Truths, n x K.
    pub truth: DMatrix<f64>,
    /// Noise-free readings, m x K.
    pub readings: DMatrix<f64>,
    /// Variance of every reading, m x K (the noise model at its value).
    pub noise_var: DMatrix<f64>,
    /// Weights, summing to 1: the training criterion's ([`Self::weighted`]).
    pub weights: Vec<f64>,
    /// The prior's own weights (summing to 1), whatever the criterion: the
    /// ensemble an error over the prior is averaged with.
    pub base: Vec<f64>,
    /// The prior sample of each pair (a sample's variants are pairs of it:
    /// what holds a sample out holds them out too).
    pub sample: Vec<usize>,
    /// The pixel of each pair (index into the pixels it was built over).
    pub pixel: Vec<usize>,
    /// Which of its sample's variants each pair reads: 0 the sample as it
    /// is, 1.. its rougher finishes and stretches (`PriorModels::variants`'
    /// order). An uncertainty stated for the materials as they are must
    /// hold on them, not only on them pooled with their variants.
    pub variant: Vec<usize>,
    /// The gloss rows' target of each pair (LINEAR x K,
    /// [`PixelOptics::gloss_target`]), when built with it and every pair has one.
    pub gloss: Option<DMatrix<f64>>,
}

impl Pairs {
    /// Every sample of `prior` at every pixel of `pixels`, each pixel's
    /// pairs sharing the prior's weights equally; a sample with variants
    /// (rougher finishes, stretches across the plane:
    /// `PriorModels::variants`) is one pair per variant, all of that
    /// sample, sharing its weight.
    pub fn build(pixels: &[PixelOptics], prior: &PriorModels) -> Self {
        Self::build_inner(pixels, prior, false)
    }

    /// [`Self::build`] with each pair's gloss target (the gloss rows').
    pub fn build_with_gloss(pixels: &[PixelOptics], prior: &PriorModels) -> Self {
        Self::build_inner(pixels, prior, true)
    }

    fn build_inner(pixels: &[PixelOptics], prior: &PriorModels, gloss: bool) -> Self {
        assert!(!pixels.is_empty(), "pairs need at least one pixel");
        let np = pixels.len();
        type Col = (
            DVector<f64>,
            DVector<f64>,
            DVector<f64>,
            f64,
            (usize, usize, usize),
            Option<[f64; brdf_meter::gloss::LINEAR]>,
        );
        // Each sample's variants (itself, and its rougher finishes and
        // stretches across the plane when the prior has them and the
        // optics see across the plane): pairs of one sample, sharing its weight.
        let sees_across = pixels.iter().any(|p| !p.in_plane());
        let variants: Vec<Vec<(SampleModel, f64)>> = (0..prior.len()).map(|k| prior.variants(k, sees_across)).collect();
        let jobs: Vec<(usize, usize, usize)> = (0..np)
            .flat_map(|p| variants.iter().enumerate().flat_map(move |(k, v)| (0..v.len()).map(move |j| (p, k, j))))
            .collect();
        let cols: Vec<Col> = jobs
            .into_par_iter()
            .map(|(p, k, j)| {
                let po = &pixels[p];
                let (model, share) = &variants[k][j];
                let t = po.truth(model);
                let v = po.readings(model, &t);
                let var = DVector::from_iterator(v.len(), v.iter().enumerate().map(|(j, x)| po.noise.variance(j, *x)));
                let g = if gloss { po.gloss_target(model, &t) } else { None };
                (t, v, var, prior.samples[k].weight * share / np as f64, (k, p, j), g)
            })
            .collect();
        let gloss = if gloss && cols.iter().all(|c| c.5.is_some()) {
            Some(DMatrix::from_fn(brdf_meter::gloss::LINEAR, cols.len(), |r, c| cols[c].5.expect("checked")[r]))
        } else {
            None
        };
        let truth = DMatrix::from_columns(&cols.iter().map(|c| c.0.clone()).collect::<Vec<_>>());
        let readings = DMatrix::from_columns(&cols.iter().map(|c| c.1.clone()).collect::<Vec<_>>());
        let noise_var = DMatrix::from_columns(&cols.iter().map(|c| c.2.clone()).collect::<Vec<_>>());
        let total: f64 = cols.iter().map(|c| c.3).sum();
        let weights: Vec<f64> = cols.iter().map(|c| c.3 / total).collect();
        Self {
            truth,
            readings,
            noise_var,
            base: weights.clone(),
            weights,
            sample: cols.iter().map(|c| c.4.0).collect(),
            pixel: cols.iter().map(|c| c.4.1).collect(),
            variant: cols.iter().map(|c| c.4.2).collect(),
            gloss,
        }
    }

    /// The in-plane model's pairs of samples on the grid: `(rho_k, H rho_k)`
    /// with the samples' weights and the noise model at each reading.
    pub fn in_plane(h: &DMatrix<f64>, samples: &DMatrix<f64>, weights: &[f64], noise: &ReadingNoise) -> Self {
        let k = samples.ncols();
        assert_eq!(weights.len(), k);
        let readings = h * samples;
        let noise_var = DMatrix::from_fn(readings.nrows(), k, |i, c| noise.variance(i, readings[(i, c)]));
        let total: f64 = weights.iter().sum();
        let w: Vec<f64> = weights.iter().map(|x| x / total).collect();
        Self {
            noise_var,
            truth: samples.clone(),
            readings,
            base: w.clone(),
            weights: w,
            sample: (0..k).collect(),
            pixel: vec![0; k],
            variant: vec![0; k],
            gloss: None,
        }
    }

    /// Number of pairs K.
    pub fn len(&self) -> usize {
        self.weights.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.weights.is_empty()
    }

    /// Bins n.
    pub fn n(&self) -> usize {
        self.truth.nrows()
    }

    /// LEDs m.
    pub fn m(&self) -> usize {
        self.readings.nrows()
    }

    /// The same pairs weighted for `criterion` (weights summing to 1). A
    /// pair whose peak (or scale) is not positive keeps its prior weight.
    pub fn weighted(&self, criterion: Criterion) -> Self {
        let mut out = self.clone();
        let size = |k: usize| match criterion {
            Criterion::Plain => 1.0,
            Criterion::PeakRelative => self.truth.column(k).amax(),
            Criterion::ScaleRelative => self.readings.column(k).sum(),
        };
        for (k, w) in out.weights.iter_mut().enumerate() {
            let x = size(k);
            if x > 0.0 && x.is_finite() {
                *w /= x * x;
            }
        }
        let total: f64 = out.weights.iter().sum();
        out.weights.iter_mut().for_each(|w| *w /= total);
        out
    }

    /// The pairs of prior samples for which `keep(sample)` holds, weights
    /// renormalised.
    pub fn of_samples(&self, keep: impl Fn(usize) -> bool) -> Self {
        let idx: Vec<usize> = (0..self.len()).filter(|&k| keep(self.sample[k])).collect();
        self.columns(&idx)
    }

    /// The pairs `idx`, weights renormalised.
    pub fn columns(&self, idx: &[usize]) -> Self {
        let pick = |a: &DMatrix<f64>| DMatrix::from_columns(&idx.iter().map(|&k| a.column(k)).collect::<Vec<_>>());
        let total: f64 = idx.iter().map(|&k| self.weights[k]).sum();
        let base: f64 = idx.iter().map(|&k| self.base[k]).sum();
        Self {
            truth: pick(&self.truth),
            readings: pick(&self.readings),
            noise_var: pick(&self.noise_var),
            weights: idx.iter().map(|&k| self.weights[k] / total).collect(),
            base: idx.iter().map(|&k| self.base[k] / base).collect(),
            sample: idx.iter().map(|&k| self.sample[k]).collect(),
            pixel: idx.iter().map(|&k| self.pixel[k]).collect(),
            variant: idx.iter().map(|&k| self.variant[k]).collect(),
            gloss: self.gloss.as_ref().map(pick),
        }
    }

    /// Concatenation, each side's weights times its share (`a` and `1 - a`).
    pub fn joined(&self, other: &Pairs, other_share: f64) -> Self {
        let cat = |a: &DMatrix<f64>, b: &DMatrix<f64>| {
            DMatrix::from_columns(&a.column_iter().chain(b.column_iter()).collect::<Vec<_>>())
        };
        let mix = |a: &[f64], b: &[f64]| -> Vec<f64> {
            a.iter().map(|w| w * (1.0 - other_share)).chain(b.iter().map(|w| w * other_share)).collect()
        };
        let weights = mix(&self.weights, &other.weights);
        let base = mix(&self.base, &other.base);
        Self {
            truth: cat(&self.truth, &other.truth),
            readings: cat(&self.readings, &other.readings),
            noise_var: cat(&self.noise_var, &other.noise_var),
            weights,
            base,
            // The other side's samples are other samples: numbered after these.
            sample: {
                let off = self.sample.iter().copied().max().map_or(0, |x| x + 1);
                self.sample.iter().copied().chain(other.sample.iter().map(|s| s + off)).collect()
            },
            pixel: self.pixel.iter().chain(&other.pixel).copied().collect(),
            variant: self.variant.iter().chain(&other.variant).copied().collect(),
            gloss: match (&self.gloss, &other.gloss) {
                (Some(a), Some(b)) => Some(cat(a, b)),
                _ => None,
            },
        }
    }

    /// `R_nn = sum_k w_k diag(var_k)`: the noise covariance averaged over the pairs.
    pub fn noise_covariance(&self) -> DMatrix<f64> {
        let m = self.m();
        let mut r = DMatrix::zeros(m, m);
        for (k, w) in self.weights.iter().enumerate() {
            for i in 0..m {
                r[(i, i)] += w * self.noise_var[(i, k)];
            }
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::{Brdf, Ward};
    use crate::forward::optics::{Instrument, RayModel};
    use std::sync::Arc;

    fn patent_pixel() -> PixelOptics {
        let inst = Instrument::patent_profile();
        let grid = inst.grid().unwrap();
        let optics = Optics::new(&inst, RayModel::legacy(false));
        PixelOptics::new(
            &optics,
            &grid,
            0.0,
            &Vector3::zeros(),
            inst.view_dir(),
            inst.centre_angles_deg(),
            ReadingNoise::relative(0.02, 7),
        )
        .unwrap()
    }

    #[test]
    fn in_plane_optics_read_models_by_rays_profiles_by_h_and_weights_follow_the_criterion() {
        let px = patent_pixel();
        assert!(px.in_plane());
        assert!((px.theta_o_deg - 45.0).abs() < 1e-9);
        let prior = PriorModels::from_brdfs(
            "w",
            vec![
                ("a".into(), Arc::new(Ward::patent(0.3, 0.05)) as Arc<dyn Brdf>),
                ("b".into(), Arc::new(Ward::patent(0.9, 0.2)) as Arc<dyn Brdf>),
            ],
        );
        let pairs = Pairs::build(std::slice::from_ref(&px), &prior);
        assert_eq!((pairs.n(), pairs.m(), pairs.len()), (81, 7, 2));
        // A reflection model is read by its rays, which a broad lobe's
        // `H rho` matches to well within the noise; a profile by `H rho`.
        let v = &px.h * pairs.truth.column(1);
        assert!((pairs.readings.column(1) - &v).amax() < 1e-3 * v.amax(), "{} vs {v}", pairs.readings.column(1));
        // A lobe narrower than the rays' spacing: read exactly as the
        // simulator reads it, which `H rho` does not.
        let narrow = Ward::patent(0.05, 0.004);
        let model = SampleModel::Brdf(Arc::new(narrow));
        let t = px.truth(&model);
        let (by_rays, exact) = (
            px.readings(&model, &t),
            crate::forward::optics::simulate_readings(&Instrument::patent_profile(), &narrow, false),
        );
        assert!((&by_rays - &exact).amax() <= 1e-12 * exact.amax(), "{by_rays} vs {exact}");
        assert!((&px.h * &t - &exact).amax() > 0.05 * exact.amax(), "H rho {} vs {exact}", &px.h * &t);
        let profile = SampleModel::Profile(pairs.truth.column(0).into_owned());
        let t = px.truth(&profile);
        assert_eq!(px.readings(&profile, &t), &px.h * &t);
        let var = pairs.noise_var[(3, 1)];
        assert!((var - (0.02 * pairs.readings[(3, 1)]).powi(2)).abs() < 1e-15);
        let pr = pairs.weighted(Criterion::PeakRelative);
        let (p0, p1) = (pairs.truth.column(0).amax(), pairs.truth.column(1).amax());
        assert!((pr.weights[0] / pr.weights[1] - (p1 * p1) / (p0 * p0)).abs() < 1e-9);
        assert_eq!(pairs.weighted(Criterion::Plain).weights, pairs.weights);
    }

    #[test]
    fn a_materials_finishes_are_pairs_of_the_same_sample_sharing_its_weight() {
        let px = patent_pixel();
        let prior = PriorModels::from_brdfs(
            "w",
            vec![
                ("glossy".into(), Arc::new(Ward::patent(0.1, 0.01)) as Arc<dyn Brdf>),
                ("glass".into(), Arc::new(crate::forward::brdf::SmoothDielectric::black_glass()) as Arc<dyn Brdf>),
            ],
        )
        .with_finishes(&[0.5, 2.0]);
        let pairs = Pairs::build(std::slice::from_ref(&px), &prior);
        // The glossy lobe as it is and at two finishes; the polished glass,
        // whose reflection is a mirror spike, only as it is.
        assert_eq!(pairs.sample, vec![0, 0, 0, 1]);
        assert_eq!(pairs.variant, vec![0, 1, 2, 0], "each pair knows whether it is its sample as it is");
        let w: Vec<f64> = pairs.base.clone();
        assert!((w[0] - 0.25).abs() < 1e-12 && (w[1] - 0.125).abs() < 1e-12 && (w[3] - 0.5).abs() < 1e-12, "{w:?}");
        // The rougher the finish, the lower and wider its peak.
        let peak = |k: usize| pairs.truth.column(k).amax();
        assert!(peak(0) > 2.0 * peak(1) && peak(1) > 2.0 * peak(2), "{} {} {}", peak(0), peak(1), peak(2));
        // Holding the material out holds out its finishes with it.
        let rest = pairs.of_samples(|s| s != 0);
        assert_eq!((rest.len(), rest.variant.clone()), (1, vec![0]));
        assert_eq!(pairs.joined(&rest, 0.5).variant, vec![0, 1, 2, 0, 0]);
    }

    #[test]
    fn extended_leds_out_of_the_plane_read_by_rays() {
        let scene = crate::forward::scene::Scene::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/handheld.toml"),
        )
        .unwrap();
        let inst = &scene.instrument;
        let grid = inst.grid().unwrap();
        let optics = Optics::new(inst, scene.ray_model());
        let px = PixelOptics::new(
            &optics,
            &grid,
            63.5,
            &scene.pixel_point(63.5),
            inst.view_dir(),
            inst.centre_angles_deg(),
            ReadingNoise::relative(0.0, 7),
        )
        .unwrap();
        assert!(!px.in_plane());
        // A diffuser reads 1 either way; a glossy lobe reads less than the
        // in-plane model says, since out-of-plane rays miss it.
        let white = SampleModel::Brdf(Arc::new(crate::forward::brdf::Lambertian::perfect()));
        let t = px.truth(&white);
        assert!(px.readings(&white, &t).iter().all(|x| (x - 1.0).abs() < 1e-12));
        let glossy = SampleModel::Brdf(Arc::new(Ward::patent(0.05, 0.01)));
        let t = px.truth(&glossy);
        let (by_rays, model) = (px.readings(&glossy, &t), &px.h * &t);
        assert!(by_rays[3] < 0.8 * model[3], "{} vs {}", by_rays[3], model[3]);
        // So the prior's materials stretched across the plane are pairs
        // here: the same truth, more light from the facet in the mirror
        // direction. In the plane they read exactly as the material does
        // and are left out.
        let prior =
            PriorModels::from_brdfs("w", vec![("glossy".into(), Arc::new(Ward::patent(0.05, 0.05)) as Arc<dyn Brdf>)])
                .with_across(&[1.5, 3.0]);
        let pairs = Pairs::build(std::slice::from_ref(&px), &prior);
        assert_eq!(pairs.sample, vec![0, 0, 0]);
        assert!((pairs.truth.column(0) - pairs.truth.column(2)).amax() <= 1e-12 * pairs.truth.column(0).amax());
        let specular = (0..7).max_by(|a, b| pairs.readings[(*a, 0)].total_cmp(&pairs.readings[(*b, 0)])).unwrap();
        let r = |k: usize| pairs.readings[(specular, k)];
        assert!(r(1) > 1.1 * r(0) && r(2) > 1.1 * r(1), "{} {} {}", r(0), r(1), r(2));
        assert_eq!(Pairs::build(std::slice::from_ref(&patent_pixel()), &prior).len(), 1);
    }
}
