#!/usr/bin/env bash
# determinism.sh BUILD_DIR OUT CASE [HIL.SH OPTION...]: runs CASE twice in lockstep (hil.sh) and requires the same
# bytes: the robot's truth (truth.csv), zerog-rt's log (rec/run.csv) and its cycle records
# (rec/cycles.csv) but for the compute-time column, which is measured on the wall clock.
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
bin=$1 out=$2 case=$3
shift 3
rm -rf "$out"
for run in a b; do
  "$here/hil.sh" --bin "$bin" --out "$out/$run" "$@" "$case" || {
    echo "determinism.sh: run $run of $case failed its checks" >&2; exit 1; }
done
status=0
for f in truth.csv rec/run.csv; do
  if cmp "$out/a/$case/$f" "$out/b/$case/$f"; then
    echo "determinism.sh: $f identical ($(wc -l <"$out/a/$case/$f") lines)"
  else
    echo "determinism.sh: $f differs between two lockstep runs of $case" >&2
    status=1
  fi
done
strip_compute() {
  /usr/bin/python3 - "$1" <<'EOF'
import csv, sys
rows = list(csv.reader(open(sys.argv[1], newline="")))
drop = rows[0].index("compute_ns")
for r in rows:
    print(",".join(v for i, v in enumerate(r) if i != drop))
EOF
}
if diff <(strip_compute "$out/a/$case/rec/cycles.csv") <(strip_compute "$out/b/$case/rec/cycles.csv") >/dev/null; then
  echo "determinism.sh: rec/cycles.csv identical but for compute_ns"
else
  echo "determinism.sh: rec/cycles.csv differs between two lockstep runs of $case" >&2
  status=1
fi
exit $status
