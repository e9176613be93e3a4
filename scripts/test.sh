#!/usr/bin/env bash
# Installs the dependencies, builds zerog with warnings as errors, and runs every test (ctest):
#   1. the CI build (RelWithDebInfo): the whole suite, VM and hardware-in-the-loop tests included;
#   2. AddressSanitizer + UndefinedBehaviorSanitizer: the whole suite again except the VM tests
#      (they run the same programs in qemu; twice would double CI's longest part);
#   3. ThreadSanitizer: the threaded tests (rings, runtime, cycle, Modbus server, telemetry);
#   4. the fuzz targets, each for a bounded time (scripts/fuzz.sh).
# Any failure, sanitizer finding or fuzz crash fails the run.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc)
bash scripts/install-deps.sh
cmake --preset ci
cmake --build --preset ci -j "$jobs"
ctest --preset ci -j "$jobs"

cmake --preset asan
cmake --build --preset asan -j "$jobs"
ctest --preset asan -j "$jobs"

cmake --preset tsan
cmake --build --preset tsan -j "$jobs" --target rtio_test rt_test loop_test modbus_test \
  telemetry_test zerog-rt
ctest --preset tsan -j "$jobs"

bash scripts/fuzz.sh
