//! The command line: one file per subcommand, each with its `Args` and a
//! `run` that parses nothing further and calls the library. Listed in the
//! order a user meets them. Register a new subcommand here (one enum
//! variant, one match arm).
use clap::{Parser, Subcommand};

pub mod accuracy;
pub mod certificate;
pub mod corrected_with;
pub mod design;
pub mod estimate;
pub mod exports;
pub mod info;
pub mod inspect;
pub mod keygen;
pub mod materials;
pub mod measure;
pub mod pixel_map;
pub mod provision;
pub mod provision_swd;
pub mod qemu;
pub mod rate;
pub mod reproduce;
pub mod sign;
pub mod sign_firmware;
pub mod sim_scene;
pub mod simulate;
pub mod stability;
pub mod standard_source;
pub mod standardise;
pub mod tradeoff;
pub mod train;
pub mod update_firmware;
pub mod verify;

/// Host tools for the handheld gloss/BRDF meter.
#[derive(Debug, Parser)]
#[command(name = "host-tools", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Reproduce the patent's Table 6 on the patent profile (every method, timed).
    Reproduce(reproduce::Args),
    /// Simulate a scene's readings (CSV, JSON and a plot), truth beside them.
    Simulate(simulate::Args),
    /// Score candidate LED layouts: held-out BRDF and gloss error per pixel, specular coverage, saturation, time per line.
    Design(design::Args),
    /// Train the estimator matrices (one per zone) and write the calibration blob.
    Train(train::Args),
    /// Generate a key pair for signing calibrations (secret + .pub).
    Keygen(keygen::Args),
    /// Sign a calibration blob with a secret key, for provisioning.
    Sign(sign::Args),
    /// Sign a firmware ELF with a secret key, for updates over the link.
    SignFirmware(sign_firmware::Args),
    /// Start the QEMU instrument (serial on 127.0.0.1) to play with.
    Qemu(qemu::Args),
    /// Show a device's identity, sizes, calibration and status.
    Info(info::Args),
    /// Provision a calibration blob onto a device over its link.
    Provision(provision::Args),
    /// Write a calibration blob into the board's flash over SWD (probe-rs).
    ProvisionSwd(provision_swd::Args),
    /// Update a device's firmware over its link with a signed image.
    UpdateFirmware(update_firmware::Args),
    /// On-device inspection: teach a recipe, provision it, run (verdicts, SPC, defect map), ROC.
    Inspect(inspect::Args),
    /// Standardise a calibration on a certified white tile (the LEDs' drift since calibration), or its gloss scale on a certified black glass.
    Standardise(standardise::Args),
    /// Verify a calibration on a certified gloss standard: per zone, whether it reads it within what both state (E_n).
    Verify(verify::Args),
    /// Measure lines on a device; write every point as CSV and JSON.
    Measure(measure::Args),
    /// Apply a calibration blob to logged readings offline, exactly as the device does.
    Estimate(estimate::Args),
    /// Accuracy against time for every estimator: table, JSON, plot, QEMU kernel counts.
    Tradeoff(tradeoff::Args),
    /// The line rate end to end: device compute by stage (QEMU counts), acquisition, link; the limiting stage.
    Rate(rate::Args),
    /// Leave-one-material-out over measured materials: errors, flags, worst-case plot.
    Materials(materials::Args),
    /// The calibration `train` would write, applied as the device does to held-out families: error, gloss, coverage, flag.
    Accuracy(accuracy::Args),
    /// Per-pixel accuracy map of a calibration kind on a scene: held-out error, black glass, tiles, flags.
    PixelMap(pixel_map::Args),
    /// Run the hard-case numerical stability checks over many generated cases.
    Stability(stability::Args),
}

/// Runs one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Reproduce(a) => reproduce::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Design(a) => design::run(a),
        Command::Train(a) => train::run(a),
        Command::Keygen(a) => keygen::run(a),
        Command::Sign(a) => sign::run(a),
        Command::SignFirmware(a) => sign_firmware::run(a),
        Command::UpdateFirmware(a) => update_firmware::run(a),
        Command::Qemu(a) => qemu::run(a),
        Command::Info(a) => info::run(a),
        Command::Provision(a) => provision::run(a),
        Command::ProvisionSwd(a) => provision_swd::run(a),
        Command::Inspect(a) => inspect::run(a),
        Command::Standardise(a) => standardise::run(a),
        Command::Verify(a) => verify::run(a),
        Command::Measure(a) => measure::run(a),
        Command::Estimate(a) => estimate::run(a),
        Command::Tradeoff(a) => tradeoff::run(a),
        Command::Rate(a) => rate::run(a),
        Command::Materials(a) => materials::run(a),
        Command::Accuracy(a) => accuracy::run(a),
        Command::PixelMap(a) => pixel_map::run(a),
        Command::Stability(a) => stability::run(a),
    }
}
