//! Where a stack overflow ends: the stack-overflow probe
//! (`src/bin/stack-overflow-probe.rs`, linked with the firmware's memory.x)
//! recurses without end under QEMU. With the stack at the start of SRAM1,
//! below the statics, the overflow runs off SRAM1 and faults, the core
//! locks up (QEMU stops with "Lockup"; the board's watchdog resets it), and
//! the canary above the stack is never written. With the stack above the
//! statics, cortex-m-rt's default, the probe finds its canary overwritten
//! and exits with a failure instead, and this test fails.
use host_tools::device::link::qemu::{MACHINE_ARGS, SEMIHOSTING_ARGS, cargo_aliases, firmware_path, workspace_root};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The start of SRAM1 (`brdf_meter::shape::board::RAM_ORIGIN`).
const SRAM1: u32 = brdf_meter::shape::board::RAM_ORIGIN;

#[test]
fn a_stack_overflow_faults_below_sram1_and_never_reaches_the_statics() {
    let root = workspace_root();
    cargo_aliases(&root, &["stack-overflow-probe"]).unwrap_or_else(|e| panic!("building the probe: {e:#}"));
    let elf = firmware_path(&root).with_file_name("stack-overflow-probe");
    let out = tempfile::NamedTempFile::new().expect("a temporary file for QEMU's output");
    let mut child = Command::new("qemu-system-arm")
        .args(MACHINE_ARGS)
        .args(["-serial", "null"])
        .args(SEMIHOSTING_ARGS)
        .arg("-kernel")
        .arg(&elf)
        .stdin(Stdio::null())
        .stdout(out.reopen().expect("QEMU's output file"))
        .stderr(out.reopen().expect("QEMU's output file"))
        .spawn()
        .expect("starting qemu-system-arm (scripts/install-test-deps.sh installs it)");
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("waiting for QEMU") {
            break status;
        }
        if started.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("the probe still ran after 60 s: the overflow neither faulted nor was caught");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let log = std::fs::read_to_string(out.path()).expect("QEMU's output");
    eprintln!("{log}");
    assert!(log.contains("stack-overflow-probe: descending"), "the probe did not start:\n{log}");
    assert!(!log.contains("FAILED"), "the overflow reached the statics, or returned:\n{log}");
    assert!(!status.success() && log.contains("Lockup"), "QEMU did not stop on a lockup ({status}):\n{log}");
    // The stack pointer at the lockup: below the start of SRAM1, where the
    // stack ran off it.
    let sp = log
        .split_whitespace()
        .find_map(|w| w.strip_prefix("R13="))
        .and_then(|hex| u32::from_str_radix(hex, 16).ok())
        .unwrap_or_else(|| panic!("no stack pointer in QEMU's lockup report:\n{log}"));
    assert!(sp < SRAM1, "the lockup's stack pointer {sp:#010x} is not below SRAM1 ({SRAM1:#010x}):\n{log}");
}
