#!/usr/bin/env bash
# Installs the dependencies, builds zerog with warnings as errors, and runs every test (ctest):
#   1. the CI build (RelWithDebInfo, the release preset's optimisation: cmake/check_presets.py):
#      the hardware-in-the-loop tests (natively, in lockstep with the emulated rig), the VM tests
#      (SocketCAN in qemu), the host pipeline's end-to-end runs, the README figures' checks and
#      every unit test binary that stage 2 does not run. Each GoogleTest binary is compiled once
#      in CI: those stage 2 runs under the sanitizers are left out here (cmake/stage_targets.py
#      --covered-by asan), but alloc_guard_test and rt_test, whose checks differ without a
#      sanitizer (the allocation hooks through glibc, mlockall);
#   2. AddressSanitizer + UndefinedBehaviorSanitizer: the unit tests of what runs on the cabinet
#      PC and reads outside data, the socket, device and HIL tests, without the VM tests, the
#      offline identification and learning tests and the host pipeline's end-to-end numeric runs
#      (labels ident_test, growing_fit_test, learn_test, robot_import_test, cli_test,
#      discovery_test, diagnose_screening_test, insight_loop_test, events_test, uncertainty_test,
#      table_diagnosis_test,
#      results_test, recordings_test, servo_cli_test),
#      the host CLI's end-to-end scripts (label host_cli: install, bag import, zerog watch), the
#      pure Python tests (label python_only: nothing to instrument) and the other HIL motion
#      seeds; the exclusions are in CMakePresets.json (test preset `asan`) and all run in stage 1;
#      this stage compiles only the binaries its tests use (cmake/stage_targets.py), like stage 3,
#      and its HIL runs take `zerog export` from stage 1's tree;
#   3. ThreadSanitizer: the threaded tests (rings, runtime, cycle, Modbus server, telemetry);
#   4. the fuzz targets, each for a bounded time (scripts/fuzz.sh).
# Any failure, sanitizer finding or fuzz crash fails the run. Each stage prints its duration, and
# the run ends with a table of them (CI has 90 minutes; scripts/fresh_machine.sh measures a run
# from a fresh clone).
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc)
start=$(date +%s)
stage_start=$start
summary=()
# Closes the running stage, named $1: its duration goes to the log and the final table.
stage_done() {
  local now
  now=$(date +%s)
  summary+=("$(printf '%-28s %5d s' "$1" $((now - stage_start)))")
  echo "=== test.sh: $1 took $((now - stage_start)) s ($((now - start)) s so far) ==="
  stage_start=$now
}
trap 'echo "=== test.sh: ran for $(( $(date +%s) - start )) s"; printf "  %s\n" "${summary[@]}"' EXIT

bash scripts/install-deps.sh
stage_done "dependencies"
python3 cmake/check_presets.py CMakePresets.json
cmake --preset ci
# The sanitizer stages build only what their test presets select (cmake/stage_targets.py derives
# the targets from ctest and the build tree: the asan preset's exclusions are not compiled).
# The HIL runs there take `zerog export` from the CI tree (ZEROG_HIL_HOST_CLI): the programs under
# test are zerog-rt and zerog-emu, and the host CLI's own tests under ASan are not in that stage.
# Configured first: stage 1 leaves out the GoogleTest binaries stage 2 runs.
cmake --preset asan -DZEROG_HIL_HOST_CLI="$(pwd)/build/ci/host/cli/zerog"
covered=(--covered-by asan --covered-build-dir build/asan --keep alloc_guard_test,rt_test)
ci_targets=$(python3 cmake/stage_targets.py --preset ci --build-dir build/ci "${covered[@]}")
ci_skip=$(python3 cmake/stage_targets.py --preset ci --build-dir build/ci "${covered[@]}" --labels)
echo "test.sh: ci builds" $ci_targets
echo "test.sh: ci leaves to the asan stage the binaries $ci_skip"
cmake --build --preset ci -j "$jobs" --target $ci_targets
stage_done "build ci"
# One test more than the cores: a few tests wait on sockets, ptys and the wall clock.
ctest --preset ci -j $((jobs + 1)) -LE "$ci_skip"
# The size check's list (every function over 120 lines, every class over 30 data members, the
# known offenders) in the log; ctest `sizes` above has checked it (docs/layout.md).
python3 scripts/check_sizes.py
stage_done "tests ci (HIL, VM included)"

asan_targets=$(python3 cmake/stage_targets.py --preset asan --build-dir build/asan)
echo "test.sh: asan builds" $asan_targets
cmake --build --preset asan -j "$jobs" --target $asan_targets
stage_done "build asan"
ctest --preset asan -j "$jobs"
stage_done "tests asan"

cmake --preset tsan
tsan_targets=$(python3 cmake/stage_targets.py --preset tsan --build-dir build/tsan)
echo "test.sh: tsan builds" $tsan_targets
cmake --build --preset tsan -j "$jobs" --target $tsan_targets
stage_done "build tsan"
ctest --preset tsan -j "$jobs"
stage_done "tests tsan"

bash scripts/fuzz.sh
stage_done "fuzz (build and run)"
