#!/usr/bin/env bash
# Fuzz campaign over every cargo-fuzz target in tests/fuzz/ (nightly), one at
# a time and niced, then a table: target, executions, time, crashes.
#
#   scripts/fuzz-campaign.sh                 # -runs=10000000 per target
#   scripts/fuzz-campaign.sh --runs N        # N executions per target
#   scripts/fuzz-campaign.sh SECONDS         # SECONDS per target instead
#   scripts/fuzz-campaign.sh --max-time S    # 1e7 executions or S seconds, whichever first
#   TARGETS="store_ops blob_parse" scripts/fuzz-campaign.sh ...   # a subset
#
# The campaign grows a scratch corpus (tests/fuzz/work/<target>/, not checked
# in) from the checked-in seeds (tests/fuzz/corpus/<target>/). Crashes land in
# tests/fuzz/artifacts/<target>/: minimise one with
#   cargo +nightly fuzz tmin --fuzz-dir tests/fuzz -s none TARGET FILE
# then fix it, copy it to tests/fuzz/regressions/<target>/ and add a named
# unit test beside the code; `cargo test` replays regressions/ and corpus/
# (tests/fuzz_replay.rs). To refresh the checked-in corpus from a campaign:
#   cargo +nightly fuzz cmin --fuzz-dir tests/fuzz -s none TARGET tests/fuzz/work/TARGET
# and copy the survivors back (keep it to tens of files).
#
# SANITIZER (default none: the code under test is safe Rust apart from the
# simulated flash's mapping, and two shared cores favour throughput) can be
# set to address for a slower run under ASan.
set -euo pipefail
cd "$(dirname "$0")/.."

FUZZ_DIR=tests/fuzz
SANITIZER=${SANITIZER:-none}
ALL_TARGETS="frame_decode frame_reader blob_parse store_ops scene_toml prior_file"
TARGETS=${TARGETS:-$ALL_TARGETS}

runs=10000000
limit=()
while [ $# -gt 0 ]; do
    case "$1" in
        --runs) runs="${2:?--runs needs a number}"; shift 2 ;;
        --max-time) limit+=(-max_total_time="${2:?--max-time needs seconds}"); shift 2 ;;
        *[!0-9]*|"") echo "usage: $0 [SECONDS_PER_TARGET | --runs N] [--max-time SECONDS]" >&2; exit 2 ;;
        *) limit+=(-max_total_time="$1"); runs=; shift ;;
    esac
done
[ -n "$runs" ] && limit+=(-runs="$runs")

if ! rustup toolchain list | grep -q '^nightly'; then
    echo "the fuzz campaign needs a nightly toolchain (rustup toolchain install nightly)" >&2
    exit 1
fi
if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "installing cargo-fuzz" >&2
    cargo install cargo-fuzz
fi

nice -n 10 cargo +nightly fuzz build --fuzz-dir "$FUZZ_DIR" -s "$SANITIZER"

logs=$FUZZ_DIR/work/logs
mkdir -p "$logs"
rows=()
failed=0
for t in $TARGETS; do
    work=$FUZZ_DIR/work/$t
    mkdir -p "$work" "$FUZZ_DIR/artifacts/$t"
    log=$logs/$t.log
    before=$(find "$FUZZ_DIR/artifacts/$t" -type f | wc -l)
    start=$(date +%s)
    set +e
    # One process per target: the first crash ends that target's run (and is
    # reported), the campaign goes on with the next target.
    nice -n 10 cargo +nightly fuzz run --fuzz-dir "$FUZZ_DIR" -s "$SANITIZER" "$t" "$work" "$FUZZ_DIR/corpus/$t" \
        -- "${limit[@]}" -print_final_stats=1 >"$log" 2>&1
    rc=$?
    set -e
    secs=$(( $(date +%s) - start ))
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
    if [ -z "$execs" ]; then
        execs=$(grep -o '^#[0-9]*' "$log" | tail -1 | tr -d '#')
    fi
    # New crash/timeout/leak/oom inputs this run wrote.
    crashes=$(( $(find "$FUZZ_DIR/artifacts/$t" -type f | wc -l) - before ))
    [ "$rc" -ne 0 ] && failed=1
    rate=$(( ${execs:-0} / (secs > 0 ? secs : 1) ))
    rows+=("$(printf '%-14s %14s %8ss %10s %8s' "$t" "${execs:-?}" "$secs" "$rate" "$crashes")")
done

printf '%-14s %14s %9s %10s %8s\n' target executions time execs/s crashes
printf '%s\n' "${rows[@]}"
echo "logs: $logs/; crash inputs: $FUZZ_DIR/artifacts/<target>/"
exit $failed
