#!/usr/bin/env bash
# ctest hil_mcap_roundtrip: a HIL run (hil.sh, case push, seed 11), its recording written as MCAP
# by `zerog export-mcap`, opened with PyPI's mcap reader and with rosbags, and read back with
# `zerog import --bag` to the recorder's run.csv, digit for digit (tests/hil/mcap_roundtrip.py);
# then the exporter's mutant (Fx and Fy swapped) must fail that round trip.
#   mcap_test.sh BUILD_DIR OUT_DIR --zerog ZEROG
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
bin=$1 out=$2 zerog=$4
py=$here/../../.venv/bin/python
"$py" -c 'import mcap, rosbags' 2>/dev/null || {
  echo "mcap_test: $py with mcap and rosbags is missing (scripts/install-deps.sh makes it)" >&2
  exit 1; }
"$here/hil.sh" --bin "$bin" --out "$out" --zerog "$zerog" --seed 11 push || {
  echo "mcap_test: the HIL run failed" >&2; exit 1; }
run=$out/push-seed11
"$py" "$here/mcap_roundtrip.py" --zerog "$zerog" --run "$run" || exit 1
if "$py" "$here/mcap_roundtrip.py" --zerog "$zerog" --run "$run" --mutant >"$run/mutant.txt" 2>&1; then
  cat "$run/mutant.txt"
  echo "mcap_test: the exporter's mutant (Fx, Fy swapped) PASSED the round trip" >&2
  exit 1
fi
grep "FAIL" "$run/mutant.txt" | head -3
grep -q "FAIL: run.csv row .* Fx_N" "$run/mutant.txt" || {
  cat "$run/mutant.txt"; echo "mcap_test: the mutant failed, but not on Fx_N" >&2; exit 1; }
echo "mcap_test: the mutant is caught (Fx_N differs); OK"
