#!/usr/bin/env bash
# The results table, generated: builds zerog, runs `zerog results` (paper-bp, paper-zp, physics,
# physics + residual network float/quantised, true-model reference and sensor floor on one
# simulated KR210/100 kg run), writes out/results/results.{md,json} and replaces the part of
# docs/learned-residual.md between the markers <!-- results:begin --> and <!-- results:end -->
# with the table (atomically: a temporary file beside it, then rename; scripts/figures.py
# results, which finds the block in README.md and docs/*.md). Extra arguments go to
# `zerog results` (e.g. --seed 7).
# Options first: --check: write nothing, compare the documented table with this run instead
# (exactly but for the training times; exit 1 on a difference); --bin DIR: the zerog built in
# DIR (no install, no build).
# Takes about 3 minutes after the build on a 2-core machine.
set -euo pipefail
cd "$(dirname "$0")/.."
check=0 bin=
while [ $# -gt 0 ]; do
  case "$1" in
    --check) check=1; shift ;;
    --bin) bin=$2; shift 2 ;;
    *) break ;;
  esac
done
if [ -z "$bin" ]; then
  if [ "${ZEROG_SKIP_INSTALL:-0}" != 1 ]; then bash scripts/install-deps.sh; fi
  cmake --preset release >/dev/null
  cmake --build --preset release -j "$(nproc)" --target zerog
  bin=build/release
fi
zerog=$bin/host/cli/zerog
out=out/results
mkdir -p "$out"
"$zerog" results --json-out "$out/results.json" "$@" > "$out/results.md.tmp"
mv "$out/results.md.tmp" "$out/results.md"
if [ "$check" = 1 ]; then
  /usr/bin/python3 scripts/figures.py --check results "$out/results.md"
else
  /usr/bin/python3 scripts/figures.py results "$out/results.md"
fi
