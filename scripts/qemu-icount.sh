#!/usr/bin/env bash
# Counts, exactly, the instructions the estimation kernel executes per point on
# the Cortex-M4F in QEMU, and reports instructions per multiply-accumulate.
#
# How: QEMU runs the QEMU firmware with one instruction per translation block
# and logs every block executed (-d exec,nochain); each log line names the
# function the instruction belongs to (QEMU reads the ELF's symbols), so the
# lines in `point_kernel` (the kernel's one non-inlined symbol, n x m MACs
# per call) are the kernel's executed instructions. The firmware is driven by
# `host-tools qemu --demo ... --measure-and-exit LINES` (train, provision,
# load a scene, measure), and the count is divided by the points measured.
#
# It also counts the whole per-point estimation path: the instructions of
# `Calibration::estimate_pixel` (not inlined) and of every function it calls
# (matrix selection, the kernel, cluster selection, the scale, the
# out-of-prior statistic and the gloss readings), per call; with a scale-free demo calibration this
# is the cost the scale-free estimators add to the plain kernel.
#
#   scripts/qemu-icount.sh [LINES] [wiener|scale-free|scale-free-piecewise]
#   (default 1 line = 32 points, Wiener)
set -euo pipefail
cd "$(dirname "$0")/.."
lines=${1:-1}
estimator=${2:-wiener}
cargo qemu-fw >&2
cargo build --release -p host-tools >&2
elf=target/thumbv7em-none-eabihf/firmware/qemu-fw
sym=$(arm-none-eabi-nm -S "$elf" | awk '/point_kernel/ {print $4}')
[ -n "$sym" ] || { echo "icount: no point_kernel symbol in $elf" >&2; exit 1; }
read -r start size < <(arm-none-eabi-nm -S "$elf" | awk '/point_kernel/ {print $1, $2}')
echo "icount: kernel symbol $sym at 0x$start, $((16#$size)) bytes" >&2
path_sym=$(arm-none-eabi-nm -S "$elf" | awk '/estimate_pixel/ {print $4}')
[ -n "$path_sym" ] || { echo "icount: no estimate_pixel symbol in $elf" >&2; exit 1; }
read -r path_start _ < <(arm-none-eabi-nm -S "$elf" | awk '/estimate_pixel/ {print $1, $2}')
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkfifo "$work/trace"
# Per call of the kernel (a call starts at its first address), the number of
# "Trace" lines in it. When an interrupt arrives, QEMU logs the block it was
# about to run, takes the interrupt, then logs and runs that block again: the
# same kernel address twice in a row (interrupt code may come between), which
# the kernel never does (it has no branch to itself, and consecutive calls end
# on a return, not on the entry), so a repeat is dropped. Every call then
# counts the same, exactly.
# The whole path: every traced instruction in estimate_pixel or a function it
# calls (by symbol), a new call at estimate_pixel's first address.
# QEMU names a traced instruction's function only for the ELF it was given
# with -kernel (the bootloader, now): the counts go by address ranges from
# the application's own symbol table instead, as 8-digit hex strings (the
# trace's form), which compare in address order.
hex_range() { printf "%08x:%08x" "$((16#$1))" "$((16#$1 + 16#$2))"; }
kernel_range=$(hex_range "$start" "$size")
path_ranges=""
while read -r a sz _ name; do
  path_ranges+="$(hex_range "$a" "$sz") "
done < <(arm-none-eabi-nm -S "$elf" | awk '$4 ~ /estimate_pixel|point_kernel|matrix_of|select_cluster|scale_free|gloss/ && NF == 4')
awk -v kr="$kernel_range" -v pr="$path_ranges" -v st="$(printf %08x "$((16#$start))")" -v pst="$(printf %08x "$((16#$path_start))")" -v calls="$work/calls" -v paths="$work/paths" '
  BEGIN { split(kr, k, ":"); nr = split(pr, r, " "); for (i = 1; i <= nr; i++) { split(r[i], b, ":"); lo[i] = b[1]; hi[i] = b[2] } }
  /^Trace / {
    split($0, f, "/"); pc = tolower(substr(f[2], length(f[2]) - 7))
    if (pc == last) next
    last = pc
    if (pc >= k[1] && pc < k[2]) {
      if (pc == st) { if (n) print n > calls; n = 0 }
      n++
    }
    if (pc == pst) { if (p) print p > paths; p = 0; inpath = 1 }
    if (inpath) { for (i = 1; i <= nr; i++) if (pc >= lo[i] && pc < hi[i]) { p++; break } }
  }
  END { if (n) print n > calls; if (p) print p > paths }' "$work/trace" &
counter=$!
out=$(./target/release/host-tools qemu --elf "$elf" --port "${QEMU_PORT:-4571}" --minutes 20 \
  --demo "$work/demo.blob" --demo-estimator "$estimator" --measure-and-exit "$lines" \
  --qemu-arg=-accel --qemu-arg=tcg,one-insn-per-tb=on \
  --qemu-arg=-d --qemu-arg=exec,nochain --qemu-arg=-D --qemu-arg="$work/trace")
wait "$counter" || true
echo "$out" >&2
points=$(echo "$out" | sed -n 's/^measured .*: \([0-9]*\) points, \([0-9]*\) multiply-accumulates$/\1/p')
macs=$(echo "$out" | sed -n 's/^measured .*: \([0-9]*\) points, \([0-9]*\) multiply-accumulates$/\2/p')
[ -n "$points" ] && [ "$points" -gt 0 ] || { echo "icount: the measurement did not complete" >&2; exit 1; }
calls=$(wc -l < "$work/calls")
[ "$calls" -eq "$points" ] || { echo "icount: $calls kernel calls for $points points" >&2; exit 1; }
echo "instructions per call (count x calls):" $(sort -n "$work/calls" | uniq -c | awk '{printf "%sx%s ", $2, $1}')
distinct=$(sort -u "$work/calls" | wc -l)
[ "$distinct" -eq 1 ] || { echo "icount: calls differ in instruction count" >&2; exit 1; }
exact=$(head -1 "$work/calls")
echo "kernel: $exact instructions per point, every call (n x m = $((macs / points)) multiply-accumulates)"
awk -v c="$exact" -v m="$((macs / points))" 'BEGIN { printf "instructions per multiply-accumulate: %.3f\n", c / m }'
paths_n=$(wc -l < "$work/paths")
[ "$paths_n" -eq "$points" ] || { echo "icount: $paths_n estimation paths for $points points" >&2; exit 1; }
sort -n "$work/paths" | awk -v est="$estimator" '{ a[NR] = $1; s += $1 } END { printf "per-point estimation path (%s): min %d, median %d, max %d, mean %.1f instructions\n", est, a[1], a[int((NR + 1) / 2)], a[NR], s / NR }'
