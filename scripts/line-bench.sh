#!/usr/bin/env bash
# Builds the line bench firmware (src/bin/line-bench.rs) and runs it once in
# QEMU (machine b-l475e-iot01a) with an exact execution trace, as
# scripts/kernel-bench.sh does for the kernels. Its input,
# target/line-bench/data.bin (a trained blob and one line of raw frames per
# build), is written by `host-tools rate`, which calls this script and reads
# OUTDIR:
#   line-bench.elf   the firmware
#   stdout.txt       what the firmware printed (segment names)
#   trace.txt        QEMU's execution trace (deleted by `host-tools rate` once counted)
#   nm.txt           symbol table with sizes
#   objdump.txt      disassembly (for the cycle estimate by instruction class)
#
#   scripts/line-bench.sh [OUTDIR]      default OUTDIR: target/line-bench
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/line-bench}
mkdir -p "$out"
[ -f target/line-bench/data.bin ] || { echo "line-bench: no target/line-bench/data.bin (host-tools rate writes it)" >&2; exit 2; }
for tool in qemu-system-arm arm-none-eabi-nm arm-none-eabi-objdump; do
  command -v "$tool" >/dev/null || { echo "line-bench: $tool not found (scripts/install-test-deps.sh installs it)" >&2; exit 2; }
done
cargo --quiet line-bench-fw
elf=target/thumbv7em-none-eabihf/firmware/line-bench
cp "$elf" "$out/line-bench.elf"
rm -f "$out/trace.txt" "$out/stdout.txt"
timeout 600 qemu-system-arm -machine b-l475e-iot01a -display none -monitor none -serial null \
  -chardev "file,id=semi,path=$out/stdout.txt" \
  -semihosting-config enable=on,target=native,chardev=semi \
  -accel tcg,one-insn-per-tb=on -d exec,nochain -D "$out/trace.txt" \
  -kernel "$out/line-bench.elf"
grep -q '^DONE' "$out/stdout.txt" || { echo "line-bench: the firmware did not finish (see $out/stdout.txt)" >&2; exit 1; }
arm-none-eabi-nm -S "$out/line-bench.elf" >"$out/nm.txt"
arm-none-eabi-objdump -d "$out/line-bench.elf" >"$out/objdump.txt"
echo "line-bench: $(wc -l <"$out/trace.txt") trace lines in $out" >&2
