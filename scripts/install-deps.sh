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
  # vcan VM tests
  qemu-system-x86 busybox-static linux-image-amd64 xz-utils cpio iproute2 can-utils
)
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${packages[@]}"
