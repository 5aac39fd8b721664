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

/// Checks the QEMU firmware's stack after a test's `workload`: its
/// high-water mark (the stack is painted at reset,
/// `host_tools::device::stack_use`) within the stack the board's firmware
/// budget reserves (`host_tools::device::budget::STACK_RESERVE`). The
/// application code is the board's; a deeper stack here would overflow the
/// board's reserve too, silently, into its statics.
pub fn assert_stack_within_reserve(q: &QemuInstrument, workload: &str) {
    use host_tools::device::budget::STACK_RESERVE;
    let s = q.stack_use(&firmware()).unwrap_or_else(|e| panic!("reading the QEMU firmware's stack: {e:#}"));
    eprintln!("qemu-fw stack after {workload}: {s}; the board's budget reserves {STACK_RESERVE} B");
    assert!(
        u64::from(s.used) <= STACK_RESERVE,
        "the QEMU firmware's stack reached {} B after {workload}, over the {STACK_RESERVE} B the board's budget reserves \
         ({s}): raise host_tools::device::budget::STACK_RESERVE and check the board's RAM budget, or move the deep \
         frame's buffers into statics",
        s.used
    );
}
