#!/usr/bin/env bash
# Installs everything zerog needs to build, test and run its demo on Debian 12.
# Idempotent: apt-get skips what is already installed. Run as root (or with sudo).
set -euo pipefail
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; else SUDO=; fi
packages=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libceres-dev
  libgtest-dev libgmock-dev googletest libbenchmark-dev
  libcli11-dev nlohmann-json3-dev libtomlplusplus-dev
  python3 python3-numpy python3-matplotlib
  clang-format
  # the fuzz targets (tests/fuzz, scripts/fuzz.sh): clang with libFuzzer and the sanitizers
  clang libclang-rt-14-dev
  # telemetry (Cyclone DDS, idlc) and the PLC interface (libmodbus; mbpoll as the test client)
  cyclonedds-dev cyclonedds-tools libmodbus-dev mbpoll python3-venv
  # the install test checks the systemd unit (systemd-analyze verify)
  systemd
  # vcan VM tests
  qemu-system-x86 busybox-static linux-image-amd64 xz-utils cpio iproute2 can-utils
)
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${packages[@]}"

# The independent DDS subscriber of the telemetry tests: Python's cyclonedds from PyPI (its wheel
# bundles its own Cyclone C library, so the wire types are checked against a second build).
# `zerog import --bag` reads ROS 2 bags (sqlite3, MCAP) with PyPI's pure-Python rosbags (no ROS
# installation; host/io/bag_to_csv.py).
venv="$(cd "$(dirname "$0")/.." && pwd)/.venv"
if ! "$venv/bin/python" -c 'import cyclonedds, rosbags' 2>/dev/null; then
  [ -x "$venv/bin/python" ] || /usr/bin/python3 -m venv "$venv"
  "$venv/bin/pip" install -q --disable-pip-version-check 'cyclonedds==11.0.1' 'rosbags==0.11.9'
fi
