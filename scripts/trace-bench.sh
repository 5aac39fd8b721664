#!/usr/bin/env bash
# Builds a QEMU bench firmware (src/bin/BENCH.rs, feature kernel-bench, its
# `cargo BENCH-fw` alias) and runs it once in QEMU (machine b-l475e-iot01a)
# with an exact execution trace: one instruction per translation block,
# every executed instruction logged (`-accel tcg,one-insn-per-tb=on -d
# exec,nochain`, design.md). Its input, target/BENCH/data.bin, is written
# by the host-tools command that calls this script through a wrapper
# (line-bench.sh: `host-tools rate`; inspect-bench.sh: `host-tools inspect
# bench`; kernel-bench.sh, `host-tools tradeoff`, has its inputs built in),
# which then counts OUTDIR:
#   BENCH.elf     the firmware
#   stdout.txt    what the firmware printed (segment names)
#   trace.txt     QEMU's execution trace (deleted once counted)
#   nm.txt        symbol table with sizes
#   objdump.txt   disassembly (for the cycle estimate by instruction class)
#
#   scripts/trace-bench.sh BENCH [OUTDIR]      default OUTDIR: target/BENCH
set -euo pipefail
cd "$(dirname "$0")/.."
bench=$1
out=${2:-target/$bench}
mkdir -p "$out"
# BENCH_INPUT=none: a bench whose inputs are built in (the kernel bench).
if [ "${BENCH_INPUT:-data}" != none ]; then
  [ -f "target/$bench/data.bin" ] || { echo "$bench: no target/$bench/data.bin (the host-tools command that runs it writes it)" >&2; exit 2; }
fi
for tool in qemu-system-arm arm-none-eabi-nm arm-none-eabi-objdump; do
  command -v "$tool" >/dev/null || { echo "$bench: $tool not found (scripts/install-test-deps.sh installs it)" >&2; exit 2; }
done
cargo --quiet "$bench-fw"
elf=target/thumbv7em-none-eabihf/firmware/$bench
cp "$elf" "$out/$bench.elf"
rm -f "$out/trace.txt" "$out/stdout.txt"
timeout 600 qemu-system-arm -machine b-l475e-iot01a -display none -monitor none -serial null \
  -chardev "file,id=semi,path=$out/stdout.txt" \
  -semihosting-config enable=on,target=native,chardev=semi \
  -accel tcg,one-insn-per-tb=on -d exec,nochain -D "$out/trace.txt" \
  -kernel "$out/$bench.elf"
grep -q '^DONE' "$out/stdout.txt" || { echo "$bench: the firmware did not finish (see $out/stdout.txt)" >&2; exit 1; }
arm-none-eabi-nm -S "$out/$bench.elf" >"$out/nm.txt"
arm-none-eabi-objdump -d "$out/$bench.elf" >"$out/objdump.txt"
echo "$bench: $(wc -l <"$out/trace.txt") trace lines in $out" >&2
