#!/usr/bin/env bash
# Installs what the test suite needs when it is missing: the Cortex-M4F Rust
# target, ARM binutils (size/objdump/nm for the firmware reports) and QEMU >= 10
# (the first release that emulates the b-l475e-iot01a machine). Idempotent:
# every step checks first, so a prepared machine pays nothing.
set -euo pipefail

need_apt_update=1
apt_install() {
  local sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  if [ $need_apt_update -eq 1 ]; then
    $sudo apt-get update -qq
    need_apt_update=0
  fi
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "$@" >/dev/null
}

if ! rustup target list --installed | grep -qx thumbv7em-none-eabihf; then
  echo "[deps] adding Rust target thumbv7em-none-eabihf"
  rustup target add thumbv7em-none-eabihf
fi
if ! rustup component list --installed 2>/dev/null | grep -q '^clippy'; then
  rustup component add clippy
fi
if ! rustup component list --installed 2>/dev/null | grep -q '^rustfmt'; then
  rustup component add rustfmt
fi

if ! command -v arm-none-eabi-size >/dev/null; then
  echo "[deps] installing binutils-arm-none-eabi"
  apt_install binutils-arm-none-eabi
fi

# Plot text (simulate, tradeoff) needs a TrueType font.
if ! fc-list 2>/dev/null | grep -qi 'dejavu\|liberation' && ! ls /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf >/dev/null 2>&1; then
  echo "[deps] installing fonts-dejavu-core (plot labels)"
  apt_install fonts-dejavu-core
fi

qemu_ok() {
  command -v qemu-system-arm >/dev/null &&
    qemu-system-arm -machine help 2>/dev/null | grep -q b-l475e-iot01a
}
if ! qemu_ok; then
  echo "[deps] installing qemu-system-arm >= 10 from bookworm-backports"
  . /etc/os-release
  if [ "${VERSION_CODENAME:-}" = "bookworm" ]; then
    src=/etc/apt/sources.list.d/bookworm-backports.sources
    if [ ! -f "$src" ]; then
      sudo_cmd=""; [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
      printf 'Types: deb\nURIs: http://deb.debian.org/debian\nSuites: bookworm-backports\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' \
        | $sudo_cmd tee "$src" >/dev/null
      need_apt_update=1
    fi
    apt_install -t bookworm-backports qemu-system-arm
  else
    apt_install qemu-system-arm
  fi
  qemu_ok || { echo "[deps] error: qemu-system-arm has no b-l475e-iot01a machine (need QEMU >= 10)" >&2; exit 1; }
fi
echo "[deps] ok: $(rustc --version), $(qemu-system-arm --version | head -1), $(arm-none-eabi-size --version | head -1)"
