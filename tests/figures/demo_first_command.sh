#!/usr/bin/env bash
# demo_first_command.sh SOURCE_DIR BUILD_DIR WORK_DIR
#
# The README's first command as a newcomer runs it (issue 26): the working tree copied into a fresh
# folder (what git tracks, plus new files it does not ignore: no build tree, no out/, no .venv),
# then `scripts/demo.sh --bin BUILD_DIR` from that folder's root with no other argument, so
# every path is the default and relative (out/demo). All ten steps must pass (exit 0), the live
# step's lockstep run must have passed its checks, and the demo must write nothing outside out/
# (checked with git in the copy).
#
# Then the mutant: the copy's tests/hil/hil.sh without the line that makes --out absolute (the
# bug a newcomer met: the rig path written relative into zerog-rt's configuration and resolved
# against the configuration's folder a second time). Step 10's command as demo.sh runs it must
# then fail within 10 s naming the doubled path; if it passes, this test cannot see the bug.
#
# The demo's JSON stays in WORK_DIR/zerog/out/demo for demo_readme_figures.
set -uo pipefail
src=$1 bin=$2 work=$3
fail() { echo "FAIL: $*"; exit 1; }
rm -rf "$work" && mkdir -p "$work/zerog"
clone=$work/zerog
if git -C "$src" rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  (cd "$src" && git ls-files -z --cached --others --exclude-standard \
     | xargs -0 -I{} sh -c 'test -e "{}" && printf "%s\0" "{}"' \
     | tar --null -T - -cf -) | tar -C "$clone" -xf - || fail "cannot copy the working tree"
else
  # A source tree without git (an exported copy): every file but the build trees, the outputs
  # and the Python environment, which are what .gitignore leaves out.
  tar -C "$src" --exclude=./build --exclude=./out --exclude=./.venv --exclude=.git -cf - . \
    | tar -C "$clone" -xf - || fail "cannot copy the source tree"
fi
[ -x "$clone/scripts/demo.sh" ] || fail "the copy has no scripts/demo.sh"
[ ! -e "$clone/out" ] && [ ! -e "$clone/build" ] || fail "the copy has an out/ or build/ already"
# A repository of its own, so that every file the demo writes shows.
git -C "$clone" init -q && git -C "$clone" add -A \
  && git -C "$clone" -c user.name=t -c user.email=t@t commit -q -m copy \
  || fail "cannot make a git repository of the copy"

echo "=== scripts/demo.sh --bin $bin, from $clone"
(cd "$clone" && scripts/demo.sh --bin "$bin") >"$work/demo.log" 2>&1
status=$?
tail -n 25 "$work/demo.log"
[ $status -eq 0 ] || fail "scripts/demo.sh exited $status (log: $work/demo.log)"
grep -q '"passed": true' "$clone/out/demo/hil/push/check.json" 2>/dev/null \
  || fail "the live step's lockstep run has no passed check.json ($clone/out/demo/hil/push)"
for f in design.csv run.csv fit_default.json diagnosis.json fit_fixed.json ladder.json \
         report/index.html timing.json; do
  [ -s "$clone/out/demo/$f" ] || fail "the demo did not write out/demo/$f"
done
stray=$(git -C "$clone" status --porcelain --untracked-files=all | grep -v '^?? out/' || true)
ignored_elsewhere=$(git -C "$clone" status --porcelain --ignored --untracked-files=all \
                      | grep '^!! ' | grep -v '^!! out/' || true)
[ -z "$stray$ignored_elsewhere" ] || fail "the demo wrote outside out/ or changed files:
$stray
$ignored_elsewhere"
echo "demo: all ten steps passed; nothing written outside out/"

echo "=== mutant: hil.sh with the --out path left relative"
mutant=$work/mutant
cp -r "$clone" "$mutant" && rm -rf "$mutant/out"
grep -q '^out=$(realpath -m -- "$out")$' "$mutant/tests/hil/hil.sh" \
  || fail "hil.sh no longer has the line this test's mutant removes"
sed -i '/^out=$(realpath -m -- "$out")$/d' "$mutant/tests/hil/hil.sh"
t0=$(date +%s)
(cd "$mutant" && timeout -s KILL 60 tests/hil/hil.sh --bin "$bin" --out out/demo/hil push) \
  >"$work/mutant.log" 2>&1
mstatus=$? took=$(( $(date +%s) - t0 ))
tail -n 5 "$work/mutant.log"
[ $mstatus -ne 0 ] || fail "the mutant passed: this test cannot see a doubled relative path"
[ $took -lt 10 ] || fail "the mutant's run took $took s to fail (the runner must stop at once)"
grep -q "out/demo/hil/push/out/demo/hil/push/rig.rig.toml: no such file" "$work/mutant.log" \
  || fail "the mutant failed, but not for the doubled path"
echo "mutant caught in $took s: the doubled relative path fails step 10"
echo "demo_first_command: PASS"
