#!/usr/bin/env bash
# Counts, exactly, the instructions one Ed25519 signature verify of a
# calibration (brdf_meter::signed::verify, salty) executes on the Cortex-M4F
# in QEMU: the verify bench firmware (src/bin/verify-bench.rs) runs with one
# instruction per translation block and every executed block logged
# (`-accel tcg,one-insn-per-tb=on -d exec,nochain`, as scripts/kernel-bench.sh);
# the instructions between consecutive calls of `verify_bench_mark` (its own
# excluded) are one segment each: a 3-byte message, then a 10 KiB one.
#
#   scripts/verify-bench.sh
set -euo pipefail
cd "$(dirname "$0")/.."
for tool in qemu-system-arm arm-none-eabi-nm; do
  command -v "$tool" >/dev/null || { echo "verify-bench: $tool not found (scripts/install-test-deps.sh installs it)" >&2; exit 2; }
done
cargo --quiet verify-bench-fw
elf=target/thumbv7em-none-eabihf/firmware/verify-bench
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkfifo "$work/trace"
awk '
  /^Trace / {
    if (index($0, "verify_bench_mark")) { if (!inmark && started) { print n }; started = 1; inmark = 1; n = 0; next }
    inmark = 0; n++
  }' "$work/trace" >"$work/counts" &
counter=$!
timeout 600 qemu-system-arm -machine b-l475e-iot01a -display none -monitor none -serial null \
  -semihosting-config enable=on,target=native \
  -accel tcg,one-insn-per-tb=on -d exec,nochain -D "$work/trace" \
  -kernel "$elf" || { echo "verify-bench: the firmware failed (a signature did not verify as expected)" >&2; exit 1; }
wait "$counter"
# Segments alternate: measured, between (setup), measured.
mapfile -t c <"$work/counts"
short=${c[0]}; long=${c[2]}
echo "verify, 3-byte message:  $short instructions"
echo "verify, 10 KiB message:  $long instructions"
