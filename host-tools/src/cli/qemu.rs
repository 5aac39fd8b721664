//! `host-tools qemu`: start the QEMU instrument for a person to play with.
use crate::device::link::qemu::{QemuInstrument, build_firmware, firmware_path, workspace_root};
use crate::device::qemu_demo::{DemoEstimator, DemoScene, connect, set_up};
use anyhow::Context;
use std::path::PathBuf;
use std::time::Duration;

/// Build the QEMU firmware and run it (QEMU machine b-l475e-iot01a) with its
/// serial on 127.0.0.1:PORT; optionally provision a calibration trained for
/// it and load a simulated scene, so `measure` works at once.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// TCP port of the instrument's serial (127.0.0.1).
    #[arg(long, default_value_t = 4555)]
    pub port: u16,
    /// Put the serial on a pseudo-terminal (reach it with `--port /dev/pts/N`,
    /// as a real instrument on /dev/ttyACM*) instead of TCP.
    #[arg(long)]
    pub pty: bool,
    /// Firmware ELF to run instead of building it.
    #[arg(long, value_name = "PATH")]
    pub elf: Option<PathBuf>,
    /// Train a calibration for the QEMU instrument's simulated optics
    /// (`--demo-scene`), write it here, provision it and load the scene.
    #[arg(long, value_name = "PATH")]
    pub demo: Option<PathBuf>,
    /// The demo calibration's estimator.
    #[arg(long, value_enum, default_value_t = DemoEstimator::ScaleFreePiecewise, requires = "demo")]
    pub demo_estimator: DemoEstimator,
    /// The demo's simulated optics: the handheld's line cut to the device's
    /// pixels, or the patent profile.
    #[arg(long, value_enum, default_value_t = DemoScene::Handheld, requires = "demo")]
    pub demo_scene: DemoScene,
    /// Stop QEMU after this many minutes.
    #[arg(long, default_value_t = 60)]
    pub minutes: u64,
    /// Extra QEMU argument (repeatable), e.g. tracing for scripts/qemu-icount.sh.
    #[arg(long = "qemu-arg", value_name = "ARG", allow_hyphen_values = true)]
    pub qemu_args: Vec<String>,
    /// Scripted run: after --demo, measure this many lines, print a summary
    /// and stop QEMU instead of waiting.
    #[arg(long, value_name = "LINES", requires = "demo")]
    pub measure_and_exit: Option<u32>,
}

/// Runs the command: returns when QEMU stops (time limit, or Ctrl-C).
pub fn run(a: Args) -> anyhow::Result<()> {
    let elf = match a.elf {
        Some(e) => e,
        None => {
            eprintln!("building the QEMU firmware ...");
            build_firmware(&workspace_root()).context("building the QEMU firmware (or pass --elf)")?
        }
    };
    let elf = if elf.is_file() { elf } else { firmware_path(&workspace_root()) };
    let max_run = Duration::from_secs(a.minutes * 60);
    let mut q = if a.pty {
        QemuInstrument::start_pty(&elf, max_run, &a.qemu_args)
            .with_context(|| format!("starting QEMU with {}", elf.display()))?
    } else {
        QemuInstrument::start(&elf, Some(a.port), max_run, &a.qemu_args)
            .with_context(|| format!("starting QEMU with {} (is port {} free?)", elf.display(), a.port))?
    };
    let addr = q.addr.clone();
    let link = if a.pty { format!("--port {addr}") } else { format!("--tcp {addr}") };
    if let Some(blob_path) = &a.demo {
        let mut c = connect(&addr, a.pty)?;
        if a.measure_and_exit.is_some() {
            // A counting run traces every instruction: provisioning (its
            // signature check) takes far longer than the interactive 5 s.
            c.timeout = Duration::from_secs(600);
        }
        eprintln!("training a {:?} calibration for the simulated optics ...", a.demo_estimator);
        let (blob, cal) = set_up(&mut c, blob_path, a.demo_estimator, a.demo_scene)?;
        eprintln!(
            "provisioned {} (CRC {:#010x}, {} zones) and loaded a 4-line {:?} scene",
            blob_path.display(),
            cal.blob_crc,
            cal.zones,
            a.demo_scene
        );
        if let Some(lines) = a.measure_and_exit {
            c.timeout = Duration::from_secs(600);
            c.set_calibration(&blob)?;
            let pts = c.measure(lines).context("measuring")?;
            let d = brdf_meter::blob::BlobView::parse(&blob).expect("trained blobs parse").dims();
            println!("measured {lines} lines: {} points, {} multiply-accumulates", pts.len(), pts.len() * d.n * d.m);
            println!("{}", demo_summary(&pts));
            q.stop();
            return Ok(());
        }
    }
    let blob = a.demo.as_ref().map_or("CAL.blob".into(), |p| p.display().to_string());
    println!("QEMU instrument running: serial on {addr}, for {} min (Ctrl-C stops it). Try:", a.minutes);
    println!("  host-tools info {link}");
    if a.demo.is_none() {
        println!("  (restart with --demo {blob} for a calibration trained for the simulated optics, or)");
        println!("  host-tools provision {link} --blob {blob}");
    }
    // The demo has loaded the scene its calibration was trained for;
    // otherwise load the one a calibration from the README's tour is for.
    let scene = if a.demo.is_some() { "" } else { " --scene scenes/handheld.toml" };
    println!("  host-tools measure {link} --blob {blob} --lines 4{scene} --csv out/m.csv --json out/m.json");
    let st = q.wait()?;
    println!("QEMU stopped ({st}); {}", q.log_text().trim());
    Ok(())
}

/// What a user checks first in a demo measurement: how many points are
/// flagged (and why), how many estimates go below -1 % of their peak (a
/// physically impossible reflectance), and the gloss reading's spread.
fn demo_summary(pts: &[crate::device::link::PointRecord]) -> String {
    use brdf_meter::protocol::flags;
    let n = pts.len().max(1) as f64;
    let share = |bit: u8| 100.0 * pts.iter().filter(|p| p.flags & bit != 0).count() as f64 / n;
    let impossible = pts
        .iter()
        .filter(|p| {
            let peak = p.values.iter().copied().fold(0.0f32, f32::max);
            p.values.iter().any(|v| *v < -0.01 * peak)
        })
        .count();
    let mut gloss: Vec<f32> =
        pts.iter().map(|p| p.readings[brdf_meter::gloss::SPECULAR_GU]).filter(|g| g.is_finite()).collect();
    gloss.sort_by(f32::total_cmp);
    let q =
        |f: f64| gloss.get(((gloss.len().saturating_sub(1)) as f64 * f).round() as usize).copied().unwrap_or(f32::NAN);
    format!(
        "flagged: out-of-prior {:.0} %, saturated {:.0} %, under-exposed {:.0} %; estimates with a bin below -1 % of their peak: {impossible}; gloss GU 10/50/90 %: {:.1} / {:.1} / {:.1}",
        share(flags::OUT_OF_PRIOR),
        share(flags::SATURATED),
        share(flags::UNDER_EXPOSED),
        q(0.1),
        q(0.5),
        q(0.9)
    )
}
