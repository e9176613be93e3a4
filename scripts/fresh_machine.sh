#!/usr/bin/env bash
# How long the README's two commands take for a newcomer: a fresh clone of the committed tree (no
# build tree, no out/, no .venv), no compiler cache, then
#   1. scripts/demo.sh          (a): install, build its three programs, steps 1-10
#   2. .ci/run                  (b): scripts/test.sh, every stage, as CI runs it (CI=true)
# one after the other, each timed on the wall clock. Writes WORK/fresh_machine.json and, with
# --write-readme, the README's first-run block from it (scripts/figures.py first-run).
#
#   scripts/fresh_machine.sh [--work DIR] [--write-readme] [--demo-only]
#     --work DIR      where the clone goes (default: a new folder under /var/tmp); kept afterwards
#     --demo-only     only (a) (a few minutes; no README figures)
#
# About an hour on a 2-core machine. Run it on a quiet machine: the times are the machine's.
# What it cannot make fresh is the machine itself: the JSON and the README say whether the Debian
# packages were already installed (then the install step is apt's check only).
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
work= write_readme=0 demo_only=0
while [ $# -gt 0 ]; do
  case "$1" in
    --work) work=$2; shift 2 ;;
    --write-readme) write_readme=1; shift ;;
    --demo-only) demo_only=1; shift ;;
    *) echo "fresh_machine.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
[ -n "$work" ] || work=$(mktemp -d /var/tmp/zerog-fresh.XXXXXX)
case "$work" in /*) ;; *) work=$(pwd)/$work ;; esac
if [ "$write_readme" = 1 ] && [ "$demo_only" = 1 ]; then
  echo "fresh_machine.sh: --write-readme needs both commands' times (no --demo-only)" >&2; exit 2
fi
mkdir -p "$work"
clone=$work/zerog
[ ! -e "$clone" ] || { echo "fresh_machine.sh: $clone exists; name a new --work" >&2; exit 2; }
# A clone, as a newcomer and CI have it: what is committed, nothing else.
if ! git -C "$root" diff --quiet HEAD; then
  echo "fresh_machine.sh: the working tree has uncommitted changes; commit them first (a fresh" \
    "clone has only what is committed)" >&2
  exit 2
fi
git clone -q "$root" "$clone" || { echo "fresh_machine.sh: git clone failed" >&2; exit 1; }
commit=$(git -C "$clone" rev-parse --short HEAD)
# No compiler cache, whatever this shell was set up with.
unset CCACHE_DIR CCACHE_PREFIX CMAKE_CXX_COMPILER_LAUNCHER CMAKE_C_COMPILER_LAUNCHER
if dpkg -s qemu-system-x86 libceres-dev clang cyclonedds-dev >/dev/null 2>&1; then
  packages="the Debian packages were already installed, so the install steps only checked them"
else
  packages="the Debian packages were installed during the run"
fi

echo "=== fresh_machine.sh: scripts/demo.sh in $clone"
t0=$SECONDS
(cd "$clone" && scripts/demo.sh) >"$work/demo.log" 2>&1
demo_status=$? demo_s=$((SECONDS - t0))
tail -n 3 "$work/demo.log"
echo "=== scripts/demo.sh: exit $demo_status after $demo_s s"
ci_status=-1 ci_s=0
if [ "$demo_only" = 0 ]; then
  echo "=== fresh_machine.sh: .ci/run in $clone"
  t0=$SECONDS
  (cd "$clone" && CI=true bash .ci/run) </dev/null >"$work/ci.log" 2>&1
  ci_status=$? ci_s=$((SECONDS - t0))
  tail -n 12 "$work/ci.log"
  echo "=== .ci/run: exit $ci_status after $ci_s s"
fi

/usr/bin/python3 - "$work" "$clone" "$commit" "$packages" "$demo_status" "$demo_s" \
  "$ci_status" "$ci_s" <<'PY'
import json, os, re, sys, time, platform
work, clone, commit, packages = sys.argv[1:5]
demo_status, demo_s, ci_status, ci_s = map(int, sys.argv[5:9])
timing = {}
path = os.path.join(clone, "out", "demo", "timing.json")
if os.path.exists(path):
    timing = json.load(open(path))
steps = timing.get("steps_1_to_9_s", 0)
demo = {"status": demo_status, "total_s": demo_s, "install_s": timing.get("install_s", 0),
        "build_s": timing.get("build_s", 0), "steps_1_to_9_s": steps,
        "live_s": max(0, timing.get("total_s", 0) - timing.get("install_s", 0)
                      - timing.get("build_s", 0) - steps)}
stages = []
ci_log = os.path.join(work, "ci.log")
if os.path.exists(ci_log):
    for line in open(ci_log, errors="replace"):
        m = re.match(r"=== test\.sh: (.+) took (\d+) s \(", line)
        if m:
            stages.append([m.group(1), int(m.group(2))])
machine = f"{platform.machine()}, Debian {open('/etc/debian_version').read().strip()}"
report = {"date": time.strftime("%Y-%m-%d"), "cores": os.cpu_count(), "machine": machine,
          "commit": commit, "packages": packages, "demo": demo,
          "ci": {"status": ci_status, "total_s": ci_s, "stages": stages}}
with open(os.path.join(work, "fresh_machine.json"), "w") as f:
    json.dump(report, f, indent=1)
print(f"fresh_machine.sh: wrote {os.path.join(work, 'fresh_machine.json')}")
PY
if [ "$write_readme" = 1 ]; then
  if [ "$demo_status" -ne 0 ] || [ "$ci_status" -ne 0 ]; then
    echo "fresh_machine.sh: a command failed; the README keeps its figures" >&2; exit 1
  fi
  /usr/bin/python3 "$root/scripts/figures.py" first-run "$work/fresh_machine.json"
fi
[ "$demo_status" -eq 0 ] && { [ "$demo_only" = 1 ] || [ "$ci_status" -eq 0 ]; }
