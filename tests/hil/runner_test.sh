#!/usr/bin/env bash
# runner_test.sh BUILD_DIR WORK_DIR [--zerog PATH]
#
# The HIL runner (hil.sh) stops as soon as one side has failed (issue 26): a zerog-rt that exits
# with a start-up error (zerog-rt --test-mutant exit_at_start) must fail the run within 10 s,
# naming zerog-rt and its last message, and leave no emulator behind. Before, the emulator waited
# 120 s for the hello of a zerog-rt that was gone.
#
# The check has its own mutant: a copy of tests/hil with the early stop removed from hil.sh must
# NOT fail within the same 10 s (the run is cut at 15 s). If it did, this test could not tell an
# early stop from a slow one.
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
bin=$1 work=$2
shift 2
extra=("$@")  # --zerog PATH, passed on to hil.sh
rm -rf "$work" && mkdir -p "$work"
limit=10

# One run of hil.sh ($1) with the exit_at_start mutant; prints the seconds it took, its status
# and keeps its stderr in $2. Cut at 15 s (timeout), which counts as "not stopped early".
run_mutant() {
  local script=$1 err=$2 t0 t1 st
  t0=$(date +%s.%N)
  timeout -s KILL 15 "$script" --bin "$bin" --out "$work/$(basename "$err" .err)" \
    --mutant exit_at_start "${extra[@]}" push >/dev/null 2>"$err"
  st=$?
  t1=$(date +%s.%N)
  awk -v a="$t0" -v b="$t1" -v s="$st" 'BEGIN { printf "%.1f %d\n", b - a, s }'
}

fail=0
read -r took status < <(run_mutant "$here/hil.sh" "$work/real.err")
echo "hil.sh with a zerog-rt that exits at start: status $status after $took s"
if [ "$status" -eq 0 ] || [ "$status" -eq 137 ]; then
  echo "FAIL: the run did not fail by itself (status $status)"; fail=1
fi
if ! awk -v t="$took" -v l="$limit" 'BEGIN { exit !(t < l) }'; then
  echo "FAIL: it took $took s, not under $limit s"; fail=1
fi
if ! grep -q "zerog-rt exited 2: zerog-rt: test mutant exit_at_start" "$work/real.err"; then
  echo "FAIL: the runner did not name zerog-rt and its last message; it said:"
  cat "$work/real.err"; fail=1
fi
if pgrep -f "zerog-emu --scenario $work/" >/dev/null; then
  echo "FAIL: an emulator of this run is still running"; pkill -KILL -f "zerog-emu --scenario $work/"
  fail=1
fi

# The mutant of the runner: the same tests/hil with the early stop switched off.
mutant=$work/mutant-hil
cp -r "$here" "$mutant"
grep -q '^  if \[ "\$first_status" -ne 0 \]; then$' "$mutant/hil.sh" \
  || { echo "FAIL: hil.sh no longer has the early stop this test's mutant removes"; exit 1; }
sed -i 's/^  if \[ "\$first_status" -ne 0 \]; then$/  if false; then/' "$mutant/hil.sh"
read -r took_m status_m < <(run_mutant "$mutant/hil.sh" "$work/mutant.err")
pkill -KILL -f "zerog-emu --scenario $work/" 2>/dev/null
echo "the runner's mutant (no early stop): status $status_m after $took_m s"
if awk -v t="$took_m" -v l="$limit" 'BEGIN { exit !(t < l) }'; then
  echo "FAIL: the mutant without the early stop also ended within $limit s: this test cannot" \
    "see the early stop"
  fail=1
fi
[ $fail -eq 0 ] && echo "runner_test: PASS" || echo "runner_test: FAIL"
exit $fail
