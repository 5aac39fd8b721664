#!/usr/bin/env bash
# Runs every test of the project, installing what the tests need first.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-test-deps.sh
# Firmware first (warning-free builds, clippy, size and budget): it also builds
# the QEMU firmware the QEMU tests below reuse, and cargo test's summary stays
# the last thing printed.
echo "[test] firmware: builds, clippy, size and flash/RAM budget"
bash scripts/check-firmware.sh
echo "[test] host, host simulation and QEMU tests"
cargo test --workspace --release
