//! The QEMU instrument: building the QEMU firmware and its bootloader and
//! running them under QEMU (machine b-l475e-iot01a) with the serial on a
//! 127.0.0.1 TCP port. The bootloader sits at the reset vector, as on the
//! board, and starts the application from the active image region.
//!
//! QEMU always runs under `timeout`, and [`QemuInstrument`] stops it when
//! dropped, so a failing test or an interrupted command never leaves it behind.
//!
//! Its machine interface (QMP, on a Unix socket) reads the emulated RAM:
//! [`QemuInstrument::stack_use`], the firmware's stack high-water mark.
use super::{Client, TcpTransport};
use anyhow::{Context, bail};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The workspace root (where the firmware is built).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("host-tools is a workspace member").to_path_buf()
}

/// Path of the firmware ELF `profile/name` (`firmware/qemu-fw`,
/// `bootloader/bootloader`) that a cargo alias builds under the target's
/// directory.
pub fn firmware_elf(root: &Path, profile_and_name: &str) -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR").map(PathBuf::from).unwrap_or_else(|| root.join("target"));
    target.join("thumbv7em-none-eabihf").join(profile_and_name)
}

/// Path of the QEMU firmware ELF that `cargo qemu-fw` builds.
pub fn firmware_path(root: &Path) -> PathBuf {
    firmware_elf(root, "firmware/qemu-fw")
}

/// The QEMU bootloader's ELF (`cargo qemu-bootloader`) for the application
/// `elf`: beside it, in the qemu-bootloader profile's folder.
pub fn bootloader_path(elf: &Path) -> PathBuf {
    let profile_dir = elf.parent().and_then(Path::parent).unwrap_or(Path::new("."));
    profile_dir.join("qemu-bootloader/bootloader")
}

/// Runs `cargo ALIAS` in the workspace `root` for each of `aliases`: the
/// aliases (.cargo/config.toml) are the one firmware build command.
pub fn cargo_aliases(root: &Path, aliases: &[&str]) -> anyhow::Result<()> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    for alias in aliases {
        let status = Command::new(&cargo)
            .current_dir(root)
            .arg(alias)
            // Host-side variables of an enclosing `cargo test` must not leak into the firmware build.
            .env_remove("RUSTFLAGS")
            .env_remove("CARGO_ENCODED_RUSTFLAGS")
            .env_remove("CARGO_BUILD_TARGET")
            .status()
            .with_context(|| format!("running cargo {alias}"))?;
        if !status.success() {
            bail!("cargo {alias} failed ({status}); is the target installed? (scripts/install-test-deps.sh)");
        }
    }
    Ok(())
}

/// Builds the QEMU firmware and its bootloader (`cargo qemu-fw`, `cargo
/// qemu-bootloader`) and returns the firmware's ELF.
pub fn build_firmware(root: &Path) -> anyhow::Result<PathBuf> {
    cargo_aliases(root, &["qemu-fw", "qemu-bootloader"])?;
    let elf = firmware_path(root);
    for built in [elf.clone(), bootloader_path(&elf)] {
        if !built.is_file() {
            bail!("cargo built the firmware but {} is missing", built.display());
        }
    }
    Ok(elf)
}

/// QEMU's machine, headless and without a monitor, as the instrument and
/// the stack-overflow probe start it (the bench scripts spell it out).
pub const MACHINE_ARGS: [&str; 6] = ["-machine", "b-l475e-iot01a", "-display", "none", "-monitor", "none"];

/// Semihosting on, to the host: how an image prints and exits.
pub const SEMIHOSTING_ARGS: [&str; 2] = ["-semihosting-config", "enable=on,target=native"];

/// A running QEMU instrument.
pub struct QemuInstrument {
    child: Option<Child>,
    /// 127.0.0.1:PORT of its serial.
    pub addr: String,
    /// QEMU's output (its messages, and firmware panics through semihosting).
    pub log: PathBuf,
    /// Its QMP socket (in the temporary directory: a Unix socket's path is
    /// limited to about 100 bytes, which a deep target directory exceeds).
    qmp: PathBuf,
}

fn free_port() -> std::io::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

impl QemuInstrument {
    /// Starts QEMU with `elf`, its serial on 127.0.0.1:`port` (a free port if
    /// `None`), stopped after `max_run` at the latest; `extra` are more QEMU
    /// arguments. Returns once the serial accepts connections.
    pub fn start(elf: &Path, port: Option<u16>, max_run: Duration, extra: &[String]) -> anyhow::Result<Self> {
        let mut last_err = None;
        for _ in 0..5 {
            let port = match port {
                Some(p) => p,
                None => free_port().context("finding a free TCP port on 127.0.0.1")?,
            };
            match Self::try_start(elf, port, max_run, extra) {
                Ok(q) => return Ok(q),
                Err(e) => last_err = Some(e),
            }
        }
        Err(last_err.expect("tried at least once"))
    }

    /// Starts QEMU with its serial on a pseudo-terminal (`-serial pty`), the
    /// way a real instrument appears as /dev/ttyACM*: [`Self::addr`] is the
    /// pty's path, for [`Self::connect_serial`] or `--port`.
    pub fn start_pty(elf: &Path, max_run: Duration, extra: &[String]) -> anyhow::Result<Self> {
        let log = elf.with_file_name(format!("qemu-pty-{}.log", std::process::id()));
        let qmp = qmp_socket();
        let child = Self::spawn(elf, "pty", max_run, extra, &log, &qmp)?;
        let mut q = Self { child: Some(child), addr: String::new(), log, qmp };
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            // QEMU prints "char device redirected to /dev/pts/N (label serial0)".
            if let Some(path) = q.log_text().split_whitespace().skip_while(|w| *w != "to").nth(1) {
                q.addr = path.to_string();
                return Ok(q);
            }
            if !q.running() {
                bail!("QEMU exited at start: {}", q.log_text());
            }
            if Instant::now() > deadline {
                bail!("QEMU did not report its pty within 10 s: {}", q.log_text());
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// A protocol client on its pty serial (see [`Self::start_pty`]), through
    /// the serial-port transport a real instrument uses.
    pub fn connect_serial(&self) -> anyhow::Result<Client<super::SerialTransport>> {
        let t = super::SerialTransport::open(&self.addr).with_context(|| format!("opening {}", self.addr))?;
        let mut c = Client::new(t)?;
        c.wait_ready(Duration::from_secs(20))
            .with_context(|| format!("the QEMU firmware did not answer: {}", self.log_text()))?;
        Ok(c)
    }

    fn spawn(
        elf: &Path,
        serial: &str,
        max_run: Duration,
        extra: &[String],
        log: &Path,
        qmp: &Path,
    ) -> anyhow::Result<Child> {
        let stderr = std::fs::File::create(log).with_context(|| format!("creating {}", log.display()))?;
        Command::new("timeout")
            .arg("--foreground")
            .arg(format!("{}", max_run.as_secs().max(1)))
            .arg("qemu-system-arm")
            .args(MACHINE_ARGS)
            .arg("-serial")
            .arg(serial)
            .arg("-qmp")
            .arg(format!("unix:{},server=on,wait=off", qmp.display()))
            .args(SEMIHOSTING_ARGS)
            .arg("-kernel")
            // The bootloader at the reset vector, the application in ACTIVE.
            .arg(bootloader_path(elf))
            .arg("-device")
            .arg(format!("loader,file={}", elf.display()))
            .args(extra)
            .stdin(Stdio::null())
            // QEMU reports its pty on stdout, firmware panics on stderr: one log.
            .stdout(stderr.try_clone().context("duplicating the log handle")?)
            .stderr(stderr)
            .spawn()
            .context("starting qemu-system-arm under timeout (install it with scripts/install-test-deps.sh)")
    }

    fn try_start(elf: &Path, port: u16, max_run: Duration, extra: &[String]) -> anyhow::Result<Self> {
        let log = elf.with_file_name(format!("qemu-{port}.log"));
        // --foreground (in spawn): QEMU stays in our process group, so a
        // Ctrl-C of `host-tools qemu` reaches it too; `timeout` still ends it.
        let qmp = qmp_socket();
        let child = Self::spawn(elf, &format!("tcp:127.0.0.1:{port},server=on,wait=off"), max_run, extra, &log, &qmp)?;
        let mut q = Self { child: Some(child), addr: format!("127.0.0.1:{port}"), log, qmp };
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            if let Some(st) = q.child.as_mut().and_then(|c| c.try_wait().ok().flatten()) {
                q.child = None;
                bail!("QEMU exited at start ({st}): {}", q.log_text());
            }
            if std::net::TcpStream::connect_timeout(&q.addr.parse()?, Duration::from_millis(200)).is_ok() {
                return Ok(q);
            }
            if Instant::now() > deadline {
                bail!("QEMU's serial on {} did not open within 10 s: {}", q.addr, q.log_text());
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// A protocol client on its serial, once the firmware answers.
    pub fn connect(&self) -> anyhow::Result<Client<TcpTransport>> {
        let t = TcpTransport::connect(&self.addr).with_context(|| format!("connecting to {}", self.addr))?;
        let mut c = Client::new(t)?;
        c.wait_ready(Duration::from_secs(20))
            .with_context(|| format!("the QEMU firmware did not answer: {}", self.log_text()))?;
        Ok(c)
    }

    /// What QEMU printed on stderr (firmware panics arrive there).
    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// Whether QEMU is still running.
    pub fn running(&mut self) -> bool {
        matches!(self.child.as_mut().map(|c| c.try_wait()), Some(Ok(None)))
    }

    /// Waits for QEMU to end (its timeout, or the firmware exiting).
    pub fn wait(&mut self) -> anyhow::Result<std::process::ExitStatus> {
        let mut c = self.child.take().context("QEMU is not running")?;
        Ok(c.wait()?)
    }

    /// `len` bytes of the machine's memory from address `addr`, read while
    /// it runs (QMP's `pmemsave` into a temporary file).
    pub fn read_memory(&self, addr: u32, len: u32) -> anyhow::Result<Vec<u8>> {
        let mut qmp = Qmp::connect(&self.qmp)?;
        let file = tempfile::NamedTempFile::new().context("creating a temporary file for QEMU's memory dump")?;
        qmp.execute(&serde_json::json!({
            "execute": "pmemsave",
            "arguments": { "val": addr, "size": len, "filename": file.path() },
        }))
        .with_context(|| format!("reading {len} bytes of QEMU's memory at {addr:#010x}"))?;
        let bytes = std::fs::read(file.path()).context("reading QEMU's memory dump")?;
        if bytes.len() != len as usize {
            bail!("QEMU wrote {} bytes of memory at {addr:#010x}, not the {len} asked", bytes.len());
        }
        Ok(bytes)
    }

    /// The stack high-water mark of the running firmware `elf` (built with
    /// cortex-m-rt's `paint-stack`, as the QEMU firmware is):
    /// [`crate::device::stack_use`].
    pub fn stack_use(&self, elf: &Path) -> anyhow::Result<crate::device::stack_use::StackUse> {
        use crate::device::stack_use::{StackRegion, StackUse};
        let bytes = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
        let region = StackRegion::of_elf(&bytes, &elf.display().to_string())?;
        StackUse::of(region, &self.read_memory(region.bottom, region.len())?)
    }

    /// Stops QEMU: SIGTERM to `timeout` (which passes it on to QEMU), then
    /// SIGKILL if it lingers.
    pub fn stop(&mut self) {
        let Some(mut c) = self.child.take() else { return };
        let _ = Command::new("kill").arg("-TERM").arg(c.id().to_string()).status();
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = c.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = c.kill();
        let _ = c.wait();
    }
}

impl Drop for QemuInstrument {
    fn drop(&mut self) {
        self.stop();
        let _ = std::fs::remove_file(&self.qmp);
    }
}

/// A new QMP socket path, unique in this process (tests start several
/// instruments at once) and across processes.
fn qmp_socket() -> PathBuf {
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    std::env::temp_dir().join(format!("brdf-qemu-{}-{k}.qmp", std::process::id()))
}

/// A connection to QEMU's machine interface: JSON lines, after the
/// greeting and the capabilities' negotiation.
struct Qmp {
    reader: std::io::BufReader<std::os::unix::net::UnixStream>,
    writer: std::os::unix::net::UnixStream,
}

impl Qmp {
    fn connect(path: &Path) -> anyhow::Result<Self> {
        let s = std::os::unix::net::UnixStream::connect(path)
            .with_context(|| format!("connecting to QEMU's machine interface at {}", path.display()))?;
        s.set_read_timeout(Some(Duration::from_secs(20)))?;
        let mut q = Self { reader: std::io::BufReader::new(s.try_clone()?), writer: s };
        let greeting = q.message()?;
        if greeting.get("QMP").is_none() {
            bail!("QEMU's machine interface greeted with {greeting}, not a QMP greeting");
        }
        q.execute(&serde_json::json!({ "execute": "qmp_capabilities" }))?;
        Ok(q)
    }

    /// The next message (a JSON line).
    fn message(&mut self) -> anyhow::Result<serde_json::Value> {
        use std::io::BufRead as _;
        let mut line = String::new();
        if self.reader.read_line(&mut line).context("reading from QEMU's machine interface")? == 0 {
            bail!("QEMU's machine interface closed");
        }
        serde_json::from_str(&line).with_context(|| format!("QEMU's machine interface sent {line:?}"))
    }

    /// Runs `command` and returns its `return`, skipping events.
    fn execute(&mut self, command: &serde_json::Value) -> anyhow::Result<serde_json::Value> {
        use std::io::Write as _;
        writeln!(self.writer, "{command}").context("writing to QEMU's machine interface")?;
        loop {
            let mut m = self.message()?;
            if let Some(r) = m.get_mut("return") {
                return Ok(r.take());
            }
            if let Some(e) = m.get("error") {
                bail!("QEMU refused {command}: {e}");
            }
        }
    }
}
