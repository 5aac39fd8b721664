#!/usr/bin/env bash
# Runs every test of the project, installing what the tests need first.
# Each stage says how long it took, and the run closes with the table of them:
# the whole run is to stay under about 20 minutes on 2 cores from a fresh
# clone, and this is where to see which stage a slower run spent it in.
set -euo pipefail
cd "$(dirname "$0")/.."

stage_names=()
stage_seconds=()
# stage NAME COMMAND...: runs COMMAND under "[test] NAME", records its time
# and returns its status.
stage() {
  local name=$1 start=$SECONDS rc=0
  shift
  echo "[test] $name"
  "$@" || rc=$?
  stage_names+=("$name")
  stage_seconds+=($((SECONDS - start)))
  echo "[test] $name: $((SECONDS - start)) s$([ "$rc" = 0 ] || echo ", FAILED")"
  return "$rc"
}
# On the way out, after a failed stage too (then the failing one is the last
# listed): the time by stage, then the totals over every test binary that ran
# (cargo's last lines are doc-test runs with nothing to run, so the summary
# says what actually ran).
finish() {
  echo "[test] time by stage:"
  for i in "${!stage_names[@]}"; do
    printf '  %5d s  %s\n' "${stage_seconds[$i]}" "${stage_names[$i]}"
  done
  printf '  %5d s  in all\n' "$SECONDS"
  if [ -s "$log" ]; then
    awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i } }
         END { printf "tests: %d passed, %d failed\n", p, f }' "$log"
  fi
  rm -f "$log"
}
log=$(mktemp)
trap finish EXIT

stage "what the tests need (scripts/install-test-deps.sh)" bash scripts/install-test-deps.sh
stage "code style (cargo fmt --check, rustfmt.toml)" cargo fmt --all -- --check
# Firmware first (warning-free builds, clippy, size and budget): it also builds
# the QEMU firmware the QEMU tests below reuse.
stage "firmware: builds, clippy, size and flash/RAM budget" bash scripts/check-firmware.sh
stage "board tests: build for the chip; run only when a debug probe is attached" bash scripts/board-test.sh
# Clippy in the dev profile: the API docs below then reuse the dependencies'
# metadata it checked (measured from cold: clippy 79 s, then the docs 17 s;
# with clippy in release the docs took 69 s, checking them all again).
stage "clippy on the host crates (-D warnings)" cargo clippy --workspace --all-targets -q -- -D warnings
# The API docs: broken intra-doc links and bad markup fail the run.
RUSTDOCFLAGS="-D warnings" stage "API docs (cargo doc, warnings denied)" cargo doc --workspace --no-deps -q

# cargo test's output is kept for the totals above; its status is cargo's.
cargo_tests() {
  cargo test --workspace --release 2>&1 | tee "$log"
  return "${PIPESTATUS[0]}"
}
stage "host, host simulation and QEMU tests" cargo_tests
