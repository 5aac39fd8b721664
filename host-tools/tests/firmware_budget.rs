//! The board firmware's flash/RAM budget for the largest calibration
//! (Z = 128 zones of 81 x 7 matrices, P = 128), checked on the real image:
//! builds `board-fw` (`cargo board-fw`: a no-op when scripts/check-firmware.sh
//! already did, same command and profile) and fails if it is over budget.
//! The bootloader's budget and the QEMU benches' stacks are checked the
//! same way. Run with `-- --nocapture` to see the tables.
use host_tools::device::link::qemu::{cargo_aliases, firmware_elf, workspace_root};
use std::path::{Path, PathBuf};

/// Builds a firmware with its cargo alias (`.cargo/config.toml`: a no-op
/// when scripts/check-firmware.sh already did, same command and profile)
/// and returns its ELF, `profile/elf` under the target's directory.
fn build_firmware(root: &Path, alias: &str, elf: &str) -> PathBuf {
    cargo_aliases(root, &[alias]).unwrap_or_else(|e| panic!("{e:#}"));
    firmware_elf(root, elf)
}

#[test]
fn the_bootloader_fits_its_24_kib() {
    use host_tools::device::budget::{ImageKind, check_file};
    let root = workspace_root();
    let elf = build_firmware(&root, "bootloader", "bootloader/bootloader");
    let script = std::fs::read_to_string(root.join("memory.x")).expect("memory.x");
    let budget = check_file(&elf, ImageKind::Bootloader, &script).expect("reading the bootloader image");
    println!("{}", budget.table());
    assert!(budget.ok(), "the bootloader is over budget:\n{}", budget.table());
    assert_eq!(budget.lines[0].limit, 24 * 1024);
    assert!(budget.lines[0].used > 1024, "an implausibly small bootloader: {}", budget.lines[0].used);
}

#[test]
fn board_firmware_fits_its_budget_with_the_largest_calibration() {
    let root = workspace_root();
    let elf = build_firmware(&root, "board-fw", "firmware/board-fw");
    let script = std::fs::read_to_string(root.join("memory.x")).expect("memory.x");
    let budget =
        host_tools::device::budget::check_file(&elf, host_tools::device::budget::ImageKind::Application, &script)
            .expect("reading the firmware image");
    println!("{}", budget.table());
    assert!(budget.ok(), "board-fw is over budget:\n{}", budget.table());
    // The image really is the board firmware and really has the sections the
    // budget is about (a check on an empty or wrong file must not pass).
    assert!(budget.lines[0].used > 16 * 1024, "an implausibly small image: {}", budget.lines[0].used);
    assert!(budget.lines[2].used > 32 * 1024, "implausibly few statics: {}", budget.lines[2].used);
    // The frames were read: the application's tasks have frames of
    // hundreds of bytes at least, and one of 29,568 B once (board.md, "The
    // stack"), which this line would refuse.
    let frame = &budget.lines[4];
    assert!(frame.what.contains("frame") && frame.used > 512, "{frame:?}");
}

#[test]
fn every_qemu_bench_links_the_stack_and_no_frame_outgrows_it() {
    let root = workspace_root();
    let script = std::fs::read_to_string(root.join("memory.x")).expect("memory.x");
    for bench in ["kernel-bench", "line-bench", "inspect-bench", "verify-bench"] {
        let elf = build_firmware(&root, &format!("{bench}-fw"), &format!("firmware/{bench}"));
        let budget = host_tools::device::budget::check_bench_file(&elf, &script).expect("reading the bench image");
        println!("{}", budget.table());
        assert!(budget.ok(), "{bench}'s stack does not fit:\n{}", budget.table());
        // The frames were read: each bench's `main` holds its inputs.
        let frame = &budget.lines[0];
        assert!(frame.what.contains("frame") && frame.used > 256, "{bench}: {frame:?}");
    }
}
