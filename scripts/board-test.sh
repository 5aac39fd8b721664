#!/usr/bin/env bash
# The on-target tests and benchmark (tests/board/main.rs, defmt-test) for the
# B-L475E-IOT01A. Called by scripts/test-all.sh.
#
#  1. Always: builds them for thumbv7em-none-eabihf (`cargo board-tests-fw`)
#     with no warning, and clippy -D warnings (`cargo board-tests-clippy`).
#  2. Only when probe-rs is installed and `probe-rs list` finds a probe: runs
#     them on the board twice (`probe-rs run`, which flashes, resets and
#     prints the defmt log). The second run must find the calibration the
#     first one committed, intact after the reset. Otherwise it says plainly
#     why they were not run and succeeds: no board is attached to CI.
#
# probe-rs is not installed here (building it takes long): see docs/guide/board.md,
# "On-target tests". BOARD_TEST_CHIP overrides the chip (default STM32L475VGTx).
set -euo pipefail
cd "$(dirname "$0")/.."

chip=${BOARD_TEST_CHIP:-STM32L475VGTx}
log=$(mktemp)
trap 'rm -f "$log" "$log".*' EXIT

echo "[board] build the board tests (cargo board-tests-fw: test target board-tests, thumbv7em-none-eabihf)"
if ! cargo board-tests-fw >"$log" 2>&1; then
  cat "$log"
  echo "[board] FAILED: the board tests do not build" >&2
  exit 1
fi
# The one expected warning: the tests trust the DEVELOPMENT key on purpose
# (their calibration is signed with it).
if grep -vF 'trusts the DEVELOPMENT calibration key' "$log" | grep -qE '^(warning|error)(\[|:)'; then
  cat "$log"
  echo "[board] FAILED: the board tests build with warnings (warnings are errors for firmware)" >&2
  exit 1
fi
# The test binary's path (cargo names it with a hash): the same build again,
# now cached, asked for its artifacts.
elf=$(cargo board-tests-fw --message-format=json 2>/dev/null |
  grep -o '"executable":"[^"]*board_tests-[^"]*"' | tail -1 | sed 's/"executable":"\(.*\)"/\1/')
if [ -z "$elf" ] || [ ! -f "$elf" ]; then
  echo "[board] FAILED: cargo named no board-tests executable" >&2
  exit 1
fi
echo "[board] clippy (-D warnings)"
if ! cargo board-tests-clippy -- -D warnings >"$log" 2>&1; then
  cat "$log"
  echo "[board] FAILED: clippy is not clean for the board tests" >&2
  exit 1
fi
echo "[board] built $elf"
arm-none-eabi-size -B -d "$elf" 2>/dev/null | tail -1 || true

if ! command -v probe-rs >/dev/null; then
  echo "[board] SKIPPED running on the board: probe-rs is not installed (docs/guide/board.md, \"On-target tests\", says how)"
  exit 0
fi
if ! probes=$(probe-rs list 2>&1); then
  echo "$probes"
  echo "[board] SKIPPED running on the board: 'probe-rs list' failed (see above)"
  exit 0
fi
if ! grep -qE '^\[[0-9]+\]' <<<"$probes"; then
  echo "[board] SKIPPED running on the board: no debug probe attached ('probe-rs list': $(head -1 <<<"$probes"))"
  exit 0
fi
echo "[board] probe found: $(grep -E '^\[[0-9]+\]' <<<"$probes" | head -1)"

for run in 1 2; do
  echo "[board] run $run of 2: probe-rs run --chip $chip"
  set +e
  probe-rs run --chip "$chip" "$elf" 2>&1 | tee "$log.$run"
  status=${PIPESTATUS[0]}
  set -e
  if [ "$status" -ne 0 ] || ! grep -q 'all tests passed!' "$log.$run"; then
    echo "[board] FAILED: run $run (exit $status)" >&2
    exit 1
  fi
done
if ! grep -q 'survived the reset' "$log.2"; then
  echo "[board] FAILED: the second run did not find the first run's calibration intact after the reset" >&2
  exit 1
fi
echo "[board] measured on the board:"
grep -hE '^(.*\] )?(cycles|sensor|kernel|reset survival)' "$log.2" || true
echo "[board] ok: on-target tests passed twice, the calibration survived the reset"
