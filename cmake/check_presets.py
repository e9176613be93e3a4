#!/usr/bin/env python3
"""check_presets.py [--mutant] CMakePresets.json: the release preset compiles what CI checks.

scripts/demo.sh builds the release preset; CI builds the ci preset with warnings as errors. GCC's
-Warray-bounds, -Wrestrict and friends depend on the optimisation level, so the two agree on
warnings only if they optimise alike: the release preset's C and C++ flags must be the ci
preset's without its debug-information flags (-g, -g1, ...), and the ci preset must have
ZEROG_WERROR on. Then every warning a release build could print fails CI (issue 26).

With --mutant the check runs on a copy whose release preset optimises at -O3 (the flags before
issue 26) and must fail: exit 0 if it did, 1 if the check could not see it.
"""
import copy
import json
import sys


def resolve(presets, name, key):
    """A configure preset's cache variable, following `inherits` (first parent wins)."""
    p = presets[name]
    value = p.get("cacheVariables", {}).get(key)
    if value is not None:
        return value["value"] if isinstance(value, dict) else value
    for parent in p.get("inherits", []) if isinstance(p.get("inherits"), list) else \
            [p["inherits"]] if "inherits" in p else []:
        value = resolve(presets, parent, key)
        if value is not None:
            return value
    return None


def problems(doc):
    presets = {p["name"]: p for p in doc["configurePresets"]}
    out = []
    if resolve(presets, "ci", "CMAKE_BUILD_TYPE") != "RelWithDebInfo":
        out.append("the ci preset is not a RelWithDebInfo build")
    if resolve(presets, "release", "CMAKE_BUILD_TYPE") != "Release":
        out.append("the release preset is not a Release build")
    if str(resolve(presets, "ci", "ZEROG_WERROR")).upper() not in ("ON", "TRUE", "1"):
        out.append("the ci preset does not treat warnings as errors (ZEROG_WERROR)")
    for lang in ("C", "CXX"):
        ci = resolve(presets, "ci", f"CMAKE_{lang}_FLAGS_RELWITHDEBINFO")
        release = resolve(presets, "release", f"CMAKE_{lang}_FLAGS_RELEASE")
        if ci is None or release is None:
            out.append(f"CMAKE_{lang}_FLAGS of the ci or release preset not set "
                       f"(ci {ci!r}, release {release!r}): CMake's defaults differ (-O2 / -O3)")
            continue
        ci_opt = sorted(f for f in ci.split() if not f.startswith("-g"))
        if sorted(release.split()) != ci_opt:
            out.append(f"{lang} flags: release {release!r} is not ci's {ci!r} without -g: a "
                       f"release build could warn where CI does not")
    return out


def main():
    args = sys.argv[1:]
    mutant = "--mutant" in args
    path = [a for a in args if a != "--mutant"][0]
    with open(path, encoding="utf-8") as f:
        doc = json.load(f)
    if mutant:
        doc = copy.deepcopy(doc)
        for p in doc["configurePresets"]:
            if p["name"] == "release":
                p["cacheVariables"]["CMAKE_CXX_FLAGS_RELEASE"] = "-O3 -DNDEBUG"
        found = problems(doc)
        print("mutant (release at -O3):", "; ".join(found) or "NOT caught")
        return 0 if found else 1
    found = problems(doc)
    for p in found:
        print(f"{path}: {p}")
    if not found:
        print(f"{path}: the release preset optimises as the ci preset (warnings as errors)")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
