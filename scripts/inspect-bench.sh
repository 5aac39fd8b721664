#!/usr/bin/env bash
# Builds the inspection bench firmware (src/bin/inspect-bench.rs) and runs it
# once in QEMU (machine b-l475e-iot01a) with an exact execution trace, as
# scripts/line-bench.sh does for the measurement's line. Its input,
# target/inspect-bench/data.bin (a calibration, a recipe and two lines of raw
# frames for the board's P = 128), is written by `host-tools inspect bench`,
# which calls this script and counts OUTDIR's trace.txt, stdout.txt, nm.txt
# and objdump.txt.
#
#   scripts/inspect-bench.sh [OUTDIR]      default OUTDIR: target/inspect-bench
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/inspect-bench}
mkdir -p "$out"
[ -f target/inspect-bench/data.bin ] || { echo "inspect-bench: no target/inspect-bench/data.bin (host-tools inspect bench writes it)" >&2; exit 2; }
for tool in qemu-system-arm arm-none-eabi-nm arm-none-eabi-objdump; do
  command -v "$tool" >/dev/null || { echo "inspect-bench: $tool not found (scripts/install-test-deps.sh installs it)" >&2; exit 2; }
done
cargo --quiet inspect-bench-fw
elf=target/thumbv7em-none-eabihf/firmware/inspect-bench
cp "$elf" "$out/inspect-bench.elf"
rm -f "$out/trace.txt" "$out/stdout.txt"
timeout 600 qemu-system-arm -machine b-l475e-iot01a -display none -monitor none -serial null \
  -chardev "file,id=semi,path=$out/stdout.txt" \
  -semihosting-config enable=on,target=native,chardev=semi \
  -accel tcg,one-insn-per-tb=on -d exec,nochain -D "$out/trace.txt" \
  -kernel "$out/inspect-bench.elf"
grep -q '^DONE' "$out/stdout.txt" || { echo "inspect-bench: the firmware did not finish (see $out/stdout.txt)" >&2; exit 1; }
arm-none-eabi-nm -S "$out/inspect-bench.elf" >"$out/nm.txt"
arm-none-eabi-objdump -d "$out/inspect-bench.elf" >"$out/objdump.txt"
echo "inspect-bench: $(wc -l <"$out/trace.txt") trace lines in $out" >&2
