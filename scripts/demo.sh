#!/usr/bin/env bash
# The model-insight loop end to end, on a simulated KR210 + Omega191 + STIM300 rig with one
# effect hidden in the truth: fit the default model, see where it fails, diagnose the missing
# effect (or discover its law in the signal dictionary), add it, watch the error fall to the
# true-model reference, write the report of the final model with its own diagnosis. Then live:
# zerog-rt floats the part in a hardware-in-the-loop run against the emulated rig.
# Usage: scripts/demo.sh [--write-readme] [--offline] [--bin BUILD_DIR] [--out DIR] [HIDDEN_EFFECT]
#   HIDDEN_EFFECT   default: cable; `zerog sim --list-effects` lists them
#   --write-readme  at the end, write the demo's figures from this run's JSON into README.md and
#                   docs/ (scripts/figures.py demo; only with the documented configuration: cable
#                   hidden)
#   --offline       steps 1-9 only (no live run)
#   --bin DIR       use the programs built in DIR (no install, no build)
#   --out DIR       outputs there instead of the repository's out/demo
# Paths (proto/paths.md): --bin and --out are relative to the folder you run this from; the
# default out/demo is the repository's, wherever you run it from.
# Without --bin it installs the Debian packages the demo needs (scripts/install-deps.sh --demo)
# and builds only the three programs it runs (zerog, zerog-rt, zerog-emu) in build/release;
# scripts/test.sh builds everything else.
set -euo pipefail
here=$(pwd)
root=$(cd "$(dirname "$0")/.." && pwd)
hidden=cable write_readme=0 offline=0 bin= out=
# A path given on the command line, made absolute against the folder the user ran this from.
given_path() { case "$1" in /*) printf '%s' "$1" ;; *) printf '%s' "$here/$1" ;; esac; }
while [ $# -gt 0 ]; do
  case "$1" in
    --write-readme) write_readme=1; shift ;;
    --offline) offline=1; shift ;;
    --bin) [ $# -ge 2 ] || { echo "demo.sh: --bin needs a folder" >&2; exit 2; }
           bin=$(given_path "$2"); shift 2 ;;
    --out) [ $# -ge 2 ] || { echo "demo.sh: --out needs a folder" >&2; exit 2; }
           out=$(given_path "$2"); shift 2 ;;
    -*) echo "demo.sh: unknown option $1" >&2; exit 2 ;;
    *) hidden=$1; shift ;;
  esac
done
cd "$root"
# The default output folder, named relative to the repository (printed paths stay short).
[ -n "$out" ] || out=out/demo
if [ "$write_readme" = 1 ] && [ "$hidden" != cable ]; then
  echo "demo.sh: --write-readme writes the documented figures, which are of the default (cable)" >&2
  exit 2
fi
install_s=0 build_s=0
if [ -z "$bin" ]; then
  if [ "${ZEROG_SKIP_INSTALL:-0}" != 1 ]; then bash scripts/install-deps.sh --demo; fi
  install_s=$SECONDS
  cmake --preset release >/dev/null
  # Only what the demo runs (and what they link): the tests and benchmarks are scripts/test.sh's.
  cmake --build --preset release -j "$(nproc)" --target zerog zerog-rt zerog-emu
  build_s=$((SECONDS - install_s))
  bin=build/release
fi
[ -x "$bin/host/cli/zerog" ] || { echo "demo.sh: $bin/host/cli/zerog is not built" >&2; exit 2; }
zerog=$bin/host/cli/zerog
mkdir -p "$out"
started=$SECONDS
step() { printf '\n\033[1m== %s\033[0m\n' "$*"; }

step "1. Design the calibration path (orthogonal array, paper 000 §4.2)"
$zerog design --kind oa --out "$out/design.csv"

step "2. Simulate the calibration run (one effect hidden in the truth)"
$zerog sim --design "$out/design.csv" --effects "$hidden" --seed 42 --out "$out/run.csv"

step "3. Fit the default model (bias, gravity, linear and rotational inertia)"
$zerog fit "$out/run.csv" --out "$out/fit_default.json" -q

step "4. Compare it with the measurements: where does it fail?"
$zerog compare "$out/run.csv" --model "$out/fit_default.json" --truth "$out/run.truth.json" -q

step "5. Diagnose: which effect is missing? (a library effect, or a law found in the signal dictionary)"
$zerog diagnose "$out/run.csv" --model "$out/fit_default.json" --discovered-out "$out/discovered.toml" \
  --json -q > "$out/diagnosis.json"
# The verdict in plain words, and what to add: a library effect, or the discovered effect file.
read -r kind effects < <(/usr/bin/python3 - "$out/diagnosis.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
v = d["verdict"]
print(v["text"], file=sys.stderr)
if d["discovery"]:
    for t in d["discovery"]["terms"]:
        print("  discovered:", t["law"], file=sys.stderr)
if v["command"]:
    print("  add it:", v["command"], file=sys.stderr)
model = ",".join(d["model"])
if v["kind"] == "effect":
    print("effect", model + "," + v["effect"])
elif v["kind"] == "discovered":
    print("discovered", model + ",@" + v["effect_file"])
else:
    print(v["kind"], "")
PY
)
if [ -z "$effects" ]; then echo "diagnose found nothing to add ($kind); stopping here."; exit 0; fi

step "6. Add it and refit: $effects"
$zerog fit "$out/run.csv" --effects "$effects" --out "$out/fit_fixed.json" --truth "$out/run.truth.json" -q

step "7. Compare again: the error falls to the true-model reference"
$zerog compare "$out/run.csv" --model "$out/fit_fixed.json" --truth "$out/run.truth.json" -q

step "8. The ladder: from bias + gravity, add the best effect while it pays"
# A discovered law is a candidate too: the ladder climbs with it like with a library effect.
candidates=()
if [ "$kind" = discovered ]; then candidates=(--candidates "@$out/discovered.toml"); fi
$zerog ladder "$out/run.csv" --truth "$out/run.truth.json" --out "$out/ladder.json" \
  "${candidates[@]}" -q

step "9. The report, with the final model's own diagnosis"
# zerog report takes only a diagnosis made for the model it shows (step 5's was of the default
# model): diagnose the final model, then report on it.
$zerog diagnose "$out/run.csv" --model "$out/fit_fixed.json" \
  --discovered-out "$out/discovered_fixed.toml" --json -q > "$out/diagnosis_fixed.json"
/usr/bin/python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["verdict"]["text"])' \
  "$out/diagnosis_fixed.json"
$zerog report "$out/run.csv" --model "$out/fit_fixed.json" --truth "$out/run.truth.json" \
  --ladder "$out/ladder.json" --diagnosis "$out/diagnosis_fixed.json" --out "$out/report"
echo "open $out/report/index.html in a browser"
# Its interactive page (zoom, hover for the pose, one axis at a time) needs plotly in .venv
# (install-deps.sh --demo installs it); without it the report says why.
if [ -f "$out/report/interactive.html" ]; then
  echo "  zoom into the time series: $out/report/interactive.html (works offline)"
fi
# How long steps 1-9 took, for the README (scripts/figures.py demo).
steps_s=$((SECONDS - started))
# timing.json: what each part took (install and build are 0 with --bin); the live step's time is
# added at the end (scripts/fresh_machine.sh reads it).
write_timing() {
  printf '{"hidden": "%s", "install_s": %d, "build_s": %d, "steps_1_to_9_s": %d, "total_s": %d}\n' \
    "$hidden" "$install_s" "$build_s" "$steps_s" "$SECONDS" >"$out/timing.json"
}
write_timing
write_figures() {
  if [ "$write_readme" = 1 ]; then /usr/bin/python3 scripts/figures.py demo "$out"; fi
}
if [ "$offline" = 1 ]; then write_figures; exit 0; fi

step "10. Live: zerog-rt floats the part (hardware in the loop against the emulated rig)"
# zerog-rt with the model of the emulated payload; the KR 210 controller on RSI/UDP, the ATI board
# on a user-space CAN bus, the STIM300 on a pty (tests/hil/hil.sh); a 0.4 s push on the part.
# In lockstep (proto/lockstep.md): the emulator is zerog-rt's clock, so the result is the same on
# any machine, however loaded; the run is checked (J/m within 1 %).
echo "lockstep run (the emulator is zerog-rt's clock: the same result on any machine):"
tests/hil/hil.sh --bin "$bin" --out "$out/hil" push \
  || { echo "the hardware-in-the-loop run failed; see $out/hil/push/check.txt and *.err"; exit 1; }
echo "hardware-in-the-loop run: $out/hil/push (truth.csv, rec/run.csv, rt.json, check.json)"
# Then once on the wall clock, as on the cabinet PC: a timing benchmark of this machine, not a
# check (its pass or fail depends on what else the machine does).
echo
echo "the same push on the wall clock (a timing benchmark of this machine, not a check):"
if tests/hil/hil.sh --bin "$bin" --out "$out/hil-realtime" --mode realtime push \
    >"$out/hil-realtime.log" 2>&1; then
  echo "  (its checks passed too)"
else
  echo "  (its checks did not all pass on this machine's clock: $out/hil-realtime.log)"
fi
/usr/bin/python3 tests/hil/timing.py "$out/hil-realtime/push" --json "$out/hil-realtime/timing.json" \
  || echo "  no timing: the real-time run did not finish ($out/hil-realtime.log)"
write_figures
write_timing
echo
echo "demo.sh: done in $SECONDS s (install ${install_s} s, build ${build_s} s, steps 1-9 ${steps_s} s," \
  "live $((SECONDS - started - steps_s)) s); outputs in $out"
