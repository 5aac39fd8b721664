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
  stage_names+=("$name$([ "$rc" = 0 ] || echo " (FAILED)")")
  stage_seconds+=($((SECONDS - start)))
  echo "[test] $name: $((SECONDS - start)) s$([ "$rc" = 0 ] || echo ", FAILED")"
  return "$rc"
}
# On the way out, after a failed stage too (marked FAILED; the host checks
# that ran beside the firmware are waited for first): the time by stage, then the totals over every test binary that ran
# (cargo's last lines are doc-test runs with nothing to run, so the summary
# says what actually ran).
finish() {
  host_checks_join || true
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

# Host clippy and the API docs check the host crates in a target directory of
# their own: nothing later reuses what they build, and cargo locks a target
# directory for the whole of each build, so in their own directory they run
# beside the firmware builds (whose fat-LTO links keep one core of two). Their
# output is held back and printed, with their stage times, once both are done.
host_checks_pid=
host_checks_log=$(mktemp)
host_checks() {
  stage_names=()
  stage_seconds=()
  trap 'for i in "${!stage_names[@]}"; do printf "%s\t%s\n" "${stage_seconds[$i]}" "${stage_names[$i]}"; done >"$host_checks_log.times"' EXIT
  export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-target}/host-checks"
  # Clippy in the dev profile: the API docs below then reuse the dependencies'
  # metadata it checked (measured from cold: clippy 79 s, then the docs 17 s;
  # with clippy in release the docs took 69 s, checking them all again).
  stage "clippy on the host crates (-D warnings; beside the firmware)" cargo clippy --workspace --all-targets -q -- -D warnings
  # The API docs: broken intra-doc links and bad markup fail the run.
  RUSTDOCFLAGS="-D warnings" stage "API docs (cargo doc, warnings denied; beside the firmware)" cargo doc --workspace --no-deps -q
}
# Waits for the host checks, prints their output and adds their stage times;
# fails when one of them failed. Also run on the way out after a failed stage.
host_checks_join() {
  [ -n "$host_checks_pid" ] || return 0
  local rc=0 seconds name
  wait "$host_checks_pid" || rc=$?
  host_checks_pid=
  cat "$host_checks_log"
  while IFS=$'\t' read -r seconds name; do
    stage_names+=("$name")
    stage_seconds+=("$seconds")
  done <"$host_checks_log.times"
  rm -f "$host_checks_log" "$host_checks_log.times"
  return "$rc"
}

stage "what the tests need (scripts/install-test-deps.sh)" bash scripts/install-test-deps.sh
stage "code style (cargo fmt --check, rustfmt.toml)" cargo fmt --all -- --check
host_checks >"$host_checks_log" 2>&1 &
host_checks_pid=$!
# Firmware first (warning-free builds, clippy, size and budget): it also builds
# the QEMU firmware the QEMU tests below reuse.
stage "firmware: builds, clippy, size and flash/RAM budget" bash scripts/check-firmware.sh
stage "board tests: build for the chip; run only when a debug probe is attached" bash scripts/board-test.sh
echo "[test] host clippy and API docs (run beside the firmware stages):"
host_checks_join

# cargo test's output is kept for the totals above; its status is cargo's.
cargo_tests() {
  cargo test --workspace --release 2>&1 | tee "$log"
  return "${PIPESTATUS[0]}"
}
stage "host, host simulation and QEMU tests" cargo_tests
