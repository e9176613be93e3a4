#!/usr/bin/env python3
"""check_sizes.py: no function over 120 lines, no class over 30 data members (issue 29).

    scripts/check_sizes.py [--root DIR] [--known FILE] [PATH ...]   # exit 0: within the limits
    scripts/check_sizes.py --list [PATH ...]                        # today's offenders, list format

Reads the C++ sources under each PATH (default: firmware and host, relative to --root, the
repository by default; tests/ are not held to it) with Universal Ctags (Debian's
`universal-ctags`): a function's length is its definition's first line to its last, both counted
(`--fields=+ne`); a class's, struct's or union's data members are the members ctags finds in its
body (nested types count their own). Prints every function over 120 lines and every class over 30
data members with file:line and size, largest first.

The list of known offenders (--known, default tests/sizes/known_offenders.txt) holds what was over
a limit when the check came, one per line as `function|class <file> <name> <size>`, while the long
functions are being split: the check fails on an offender that is not on the list, on a listed one
that grew, and on a listed one that is now within the limit or gone (take it off the list). So the
list only shrinks; a listed one that shrank but is still over is a note (lower its size in the
list). The list is printed on every run, each entry with its size today.
"""
import argparse
import collections
import json
import os
import re
import shutil
import subprocess
import sys

MAX_FUNCTION_LINES = 120
MAX_DATA_MEMBERS = 30
HERE = os.path.dirname(os.path.abspath(__file__))


def find_ctags():
    for name in ("ctags-universal", "universal-ctags", "ctags"):
        path = shutil.which(name)
        if path:
            version = subprocess.run([path, "--version"], capture_output=True, text=True).stdout
            if "Universal Ctags" in version:
                return path
    sys.exit("check_sizes: Universal Ctags not found (Debian: apt-get install universal-ctags)")


def qualified(tag):
    """scope::name with anonymous namespaces left out (their names change with the file)."""
    parts = [p for p in tag.get("scope", "").split("::") if p and not p.startswith("__anon")]
    return "::".join(parts + [tag["name"]])


def measure(root, paths):
    """(functions, classes): lists of (size, file, line, name), each keyed uniquely per file."""
    out = subprocess.run(
        [find_ctags(), "-R", "--languages=C++", "--kinds-C++=fmcsu", "--fields=+neKZ",
         "--extras=-F", "--output-format=json", "-f", "-"] + paths,
        cwd=root, check=True, capture_output=True, text=True).stdout
    functions, members, types = [], collections.Counter(), {}
    for line in out.splitlines():
        tag = json.loads(line)
        if tag.get("_type") != "tag":
            continue
        kind = tag.get("kind")
        if kind == "function" and "end" in tag:
            functions.append((tag["end"] - tag["line"] + 1, tag["path"], tag["line"],
                              qualified(tag)))
        elif kind in ("class", "struct", "union"):
            full = "::".join(p for p in (tag.get("scope"), tag["name"]) if p)
            types.setdefault(full, (tag["path"], tag["line"], qualified(tag)))
        elif kind == "member" and tag.get("scopeKind") in ("class", "struct", "union"):
            members[tag["scope"]] += 1
            types.setdefault("member-of:" + tag["scope"], (tag["path"], tag["line"], None))
    classes = []
    for scope, n in members.items():
        path, line, name = types.get(scope) or types["member-of:" + scope]
        if name is None:
            name = "::".join(p for p in scope.split("::") if not p.startswith("__anon"))
        classes.append((n, path, line, name))
    return unique(functions), unique(classes)


def unique(items):
    """Names made unique within a file (an overload's second definition becomes name#2)."""
    seen = collections.Counter()
    out = []
    for size, path, line, name in sorted(items, key=lambda i: (i[1], i[2])):
        seen[(path, name)] += 1
        k = seen[(path, name)]
        out.append((size, path, line, name if k == 1 else f"{name}#{k}"))
    return out


def read_known(path):
    """{(kind, file, name): size} from the list of known offenders."""
    known = {}
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            line = line.strip()
            if not line or line.startswith("#"):  # a comment (names may hold '#': name#2)
                continue
            fields = line.split()
            if len(fields) != 4 or fields[0] not in ("function", "class") \
                    or not fields[3].isdigit():
                sys.exit(f"check_sizes: {path}:{n}: expected `function|class <file> <name> "
                         f"<size>`, got: {line}")
            known[(fields[0], fields[1], fields[2])] = int(fields[3])
    return known


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", default=os.path.join(HERE, ".."))
    ap.add_argument("--known", default=os.path.join(HERE, "..", "tests", "sizes",
                                                    "known_offenders.txt"))
    ap.add_argument("--list", action="store_true",
                    help="print today's offenders in the list's format and exit")
    ap.add_argument("paths", nargs="*", default=["firmware", "host"])
    args = ap.parse_args()
    root = os.path.abspath(args.root)
    functions, classes = measure(root, args.paths)
    now = {}
    for kind, items, limit in (("function", functions, MAX_FUNCTION_LINES),
                               ("class", classes, MAX_DATA_MEMBERS)):
        for size, path, line, name in items:
            now[(kind, path, name)] = (size, f"{path}:{line}", limit)
    over = sorted(((k, v) for k, v in now.items() if v[0] > v[2]),
                  key=lambda kv: (kv[0][0] != "function", -kv[1][0], kv[1][1]))
    if args.list:
        for (kind, path, name), (size, _, _) in over:
            print(f"{kind} {path} {name} {size}")
        return 0

    for kind, plural, limit, unit in (("function", "functions", MAX_FUNCTION_LINES, "lines"),
                                      ("class", "classes", MAX_DATA_MEMBERS, "data members")):
        rows = [(k, v) for k, v in over if k[0] == kind]
        print(f"{plural} over {limit} {unit} in {' '.join(args.paths)}: {len(rows)}")
        for (_, _, name), (size, where, _) in rows:
            print(f"  {size:5d} {unit:<12} {where}  {name}")

    known = read_known(args.known)
    problems, notes = [], []
    for key, (size, where, limit) in over:
        if key not in known:
            problems.append(f"{key[0]} {key[2]} ({where}) has {size}, over {limit}, and is not "
                            f"in the list of known offenders: split it")
        elif size > known[key]:
            problems.append(f"{key[0]} {key[2]} ({where}) grew from {known[key]} to {size}")
        elif size < known[key]:
            notes.append(f"{key[0]} {key[2]} ({where}) shrank from {known[key]} to {size}: "
                         f"lower its size in {os.path.relpath(args.known, root)}")
    for key, size in sorted(known.items()):
        if key not in now:
            problems.append(f"{key[0]} {key[2]} ({key[1]}) is gone: take it off the list")
        elif now[key][0] <= now[key][2]:
            problems.append(f"{key[0]} {key[2]} ({now[key][1]}) is now {now[key][0]}, within "
                            f"{now[key][2]}: take it off the list")
    print(f"known offenders ({os.path.relpath(args.known, root)}): {len(known)}")
    for (kind, path, name), size in sorted(known.items(), key=lambda kv: (kv[0][0], -kv[1])):
        today = now.get((kind, path, name), (None,))[0]
        print(f"  {kind:<8} {size:5d} (today {today if today is not None else 'gone'}) "
              f"{path}  {name}")
    for n in notes:
        print(f"note: {n}")
    for p in problems:
        print(f"FAIL: {p}")
    print(f"check_sizes: {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
