//! `host-tools train`: train the estimator matrices and write the calibration blob.
use crate::calibration::estimators::kind_name;
use crate::calibration::train::{TrainSpec, train};
use crate::forward::optics::Instrument;
use crate::forward::pairs::Criterion;
use crate::forward::prior_measured::PriorMix;
use crate::forward::zone_optics::uniform_zones;
use anyhow::{Context, ensure};
use brdf_meter::blob::{BlobView, EstimatorKind};
use std::path::PathBuf;

/// Estimators on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Estimator {
    /// Wiener estimation with the noise term (eq. 22).
    Wiener,
    /// Wiener estimation without noise (eq. 20).
    WienerNoiseFree,
    /// Moore-Penrose pseudo-inverse of H (claim 4).
    PseudoInverse,
    /// Inverse of a square H (claim 3).
    Inverse,
    /// Linear interpolation between the LEDs' centre angles (the patent's paragraph 0004).
    Interpolation,
    /// Scale-free affine Wiener: shape from readings / their sum, times the sum
    /// (format 2 blob, with the out-of-prior flag data).
    ScaleFree,
    /// Scale-free, one map per cluster of normalised readings (K by cross-validation).
    ScaleFreePiecewise,
}

impl From<Estimator> for EstimatorKind {
    fn from(e: Estimator) -> Self {
        match e {
            Estimator::Wiener => Self::Wiener,
            Estimator::WienerNoiseFree => Self::WienerNoiseFree,
            Estimator::PseudoInverse => Self::PseudoInverse,
            Estimator::Inverse => Self::Inverse,
            Estimator::Interpolation => Self::Interpolation,
            Estimator::ScaleFree => Self::ScaleFree,
            Estimator::ScaleFreePiecewise => Self::ScaleFreePiecewise,
        }
    }
}

/// Train the estimator matrices (one per zone) and write the calibration blob.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Where to write the blob.
    #[arg(long, value_name = "PATH", default_value = "out/calibration.blob")]
    pub out: PathBuf,
    /// Also write bins_deg, H, W and the per-bin uncertainty (f64) as JSON here.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// What to train: the calibration's kind, prior, optics and noise.
    #[command(flatten)]
    pub cal: CalibrationArgs,
    /// Sign the calibration with this secret key (`host-tools keygen`): the
    /// blob is written with its signature trailer, ready to provision. Without
    /// it the blob is unsigned and devices refuse it until `host-tools sign`.
    #[arg(long, value_name = "KEY")]
    pub sign: Option<PathBuf>,
}

/// What a calibration is trained from: every argument of `train` but its
/// outputs. Shared with the commands that evaluate "the calibration `train`
/// would write with these flags" (`accuracy`), so both read the same flags
/// with the same defaults and build the same [`TrainSpec`] ([`Self::setup`]).
#[derive(Clone, Debug, clap::Args)]
pub struct CalibrationArgs {
    /// Zones of pixels, each with its own matrix.
    #[arg(long, default_value_t = 1)]
    pub zones: usize,
    /// Pixels of the line sensor.
    #[arg(long, default_value_t = 128)]
    pub pixels: usize,
    /// Relative measurement noise (standard deviation / value; 0.02 = 2 %).
    /// Default: with --scene, the level the scene's `noise` effect implies
    /// (0 when it lists none); otherwise 0.02, the patent's.
    #[arg(long)]
    pub noise: Option<f64>,
    /// Estimator. The default, scale-free piecewise on the measured prior in
    /// the root form, is the one that reads real materials best (never a
    /// negative value; `host-tools accuracy` measures it).
    #[arg(long, value_enum, default_value_t = Estimator::ScaleFreePiecewise)]
    pub estimator: Estimator,
    /// Prior: `patent` (Table 5, built in), `merl` (the vendored measured
    /// set), a prior TOML file, a measured file (.csv `angle_deg,value`,
    /// .binary MERL, .json NBRDF, .astm ASTM E1392 table), a directory or
    /// comma list of them, or a mixture with explicit weights:
    /// `merl@0.8+patent@0.2`.
    #[arg(long, value_name = "patent|merl|PATH|MIX", default_value = "merl")]
    pub prior: String,
    /// Rougher finishes each prior material also trains at: standard
    /// deviations (deg) of a further spread of its facets' tilts, comma
    /// separated, or `none`. A measured set holds each material at one
    /// finish, mostly polished to a cusp; its finishes fill the round-topped
    /// lobes between. Default: 0.5,1,2 (from the patent profile's source
    /// spacing to its LED spacing, in tilt) on the built-in instrument or
    /// --instrument; none with --scene (each finish is an integral over
    /// the material, 12 to 32 evaluations of it per ray, on every pixel).
    #[arg(long, value_name = "DEG,...|none")]
    pub finishes: Option<String>,
    /// How many times wider across the plane of incidence than as measured
    /// each prior material also trains, comma separated, or `none`. Only
    /// optics whose LEDs reach across the plane read the difference (a
    /// scene with extended LEDs and 3-D geometry, such as the handheld's
    /// facets): there a measured set's isotropic lobes, 0.7 as wide across
    /// the plane as along it, would read satins and effect paints, as wide
    /// or wider across, two to three times too high at the peak. Default:
    /// 1.5,3 (lobes about as wide across as along, and twice as wide)
    #[arg(long, value_name = "S,...|none")]
    pub across: Option<String>,
    /// The error training minimises: relative to each sample's peak (what
    /// a user judges an estimate by), the patent's plain mean squared error,
    /// or relative to the readings' scale.
    #[arg(long, value_enum, default_value_t = CriterionArg::PeakRelative)]
    pub criterion: CriterionArg,
    /// The piecewise kind's cluster count (2..=8), fixed for every zone;
    /// default: 2 to 6, the most accurate in cross-validation of those that
    /// read kinds of material held out of training no worse than 2 do. K
    /// matrices per zone: fewer fit more zones in a calibration slot.
    #[arg(long)]
    pub clusters: Option<usize>,
    /// The form: `root` (the scale-free kinds' default: every estimate
    /// non-negative, every reading within its definition) or `linear` (the
    /// patent's, the other kinds' only form).
    #[arg(long, value_enum)]
    pub form: Option<crate::calibration::train::Form>,
    /// The patent's calibration: Wiener estimation (eq. 22) on its Table 5
    /// Ward prior with the plain mean squared error, in the linear form
    /// (what `reproduce` evaluates).
    #[arg(long, conflicts_with_all = ["estimator", "prior", "criterion", "form", "clusters"])]
    pub patent: bool,
    /// Out-of-prior flag (scale-free kinds): false-alarm rate on held-out prior samples, held on the
    /// materials as they are and on their variants (rougher finishes, stretches) each.
    #[arg(long, default_value_t = crate::calibration::estimators::scale_free::DEFAULT_FALSE_ALARM)]
    pub false_alarm: f64,
    /// Instrument description (TOML); default: the built-in patent profile.
    #[arg(long, value_name = "PATH")]
    pub instrument: Option<PathBuf>,
    /// Model the optics far-field (every LED a single ray at its centre angle).
    #[arg(long)]
    pub far_field: bool,
    /// Scene file (TOML): the instrument, its optics (exactly the geometric
    /// effects the scene lists) and its sensor. Each zone is trained on
    /// sample pairs at up to 5 of its pixels, each pixel's own rays, view
    /// and noise; the blob gets the scene's white reference; the scene's P
    /// replaces --pixels. Never uses the scene's surface or noise draw.
    #[arg(long, value_name = "PATH", conflicts_with_all = ["instrument", "far_field"])]
    pub scene: Option<PathBuf>,
    /// With --scene: the scene's line cut to a device of this many pixels
    /// about its centre (the QEMU instrument has 32), as `qemu --demo` does.
    #[arg(long, value_name = "P", requires = "scene")]
    pub device_pixels: Option<usize>,
}

/// Everything a [`TrainSpec`] borrows, owned: what [`CalibrationArgs`]
/// resolve to (the instrument, its grid, the prior's models and the zones'
/// optics).
pub struct Setup {
    /// The instrument (the scene's with --scene).
    pub inst: Instrument,
    /// Its angle grid.
    pub grid: crate::forward::grid::AngleGrid,
    /// The estimator kind.
    pub kind: EstimatorKind,
    /// The parsed prior argument.
    pub mix: PriorMix,
    /// The prior's samples.
    pub prior: crate::forward::prior_models::PriorModels,
    /// The zones' optics, P, white reference, field model and noise level.
    pub optics: TrainingZones,
    /// The training criterion.
    pub criterion: Criterion,
    /// The flag's false-alarm rate.
    pub false_alarm: f64,
    /// The piecewise kind's fixed cluster count.
    pub clusters: Option<usize>,
    /// Whether the calibration is trained in the root form.
    pub root: bool,
}

impl Setup {
    /// The training specification `train` trains with.
    pub fn spec(&self) -> TrainSpec<'_> {
        let TrainingZones { zones, pixels, white, linearity, far_field, noise } = self.optics.clone();
        TrainSpec {
            bins_deg: self.grid.bins_deg(),
            zones,
            pixels,
            view_deg: self.inst.view_deg,
            prior: &self.prior,
            noise_rel: noise,
            estimator: self.kind,
            criterion: self.criterion,
            false_alarm: self.false_alarm,
            clusters: self.clusters,
            root: self.root,
            far_field,
            led_order: None,
            white,
            linearity: linearity.map(|l| l.correction),
            max_blob_len: crate::calibration::train::board_blob_capacity(),
        }
    }
}

impl CalibrationArgs {
    /// Checks the arguments and resolves them: the scene or instrument, the
    /// prior's models and the zones' optics.
    pub fn setup(&self) -> anyhow::Result<Setup> {
        if self.patent {
            let patent = Self {
                estimator: Estimator::Wiener,
                prior: "patent".into(),
                criterion: CriterionArg::Plain,
                form: Some(crate::calibration::train::Form::Linear),
                patent: false,
                ..self.clone()
            };
            return patent.setup();
        }
        let scene = match (&self.scene, self.device_pixels) {
            (Some(p), None) => Some(crate::forward::scene::Scene::load(p)?),
            (Some(p), Some(n)) => Some(
                crate::forward::scene::Scene::load(p)?
                    .for_device(n)
                    .with_context(|| format!("--device-pixels {n} with --scene {}", p.display()))?,
            ),
            (None, _) => None,
        };
        if let Some(x) = self.noise
            && (!x.is_finite() || !(0.0..1.0).contains(&x))
        {
            anyhow::bail!("--noise {x}: must be a relative level in [0, 1) (0.02 is 2 %)");
        }
        ensure!(
            self.false_alarm > 0.0 && self.false_alarm < 1.0,
            "--false-alarm {}: must be in (0, 1)",
            self.false_alarm
        );
        let inst: Instrument = match (&scene, &self.instrument) {
            (Some(s), _) => s.instrument.clone(),
            (None, Some(p)) => crate::output::config::load_toml(p)?,
            (None, None) => Instrument::patent_profile(),
        };
        let grid = inst.grid().context("the instrument's angle grid")?;
        let kind: EstimatorKind = self.estimator.into();
        let mix = PriorMix::parse(&self.prior)?;
        let finishes = finishes_deg(self.finishes.as_deref(), scene.is_some())?;
        let prior = mix
            .models(&grid, inst.view_deg, inst.spectral_weights)
            .context("building the prior")?
            .with_finishes(&finishes)
            .with_across(&across(self.across.as_deref())?);
        let optics = zone_optics(self, scene.as_ref(), &inst, &grid)?;
        let form = self.form.unwrap_or(crate::calibration::train::Form::default_for(kind));
        Ok(Setup {
            inst,
            grid,
            kind,
            mix,
            prior,
            optics,
            criterion: self.criterion.into(),
            false_alarm: self.false_alarm,
            clusters: self.clusters,
            root: form == crate::calibration::train::Form::Root,
        })
    }
}

/// The rougher finishes the prior's materials train at, by default on an
/// instrument's own optics; `--finishes` (a comma list of tilt spreads in
/// degrees, or `none`) otherwise.
pub const DEFAULT_FINISHES_DEG: [f64; 3] = [0.5, 1.0, 2.0];

/// `--finishes` as tilt spreads (degrees): `none` is none, no argument the
/// default ([`DEFAULT_FINISHES_DEG`], none for a scene's line).
pub fn finishes_deg(arg: Option<&str>, scene: bool) -> anyhow::Result<Vec<f64>> {
    let Some(text) = arg else {
        return Ok(if scene { Vec::new() } else { DEFAULT_FINISHES_DEG.to_vec() });
    };
    number_list(
        "--finishes",
        text,
        |v| v > 0.0 && v <= 10.0,
        |v| format!("a tilt spread of {v} deg is not in (0, 10]; give spreads in degrees, or `none`"),
    )
}

/// `--across` as stretches across the plane of incidence: `none` is none,
/// no argument the default (`crate::forward::prior_models::DEFAULT_ACROSS`).
pub fn across(arg: Option<&str>) -> anyhow::Result<Vec<f64>> {
    let Some(text) = arg else {
        return Ok(crate::forward::prior_models::DEFAULT_ACROSS.to_vec());
    };
    number_list(
        "--across",
        text,
        |v| (0.1..=10.0).contains(&v) && v != 1.0,
        |v| {
            format!(
                "a stretch of {v} is not in [0.1, 10] or is 1 (the material as it is, always read); give factors such as 1.5,3, or `none`"
            )
        },
    )
}

/// A flag's comma list of finite numbers, each passing `ok` (else the
/// error says `wrong` of it), or `none` for an empty list.
fn number_list(
    flag: &str,
    text: &str,
    ok: impl Fn(f64) -> bool,
    wrong: impl Fn(f64) -> String,
) -> anyhow::Result<Vec<f64>> {
    if text.trim() == "none" {
        return Ok(Vec::new());
    }
    text.split(',')
        .map(|x| {
            let v: f64 = x.trim().parse().with_context(|| format!("{flag} {text:?}: {x:?} is not a number"))?;
            ensure!(v.is_finite() && ok(v), "{flag} {text:?}: {}", wrong(v));
            Ok(v)
        })
        .collect()
}

/// The error training minimises, on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum CriterionArg {
    /// Relative to each sample's peak: what a user judges an estimate by.
    PeakRelative,
    /// The prior's plain mean squared error (the patent's).
    Plain,
    /// Relative to each sample's readings' scale.
    ScaleRelative,
}

impl From<CriterionArg> for Criterion {
    fn from(c: CriterionArg) -> Self {
        match c {
            CriterionArg::PeakRelative => Criterion::PeakRelative,
            CriterionArg::Plain => Criterion::Plain,
            CriterionArg::ScaleRelative => Criterion::ScaleRelative,
        }
    }
}

/// Runs the command: parses the arguments into a training specification,
/// trains (`crate::calibration::train`), signs and writes. Nothing is
/// written unless training succeeds.
pub fn run(a: Args) -> anyhow::Result<()> {
    // The key is read before training, which may take minutes: a missing or
    // malformed key file is said at once.
    let seed = a.sign.as_deref().map(crate::calibration::signing::read_secret).transpose()?;
    let setup = a.cal.setup()?;
    let kind = setup.kind;
    let noise = setup.optics.noise;
    let (mix, prior) = (&setup.mix, &setup.prior);
    let trained = train(&setup.spec())?;
    // Everything is computed; serialise (and sign) before writing anything.
    let json = a.json.as_ref().map(|_| trained.to_json());
    let out = match &seed {
        Some(seed) => crate::calibration::signing::sign_blob(&trained.blob, seed),
        None => trained.blob.clone(),
    };
    crate::output::io::write_atomic(&a.out, &out).with_context(|| format!("writing {}", a.out.display()))?;
    if let (Some(p), Some(j)) = (&a.json, &json) {
        crate::output::io::write_json(p, j).with_context(|| format!("writing {}", p.display()))?;
    }
    let view = BlobView::parse(&trained.blob).expect("validated");
    let families: Vec<String> = mix.families.iter().map(|(l, _, w)| format!("{l} (weight {w})")).collect();
    println!(
        "trained {} for {} zone(s) x {} pixels: n = {}, m = {}, K = {}, prior {} samples from {}, noise {noise}",
        kind_name(kind),
        trained.dims.zones,
        trained.dims.pixels,
        trained.dims.n,
        trained.dims.m,
        trained.clusters,
        prior.len(),
        families.join(" + "),
    );
    if let Some(l) = &setup.optics.linearity {
        println!("{}", linearity_note(l));
    }
    match trained.worst_zone() {
        Some((worst, s)) => {
            println!(
                "worst-conditioned zone {worst}: cond(H) {:.3e}, cond(system) {:.3e}, effective rank {:.2}, regularisation {:.1e}, predicted RMSE {:.4}; f32 vs f64 over all zones {:.1e}",
                s.condition_h,
                s.condition_system,
                s.effective_rank,
                s.regularisation,
                s.predicted_rmse,
                trained.f32_rel_error
            );
            println!("{}", s.method);
        }
        None => {
            let z0 = trained.zones[0].scale_free().expect("a scale-free calibration");
            println!(
                "zone 0: ridge {:.0e} (cross-validated peak-normalised error {:.4}); out-of-prior flag: the {} statistic, each zone's threshold at {:.0} % false alarms on held-out samples (materials and their variants each), a flagged point's band {:.2}x wider; f32 vs f64 {:.1e}",
                z0.ridge,
                z0.cv_error,
                z0.out_of_prior.form.name(),
                100.0 * a.cal.false_alarm,
                view.out_of_prior_band_factor(),
                trained.f32_rel_error
            );
        }
    }
    if let Some(f) = &trained.flag_on_kinds {
        println!("{}", f.note());
    }
    if view.has_gloss_centroids() {
        println!(
            "gloss rows: {} clusters of their own (they read the gloss of samples held out of them better than the maps' {})",
            view.gloss_clusters(),
            view.clusters()
        );
    }
    for (k, len) in &trained.slot_refused {
        println!(
            "{k} clusters would make a blob of {len} bytes, more than the board's calibration slot takes ({} bytes): the count was chosen among fewer",
            crate::calibration::train::board_blob_capacity()
        );
    }
    if let Some(r) = view.peak_resolution_deg() {
        let f = crate::output::peak::RESOLVED_WIDTH_FACTOR;
        let finest = (0..view.dims().pixels).filter_map(|p| view.peak_resolution_at(p)).fold(r, f32::min);
        let (range, limit) = if finest < r {
            (
                format!("{r:.2} deg ({finest:.2}-{r:.2} over the pixels, each recorded)"),
                format!("{:.2}-{:.2} deg at its pixel", f * f64::from(finest), f * f64::from(r)),
            )
        } else {
            (format!("{r:.2} deg"), format!("{:.2} deg", f * f64::from(r)))
        };
        println!(
            "peak resolution {range}: the width it puts out for a mirror (the black glass); a specular peak narrower than {limit} is reported as not resolved, with no uncertainty"
        );
        if let Some(pf) = view.peak_factors() {
            println!(
                "a resolved peak's uncertainties: {:.2} x the first-order height's, {:.2} x the width's (what covers 95 % of the resolved peaks of samples held out of training at k = 2)",
                pf.height, pf.width
            );
        }
    }
    if !view.has_gloss() {
        println!("{}", crate::calibration::gloss_rows::NO_GLOSS_NOTE);
    } else if let Some(note) = crate::calibration::gloss_rows::zones_without_reading_note(&view) {
        println!("{note}");
    }
    let signed = match (&a.sign, &seed) {
        (Some(key), Some(seed)) => {
            format!("signed with {}{}", key.display(), crate::calibration::signing::untrusted_note(seed))
        }
        _ => "unsigned: sign it with `host-tools sign` before provisioning".into(),
    };
    println!(
        "wrote {} ({} bytes, format {}, CRC {:#010x}, {signed})",
        a.out.display(),
        out.len(),
        view.version(),
        view.crc()
    );
    if let Some(note) = over_slot_note(out.len(), crate::calibration::train::board_blob_capacity()) {
        println!("{note}");
    }
    if let Some(p) = &a.json {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// What to tell the user when the blob (`len` bytes, signature excluded)
/// is more than the board's calibration slot takes (`capacity`): training
/// lowers a cluster count it chose to fit the slot, but a zone count or a
/// fixed cluster count is the user's, and the board refuses such a blob
/// only when it is provisioned. The blob is still written: it serves
/// `estimate` and the evaluations.
fn over_slot_note(len: usize, capacity: usize) -> Option<String> {
    (len > capacity).then(|| {
        format!(
            "note: this blob is {} bytes more than the board's calibration slot takes ({capacity} bytes): the board will refuse it; for the board, train fewer zones (--zones) or clusters (--clusters)",
            len - capacity
        )
    })
}

/// What `train` says of the sensor's measured linearity.
fn linearity_note(l: &crate::forward::scene::sensor_linearity::SensorLinearity) -> String {
    let pct = |c: f64| 100.0 * l.bend(c, 2000.0);
    format!(
        "sensor linearity: measured by an exposure sweep ({} exposures x {} lines): the sensor reads 30, 100 and 1000 counts {:.1}, {:.1} and {:.1} % low against 2000 counts; the blob's correction gives the sweep back within {:.2} % (rms){}",
        l.exposures,
        crate::forward::scene::sensor_linearity::LINES,
        pct(30.0),
        pct(100.0),
        pct(1000.0),
        100.0 * l.residual_rms,
        if l.clamped {
            "; the sensor bends more than a correction may undo: its dimmest readings stay partly bent"
        } else {
            ""
        }
    )
}

/// The zones' optics `train` trains on: from the scene (`--scene`: its
/// optics, white reference, sensor linearity, field model and noise,
/// `--noise` overriding it) or the instrument's uniform zones (relative
/// noise `--noise`, 0.02 by default).
#[derive(Clone, Debug)]
pub struct TrainingZones {
    /// The zones' optics.
    pub zones: Vec<crate::forward::zone_optics::ZoneOptics>,
    /// Pixels P.
    pub pixels: usize,
    /// The white reference (`None`: a sensor already white-normalised).
    pub white: Option<Vec<f32>>,
    /// The factory's measurement of the sensor's linearity, when the
    /// scene's sensor needs a correction (the blob carries it).
    pub linearity: Option<crate::forward::scene::sensor_linearity::SensorLinearity>,
    /// Whether the optics are modelled far-field.
    pub far_field: bool,
    /// The noise level the blob records.
    pub noise: f64,
}

/// See [`TrainingZones`].
pub fn zone_optics(
    a: &CalibrationArgs,
    scene: Option<&crate::forward::scene::Scene>,
    inst: &Instrument,
    grid: &crate::forward::grid::AngleGrid,
) -> anyhow::Result<TrainingZones> {
    Ok(match scene {
        Some(s) => {
            let t = crate::forward::scene::training_optics(s, a.zones, a.noise).context("--zones with --scene")?;
            TrainingZones {
                zones: t.zones,
                pixels: t.pixels,
                white: Some(t.white),
                linearity: t.linearity,
                far_field: !s.has("near-field"),
                noise: t.noise_level,
            }
        }
        None => {
            let noise = a.noise.unwrap_or(0.02);
            TrainingZones {
                zones: uniform_zones(inst, grid, a.zones, a.pixels, a.far_field, noise).context("--zones/--pixels")?,
                pixels: a.pixels,
                white: None,
                linearity: None,
                far_field: a.far_field,
                noise,
            }
        }
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn a_blob_over_the_boards_slot_is_said_to_be_and_by_how_much() {
        let cap = crate::calibration::train::board_blob_capacity();
        assert_eq!(over_slot_note(cap, cap), None);
        let note = over_slot_note(cap + 18_000, cap).unwrap();
        assert!(note.contains("18000 bytes more") && note.contains(&format!("({cap} bytes)")), "{note}");
        assert!(note.contains("--zones"), "{note}");
    }

    #[test]
    fn finishes_default_on_an_instruments_own_optics_and_parse_or_say_what_is_wrong() {
        assert_eq!(finishes_deg(None, false).unwrap(), DEFAULT_FINISHES_DEG.to_vec());
        assert!(finishes_deg(None, true).unwrap().is_empty());
        assert!(finishes_deg(Some("none"), false).unwrap().is_empty());
        assert_eq!(finishes_deg(Some("0.5, 3"), true).unwrap(), vec![0.5, 3.0]);
        for bad in ["0", "-1", "x", "1,,2", "20"] {
            let e = finishes_deg(Some(bad), false).unwrap_err().to_string();
            assert!(e.contains("--finishes"), "{bad}: {e}");
        }
    }

    #[test]
    fn across_defaults_to_one_and_a_half_and_three_and_parses_or_says_what_is_wrong() {
        assert_eq!(across(None).unwrap(), vec![1.5, 3.0]);
        assert!(across(Some("none")).unwrap().is_empty());
        assert_eq!(across(Some("2, 0.5")).unwrap(), vec![2.0, 0.5]);
        for bad in ["0", "1", "-2", "x", "1.5,,3", "20"] {
            let e = across(Some(bad)).unwrap_err().to_string();
            assert!(e.contains("--across"), "{bad}: {e}");
        }
    }

    fn args(dir: &Path) -> Args {
        Args {
            out: dir.join("out/cal.blob"),
            json: Some(dir.join("out/cal.json")),
            cal: CalibrationArgs {
                zones: 2,
                pixels: 16,
                noise: Some(0.02),
                estimator: Estimator::Wiener,
                prior: "patent".into(),
                finishes: None,
                across: None,
                instrument: None,
                far_field: false,
                scene: None,
                criterion: CriterionArg::PeakRelative,
                clusters: None,
                false_alarm: 0.05,
                form: None,
                patent: false,
                device_pixels: None,
            },
            sign: None,
        }
    }

    /// One-zone, 8-pixel arguments for `estimator` on `prior`, writing into `dir`.
    pub(crate) fn args_with(dir: &Path, estimator: Estimator, prior: &str) -> Args {
        let a = args(dir);
        Args {
            out: dir.join("cal.blob"),
            json: Some(dir.join("cal.json")),
            cal: CalibrationArgs { zones: 1, pixels: 8, estimator, prior: prior.into(), ..a.cal },
            ..a
        }
    }

    #[test]
    fn train_sign_writes_a_signed_calibration_the_device_accepts() {
        let dir = tempfile::tempdir().unwrap();
        let mut a = args(dir.path());
        a.sign = Some(crate::calibration::signing::dev_key_path());
        run(a).unwrap();
        let image = std::fs::read(dir.path().join("out/cal.blob")).unwrap();
        let v = crate::device::provision::parse_signed(&image, "cal.blob").unwrap();
        assert_eq!(v.as_bytes().len() + brdf_meter::signed::TRAILER_LEN, image.len());
        // A missing key is a named error and writes nothing.
        let dir = tempfile::tempdir().unwrap();
        let mut a = args(dir.path());
        a.sign = Some(dir.path().join("absent.key"));
        let e = format!("{:#}", run(a).unwrap_err());
        assert!(e.contains("absent.key"), "{e}");
        assert!(!dir.path().join("out").exists());
    }

    #[test]
    fn writes_a_parsable_blob_and_the_inspection_json() {
        let dir = tempfile::tempdir().unwrap();
        run(args(dir.path())).unwrap();
        let blob = std::fs::read(dir.path().join("out/cal.blob")).unwrap();
        let v = BlobView::parse(&blob).unwrap();
        assert_eq!((v.dims().zones, v.dims().pixels), (2, 16));
        let j: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("out/cal.json")).unwrap()).unwrap();
        assert_eq!(j["W"].as_array().unwrap().len(), 81);
        assert_eq!(j["zones"].as_array().unwrap().len(), 2);
    }

    #[test]
    fn failures_name_the_problem_and_write_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("prior.toml");
        std::fs::write(&bad, "[[ward_grid]]\nrho_d = [0.5]\nalpha = [\"x\"]\n").unwrap();
        let csv = dir.path().join("m.csv");
        std::fs::write(&csv, "20,1.0\n30,oops\n").unwrap();
        type Edit<'a> = Box<dyn Fn(&mut Args) + 'a>;
        let cases: Vec<(Edit, &str)> = vec![
            (Box::new(|a: &mut Args| a.cal.prior = bad.display().to_string()), "prior.toml:3"),
            (Box::new(|a: &mut Args| a.cal.prior = csv.display().to_string()), "m.csv:2"),
            (Box::new(|a: &mut Args| a.cal.noise = Some(-0.1)), "--noise"),
            (Box::new(|a: &mut Args| a.cal.zones = 17), "zones = 17"),
            (Box::new(|a: &mut Args| a.cal.estimator = Estimator::Inverse), "square"),
        ];
        for (edit, want) in cases {
            let mut a = args(dir.path());
            edit(&mut a);
            let e = format!("{:#}", run(a).unwrap_err());
            assert!(e.contains(want), "{e:?} should mention {want:?}");
            assert!(!dir.path().join("out").exists(), "output written despite: {e}");
        }
    }

    #[test]
    fn device_pixels_cut_the_scene_to_the_device_as_the_qemu_demo_does() {
        use clap::Parser;
        let dir = tempfile::tempdir().unwrap();
        let blob = dir.path().join("cal.blob");
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/handheld.toml");
        let args = ["host-tools", "train", "--scene", path.to_str().unwrap(), "--device-pixels", "32", "--out"];
        let cli = crate::cli::Cli::try_parse_from(args.iter().copied().chain([blob.to_str().unwrap()])).unwrap();
        crate::cli::run(cli).unwrap();
        let bytes = std::fs::read(&blob).unwrap();
        let v = brdf_meter::blob::BlobView::parse(&bytes).unwrap();
        assert_eq!(v.dims().pixels, 32);
        // The white reference is the cut scene's, pixel for pixel.
        let cut = crate::forward::scene::Scene::load(&path).unwrap().for_device(32).unwrap();
        let white = crate::forward::scene::white_reference(&cut).unwrap();
        assert_eq!(v.white(31, 6), white[31 * 7 + 6]);
        // Without a scene there is nothing to cut.
        let e = crate::cli::Cli::try_parse_from(["host-tools", "train", "--device-pixels", "32"]).unwrap_err();
        assert!(e.to_string().contains("--scene"), "{e}");
    }

    #[test]
    fn train_scene_puts_the_scene_optics_and_white_reference_in_the_blob() {
        use clap::Parser;
        let dir = tempfile::tempdir().unwrap();
        let blob = dir.path().join("cal.blob");
        let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/handheld.toml");
        let cli = crate::cli::Cli::try_parse_from([
            "host-tools",
            "train",
            "--scene",
            scene.to_str().unwrap(),
            "--zones",
            "4",
            "--out",
            blob.to_str().unwrap(),
        ])
        .unwrap();
        crate::cli::run(cli).unwrap();
        let bytes = std::fs::read(&blob).unwrap();
        let v = brdf_meter::blob::BlobView::parse(&bytes).unwrap();
        assert_eq!((v.dims().pixels, v.dims().zones, v.dims().m, v.dims().n), (128, 4, 7, 81));
        assert_eq!((0..4).map(|z| v.zone_start(z)).collect::<Vec<_>>(), [0, 32, 64, 96]);
        assert!(!v.far_field());
        let white =
            crate::forward::scene::white_reference(&crate::forward::scene::Scene::load(&scene).unwrap()).unwrap();
        for p in [0, 77, 127] {
            for i in 0..7 {
                assert_eq!(v.white(p, i), white[p * 7 + i]);
            }
        }
        // --scene replaces --instrument and --far-field.
        let clash = crate::cli::Cli::try_parse_from(["host-tools", "train", "--scene", "a.toml", "--far-field"]);
        assert!(clash.is_err());
    }

    #[test]
    fn measured_and_mixed_priors_train_every_kind_into_the_right_format() {
        let dir = tempfile::tempdir().unwrap();
        for (est, prior, kind, version) in [
            // Format 4: every kind carries the gloss section (one reference per pixel).
            (Estimator::ScaleFree, "merl", EstimatorKind::ScaleFree, 4),
            (Estimator::ScaleFreePiecewise, "merl@0.9+patent@0.1", EstimatorKind::ScaleFreePiecewise, 4),
            (Estimator::Wiener, "merl", EstimatorKind::Wiener, 4),
        ] {
            run(args_with(dir.path(), est, prior)).unwrap();
            let blob = std::fs::read(dir.path().join("cal.blob")).unwrap();
            let v = BlobView::parse(&blob).unwrap();
            assert_eq!((v.estimator(), v.version()), (kind, version), "{prior}");
            assert!(v.has_gloss());
            assert_eq!(v.out_of_prior_threshold().is_some(), kind != EstimatorKind::Wiener);
            assert!(dir.path().join("cal.json").exists());
        }
    }

    #[test]
    fn bad_priors_are_refused_and_nothing_is_written() {
        let dir = tempfile::tempdir().unwrap();
        for (prior, why) in
            [("merl+patent", "needs its weight"), ("merl@0.5+patent@0.4", "sum to"), ("nope.xyz", "not `patent`")]
        {
            let e = format!("{:#}", run(args_with(dir.path(), Estimator::ScaleFree, prior)).unwrap_err());
            assert!(e.contains(why), "{prior}: {e}");
        }
        // Fewer samples than the cross-validation needs.
        std::fs::write(dir.path().join("a.csv"), "20,1.0\n70,2.0\n").unwrap();
        let e = format!(
            "{:#}",
            run(args_with(dir.path(), Estimator::ScaleFree, &dir.path().join("a.csv").display().to_string()))
                .unwrap_err()
        );
        assert!(e.contains("at least"), "{e}");
        assert!(!dir.path().join("cal.blob").exists());
    }
}
