#!/usr/bin/env bash
# Firmware checks for CI (called by scripts/test-all.sh):
#  1. every firmware binary (board-fw; qemu-fw when the package has it) builds
#     for thumbv7em-none-eabihf with no warning at all: board-fw and qemu-fw
#     in the firmware profile (release + fat LTO), qemu-fw (and the
#     stack-overflow probe, built on the same library) as their QEMU tests
#     use them, so the test run builds each once;
#     The QEMU benches (kernel-bench, line-bench, inspect-bench, verify-bench)
#     are built and checked too: the test suite does not run them (their
#     traces take minutes), but host-tools/tests/firmware_budget.rs checks
#     their stack frames on these images;
#  2. clippy is clean (-D warnings) for each of them, library included;
#  3. the board image links its logger and memory.x's slot symbols, and a
#     size report (flash and RAM per section). The budget check on that image
#     is host-tools/tests/firmware_budget.rs, in the cargo tests.
# Warnings are checked from cargo's output (cargo replays cached warnings), not
# with RUSTFLAGS, so nothing is rebuilt twice and the host builds are untouched.
set -euo pipefail
cd "$(dirname "$0")/.."

TARGET=thumbv7em-none-eabihf
target_dir=${CARGO_TARGET_DIR:-target}

# bin:profile (where its ELF lands); each is built with `cargo BIN` and
# checked with `cargo BIN-clippy`, the aliases in .cargo/config.toml (the one
# place the firmware command lines live). qemu-fw only if the package has it.
# The bootloaders (board and QEMU: one binary, two features) are
# alias:profile:bin, their alias not being their binary's name.
firmwares=("board-fw:firmware" "bootloader:bootloader:bootloader" "qemu-bootloader:qemu-bootloader:bootloader")
if grep -q '^name = "qemu-fw"' Cargo.toml; then
  firmwares+=("qemu-fw:firmware" "stack-overflow-probe:firmware")
fi
for bench in kernel-bench line-bench inspect-bench verify-bench; do
  firmwares+=("$bench-fw:firmware:$bench")
done

log=$(mktemp)
trap 'rm -f "$log"' EXIT

elfs=()
for fw in "${firmwares[@]}"; do
  IFS=: read -r bin profile elf_name <<<"$fw"
  start=$SECONDS
  echo "[firmware] build $bin (cargo $bin: profile $profile, $TARGET)"
  if ! cargo "$bin" >"$log" 2>&1; then
    cat "$log"
    echo "[firmware] FAILED: $bin does not build" >&2
    exit 1
  fi
  # The one expected warning: these test builds trust the DEVELOPMENT
  # calibration key on purpose (build.rs says so for every board build).
  if grep -vF 'trusts the DEVELOPMENT calibration key' "$log" | grep -qE '^(warning|error)(\[|:)'; then
    cat "$log"
    echo "[firmware] FAILED: $bin builds with warnings (warnings are errors for firmware)" >&2
    exit 1
  fi
  echo "[firmware] clippy $bin (-D warnings)"
  if ! cargo "$bin-clippy" -- -D warnings >"$log" 2>&1; then
    cat "$log"
    echo "[firmware] FAILED: clippy is not clean for $bin" >&2
    exit 1
  fi
  elfs+=("$target_dir/$TARGET/$profile/${elf_name:-$bin}")
  echo "[firmware] $bin: built and clippy-clean in $((SECONDS - start)) s"
done

# The board image must carry its logger (RTT control block) and find the
# calibration slots through memory.x's symbols at the addresses memory.x gives.
board_elf="$target_dir/$TARGET/firmware/board-fw"
syms=$(arm-none-eabi-nm "$board_elf")
for want in "D _SEGGER_RTT" "A __cal_slot_a_start" "A __cal_slot_b_start"; do
  if ! grep -q " $want\$" <<<"$syms"; then
    echo "[firmware] FAILED: board-fw has no symbol '$want'" >&2
    exit 1
  fi
done
slot_a=$(awk '$3 == "__cal_slot_a_start" {print $1}' <<<"$syms")
slot_a_x=$(sed -n 's/^ *CAL_SLOT_A *: *ORIGIN *= *0x\([0-9A-Fa-f]*\).*/\1/p' memory.x)
if [ "$((16#$slot_a))" -ne "$((16#$slot_a_x))" ]; then
  echo "[firmware] FAILED: board-fw's slot A at 0x$slot_a, memory.x says 0x$slot_a_x" >&2
  exit 1
fi

echo "[firmware] size report (arm-none-eabi-size -A -d)"
for elf in "${elfs[@]}"; do
  arm-none-eabi-size -A -d "$elf" | awk 'NR <= 2 || ($2 > 0 && $3 > 0)'
  arm-none-eabi-size -B -d "$elf"
done

# The budget check itself (flash outside the calibration slots, a slot for the
# Z = 128 blob, RAM after statics and stack) is host-tools' test
# tests/firmware_budget.rs, run by the cargo tests right after this script on
# this same image (no second host-tools build). By hand:
#   cargo test --release -p host-tools --test firmware_budget -- --nocapture
echo "[firmware] ok: ${#elfs[@]} firmware image(s) built warning-free, clippy clean"
