#!/usr/bin/env bash
# Builds the libFuzzer targets (preset `fuzz`: clang, ASan + UBSan, warnings as errors) and runs
# each for a bounded time on a copy of its seed corpus (tests/fuzz/corpus/<target>, copied to
# build/fuzz/fuzz-corpus/<target>, which keeps growing from run to run; the repository is not
# modified). Any crash, leak, undefined behaviour, timeout or out-of-memory fails the run, naming
# the target and the input that shows it.
#
#   scripts/fuzz.sh                       # every target, FUZZ_SECONDS (default 7) s each
#   FUZZ_SECONDS=300 scripts/fuzz.sh rsi  # one target (or several), longer
#
# Prints one line per target: executions, coverage (cov: edges, ft: features) and corpus size
# from libFuzzer's final statistics. tests/fuzz/README.md says how to reproduce a finding.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
seconds=${FUZZ_SECONDS:-7}
all_targets=(rsi stim300_stream netcanoem_frames candump modbus_request log_csv rig_toml effect_file
             import_mapping model_file deploy_file rt_config)
if [ $# -gt 0 ]; then targets=("$@"); else targets=("${all_targets[@]}"); fi
for t in "${targets[@]}"; do
  if [ ! -d "tests/fuzz/corpus/$t" ]; then
    echo "fuzz.sh: unknown target '$t' (known: ${all_targets[*]})" >&2
    exit 2
  fi
done

cmake --preset fuzz >/dev/null
cmake --build --preset fuzz -j "${FUZZ_JOBS:-$(nproc)}"

build=$root/build/fuzz
work=$build/fuzz-work
mkdir -p "$work"
# The file-reading targets write their inputs here (RAM); libFuzzer's exit skips their cleanup.
scratch=$(mktemp -d /dev/shm/zerog-fuzz-run-XXXXXX)
trap 'rm -rf "$scratch"' EXIT
export ZEROG_FUZZ_SCRATCH=$scratch
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:strict_string_checks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}

# One target: runs it and writes its report (the lines printed below) to $build/fuzz-logs/$t.result;
# exit 1 if it found something.
run_target() {
  local t=$1 corpus=$build/fuzz-corpus/$1 artifacts=$build/fuzz-artifacts/$1
  local log=$build/fuzz-logs/$1.log result=$build/fuzz-logs/$1.result
  mkdir -p "$corpus" "$artifacts" "$(dirname "$log")"
  cp -n "tests/fuzz/corpus/$t"/* "$corpus"/ 2>/dev/null || true
  local rc=0
  # Run in a scratch folder: libFuzzer's -fork/-merge temporaries and stray files stay there.
  (cd "$work" && "$build/tests/fuzz/${t}_fuzz" -max_total_time="$seconds" -timeout=5 \
     -rss_limit_mb=2048 -malloc_limit_mb=1024 -detect_leaks=1 -print_final_stats=1 \
     -artifact_prefix="$artifacts/" "$corpus") >"$log" 2>&1 || rc=$?
  local stats execs cov ft files bytes artifact
  stats=$(grep -E '^#[0-9]+[[:space:]]+DONE' "$log" | tail -1 || true)
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  cov=$(sed -nE 's/.*cov: ([0-9]+).*/\1/p' <<<"$stats")
  ft=$(sed -nE 's/.*ft: ([0-9]+).*/\1/p' <<<"$stats")
  files=$(find "$corpus" -type f | wc -l)
  bytes=$(du -sb "$corpus" | cut -f1)
  if [ "$rc" -ne 0 ]; then
    artifact=$(sed -nE 's/.*Test unit written to (.*)$/\1/p' "$log" | tail -1)
    { echo "FAIL $t: libFuzzer exit $rc; input: ${artifact:-none written}; log: $log"
      grep -E 'ERROR: |SUMMARY: |runtime error|property violated|undocumented|deadly signal' \
        "$log" | head -8 | sed 's/^/    /'; } >"$result"
    return 1
  fi
  printf 'ok   %-17s %9s execs  cov: %-5s ft: %-6s corpus: %s files, %s bytes\n' "$t" \
    "${execs:-?}" "${cov:-?}" "${ft:-?}" "$files" "$bytes" >"$result"
}

# Each target is one single-threaded process: FUZZ_JOBS (default: the cores) of them at a time,
# so the stage takes (targets / cores) × FUZZ_SECONDS, each target still its full time.
parallel=${FUZZ_JOBS:-$(nproc)}
declare -A pid_of
running=0
mkdir -p "$build/fuzz-logs"
for t in "${targets[@]}"; do
  rm -f "$build/fuzz-logs/$t.result"
  if [ "$running" -ge "$parallel" ]; then
    wait -n || true
    running=$((running - 1))
  fi
  run_target "$t" &
  pid_of[$t]=$!
  running=$((running + 1))
done
failed=()
for t in "${targets[@]}"; do
  # The report file, not wait's status, decides: `wait -n` above may have reaped the job.
  wait "${pid_of[$t]}" 2>/dev/null || true
  result=$build/fuzz-logs/$t.result
  if [ ! -s "$result" ]; then
    echo "FAIL $t: no report (the run was killed?); log: $build/fuzz-logs/$t.log"
    failed+=("$t")
    continue
  fi
  cat "$result"
  if ! grep -q '^ok ' "$result"; then failed+=("$t"); fi
done

if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: ${#failed[@]} of ${#targets[@]} targets found a problem: ${failed[*]}" \
       "(reproduce: build/fuzz/tests/fuzz/<target>_fuzz <input>; tests/fuzz/README.md)"
  exit 1
fi
echo "fuzz: ${#targets[@]} targets ran ${seconds} s each, no finding"
