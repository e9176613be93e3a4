#!/usr/bin/env python3
"""stage_targets.py --preset P --build-dir DIR: the build targets ctest's test preset P needs.

scripts/test.sh builds a sanitizer stage with `cmake --build --target $(this)` instead of the
whole tree: the asan test preset leaves out the VM tests and the long end-to-end binaries, the
tsan one runs a few threaded binaries only. The list is derived, not written down, so it follows
the presets' filters and the tests as they change:

  * ctest --preset P --show-only=json-v1 gives the selected tests. A GoogleTest binary not built
    yet stands there as its placeholder <target>_NOT_BUILT, labelled <target> like its cases
    (tests/CMakeLists.txt, zerog_add_test), so the preset's label filters apply to it.
  * The CMake file API (codemodel) gives every executable target and its file. A selected test
    needs the executables whose files appear in its command, its arguments or its REQUIRED_FILES
    (the script tests name the programs they run there, e.g. tests/hil).
  * An executable that no test of the tree names at all (a program a script finds by itself) is
    always built: nothing is left out that cannot be shown unneeded.

Targets a needed target depends on (libraries, add_dependencies) come with it. Prints one target
per line; fails if the preset selects no test. A test whose program was not built fails in ctest
(missing executable or required file): never a skip.

--covered-by P2 --covered-build-dir DIR2 [--keep T,...]: scripts/test.sh's first stage compiles
each GoogleTest binary once in CI (issue 26). The binaries whose cases preset P2 (asan) runs are
left out of preset P's targets (but those named by --keep, whose checks differ without a
sanitizer: the allocation hooks through glibc, mlockall), and --labels prints the ctest -LE
regex that leaves their cases out of P's run. A GoogleTest binary is a target that labels its
cases with its own name (tests/CMakeLists.txt, zerog_add_test).
"""
import argparse
import json
import os
import re
import subprocess
import sys


def run(cmd, cwd):
    return subprocess.run(cmd, cwd=cwd, check=True, capture_output=True, text=True).stdout


def codemodel_executables(build_dir, source_dir):
    """{absolute artifact path: target name} of every executable target (file API)."""
    api = os.path.join(build_dir, ".cmake", "api", "v1")
    query = os.path.join(api, "query", "codemodel-v2")
    reply = os.path.join(api, "reply")
    if not os.path.exists(query) or not os.path.isdir(reply):
        os.makedirs(os.path.dirname(query), exist_ok=True)
        open(query, "a").close()
        run(["cmake", build_dir], source_dir)  # re-runs the configuration: writes the reply
    indexes = sorted(f for f in os.listdir(reply) if f.startswith("index-"))
    if not indexes:
        sys.exit(f"stage_targets: no CMake file API reply in {reply}")
    with open(os.path.join(reply, indexes[-1])) as f:
        index = json.load(f)
    codemodel = next(o for o in index["objects"] if o["kind"] == "codemodel")
    with open(os.path.join(reply, codemodel["jsonFile"])) as f:
        model = json.load(f)
    exes = {}
    for config in model["configurations"][:1]:
        for t in config["targets"]:
            with open(os.path.join(reply, t["jsonFile"])) as f:
                target = json.load(f)
            if target["type"] != "EXECUTABLE":
                continue
            for a in target.get("artifacts", []):
                path = a["path"]
                if not os.path.isabs(path):
                    path = os.path.join(build_dir, path)
                exes[os.path.normpath(path)] = target["name"]
    return exes


def tests_of(ctest_args, source_dir):
    return json.loads(run(["ctest", *ctest_args, "--show-only=json-v1"], source_dir))["tests"]


def add_test_lines(build_dir):
    """{test name: its add_test() line} from the build tree's CTestTestfile.cmake files: ctest's
    JSON leaves out the command of a test whose program is not built yet."""
    lines = {}
    for root, _, files in os.walk(build_dir):
        if "CTestTestfile.cmake" in files:
            with open(os.path.join(root, "CTestTestfile.cmake")) as f:
                for line in f:
                    m = re.match(r"\s*add_test\((?:\[=\[(.*?)\]=\]|(\S+))\s(.*)", line)
                    if m:
                        lines[m.group(1) or m.group(2)] = m.group(3)
    return lines


def needed(test, exes, names, lines):
    """The executable targets `test` names."""
    found = set()
    if test["name"].endswith("_NOT_BUILT"):
        base = test["name"][: -len("_NOT_BUILT")]
        if base in names:
            found.add(base)
    words = list(test.get("command") or []) + [lines.get(test["name"], "")]
    for p in test.get("properties", []):
        if p["name"] == "REQUIRED_FILES":
            words += p["value"] if isinstance(p["value"], list) else [p["value"]]
    for w in words:
        for path, target in exes.items():
            if re.search(re.escape(path) + r"(?![\w.+-])", w):
                found.add(target)
    return found


def labels_of(test):
    for p in test.get("properties", []):
        if p["name"] == "LABELS":
            return p["value"] if isinstance(p["value"], list) else [p["value"]]
    return []


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", required=True, help="the test preset (CMakePresets.json)")
    ap.add_argument("--build-dir", required=True, help="its configured build directory")
    ap.add_argument("--presets-dir", help="where ctest finds CMakePresets.json (default: the source tree;"
                    " a copy whose preset points at another build directory, for trying this out)")
    ap.add_argument("--covered-by", help="a second test preset whose GoogleTest binaries are left out")
    ap.add_argument("--covered-build-dir", help="its configured build directory")
    ap.add_argument("--keep", default="", help="comma list of binaries built and run all the same")
    ap.add_argument("--labels", action="store_true",
                    help="with --covered-by: print the ctest -LE regex of the left-out binaries")
    args = ap.parse_args()
    source_dir = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    build_dir = os.path.abspath(os.path.join(source_dir, args.build_dir))

    exes = codemodel_executables(build_dir, source_dir)
    names = set(exes.values())
    selected = tests_of(["--preset", args.preset], args.presets_dir or source_dir)
    if not selected:
        sys.exit(f"stage_targets: the test preset {args.preset} selects no test")
    everything = tests_of(["--test-dir", build_dir], source_dir)

    covered = set()
    if args.covered_by:
        if not args.covered_build_dir:
            sys.exit("stage_targets: --covered-by needs --covered-build-dir")
        other_dir = os.path.abspath(os.path.join(source_dir, args.covered_build_dir))
        other_names = set(codemodel_executables(other_dir, source_dir).values())
        other = tests_of(["--preset", args.covered_by], args.presets_dir or source_dir)
        covered = {label for t in other for label in labels_of(t) if label in other_names}
        covered -= {k for k in args.keep.split(",") if k}
        if args.labels:
            print("^(" + "|".join(sorted(covered)) + ")$" if covered else "^$")
            return
        # Their cases need only their own binary: leave the cases out, not what others need.
        selected = [t for t in selected if not (set(labels_of(t)) & covered)]

    lines = add_test_lines(build_dir)
    referenced = set().union(*(needed(t, exes, names, lines) for t in everything))
    targets = set().union(*(needed(t, exes, names, lines) for t in selected))
    targets |= (names - referenced) - covered
    print("\n".join(sorted(targets)))


if __name__ == "__main__":
    main()
