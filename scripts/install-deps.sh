#!/usr/bin/env bash
# Installs everything zerog needs to build, test and run its demo on Debian 12.
# Idempotent: apt-get skips what is already installed. Run as root (or with sudo).
#   scripts/install-deps.sh          # everything scripts/test.sh needs (also the demo's)
#   scripts/install-deps.sh --demo   # only what scripts/demo.sh needs: the build of zerog,
#                                    # zerog-rt and zerog-emu, Python with numpy and matplotlib,
#                                    # and .venv with plotly (the report's interactive page)
set -euo pipefail
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; else SUDO=; fi
demo_only=0
case "${1:-}" in
  "") ;;
  --demo) demo_only=1 ;;
  *) echo "install-deps.sh: unknown option $1 (--demo: only the demo's packages)" >&2; exit 2 ;;
esac
# The demo: compilers, the libraries the three programs link, the report's Python. CMake's
# configure step looks for GoogleTest and Google Benchmark too (the release preset has tests).
packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libceres-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev nlohmann-json3-dev libtomlplusplus-dev
  python3 python3-numpy python3-matplotlib
  # python3-venv: the .venv below (plotly, for the report's interactive page)
  python3-venv
  # telemetry (Cyclone DDS, idlc) and the PLC interface (libmodbus)
  cyclonedds-dev cyclonedds-tools libmodbus-dev
)
if [ "$demo_only" = 0 ]; then
  packages+=(
    git googletest clang-format
    # the size check (scripts/check_sizes.py, ctest sizes): Universal Ctags measures functions
    universal-ctags
    # the fuzz targets (tests/fuzz, scripts/fuzz.sh): clang with libFuzzer and the sanitizers
    clang libclang-rt-14-dev
    # mbpoll: the Modbus test client
    mbpoll
    # the report's browser test (tests/report/test_report_browser.py): a real headless browser
    chromium chromium-driver
    # the install test checks the systemd unit (systemd-analyze verify)
    systemd
    # vcan VM tests
    qemu-system-x86 busybox-static linux-image-amd64 xz-utils cpio iproute2 can-utils
  )
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${packages[@]}"

# PyPI's packages go into the project's .venv (zerog finds its python there, or at $ZEROG_PYTHON).
# The demo's too: `zerog report` draws its interactive page (host/report/interactive_report.py)
# with plotly, which embeds plotly.js in the page (no CDN); without plotly the report is the
# static one and says why.
pypi=('plotly==7.1.0' 'numpy==2.4.6')
modules=plotly,numpy
if [ "$demo_only" = 0 ]; then
  # The independent DDS subscriber of the telemetry tests: Python's cyclonedds (its wheel
  # bundles its own Cyclone C library, so the wire types are checked against a second build).
  # `zerog import --bag` reads ROS 2 bags (sqlite3, MCAP) with the pure-Python rosbags (no ROS
  # installation; host/io/bag_to_csv.py), and writes the rig it found in the bag with tomli-w.
  # selenium drives the Debian chromium above in the report's browser test. `zerog export-mcap`
  # writes MCAP with PyPI's mcap (the format's reference library; rosbags gives the ROS 2
  # message definitions and the CDR), and the round-trip test opens the file with its reader.
  pypi+=('cyclonedds==11.0.1' 'rosbags==0.11.9' 'tomli-w==1.0.0' 'selenium==4.51.0' 'mcap==1.6.0')
  modules+=,cyclonedds,rosbags,tomli_w,selenium,mcap
fi
venv="$(cd "$(dirname "$0")/.." && pwd)/.venv"
if ! "$venv/bin/python" -c "import $modules" 2>/dev/null; then
  [ -x "$venv/bin/python" ] || /usr/bin/python3 -m venv "$venv"
  "$venv/bin/pip" install -q --disable-pip-version-check "${pypi[@]}"
fi
