#!/usr/bin/env bash
# Runs every test of the project, installing what the tests need first.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-test-deps.sh
echo "[test] code style (cargo fmt --check, rustfmt.toml)"
cargo fmt --all -- --check
# Firmware first (warning-free builds, clippy, size and budget): it also builds
# the QEMU firmware the QEMU tests below reuse, and cargo test's summary stays
# the last thing printed.
echo "[test] firmware: builds, clippy, size and flash/RAM budget"
bash scripts/check-firmware.sh
echo "[test] board tests: build for the chip; run only when a debug probe is attached"
bash scripts/board-test.sh
echo "[test] clippy on the host crates (-D warnings)"
cargo clippy --workspace --release --all-targets -q -- -D warnings
# The API docs: broken intra-doc links and bad markup fail the run (about a
# minute and a half on a cold cache: rustdoc checks the dependencies' metadata).
echo "[test] API docs (cargo doc, warnings denied)"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps -q
echo "[test] host, host simulation and QEMU tests"
log=$(mktemp)
trap 'rm -f "$log"' EXIT
set +e
cargo test --workspace --release 2>&1 | tee "$log"
status=${PIPESTATUS[0]}
set -e
# cargo's last lines are doc-test runs with nothing to run; close with the
# totals over every test binary so the summary says what actually ran.
awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i } }
     END { printf "tests: %d passed, %d failed\n", p, f }' "$log"
exit "$status"
