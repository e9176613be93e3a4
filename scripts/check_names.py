#!/usr/bin/env python3
"""check_names.py: namespaces match directories (issue 29, "names that tell the truth").

    scripts/check_names.py [--root DIR] [LIBRARY_DIR ...]   # exit 0: every name matches

A library is a directory firmware/<name>/ or host/<name>/ (by default every one under --root,
the repository by default). Every `namespace zerog::...` it opens in a C++ source or header must
start with zerog::<name> (zerog::<name>::detail and other nested namespaces are fine), and its
public headers must live in include/zerog/<name>/, so that `#include "zerog/X/..."`, the
directory and the namespace all say X. The one exception is written below with its reason.
Prints every mismatch as `FAIL: <file>:<line>: ...`; the last line says how many were checked.
"""
import argparse
import pathlib
import re
import sys

# Library directory -> the namespace it may open instead of zerog::<name>, and why.
EXCEPTIONS = {
    # zerog::Status (firmware/status, the one header zerog/status.hpp) is the project-wide result
    # type every library returns; it sits in zerog itself, as absl::Status sits in absl.
    "firmware/status": "zerog",
}
SOURCE = {".cpp", ".hpp", ".h", ".cc"}
OPEN = re.compile(r"^\s*namespace\s+(zerog(?:::[A-Za-z_0-9]+)*)\s*\{")


def libraries(root, given):
    if given:
        return [pathlib.Path(g) for g in given]
    return sorted(p.relative_to(root) for top in ("firmware", "host")
                  for p in (root / top).iterdir() if p.is_dir())


def check(root, lib):
    failures, files = [], 0
    name = lib.name
    allowed = EXCEPTIONS.get(lib.as_posix(), f"zerog::{name}")
    for path in sorted((root / lib).rglob("*")):
        if path.suffix not in SOURCE or not path.is_file():
            continue
        files += 1
        rel = path.relative_to(root).as_posix()
        parts = path.relative_to(root / lib).parts
        if (parts[0] == "include" and len(parts) > 3 and parts[1] == "zerog" and parts[2] != name):
            failures.append(f"FAIL: {rel}: a public header of {lib.as_posix()} under "
                            f"include/zerog/{parts[2]}/, not include/zerog/{name}/")
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            m = OPEN.match(line)
            if not m:
                continue
            ns = m.group(1)
            if ns != allowed and not ns.startswith(allowed + "::"):
                failures.append(f"FAIL: {rel}:{number}: namespace {ns} in {lib.as_posix()}, "
                                f"which is {allowed}")
    return failures, files


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=pathlib.Path(__file__).resolve().parent.parent,
                    type=pathlib.Path)
    ap.add_argument("libraries", nargs="*")
    a = ap.parse_args()
    root = a.root.resolve()
    failures, files, libs = [], 0, libraries(root, a.libraries)
    for lib in libs:
        f, n = check(root, lib)
        failures += f
        files += n
    for f in failures:
        print(f)
    print(f"check_names: {len(libs)} libraries, {files} files, {len(failures)} mismatches")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
