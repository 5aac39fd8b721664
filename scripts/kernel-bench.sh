#!/usr/bin/env bash
# The kernel bench (src/bin/kernel-bench.rs): the device's estimator
# kernels on their built-in inputs, traced in QEMU (machine b-l475e-iot01a,
# the chip itself; scripts/trace-bench.sh). `host-tools tradeoff --qemu`
# calls it and reads OUTDIR:
#   kernel-bench.elf   the firmware
#   stdout.txt         what the firmware printed (segments, inputs, results)
#   trace.txt          QEMU's execution trace
#   nm.txt             symbol table with sizes (arm-none-eabi-nm -S)
#   objdump.txt        disassembly (for the cycle estimate by instruction class)
#
#   scripts/kernel-bench.sh [OUTDIR]      default OUTDIR: target/kernel-bench
BENCH_INPUT=none exec bash "$(dirname "$0")/trace-bench.sh" kernel-bench "$@"
