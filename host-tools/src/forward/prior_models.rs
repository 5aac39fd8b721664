//! A prior as the models of its samples, not only their values on the grid.
//!
//! Training from sample pairs (`crate::forward::pairs`) needs, for every
//! prior sample, what the instrument would read of it through optics that
//! are not in-plane (extended LEDs, each pixel's own view) and its truth at
//! each pixel's own view. A sample known as a reflection model (Ward, GGX,
//! a measured MERL or NBRDF material, a smooth dielectric) can be evaluated
//! for any pair of directions: [`SampleModel::Brdf`]. A sample known only as
//! an in-plane profile at the instrument's nominal view (a goniometric CSV,
//! an ASTM E1392 table's profile) cannot: [`SampleModel::Profile`], whose
//! readings are the in-plane model's `H rho` and whose truth stays the
//! profile at every pixel. A prior may also train every rough reflection
//! model at rougher finishes of itself, and stretched across the plane of
//! incidence where the optics see across it ([`PriorModels::variants`]):
//! pairs of the same sample, so what holds a sample out holds them out too.
use crate::calibration::estimators::scale_free::WeightedSamples;
use crate::forward::brdf::Brdf;
use crate::forward::grid::AngleGrid;
use nalgebra::{DMatrix, DVector};
use std::sync::Arc;

/// What is known of one prior sample.
#[derive(Clone, Debug)]
pub enum SampleModel {
    /// A reflection model, evaluable for any pair of directions.
    Brdf(Arc<dyn Brdf>),
    /// Reflectance factors on the grid's bins at the instrument's nominal
    /// view only (in-plane).
    Profile(DVector<f64>),
}

impl SampleModel {
    /// The sample on `grid` at `view_deg` (reflectance factors; a model's
    /// mirror spike is not included, as in the priors' grid vectors).
    pub fn on_grid(&self, grid: &AngleGrid, view_deg: f64) -> DVector<f64> {
        match self {
            Self::Brdf(b) => {
                let wo = crate::forward::brdf::view_dir(view_deg);
                DVector::from_iterator(
                    grid.n(),
                    grid.bins_deg()
                        .iter()
                        .map(|t| crate::forward::brdf::binned_factor_at(b.as_ref(), *t, &wo, grid.step_deg())),
                )
            }
            Self::Profile(p) => p.clone(),
        }
    }
}

/// One prior sample: its name, family, weight and model.
#[derive(Clone, Debug)]
pub struct PriorSample {
    /// Name for reports, e.g. `merl:blue-acrylic`.
    pub name: String,
    /// The family it came from (the prior argument's label).
    pub family: String,
    /// Weight in the prior (the weights of a prior sum to 1).
    pub weight: f64,
    /// What is known of it.
    pub model: SampleModel,
}

/// The share of a material's weight its own model keeps when it also
/// trains at rougher finishes or stretched ([`PriorModels::variants`]):
/// half. What was measured stays what the prior is mostly made of; the
/// variants, constructions from it, fill the gaps between its lobes. (Equal shares,
/// a quarter each at three finishes, let the constructed lobes outweigh
/// the measured ones: the measured set's held-out median error went from
/// 0.0213 to 0.0246 and its false flags from 5 to 15 %, `host-tools
/// accuracy`.)
pub const MEASURED_SHARE: f64 = 0.5;

/// The samples of a prior, as models.
#[derive(Clone, Debug, Default)]
pub struct PriorModels {
    /// The samples, weights summing to 1.
    pub samples: Vec<PriorSample>,
    /// Rougher finishes each rough reflection model also trains at: the
    /// standard deviations of a further spread of facet tilts, degrees
    /// ([`Self::variants`]). Empty: the samples as they are.
    pub finishes_deg: Vec<f64>,
    /// How much wider across the plane of incidence each rough reflection
    /// model is also read, where the optics see across it
    /// ([`Self::variants`]). Empty: the samples as they are.
    pub across: Vec<f64>,
}

impl PriorModels {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Equal-weight samples of one family from reflection models.
    pub fn from_brdfs(family: &str, brdfs: Vec<(String, Arc<dyn Brdf>)>) -> Self {
        let w = 1.0 / brdfs.len().max(1) as f64;
        Self {
            samples: brdfs
                .into_iter()
                .map(|(name, b)| PriorSample { name, family: family.into(), weight: w, model: SampleModel::Brdf(b) })
                .collect(),
            finishes_deg: Vec::new(),
            across: Vec::new(),
        }
    }

    /// The samples on the grid at `view_deg` with their weights.
    pub fn on_grid(&self, grid: &AngleGrid, view_deg: f64) -> WeightedSamples {
        let cols: Vec<DVector<f64>> = self.samples.iter().map(|s| s.model.on_grid(grid, view_deg)).collect();
        WeightedSamples {
            samples: DMatrix::from_columns(&cols),
            weights: self.samples.iter().map(|s| s.weight).collect(),
        }
    }

    /// The names, in order.
    pub fn names(&self) -> Vec<String> {
        self.samples.iter().map(|s| s.name.clone()).collect()
    }

    /// The subset `idx`, weights renormalised to sum to 1.
    pub fn subset(&self, idx: &[usize]) -> Self {
        let total: f64 = idx.iter().map(|&k| self.samples[k].weight).sum();
        Self {
            samples: idx
                .iter()
                .map(|&k| {
                    let mut s = self.samples[k].clone();
                    s.weight /= total;
                    s
                })
                .collect(),
            finishes_deg: self.finishes_deg.clone(),
            across: self.across.clone(),
        }
    }

    /// Two priors mixed as families: this one's weights times `1 - w`, the
    /// other's times `w`.
    pub fn mixed_with(&self, other: &PriorModels, w: f64) -> Self {
        fn scaled(p: &PriorModels, f: f64) -> impl Iterator<Item = PriorSample> + '_ {
            let total: f64 = p.samples.iter().map(|s| s.weight).sum();
            p.samples.iter().map(move |s| PriorSample { weight: s.weight / total * f, ..s.clone() })
        }
        Self {
            samples: scaled(self, 1.0 - w).chain(scaled(other, w)).collect(),
            finishes_deg: self.finishes_deg.clone(),
            across: self.across.clone(),
        }
    }

    /// This prior with every rough reflection model also at rougher
    /// finishes, `sigma_deg` the tilt spreads (each > 0).
    pub fn with_finishes(mut self, sigma_deg: &[f64]) -> Self {
        self.finishes_deg = sigma_deg.to_vec();
        self
    }

    /// This prior with every rough reflection model also stretched across
    /// the plane of incidence by each of `s` (each > 0), where the optics
    /// see across it ([`Self::variants`]).
    pub fn with_across(mut self, s: &[f64]) -> Self {
        self.across = s.to_vec();
        self
    }

    /// Sample `k`'s variants that training reads, each with its share of
    /// the sample's weight: the model as it is, and, for a reflection
    /// model without a mirror spike (a measured material or a rough model:
    /// a polished standard's Fresnel spike is no lobe to spread), each of
    /// [`Self::finishes_deg`] as `crate::forward::brdf::roughened::Roughened`
    /// and, when the optics read light from across the plane of incidence
    /// (`sees_across`), each of [`Self::across`] as
    /// `crate::forward::brdf::stretched::Stretched`. In-plane optics read a
    /// stretched material exactly as the material itself (the same rays,
    /// the same in-plane truth), so there it is the material once. The
    /// material as it is keeps [`MEASURED_SHARE`] of the weight and its
    /// variants share the rest equally. They stay one sample (one fold,
    /// one prior index), so nothing held out of training leaves a twin of
    /// itself behind in it.
    pub fn variants(&self, k: usize, sees_across: bool) -> Vec<(SampleModel, f64)> {
        use crate::forward::brdf::{roughened::Roughened, stretched::Stretched};
        let model = &self.samples[k].model;
        let across: &[f64] = if sees_across { &self.across } else { &[] };
        // A model with a mirror spike has it at every incidence; 45 deg is any.
        let rough = match model {
            SampleModel::Brdf(b) if b.mirror_reflectance(45.0) == 0.0 => b,
            _ => return vec![(model.clone(), 1.0)],
        };
        let extra = self.finishes_deg.len() + across.len();
        if extra == 0 {
            return vec![(model.clone(), 1.0)];
        }
        let share = (1.0 - MEASURED_SHARE) / extra as f64;
        let finishes = self.finishes_deg.iter().map(|&s| Arc::new(Roughened::new(rough.clone(), s)) as Arc<dyn Brdf>);
        let stretched = across.iter().map(|&s| Arc::new(Stretched::new(rough.clone(), s)) as Arc<dyn Brdf>);
        std::iter::once((model.clone(), MEASURED_SHARE))
            .chain(finishes.chain(stretched).map(|b| (SampleModel::Brdf(b), share)))
            .collect()
    }
}

/// How much wider across the plane of incidence than as measured a prior
/// also holds each material by default ([`PriorModels::with_across`]):
/// one and a half and three times. An isotropic lobe at 45 deg is 0.7 as
/// wide across the plane as along it, so these are lobes about as wide
/// across as along, and twice as wide, as satins and effect paints are
/// (`crate::forward::brdf::stretched`; docs/handheld.md has what they do).
pub const DEFAULT_ACROSS: [f64; 2] = [1.5, 3.0];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::{Lambertian, Ward};

    #[test]
    fn rough_models_train_at_their_finishes_and_stretches_and_what_has_no_lobe_as_it_is() {
        let p = PriorModels {
            samples: vec![
                PriorSample {
                    name: "w".into(),
                    family: "a".into(),
                    weight: 0.5,
                    model: SampleModel::Brdf(Arc::new(Ward::patent(0.3, 0.05))),
                },
                PriorSample {
                    name: "g".into(),
                    family: "a".into(),
                    weight: 0.25,
                    model: SampleModel::Brdf(Arc::new(crate::forward::brdf::SmoothDielectric::black_glass())),
                },
                PriorSample {
                    name: "p".into(),
                    family: "b".into(),
                    weight: 0.25,
                    model: SampleModel::Profile(DVector::from_element(81, 0.2)),
                },
            ],
            ..Default::default()
        };
        assert_eq!(p.variants(0, true).len(), 1, "no variants unless asked for");
        let p = p.with_finishes(&[0.5, 1.0, 2.0]);
        let shares =
            |p: &PriorModels, k: usize, across: bool| p.variants(k, across).iter().map(|v| v.1).collect::<Vec<_>>();
        let third = (1.0 - MEASURED_SHARE) / 3.0;
        assert_eq!(shares(&p, 0, true), vec![MEASURED_SHARE, third, third, third]);
        assert_eq!(shares(&p, 1, true), vec![1.0], "a mirror spike has no lobe to spread");
        assert_eq!(shares(&p, 2, true), vec![1.0], "a profile is known in-plane only");
        // Stretched across the plane only where the optics see across it.
        let p = p.with_across(&[1.5, 3.0]);
        let fifth = (1.0 - MEASURED_SHARE) / 5.0;
        assert_eq!(shares(&p, 0, true), vec![MEASURED_SHARE, fifth, fifth, fifth, fifth, fifth]);
        assert_eq!(shares(&p, 0, false), vec![MEASURED_SHARE, third, third, third]);
        let stretched_only = p.clone().with_finishes(&[]);
        assert_eq!(shares(&stretched_only, 0, false), vec![1.0]);
        assert_eq!(shares(&stretched_only, 0, true), vec![MEASURED_SHARE, 0.25, 0.25]);
        assert_eq!(shares(&p, 1, true), vec![1.0]);
        // A stretched variant is the material in the plane and wider across it.
        let v = stretched_only.variants(0, true);
        let (SampleModel::Brdf(a), SampleModel::Brdf(b)) = (&v[0].0, &v[2].0) else { panic!("models") };
        assert!((a.reflectance(44.0, 45.0) - b.reflectance(44.0, 45.0)).abs() < 1e-12 * a.reflectance(44.0, 45.0));
        let tilt = 0.1f64;
        let off = crate::forward::brdf::light_dir(45.0) * tilt.cos() + nalgebra::Vector3::new(0.0, tilt.sin(), 0.0);
        let wo = crate::forward::brdf::view_dir(45.0);
        assert!(b.f_r(&off, &wo) > 1.5 * a.f_r(&off, &wo));
        // Kept through a subset and a mixture.
        assert_eq!(p.subset(&[0]).finishes_deg, vec![0.5, 1.0, 2.0]);
        assert_eq!(p.subset(&[0]).across, vec![1.5, 3.0]);
        assert_eq!(p.mixed_with(&p.subset(&[2]), 0.5).variants(0, true).len(), 6);
    }

    #[test]
    fn models_sample_the_grid_and_mix_with_the_stated_weights() {
        let grid = AngleGrid::patent();
        let a = PriorModels::from_brdfs(
            "a",
            vec![
                ("w".into(), Arc::new(Ward::patent(0.3, 0.1)) as Arc<dyn Brdf>),
                ("l".into(), Arc::new(Lambertian::perfect()) as Arc<dyn Brdf>),
            ],
        );
        let ws = a.on_grid(&grid, 45.0);
        assert_eq!(ws.samples.shape(), (81, 2));
        assert!((ws.samples[(40, 1)] - 1.0).abs() < 1e-12);
        assert_eq!(ws.weights, vec![0.5, 0.5]);
        let p = PriorModels {
            samples: vec![PriorSample {
                name: "p".into(),
                family: "b".into(),
                weight: 1.0,
                model: SampleModel::Profile(DVector::from_element(81, 0.2)),
            }],
            ..Default::default()
        };
        let m = a.mixed_with(&p, 0.25);
        assert_eq!(m.samples.iter().map(|s| s.weight).collect::<Vec<_>>(), vec![0.375, 0.375, 0.25]);
        assert_eq!(m.on_grid(&grid, 45.0).samples[(3, 2)], 0.2);
        let s = m.subset(&[0, 2]);
        assert!((s.samples.iter().map(|s| s.weight).sum::<f64>() - 1.0).abs() < 1e-15);
    }
}
