#!/usr/bin/env bash
# Builds the kernel bench firmware (src/bin/kernel-bench.rs) and runs it once
# in QEMU (machine b-l475e-iot01a, the chip itself) with an exact execution
# trace: one instruction per translation block, every executed instruction
# logged (`-accel tcg,one-insn-per-tb=on -d exec,nochain`, design.md).
# `host-tools tradeoff --qemu` calls it and reads OUTDIR:
#   kernel-bench.elf   the firmware
#   stdout.txt         what the firmware printed (segments, inputs, results)
#   trace.txt          QEMU's execution trace
#   nm.txt             symbol table with sizes (arm-none-eabi-nm -S)
#   objdump.txt        disassembly (for the cycle estimate by instruction class)
#
#   scripts/kernel-bench.sh [OUTDIR]      default OUTDIR: target/kernel-bench
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/kernel-bench}
mkdir -p "$out"
for tool in qemu-system-arm arm-none-eabi-nm arm-none-eabi-objdump; do
  command -v "$tool" >/dev/null || { echo "kernel-bench: $tool not found (scripts/install-test-deps.sh installs it)" >&2; exit 2; }
done
cargo --quiet kernel-bench-fw
elf=target/thumbv7em-none-eabihf/firmware/kernel-bench
cp "$elf" "$out/kernel-bench.elf"
rm -f "$out/trace.txt"
rm -f "$out/stdout.txt"
timeout 300 qemu-system-arm -machine b-l475e-iot01a -display none -monitor none -serial null \
  -chardev "file,id=semi,path=$out/stdout.txt" \
  -semihosting-config enable=on,target=native,chardev=semi \
  -accel tcg,one-insn-per-tb=on -d exec,nochain -D "$out/trace.txt" \
  -kernel "$out/kernel-bench.elf"
grep -q '^DONE' "$out/stdout.txt" || { echo "kernel-bench: the firmware did not finish (see $out/stdout.txt)" >&2; exit 1; }
arm-none-eabi-nm -S "$out/kernel-bench.elf" >"$out/nm.txt"
arm-none-eabi-objdump -d "$out/kernel-bench.elf" >"$out/objdump.txt"
echo "kernel-bench: $(wc -l <"$out/trace.txt") trace lines in $out" >&2
