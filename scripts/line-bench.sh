#!/usr/bin/env bash
# The line bench (src/bin/line-bench.rs): the measurement's per-line device
# path by stage, traced in QEMU (scripts/trace-bench.sh). Its input,
# target/line-bench/data.bin, is written by `host-tools rate`, which calls
# this script and counts OUTDIR.
#
#   scripts/line-bench.sh [OUTDIR]      default OUTDIR: target/line-bench
exec bash "$(dirname "$0")/trace-bench.sh" line-bench "$@"
