#!/usr/bin/env bash
# The inspection bench (src/bin/inspect-bench.rs): correction, decision and
# verdict frame of a line against the estimation path, traced in QEMU
# (scripts/trace-bench.sh). Its input, target/inspect-bench/data.bin, is
# written by `host-tools inspect bench`, which calls this script and counts
# OUTDIR.
#
#   scripts/inspect-bench.sh [OUTDIR]      default OUTDIR: target/inspect-bench
exec bash "$(dirname "$0")/trace-bench.sh" inspect-bench "$@"
