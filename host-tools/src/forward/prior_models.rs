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
//! model at rougher finishes of itself ([`PriorModels::finishes`]): pairs of
//! the same sample, so what holds a sample out holds them out too.
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
/// trains at rougher finishes ([`PriorModels::finishes`]): half. What was
/// measured stays what the prior is mostly made of; the finishes, a
/// construction from it, fill the gaps between its lobes. (Equal shares,
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
    /// ([`Self::finishes`]). Empty: the samples as they are.
    pub finishes_deg: Vec<f64>,
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
        }
    }

    /// This prior with every rough reflection model also at rougher
    /// finishes, `sigma_deg` the tilt spreads (each > 0).
    pub fn with_finishes(mut self, sigma_deg: &[f64]) -> Self {
        self.finishes_deg = sigma_deg.to_vec();
        self
    }

    /// Sample `k`'s variants that training reads, each with its share of
    /// the sample's weight: the model as it is, and, for a reflection
    /// model without a mirror spike (a measured material or a rough model:
    /// a polished standard's Fresnel spike is no lobe to spread), each of
    /// [`Self::finishes_deg`] as `crate::forward::brdf::roughened::Roughened`.
    /// The material as it is keeps [`MEASURED_SHARE`] of the weight and its
    /// finishes share the rest equally. They stay one sample (one fold, one
    /// prior index), so nothing held out of training leaves a rougher twin
    /// behind in it.
    pub fn finishes(&self, k: usize) -> Vec<(SampleModel, f64)> {
        let model = &self.samples[k].model;
        // A model with a mirror spike has it at every incidence; 45 deg is any.
        let rough = match model {
            SampleModel::Brdf(b) if !self.finishes_deg.is_empty() && b.mirror_reflectance(45.0) == 0.0 => b,
            _ => return vec![(model.clone(), 1.0)],
        };
        let share = (1.0 - MEASURED_SHARE) / self.finishes_deg.len() as f64;
        std::iter::once((model.clone(), MEASURED_SHARE))
            .chain(self.finishes_deg.iter().map(|&s| {
                let r = crate::forward::brdf::roughened::Roughened::new(rough.clone(), s);
                (SampleModel::Brdf(Arc::new(r)), share)
            }))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::{Lambertian, Ward};

    #[test]
    fn rough_models_train_at_their_finishes_and_what_has_no_lobe_to_spread_as_it_is() {
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
        assert_eq!(p.finishes(0).len(), 1, "no finishes unless asked for");
        let p = p.with_finishes(&[0.5, 1.0, 2.0]);
        let shares = |k: usize| p.finishes(k).iter().map(|v| v.1).collect::<Vec<_>>();
        let third = (1.0 - MEASURED_SHARE) / 3.0;
        assert_eq!(shares(0), vec![MEASURED_SHARE, third, third, third]);
        assert_eq!(shares(1), vec![1.0], "a mirror spike has no lobe to spread");
        assert_eq!(shares(2), vec![1.0], "a profile is known in-plane only");
        // Kept through a subset and a mixture.
        assert_eq!(p.subset(&[0]).finishes_deg, vec![0.5, 1.0, 2.0]);
        assert_eq!(p.mixed_with(&p.subset(&[2]), 0.5).finishes(0).len(), 4);
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
