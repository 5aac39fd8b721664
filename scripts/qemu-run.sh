#!/usr/bin/env bash
# Runs the QEMU firmware (an ELF built with `cargo qemu-fw`) behind its
# bootloader (`cargo qemu-bootloader`, built here if missing) on QEMU's
# b-l475e-iot01a machine, with USART1 (the instrument's link) as a TCP serial
# server on 127.0.0.1 and semihosting on (firmware panics print and exit).
#
#   scripts/qemu-run.sh [ELF]            default ELF: target/thumbv7em-none-eabihf/firmware/qemu-fw
#   QEMU_PORT=4555      TCP port of the serial (127.0.0.1 only)
#   QEMU_TIMEOUT=3600   seconds before QEMU is stopped (it always runs under timeout)
#   QEMU_EXTRA="..."    extra QEMU arguments (e.g. tracing for scripts/qemu-icount.sh)
#
# Also the cargo runner of `cargo qemu-run` (.cargo/config.toml), which passes the ELF.
set -euo pipefail
cd "$(dirname "$0")/.."
elf=${1:-target/thumbv7em-none-eabihf/firmware/qemu-fw}
port=${QEMU_PORT:-4555}
[ -f "$elf" ] || { echo "qemu-run: no firmware at $elf: build it with 'cargo qemu-fw'" >&2; exit 2; }
boot=$(dirname "$(dirname "$elf")")/qemu-bootloader/bootloader
[ -f "$boot" ] || cargo qemu-bootloader >&2
command -v qemu-system-arm >/dev/null || { echo "qemu-run: qemu-system-arm not found: run scripts/install-test-deps.sh" >&2; exit 2; }
echo "qemu-run: instrument serial on tcp 127.0.0.1:$port (e.g. host-tools info --tcp 127.0.0.1:$port)" >&2
# shellcheck disable=SC2086
exec timeout --foreground "${QEMU_TIMEOUT:-3600}" qemu-system-arm \
  -machine b-l475e-iot01a -display none -monitor none \
  -serial "tcp:127.0.0.1:$port,server=on,wait=off" \
  -semihosting-config enable=on,target=native \
  -kernel "$boot" -device "loader,file=$elf" ${QEMU_EXTRA:-}
