#!/usr/bin/env bash
# The results table, generated: builds zerog, runs `zerog results` (paper-bp, paper-zp, physics,
# physics + residual network float/quantised, true-model reference and sensor floor on one
# simulated KR210/100 kg run), writes out/results/results.{md,json} and replaces the part of
# README.md between the markers <!-- results:begin --> and <!-- results:end --> with the table
# (atomically: a temporary file beside README.md, then rename). Extra arguments go to
# `zerog results` (e.g. --seed 7).
# Takes about 2 minutes after the build on a 2-core machine.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${ZEROG_SKIP_INSTALL:-0}" != 1 ]; then bash scripts/install-deps.sh; fi
cmake --preset release >/dev/null
cmake --build --preset release -j "$(nproc)" --target zerog
zerog=build/release/host/cli/zerog
out=out/results
mkdir -p "$out"
"$zerog" results --json-out "$out/results.json" "$@" > "$out/results.md.tmp"
mv "$out/results.md.tmp" "$out/results.md"
/usr/bin/python3 - "$out/results.md" README.md <<'PY'
import os, sys, tempfile
table_path, readme_path = sys.argv[1], sys.argv[2]
begin, end = "<!-- results:begin -->", "<!-- results:end -->"
table = open(table_path, encoding="utf-8").read().strip("\n")
text = open(readme_path, encoding="utf-8").read()
if text.count(begin) != 1 or text.count(end) != 1 or text.index(begin) > text.index(end):
    sys.exit(f"results.sh: {readme_path} needs exactly one '{begin}' followed by one '{end}'; "
             f"the table is in {table_path}")
head, rest = text.split(begin, 1)
_, tail = rest.split(end, 1)
new = f"{head}{begin}\n{table}\n{end}{tail}"
folder = os.path.dirname(os.path.abspath(readme_path))
fd, tmp = tempfile.mkstemp(prefix=".README.", dir=folder)
try:
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(new)
        f.flush()
        os.fsync(f.fileno())
    os.chmod(tmp, os.stat(readme_path).st_mode & 0o777)
    os.replace(tmp, readme_path)
except BaseException:
    os.unlink(tmp)
    raise
print(f"results.sh: wrote {table_path} and the table in {readme_path}")
PY
