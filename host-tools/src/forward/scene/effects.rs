//! The effects a scene may list, their parameters and their fixed order.
//!
//! | stage | effect (`kind`) | parameters | what it does when listed | when not listed |
//! |---|---|---|---|---|
//! | 1 | `near-field` | - | one ray per point source of each LED (cluster, listed sources or the sample points of an extended emitter) | one ray per LED along its nominal direction (far field); no source positions are built |
//! | 2 | `3d-geometry` | - | LED azimuths and offsets across the plane of incidence, pixels off the plane | everything projected into the plane of incidence |
//! | 3 | `per-pixel-geometry` | - | pixel k sees its own point along the line and (with `instrument.view_distance_cm`) its own view direction | every pixel sees the centre point along `view_deg`; rays are computed once for all pixels |
//! | 4 | `inverse-square` | - | ray weight x (d / r)^2, d the LED's nominal distance | no distance is computed |
//! | 5 | `emission-profile` | - | ray weight x the LED's emission profile (`leds[i].emission`, Lambertian when absent) | isotropic LEDs |
//! | 6 | `led-drift` | `rate_per_frame` (every LED) or `rates_per_frame` (one per LED, in `instrument.leds` order) | LED k's frame at time t (frames since calibration) scaled by 1 + rate_k t | constant LEDs |
//! | 7 | `ambient-light` | `counts` | adds ambient light to every frame, dark frame included | none |
//! | 8 | `nonlinearity` | `gamma` | counts -> full_scale (counts / full_scale)^gamma | linear camera |
//! | 9 | `dark-offset` | `counts`, `fixed_pattern_rms` = 0, `seed` = 1 | adds the dark level (plus a fixed per-pixel pattern) to every frame | zero dark level |
//! | 10 | `noise` | `model` = `additive` (`sigma_counts`) / `proportional` (`sigma`) / `shot-read` (`electrons_per_count`, `read_sigma_counts`), `seed` = 1 | Gaussian noise drawn per (seed, line, frame) | no random number generator exists |
//! | 11 | `saturation` | - | clips to 0..=`instrument.sensor.full_scale` | unbounded counts |
//! | 12 | `quantisation` | `step_counts` = 1 | rounds to a multiple of the step (the ADC's LSB) | continuous counts |
//! | 13 | `short-exposure` | `ratios` (ascending, each > 1) | a frame that saturates is taken again with the exposure 1 / `ratios[0]`, and again at the next ratio while it still saturates (with a dark frame at each), and each saturated pixel's reading comes from its longest unsaturated exposure times that ratio, as the device does | a saturated reading stays saturated |
//!
//! Stages 1-5 shape the rays (the optics); 6 acts on the light; 7-12 are the
//! sensor; 13 is the acquisition. The pipeline runs them in this order whatever order the file lists
//! them in; listing one twice is an error.
use crate::output::config::{FieldError, check_positive, check_range};
use serde::{Deserialize, Serialize};

/// Most shorter exposures the `short-exposure` effect (and the device) takes.
pub const MAX_SHORT_EXPOSURES: usize = brdf_meter::acquire::MAX_SHORT_EXPOSURES;

/// The stage order; also every effect name there is.
pub const STAGE_ORDER: [&str; 13] = [
    "near-field",
    "3d-geometry",
    "per-pixel-geometry",
    "inverse-square",
    "emission-profile",
    "led-drift",
    "ambient-light",
    "nonlinearity",
    "dark-offset",
    "noise",
    "saturation",
    "quantisation",
    "short-exposure",
];

/// How sensor noise is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseModel {
    /// N(0, sigma_counts^2), independent of the signal.
    Additive,
    /// N(0, (sigma x)^2): the patent's "2 % of the measured value".
    Proportional,
    /// Photon shot noise (variance x / electrons_per_count, Gaussian
    /// approximation) plus read noise N(0, read_sigma_counts^2).
    ShotRead,
}

/// The `led-drift` effect's rates: relative change of intensity per frame
/// since calibration. LEDs age and warm unequally (their junction
/// temperatures, their bins), so a real head's LEDs drift each at its own
/// rate, which changes the readings' ratios (a BRDF's shape), not only
/// their scale: what the white standardisation corrects LED by LED.
#[derive(Clone, Debug, PartialEq)]
pub enum DriftRate {
    /// One rate for every LED (`rate_per_frame`).
    Common(f64),
    /// One rate per LED, in `instrument.leds` order (`rates_per_frame`).
    PerLed(Vec<f64>),
}

impl DriftRate {
    /// LED `k`'s rate (0 past the list: the scene's check refuses a list
    /// of the wrong length before any frame is drawn).
    pub fn of_led(&self, k: usize) -> f64 {
        match self {
            Self::Common(r) => *r,
            Self::PerLed(r) => r.get(k).copied().unwrap_or(0.0),
        }
    }
}

/// One effect of a scene, as written in its `effects` list: a table with a
/// `kind` and that effect's parameters. (Read through a flat table so that an
/// unknown name, an unknown or foreign parameter and a missing one are all
/// reported at their own line.)
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "EffectEntry", into = "EffectEntry")]
pub enum EffectSpec {
    /// Near-field ray distribution.
    NearField {},
    /// LEDs off the plane of incidence.
    ThreeDGeometry {},
    /// Each pixel sees its own point and view.
    PerPixelGeometry {},
    /// Inverse-square falloff.
    InverseSquare {},
    /// LED emission profile.
    EmissionProfile {},
    /// LED intensity drift with time.
    LedDrift {
        /// Relative change of intensity per frame since calibration.
        rate: DriftRate,
    },
    /// Ambient light in every frame.
    AmbientLight {
        /// Counts added by the ambient light.
        counts: f64,
    },
    /// Camera response curve.
    Nonlinearity {
        /// Exponent of the response (1 = linear).
        gamma: f64,
    },
    /// Dark level.
    DarkOffset {
        /// Mean dark level, counts.
        counts: f64,
        /// RMS of a fixed per-pixel pattern around it, counts.
        fixed_pattern_rms: f64,
        /// Seed of the fixed pattern.
        seed: u64,
    },
    /// Sensor noise.
    Noise {
        /// Which noise.
        model: NoiseModel,
        /// Relative sigma (`proportional`).
        sigma: Option<f64>,
        /// Sigma in counts (`additive`).
        sigma_counts: Option<f64>,
        /// Photo-electrons per count (`shot-read`).
        electrons_per_count: Option<f64>,
        /// Read noise in counts (`shot-read`).
        read_sigma_counts: Option<f64>,
        /// Seed of the draws.
        seed: u64,
    },
    /// Clipping at the converter's rails.
    Saturation {},
    /// ADC rounding.
    Quantisation {
        /// Size of one step, counts.
        step_counts: f64,
    },
    /// Shorter exposures of a frame that saturates.
    ShortExposure {
        /// The long exposure over each shorter one, ascending.
        ratios: Vec<f64>,
    },
}

/// The names an effect's `kind` may take.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
enum EffectKind {
    NearField,
    #[serde(rename = "3d-geometry")]
    ThreeDGeometry,
    PerPixelGeometry,
    InverseSquare,
    EmissionProfile,
    LedDrift,
    AmbientLight,
    Nonlinearity,
    DarkOffset,
    Noise,
    Saturation,
    Quantisation,
    ShortExposure,
}

/// An effect table as written: the kind and every parameter any effect takes.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct EffectEntry {
    kind: Option<EffectKind>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rate_per_frame: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rates_per_frame: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    counts: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gamma: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fixed_pattern_rms: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    model: Option<NoiseModel>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sigma: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sigma_counts: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    electrons_per_count: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    read_sigma_counts: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    step_counts: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    seed: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    ratios: Option<Vec<f64>>,
}

impl EffectEntry {
    /// The parameters given, by name.
    fn given(&self) -> Vec<&'static str> {
        let mut g = Vec::new();
        let mut add = |name, present: bool| {
            if present {
                g.push(name)
            }
        };
        add("rate_per_frame", self.rate_per_frame.is_some());
        add("rates_per_frame", self.rates_per_frame.is_some());
        add("counts", self.counts.is_some());
        add("gamma", self.gamma.is_some());
        add("fixed_pattern_rms", self.fixed_pattern_rms.is_some());
        add("model", self.model.is_some());
        add("sigma", self.sigma.is_some());
        add("sigma_counts", self.sigma_counts.is_some());
        add("electrons_per_count", self.electrons_per_count.is_some());
        add("read_sigma_counts", self.read_sigma_counts.is_some());
        add("step_counts", self.step_counts.is_some());
        add("seed", self.seed.is_some());
        add("ratios", self.ratios.is_some());
        g
    }
}

fn need<T>(kind: &str, field: &str, v: Option<T>) -> Result<T, FieldError> {
    v.ok_or_else(|| FieldError::new(field, format!("effect `{kind}`: missing field `{field}`")))
}

impl TryFrom<EffectEntry> for EffectSpec {
    type Error = String;
    fn try_from(e: EffectEntry) -> Result<Self, String> {
        EffectSpec::from_entry(e).map_err(|e| format!("field `{}`: {}", e.path, e.message))
    }
}

impl EffectSpec {
    /// Reads an effect table; errors name the field (relative to the table).
    pub(crate) fn from_entry(e: EffectEntry) -> Result<Self, FieldError> {
        let kind = e.kind.ok_or_else(|| {
            FieldError::new(
                "kind",
                format!("missing field `kind`; name one of the effects: {}", STAGE_ORDER.join(", ")),
            )
        })?;
        // Which parameters each effect takes.
        let (allowed, spec): (&[&str], EffectSpec) = match kind {
            EffectKind::NearField => (&[], EffectSpec::NearField {}),
            EffectKind::ThreeDGeometry => (&[], EffectSpec::ThreeDGeometry {}),
            EffectKind::PerPixelGeometry => (&[], EffectSpec::PerPixelGeometry {}),
            EffectKind::InverseSquare => (&[], EffectSpec::InverseSquare {}),
            EffectKind::EmissionProfile => (&[], EffectSpec::EmissionProfile {}),
            EffectKind::Saturation => (&[], EffectSpec::Saturation {}),
            EffectKind::LedDrift => {
                let rate = match (e.rate_per_frame, e.rates_per_frame.clone()) {
                    (Some(r), None) => DriftRate::Common(r),
                    (None, Some(r)) => DriftRate::PerLed(r),
                    (Some(_), Some(_)) => {
                        return Err(FieldError::new(
                            "rates_per_frame",
                            "effect `led-drift`: give `rate_per_frame` (one rate for every LED) or \
                             `rates_per_frame` (one per LED), not both",
                        ));
                    }
                    (None, None) => {
                        return Err(FieldError::new(
                            "rate_per_frame",
                            "effect `led-drift`: missing field `rate_per_frame` (one rate for every LED) or \
                             `rates_per_frame` (one per LED, in `instrument.leds` order)",
                        ));
                    }
                };
                (&["rate_per_frame", "rates_per_frame"], EffectSpec::LedDrift { rate })
            }
            EffectKind::AmbientLight => {
                (&["counts"], EffectSpec::AmbientLight { counts: need("ambient-light", "counts", e.counts)? })
            }
            EffectKind::Nonlinearity => {
                (&["gamma"], EffectSpec::Nonlinearity { gamma: need("nonlinearity", "gamma", e.gamma)? })
            }
            EffectKind::DarkOffset => (
                &["counts", "fixed_pattern_rms", "seed"],
                EffectSpec::DarkOffset {
                    counts: need("dark-offset", "counts", e.counts)?,
                    fixed_pattern_rms: e.fixed_pattern_rms.unwrap_or(0.0),
                    seed: e.seed.unwrap_or(1),
                },
            ),
            EffectKind::Quantisation => {
                (&["step_counts"], EffectSpec::Quantisation { step_counts: e.step_counts.unwrap_or(1.0) })
            }
            EffectKind::ShortExposure => {
                (&["ratios"], EffectSpec::ShortExposure { ratios: need("short-exposure", "ratios", e.ratios.clone())? })
            }
            EffectKind::Noise => {
                let model = need("noise", "model", e.model)?;
                let (allowed, needed): (&[&str], &[&str]) = match model {
                    NoiseModel::Additive => (&["model", "sigma_counts", "seed"], &["sigma_counts"]),
                    NoiseModel::Proportional => (&["model", "sigma", "seed"], &["sigma"]),
                    NoiseModel::ShotRead => (
                        &["model", "electrons_per_count", "read_sigma_counts", "seed"],
                        &["electrons_per_count", "read_sigma_counts"],
                    ),
                };
                let given = e.given();
                for f in needed {
                    if !given.contains(f) {
                        return Err(FieldError::new(
                            *f,
                            format!(
                                "effect `noise`: missing field `{f}`, which noise model `{}` needs",
                                model_name(model)
                            ),
                        ));
                    }
                }
                (
                    allowed,
                    EffectSpec::Noise {
                        model,
                        sigma: e.sigma,
                        sigma_counts: e.sigma_counts,
                        electrons_per_count: e.electrons_per_count,
                        read_sigma_counts: e.read_sigma_counts,
                        seed: e.seed.unwrap_or(1),
                    },
                )
            }
        };
        if let Some(f) = e.given().into_iter().find(|f| !allowed.contains(f)) {
            let takes =
                if allowed.is_empty() { "no parameters".to_string() } else { format!("only {}", allowed.join(", ")) };
            return Err(FieldError::new(
                f,
                format!("field `{f}` does not apply to effect `{}`, which takes {takes}", spec.name()),
            ));
        }
        Ok(spec)
    }
}

impl From<EffectSpec> for EffectEntry {
    fn from(s: EffectSpec) -> Self {
        let mut e = EffectEntry::default();
        e.kind = Some(match s {
            EffectSpec::NearField {} => EffectKind::NearField,
            EffectSpec::ThreeDGeometry {} => EffectKind::ThreeDGeometry,
            EffectSpec::PerPixelGeometry {} => EffectKind::PerPixelGeometry,
            EffectSpec::InverseSquare {} => EffectKind::InverseSquare,
            EffectSpec::EmissionProfile {} => EffectKind::EmissionProfile,
            EffectSpec::Saturation {} => EffectKind::Saturation,
            EffectSpec::LedDrift { rate } => {
                match rate {
                    DriftRate::Common(r) => e.rate_per_frame = Some(r),
                    DriftRate::PerLed(r) => e.rates_per_frame = Some(r),
                }
                EffectKind::LedDrift
            }
            EffectSpec::AmbientLight { counts } => {
                e.counts = Some(counts);
                EffectKind::AmbientLight
            }
            EffectSpec::Nonlinearity { gamma } => {
                e.gamma = Some(gamma);
                EffectKind::Nonlinearity
            }
            EffectSpec::DarkOffset { counts, fixed_pattern_rms, seed } => {
                e.counts = Some(counts);
                e.fixed_pattern_rms = Some(fixed_pattern_rms);
                e.seed = Some(seed);
                EffectKind::DarkOffset
            }
            EffectSpec::Quantisation { step_counts } => {
                e.step_counts = Some(step_counts);
                EffectKind::Quantisation
            }
            EffectSpec::ShortExposure { ratios } => {
                e.ratios = Some(ratios);
                EffectKind::ShortExposure
            }
            EffectSpec::Noise { model, sigma, sigma_counts, electrons_per_count, read_sigma_counts, seed } => {
                e.model = Some(model);
                e.sigma = sigma;
                e.sigma_counts = sigma_counts;
                e.electrons_per_count = electrons_per_count;
                e.read_sigma_counts = read_sigma_counts;
                e.seed = Some(seed);
                EffectKind::Noise
            }
        });
        e
    }
}

impl EffectSpec {
    /// The effect's name, as written in `kind`.
    pub fn name(&self) -> &'static str {
        match self {
            EffectSpec::NearField {} => STAGE_ORDER[0],
            EffectSpec::ThreeDGeometry {} => STAGE_ORDER[1],
            EffectSpec::PerPixelGeometry {} => STAGE_ORDER[2],
            EffectSpec::InverseSquare {} => STAGE_ORDER[3],
            EffectSpec::EmissionProfile {} => STAGE_ORDER[4],
            EffectSpec::LedDrift { .. } => STAGE_ORDER[5],
            EffectSpec::AmbientLight { .. } => STAGE_ORDER[6],
            EffectSpec::Nonlinearity { .. } => STAGE_ORDER[7],
            EffectSpec::DarkOffset { .. } => STAGE_ORDER[8],
            EffectSpec::Noise { .. } => STAGE_ORDER[9],
            EffectSpec::Saturation {} => STAGE_ORDER[10],
            EffectSpec::Quantisation { .. } => STAGE_ORDER[11],
            EffectSpec::ShortExposure { .. } => STAGE_ORDER[12],
        }
    }

    /// Position in [`STAGE_ORDER`].
    pub fn order(&self) -> usize {
        STAGE_ORDER.iter().position(|n| *n == self.name()).expect("every effect is in STAGE_ORDER")
    }

    /// Checks the parameters; paths are relative to the effect's table.
    pub fn validate(&self) -> Result<(), FieldError> {
        match self {
            EffectSpec::LedDrift { rate: DriftRate::Common(r) } => {
                check_range("rate_per_frame", *r, -0.01, 0.01, "per frame")
            }
            EffectSpec::LedDrift { rate: DriftRate::PerLed(rates) } => {
                if rates.is_empty() {
                    return Err(FieldError::new("rates_per_frame", "must list one rate per LED; it is empty"));
                }
                for (k, r) in rates.iter().enumerate() {
                    check_range(&format!("rates_per_frame[{k}]"), *r, -0.01, 0.01, "per frame")?;
                }
                Ok(())
            }
            EffectSpec::AmbientLight { counts } => check_range("counts", *counts, 0.0, 1e9, "counts"),
            EffectSpec::Nonlinearity { gamma } => check_range("gamma", *gamma, 0.2, 5.0, ""),
            EffectSpec::DarkOffset { counts, fixed_pattern_rms, .. } => {
                check_range("counts", *counts, 0.0, 1e9, "counts")?;
                check_range("fixed_pattern_rms", *fixed_pattern_rms, 0.0, 1e9, "counts")
            }
            EffectSpec::Noise { model, sigma, sigma_counts, electrons_per_count, read_sigma_counts, .. } => {
                let need = |name: &str, v: &Option<f64>| {
                    v.ok_or_else(|| {
                        FieldError::new(
                            name,
                            format!("missing field `{name}`, which noise model `{}` needs", model_name(*model)),
                        )
                    })
                };
                // (Files are checked on reading; this guards specs built in code.)
                let forbid = |name: &str, v: &Option<f64>| match v {
                    Some(_) => Err(FieldError::new(
                        name,
                        format!("`{name}` does not apply to noise model `{}`", model_name(*model)),
                    )),
                    None => Ok(()),
                };
                match model {
                    NoiseModel::Additive => {
                        forbid("sigma", sigma)?;
                        forbid("electrons_per_count", electrons_per_count)?;
                        forbid("read_sigma_counts", read_sigma_counts)?;
                        check_range("sigma_counts", need("sigma_counts", sigma_counts)?, 0.0, 1e9, "counts")
                    }
                    NoiseModel::Proportional => {
                        forbid("sigma_counts", sigma_counts)?;
                        forbid("electrons_per_count", electrons_per_count)?;
                        forbid("read_sigma_counts", read_sigma_counts)?;
                        check_range("sigma", need("sigma", sigma)?, 0.0, 1.0, "(relative)")
                    }
                    NoiseModel::ShotRead => {
                        forbid("sigma", sigma)?;
                        forbid("sigma_counts", sigma_counts)?;
                        check_positive(
                            "electrons_per_count",
                            need("electrons_per_count", electrons_per_count)?,
                            "e-/count",
                        )?;
                        check_range(
                            "read_sigma_counts",
                            need("read_sigma_counts", read_sigma_counts)?,
                            0.0,
                            1e9,
                            "counts",
                        )
                    }
                }
            }
            EffectSpec::Quantisation { step_counts } => {
                check_range("step_counts", *step_counts, 1e-9, 65535.0, "counts")
            }
            EffectSpec::ShortExposure { ratios } => {
                if ratios.is_empty() || ratios.len() > MAX_SHORT_EXPOSURES {
                    return Err(FieldError::new(
                        "ratios",
                        format!("give 1..={MAX_SHORT_EXPOSURES} ratios of the long exposure over a shorter one"),
                    ));
                }
                let mut last = 1.0;
                for (i, r) in ratios.iter().enumerate() {
                    check_range(
                        &format!("ratios[{i}]"),
                        *r,
                        1.0 + 1e-9,
                        1e6,
                        "(the long exposure over a shorter one, > 1)",
                    )?;
                    if *r <= last {
                        return Err(FieldError::new(
                            format!("ratios[{i}]"),
                            "ratios must ascend: each exposure shorter than the one before",
                        ));
                    }
                    last = *r;
                }
                Ok(())
            }
            EffectSpec::NearField {}
            | EffectSpec::ThreeDGeometry {}
            | EffectSpec::PerPixelGeometry {}
            | EffectSpec::InverseSquare {}
            | EffectSpec::EmissionProfile {}
            | EffectSpec::Saturation {} => Ok(()),
        }
    }
}

fn model_name(m: NoiseModel) -> &'static str {
    match m {
        NoiseModel::Additive => "additive",
        NoiseModel::Proportional => "proportional",
        NoiseModel::ShotRead => "shot-read",
    }
}
