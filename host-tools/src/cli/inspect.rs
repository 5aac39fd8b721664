//! `host-tools inspect`: on-device inspection. `teach` a recipe from lines
//! of a reference sample, `provision` it, `run` an inspection (live
//! verdicts, SPC figures, CSV/JSON, the defect map), and `roc`: the
//! probability of detection against false calls on simulated runs.
//! See `host_tools::inspection` and the device's `brdf_meter::inspect`.
use crate::calibration::signing;
use crate::device::link::{Client, Endpoint};
use crate::device::provision;
use crate::forward::scene::Scene;
use crate::forward::scene::defects::DefectScene;
use crate::inspection::lines::{DeviceModel, Line};
use crate::inspection::roc::{self, RocSpec};
use crate::inspection::spc::spc;
use crate::inspection::teach::{DriftLimit, TeachSpec, Window, teach};
use crate::inspection::{defect_map, measured};
use anyhow::{Context, ensure};
use brdf_meter::blob::BlobView;
use brdf_meter::inspect::RecipeView;
use brdf_meter::inspect::recipe::DelayUnit;
use std::path::{Path, PathBuf};

/// On-device inspection: teach, provision, run, ROC.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// What to do.
    #[command(subcommand)]
    pub command: Sub,
}

/// The inspection subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum Sub {
    /// Teach a recipe from lines of a reference sample, measured by the
    /// device (`--port`, `--tcp`) or simulated from a scene as the device
    /// reads it (`--scene`), and write it signed.
    Teach(TeachArgs),
    /// Provision a signed recipe onto a device.
    Provision(ProvisionArgs),
    /// Inspect lines on a device: live verdicts, SPC figures, CSV/JSON, defect map.
    Run(RunArgs),
    /// Probability of detection per defect kind and size against false calls, simulated.
    Roc(RocArgs),
    /// The decision's latency and cost, counted exactly in QEMU (needs QEMU and the ARM binutils).
    Bench(BenchArgs),
}

/// `inspect bench`.
#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    /// Zones of the calibration (at most the board's RAM budget, 8).
    #[arg(long, default_value_t = 8)]
    pub zones: usize,
    /// Also write the figures as JSON.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
}

/// The recipe's settings, as `teach` and `roc` take them.
#[derive(Debug, Clone, clap::Args)]
pub struct RecipeArgs {
    /// Gloss window: change from the reference allowed, `LO:HI` GU, `LO%:HI%` or `off`.
    #[arg(long, default_value = "-1.5:1.5", allow_hyphen_values = true)]
    pub gloss_window: Window,
    /// Haze window (HU, %, or off).
    #[arg(long, default_value = "off", allow_hyphen_values = true)]
    pub haze_window: Window,
    /// Distinctness window (%, relative %, or off).
    #[arg(long, default_value = "off", allow_hyphen_values = true)]
    pub distinctness_window: Window,
    /// False calls per defect-free line the distance threshold is set for.
    #[arg(long, default_value_t = 1e-4)]
    pub false_call_rate: f64,
    /// Smallest defect, pixels.
    #[arg(long, default_value_t = 3)]
    pub min_pixels: u16,
    /// Smallest defect, lines.
    #[arg(long, default_value_t = 1)]
    pub min_lines: u16,
    /// Hysteresis: a point out stays out until below this share of the thresholds.
    #[arg(long, default_value_t = crate::inspection::teach::HYSTERESIS)]
    pub hysteresis: f32,
    /// Drift alarm: EWMA weight.
    #[arg(long, default_value_t = 0.1)]
    pub ewma_lambda: f32,
    /// Drift alarm limit in GU (default: 4 standard deviations of the EWMA of the reference's line means).
    #[arg(long)]
    pub drift_limit_gu: Option<f64>,
    /// Reject pulse length, ms (a PLC scanning every 10 ms sees >= 20 ms).
    #[arg(long, default_value_t = 25.0)]
    pub pulse_ms: f64,
    /// Reject delay: `N` lines (encoder counts) or `Nus` microseconds.
    #[arg(long, default_value = "0")]
    pub delay: String,
    /// The recipe's version number.
    #[arg(long, default_value_t = 1)]
    pub version: u32,
}

impl RecipeArgs {
    fn spec(&self, max_bytes: usize) -> anyhow::Result<TeachSpec> {
        ensure!(self.hysteresis > 0.0 && self.hysteresis <= 1.0, "--hysteresis {}: within (0, 1]", self.hysteresis);
        ensure!(self.pulse_ms >= 1.0, "--pulse-ms {}: at least 1 ms", self.pulse_ms);
        ensure!(self.min_pixels >= 1 && self.min_lines >= 1, "--min-pixels and --min-lines: at least 1");
        let delay = match self.delay.strip_suffix("us") {
            Some(us) => (us.parse().with_context(|| format!("--delay {}", self.delay))?, DelayUnit::Micros),
            None => (
                self.delay.parse().with_context(|| format!("--delay {}: N lines or Nus", self.delay))?,
                DelayUnit::Lines,
            ),
        };
        Ok(TeachSpec {
            false_call_rate: self.false_call_rate,
            windows: [self.gloss_window, self.haze_window, self.distinctness_window],
            min_pixels: self.min_pixels,
            min_lines: self.min_lines,
            hysteresis: self.hysteresis,
            ewma_lambda: self.ewma_lambda,
            drift_limit: self.drift_limit_gu.map_or(DriftLimit::Sigmas(4.0), DriftLimit::Gu),
            pulse_us: (self.pulse_ms * 1000.0) as u32,
            delay,
            version: self.version,
            max_bytes,
        })
    }
}

/// `inspect teach`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("reference").required(true).multiple(true).args(["scene", "port", "tcp"])))]
pub struct TeachArgs {
    /// The signed calibration the device runs.
    #[arg(long, value_name = "PATH")]
    pub blob: PathBuf,
    /// The reference sample as a scene (its surface, with every effect it
    /// lists), simulated as the device reads it; with `--tcp`, the scene fed
    /// to the simulated device's sensor.
    #[arg(long, value_name = "PATH")]
    pub scene: Option<PathBuf>,
    /// Teach on the instrument: its serial port (e.g. /dev/ttyACM0). It
    /// measures the reference sample under it, with the calibration `--blob`.
    #[arg(long, value_name = "PATH", conflicts_with_all = ["tcp", "scene"])]
    pub port: Option<String>,
    /// Teach on the QEMU instrument: its TCP serial (e.g. 127.0.0.1:4555);
    /// give `--scene` for the reference its simulated sensor is fed.
    #[arg(long, value_name = "HOST:PORT", requires = "scene")]
    pub tcp: Option<String>,
    /// Lines of the reference to teach from.
    #[arg(long, default_value_t = 1000)]
    pub lines: usize,
    /// First scene line (its noise draw).
    #[arg(long, default_value_t = 0)]
    pub first_line: u64,
    /// Secret key to sign the recipe with (default: the DEVELOPMENT key).
    #[arg(long, value_name = "PATH")]
    pub key: Option<PathBuf>,
    /// The recipe's settings.
    #[command(flatten)]
    pub recipe: RecipeArgs,
    /// Where to write the signed recipe (and `.json` beside it: the teach report).
    #[arg(long, value_name = "PATH", default_value = "out/recipe.bin")]
    pub out: PathBuf,
}

/// `inspect provision`.
#[derive(Debug, clap::Args)]
pub struct ProvisionArgs {
    /// The device.
    #[command(flatten)]
    pub device: Endpoint,
    /// The signed recipe.
    #[arg(long, value_name = "PATH")]
    pub recipe: PathBuf,
}

/// `inspect run`.
#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// The device.
    #[command(flatten)]
    pub device: Endpoint,
    /// The signed recipe the device runs (for its windows and the map).
    #[arg(long, value_name = "PATH")]
    pub recipe: PathBuf,
    /// Lines to inspect.
    #[arg(long, default_value_t = 100)]
    pub lines: u32,
    /// Send a rejected line's points too, and write them (the point schema)
    /// as CSV to PATH and as JSON beside it; needs `--blob` to read them.
    #[arg(long, value_name = "PATH", requires = "blob")]
    pub defect_points: Option<PathBuf>,
    /// The calibration blob the device runs (signed or not; checked against
    /// the device's by CRC), to read the rejected lines' points with.
    #[arg(long, value_name = "PATH")]
    pub blob: Option<PathBuf>,
    /// A defect scene (or scene) to load into a simulated device first (4 lines, cycled).
    #[arg(long, value_name = "PATH")]
    pub scene: Option<PathBuf>,
    /// First scene line loaded.
    #[arg(long, default_value_t = 0)]
    pub scene_line: u64,
    /// Verdicts as CSV.
    #[arg(long, value_name = "PATH")]
    pub csv: Option<PathBuf>,
    /// Verdicts, pulses and SPC figures as JSON.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// The defect map (PNG).
    #[arg(long, value_name = "PATH")]
    pub map: Option<PathBuf>,
}

/// `inspect roc`.
#[derive(Debug, clap::Args)]
pub struct RocArgs {
    /// The instrument and its effects (the defect-free surface).
    #[arg(long, value_name = "PATH", default_value = "scenes/handheld.toml")]
    pub scene: PathBuf,
    /// The signed calibration (default: trained here, scale-free piecewise on MERL, --zones).
    #[arg(long, value_name = "PATH")]
    pub blob: Option<PathBuf>,
    /// Zones of the calibration trained here.
    #[arg(long, default_value_t = 32)]
    pub zones: usize,
    /// Lines to teach from (1,000: 40 s of the handheld's line rate; 200
    /// leave the per-pixel statistics noisy enough to cost detection).
    #[arg(long, default_value_t = 1000)]
    pub teach_lines: usize,
    /// Defect-free lines.
    #[arg(long, default_value_t = 10_000)]
    pub clean_lines: usize,
    /// Lines per defect case.
    #[arg(long, default_value_t = 400)]
    pub defect_lines: usize,
    /// The small run the tests make: 1,000 teach, 2,000 defect-free, 40 per case.
    #[arg(long)]
    pub quick: bool,
    /// The recipe's settings.
    #[command(flatten)]
    pub recipe: RecipeArgs,
    /// Output directory: roc.md, roc.json, roc.svg/.png.
    #[arg(long, value_name = "DIR", default_value = "out/inspect-roc")]
    pub out: PathBuf,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    match a.command {
        Sub::Teach(a) => run_teach(a),
        Sub::Provision(a) => run_provision(a),
        Sub::Run(a) => run_inspect(a),
        Sub::Roc(a) => run_roc(a),
        Sub::Bench(a) => run_bench(a),
    }
}

/// The slot's room for a signed recipe.
fn recipe_room() -> usize {
    brdf_meter::shape::board::RECIPE_SLOT_LEN as usize
        - brdf_meter::store::SLOT_HEADER_LEN
        - brdf_meter::signed::TRAILER_LEN
}

/// The device a scene's calibration runs on: the board's acquisition for
/// its pixel count, else the QEMU build's (the same exposure ratios).
fn device_model<'a>(view: BlobView<'a>, scene: &Scene) -> anyhow::Result<DeviceModel<'a>> {
    let full_scale = scene.instrument.sensor.full_scale.round() as u16;
    DeviceModel::new(view, full_scale, acquisition_for(scene.instrument.sensor.pixels))
}

/// The acquisition of a device of `pixels` pixels: the board's, else the
/// QEMU build's (the same exposure ratios).
fn acquisition_for(pixels: usize) -> brdf_meter::acquire::AcqConfig {
    if pixels == brdf_meter::shape::board::PIXELS {
        brdf_meter::platform::timing::ACQUISITION
    } else {
        brdf_meter::platform::timing::QEMU_ACQUISITION
    }
}

fn run_teach(a: TeachArgs) -> anyhow::Result<()> {
    let image = provision::read_blob(&a.blob)?;
    let view = provision::parse_signed(&image, &a.blob.display().to_string())?;
    let pixels = view.dims().pixels;
    let scene = match &a.scene {
        Some(path) => {
            let (ds, cut) = DefectScene::load_any_for_device(path, pixels)?;
            if let Some(note) = cut {
                eprintln!("{note}");
            }
            Some(ds)
        }
        None => None,
    };
    let spec = a.recipe.spec(recipe_room())?;
    let (model, lines) = if a.port.is_some() || a.tcp.is_some() {
        let endpoint = Endpoint { port: a.port.clone(), tcp: a.tcp.clone() };
        let mut c = Client::new(endpoint.open()?)?;
        let info = c.info().context("asking the device for its information")?;
        provision::check_device_runs(info.calibration, view.crc(), &a.blob)?;
        ensure!(
            scene.is_none() || info.simulated,
            "--scene is for simulated devices (QEMU); this device has a real sensor: put the reference under it"
        );
        c.timeout = std::time::Duration::from_secs(10);
        c.set_calibration(&image)?;
        let progress = crate::output::progress::bar(a.lines as u64, "reference lines");
        let lines = measured::measure_reference(
            &mut c,
            pixels,
            a.lines,
            scene.as_ref().map(|ds| (ds, a.first_line)),
            &mut |done| progress.set_position(done as u64),
        )?;
        progress.finish_and_clear();
        (DeviceModel::new(view, info.full_scale, acquisition_for(pixels))?, lines)
    } else {
        let ds = scene.expect("clap requires --scene without a device");
        let model = device_model(view, &ds.scene)?;
        let lines: Vec<Line> = (a.first_line..a.first_line + a.lines as u64)
            .map(|l| Ok(model.correct(&ds.raw_frames_at(l)?)))
            .collect::<anyhow::Result<_>>()?;
        (model, lines)
    };
    let taught = teach(&model, &lines, &spec)?;
    let seed = match &a.key {
        Some(k) => signing::read_secret(k)?,
        None => signing::read_secret(&signing::dev_key_path())?,
    };
    let signed = signing::sign_blob(&taught.bytes, &seed);
    crate::output::io::write_atomic(&a.out, &signed)?;
    crate::output::io::write_json(&a.out.with_extension("json"), &taught.report)?;
    let r = &taught.report;
    println!(
        "taught {} from {} lines: {} groups, distance threshold {:.1}, gloss sd {:.3} GU (median pixel), windows {:?}, teach quality {:.2}{}; {} bytes signed",
        a.out.display(),
        r.lines,
        r.groups,
        r.threshold,
        r.reading_sd[0],
        r.windows,
        r.quality,
        if r.quality < 1.0 { " (below 1: the window is inside the reference's own +-3 sd; widen it)" } else { "" },
        signed.len()
    );
    if r.no_reading_pixels > 0 {
        println!(
            "  {} pixel(s) have no gloss reading (their zones cannot read the standard): only the distance applies there",
            r.no_reading_pixels
        );
    }
    Ok(())
}

/// Refuses a recipe (`name`, taught for `(pixels, leds)`) for a device of
/// another shape, saying what to do.
fn check_recipe_shape(
    name: &str,
    (pixels, leds): (usize, usize),
    info: &brdf_meter::protocol::DeviceInfo,
) -> anyhow::Result<()> {
    ensure!(
        pixels == usize::from(info.pixels) && leds == usize::from(info.leds),
        "{name} was taught for a device with {pixels} pixels and {leds} LEDs; this device has {} and {}: teach it \
         again with the calibration this device runs (`host-tools inspect teach --blob`; `host-tools info` gives its \
         CRC); nothing was sent, the device keeps its recipe",
        info.pixels,
        info.leds
    );
    Ok(())
}

/// Reads a signed recipe, checked as the device will.
fn read_recipe(path: &Path) -> anyhow::Result<Vec<u8>> {
    let image = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let body = signing::check_signed(&image, &path.display().to_string(), signing::Signed::Recipe)?;
    RecipeView::parse(body)
        .map_err(|e| anyhow::anyhow!("{}: not a recipe this firmware reads ({e:?}); teach it again", path.display()))?;
    Ok(image)
}

/// The recipe in an image [`read_recipe`] has checked.
fn recipe_view(image: &[u8]) -> RecipeView<'_> {
    RecipeView::parse(&image[..image.len() - brdf_meter::signed::TRAILER_LEN]).expect("read_recipe checked it")
}

fn run_provision(a: ProvisionArgs) -> anyhow::Result<()> {
    let image = read_recipe(&a.recipe)?;
    let mut c = Client::new(a.device.open()?)?;
    // The device would refuse another device's recipe too, but a board
    // recipe is larger than a QEMU slot, and its refusal for size would
    // come first and not say why.
    let info = c.info()?;
    let view = recipe_view(&image);
    check_recipe_shape(&a.recipe.display().to_string(), (view.pixels(), view.leds()), &info)?;
    let info = c.provision_recipe(&image, |_, _| {}).with_context(|| format!("provisioning {}", a.recipe.display()))?;
    println!(
        "provisioned {}: recipe {:#010x} version {}, for calibration {:#010x}, slot {}, sequence {}",
        a.recipe.display(),
        info.crc,
        info.version,
        info.calibration_crc,
        provision::slot_name(info.slot),
        info.sequence
    );
    Ok(())
}

fn run_inspect(a: RunArgs) -> anyhow::Result<()> {
    ensure!(a.lines >= 1, "--lines must be at least 1");
    let image = read_recipe(&a.recipe)?;
    let recipe = recipe_view(&image);
    let mut c = Client::new(a.device.open()?)?;
    let info = c.info()?;
    if let Some(path) = &a.scene {
        ensure!(info.simulated, "--scene is for simulated devices (QEMU); this device has a real sensor");
        let (ds, cut) = DefectScene::load_any_for_device(path, usize::from(info.pixels))?;
        if let Some(note) = cut {
            eprintln!("{note}");
        }
        let lines = brdf_meter::shape::qemu::FRAME_LINES;
        let frames = (a.scene_line..a.scene_line + lines as u64)
            .map(|l| ds.raw_frames_at(l))
            .collect::<anyhow::Result<Vec<_>>>()?;
        c.load_scene(&frames).context("loading the scene into the simulated sensor")?;
        if a.lines as usize > lines {
            eprintln!(
                "note: the simulated sensor holds {lines} scene lines and cycles through them: the gloss statistics below are of those {lines}, repeated"
            );
        }
    }
    // The rejected lines' points are read with the calibration the device runs.
    let blob = match &a.blob {
        Some(path) => {
            let bytes = provision::read_blob_to_decode(path)?;
            let crc = BlobView::parse(&bytes).expect("read_blob_to_decode checked it").crc();
            provision::check_device_runs(info.calibration, crc, path)?;
            c.set_calibration(&bytes)?;
            Some(bytes)
        }
        None => None,
    };
    // The run ends after its last reject pulse, which a delay in time may
    // put well after the last line.
    let settings = recipe.settings();
    c.timeout =
        c.timeout.max(crate::device::link::end_of_run_wait(settings.pulse_us, (settings.delay, settings.delay_unit)));
    let progress = crate::output::progress::bar(a.lines as u64, "lines");
    let mut rejected = 0usize;
    let run = c.inspect(a.lines, a.defect_points.is_some(), &mut |v| {
        rejected += v.rejected() as usize;
        progress.set_position(v.line as u64 + 1);
        progress.set_message(format!("{rejected} rejected, EWMA {:+.3} GU", v.ewma));
    })?;
    progress.finish_and_clear();
    let [lsl, usl] = recipe.settings().windows[brdf_meter::gloss::SPECULAR_GU];
    let means: Vec<f32> = run.verdicts.iter().map(|v| v.mean_gloss).collect();
    let s = spc(&means, lsl, usl);
    let status = c.inspect_status()?;
    println!(
        "{} lines, {} rejected, {} defects, {} drift alarm(s) raised ({} lines in alarm), {} reject pulse(s); gloss change mean {:+.3} GU, sd {:.3}, Cp {:.2}, Cpk {:.2}; {:.1} link bytes per line",
        run.verdicts.len(),
        status.counters.rejected,
        status.counters.defects,
        status.counters.drift_alarms,
        run.verdicts.iter().filter(|v| v.drift_alarm()).count(),
        run.pulses.len(),
        s.mean,
        s.sd,
        s.cp,
        s.cpk,
        run.link_bytes as f64 / run.verdicts.len() as f64
    );
    for v in run.verdicts.iter().filter(|v| v.rejected()).take(10) {
        let runs: Vec<String> = v
            .runs
            .as_slice()
            .iter()
            .map(|r| format!("{} px {}..{}", r.kind.name(), r.first, r.first + r.len - 1))
            .collect();
        println!("  line {}: {}", v.line, runs.join(", "));
    }
    if let Some(path) = &a.csv {
        crate::output::io::write_atomic(path, &crate::output::io::csv_bytes(&verdict_rows(&run.verdicts))?)?;
    }
    if let Some(path) = &a.json {
        crate::output::io::write_json(
            path,
            &serde_json::json!({ "verdicts": verdict_rows(&run.verdicts), "pulses": run.pulses, "spc": s, "counters": status.counters }),
        )?;
    }
    if let Some(path) = &a.map {
        defect_map::write_png(path, &run.verdicts, usize::from(info.pixels), 4)?;
    }
    if let (Some(path), Some(bytes)) = (&a.defect_points, &blob) {
        let view = BlobView::parse(bytes).expect("read_blob_to_decode checked it");
        let json = path.with_extension("json");
        crate::device::measurement::measurement_points(&view, &run.points, crate::cli::exports::DEFAULT_VIEW_DEG)
            .write(path, Some(&json))?;
        println!("the rejected lines' {} points: {} and {}", run.points.len(), path.display(), json.display());
    }
    Ok(())
}

/// One row per verdict (and per defect of it) for CSV and JSON.
#[derive(serde::Serialize)]
struct VerdictRow {
    line: u32,
    rejected: bool,
    drift_alarm: bool,
    mean_gloss_gu: f32,
    ewma_gu: f32,
    max_d2: f32,
    defects: String,
}

fn verdict_rows(v: &[brdf_meter::inspect::Verdict]) -> Vec<VerdictRow> {
    v.iter()
        .map(|v| VerdictRow {
            line: v.line,
            rejected: v.rejected(),
            drift_alarm: v.drift_alarm(),
            mean_gloss_gu: v.mean_gloss,
            ewma_gu: v.ewma,
            max_d2: v.max_d2,
            defects: v
                .runs
                .as_slice()
                .iter()
                .map(|r| format!("{}:{}+{}", r.kind.name(), r.first, r.len))
                .collect::<Vec<_>>()
                .join(" "),
        })
        .collect()
}

fn run_roc(a: RocArgs) -> anyhow::Result<()> {
    let scene = Scene::load(&a.scene)?;
    let image = match &a.blob {
        Some(path) => provision::read_blob(path)?,
        None => {
            eprintln!(
                "training a scale-free piecewise calibration, {} zones, on MERL for {}",
                a.zones,
                a.scene.display()
            );
            let noise = crate::forward::scene::noise_level::relative_noise_level(&scene)?;
            crate::calibration::demo::train_scale_free_for_scene(&scene, a.zones, noise, true)?.blob
        }
    };
    let view = match &a.blob {
        Some(path) => provision::parse_signed(&image, &path.display().to_string())?,
        None => BlobView::parse(&image).map_err(|e| anyhow::anyhow!("{e:?}"))?,
    };
    let model = device_model(view, &scene)?;
    let teach = a.recipe.spec(recipe_room())?;
    let spec = if a.quick {
        RocSpec::quick(teach)
    } else {
        RocSpec { teach_lines: a.teach_lines, clean_lines: a.clean_lines, defect_lines: a.defect_lines, teach }
    };
    let started = std::time::Instant::now();
    let result = roc::run(&scene, &model, &spec, &|s| eprintln!("  {s}"))?;
    let table = roc::report::markdown(&result);
    println!("{table}");
    eprintln!("({:.0} s)", started.elapsed().as_secs_f64());
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    crate::output::io::write_atomic(&a.out.join("roc.md"), table.as_bytes())?;
    crate::output::io::write_json(&a.out.join("roc.json"), &result)?;
    roc::report::plot(&result, &a.out.join("roc.svg"))?;
    roc::report::plot(&result, &a.out.join("roc.png"))?;
    Ok(())
}

fn run_bench(a: BenchArgs) -> anyhow::Result<()> {
    ensure!(
        (1..=brdf_meter::shape::board::RAM_ZONES).contains(&a.zones),
        "--zones {}: 1 to {} (the board's RAM budget)",
        a.zones,
        brdf_meter::shape::board::RAM_ZONES
    );
    let root = crate::device::link::qemu::workspace_root();
    let lines = crate::inspection::bench::run(&root, a.zones, &|s| eprintln!("  {s}"))?;
    let p = brdf_meter::shape::board::PIXELS as f64;
    println!(
        "| line (P = 128) | verdict | frame bytes | frames corrected while the next settles (largest) | first part while the last frame integrates (points) | correct after the last frame | decide | frame | latency (cycles) | latency at 80 MHz | decide per point | estimate per point | decide / estimate (with the first part) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for l in &lines {
        let get = |n: &str| l.stages.iter().filter(|s| s.0 == n).fold((0.0, 0.0), |a, s| (a.0 + s.1, a.1 + s.2));
        let (c, d, f, e) = (get("correct"), get("decide"), get("frame"), get("estimate"));
        println!(
            "| {} | {} | {} | {} ({:.0} cyc = {:.0} us) | {:.0} cyc = {:.0} us ({}) | {:.0} instr / {:.0} cyc | {:.0} / {:.0} | {:.0} / {:.0} | {:.0} | {:.3} ms | {:.0} cyc | {:.0} cyc | {:.1} % ({:.1} %) |",
            l.line,
            if l.rejected { "reject" } else { "good" },
            l.frame_bytes,
            l.overlapped_frames,
            l.overlapped_max_cycles,
            l.overlapped_max_cycles / brdf_meter::platform::timing::SYSCLK_HZ as f64 * 1e6,
            l.early_cycles,
            l.early_cycles / brdf_meter::platform::timing::SYSCLK_HZ as f64 * 1e6,
            l.early_points,
            c.0,
            c.1,
            d.0,
            d.1,
            f.0,
            f.1,
            l.latency_cycles,
            l.latency_us / 1000.0,
            d.1 / p,
            e.1 / p,
            100.0 * l.decision_share,
            100.0 * l.decision_share_with_early
        );
    }
    if let Some(path) = &a.json {
        crate::output::io::write_json(path, &lines)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn teach_takes_its_reference_from_a_scene_or_a_device_and_says_so() {
        use clap::Parser;
        let parse = |args: &[&str]| {
            crate::cli::Cli::try_parse_from(["host-tools", "inspect", "teach", "--blob", "cal.blob"].iter().chain(args))
        };
        for ok in
            [&["--scene", "s.toml"][..], &["--port", "/dev/ttyACM0"], &["--tcp", "127.0.0.1:4555", "--scene", "s.toml"]]
        {
            assert!(parse(ok).is_ok(), "{ok:?}");
        }
        let e = parse(&[]).unwrap_err().to_string();
        assert!(e.contains("--scene") && e.contains("--port") && e.contains("--tcp"), "{e}");
        // A real instrument measures the sample under it; QEMU's sensor is fed a scene.
        assert!(
            parse(&["--port", "/dev/ttyACM0", "--scene", "s.toml"]).unwrap_err().to_string().contains("cannot be used")
        );
        assert!(parse(&["--tcp", "127.0.0.1:4555"]).unwrap_err().to_string().contains("--scene"));
    }

    #[test]
    fn a_recipe_for_another_devices_shape_is_refused_before_sending_and_says_why() {
        let qemu = brdf_meter::protocol::DeviceInfo {
            protocol: brdf_meter::protocol::PROTOCOL_VERSION,
            firmware: [0, 1, 0],
            bins: 81,
            leds: 7,
            pixels: 32,
            full_scale: 4095,
            max_blob: 24_576,
            ram_matrix_words: 0,
            simulated: true,
            calibration: None,
        };
        assert!(check_recipe_shape("r.bin", (32, 7), &qemu).is_ok());
        let e = check_recipe_shape("r.bin", (128, 7), &qemu).unwrap_err().to_string();
        assert!(e.contains("r.bin") && e.contains("128 pixels") && e.contains("has 32"), "{e}");
        assert!(e.contains("inspect teach") && e.contains("nothing was sent"), "{e}");
        assert!(check_recipe_shape("r.bin", (32, 8), &qemu).is_err(), "the LEDs count too");
    }
}
