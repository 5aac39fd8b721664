#!/usr/bin/env bash
# Runs every test of the project, installing what the tests need first.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-test-deps.sh
echo "[test] host, host simulation and QEMU tests"
cargo test --workspace --release
