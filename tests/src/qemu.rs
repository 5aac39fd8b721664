//! Building the QEMU firmware once per test binary and running it under QEMU.
use host_tools::device::link::qemu::{QemuInstrument, build_firmware, workspace_root};
use std::path::PathBuf;
use std::sync::OnceLock;
use std::time::Duration;

/// The QEMU firmware ELF, built (once per test binary) with the shared
/// target directory and the firmware profile.
pub fn firmware() -> PathBuf {
    static ELF: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    ELF.get_or_init(|| build_firmware(&workspace_root()).map_err(|e| format!("{e:#}")))
        .clone()
        .unwrap_or_else(|e| panic!("cannot build the QEMU firmware: {e}"))
}

/// A QEMU instrument on a free 127.0.0.1 port, stopped after `max_run` at
/// the latest (and when dropped).
pub fn start(max_run: Duration) -> QemuInstrument {
    QemuInstrument::start(&firmware(), None, max_run, &[]).unwrap_or_else(|e| panic!("starting QEMU: {e:#}"))
}
