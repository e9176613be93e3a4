#!/usr/bin/env python3
"""check_refs.py [--root DIR] [FILE ...]: what the sources and docs cite exists (issue 29).

Two kinds of citation, each checked against the tree it names:

- The style guide: every citation of it, in any file, must name the repository's docs/STYLE.md
  by a path (from the root, or from the citing file's folder), and a habit it names
  ("docs/STYLE.md habit 7", "habits 3 and 4") must be one of the guide's numbered habits, a section
  it names (docs/STYLE.md, "The architecture should be visible from the tree") one of its `##`
  headings.
- Repository paths (firmware/..., host/..., tests/..., proto/..., docs/..., calib/...,
  scripts/..., cmake/...): in comments of C++, CMake, shell and Python files (and a Python file's
  module docstring), in backticks and as relative link targets in Markdown. A path exists if it
  names a file or folder, or a source file once `.cpp`, `.hpp`, `.py` or `.sh` is added (a test
  named after its source). `...` or `…` stands for any folders, an all-capitals word (CASE, NAME)
  for any name, and {a,b} for each of a and b (each must exist). In README.md, proto/*.md and
  docs/*.md, a source or doc named in backticks without its folder (`eiv.hpp`, `hil.sh`,
  `loop.md`) must be the name of a file somewhere in the repository.

Without FILE, every file git tracks under --root (default: the repository holding this script) is
read, but the fixtures of the checks' own mutants (tests/docs/fixtures, tests/sizes/fixtures).
Prints each problem as file:line: what; exit 0 when there is none, 1 otherwise.
"""
import argparse
import glob
import os
import re
import subprocess
import sys

TOP = ("firmware", "host", "tests", "proto", "docs", "calib", "scripts", "cmake")
STYLE = "docs/STYLE.md"
SKIP_PREFIXES = ("tests/docs/fixtures/", "tests/sizes/fixtures/")
CXX = (".cpp", ".hpp", ".h", ".cc", ".idl")
HASH = (".cmake", ".sh", ".py", ".txt", ".toml")
SOURCE_SUFFIXES = (".cpp", ".hpp", ".py", ".sh")

PATH_RE = re.compile(r"(?<![\w./$<>{}-])(?:%s)/(?:[\w.*…+-]|/|\{[\w.,*-]*\})+" % "|".join(TOP))
STYLE_RE = re.compile(r"[\w./-]*STYLE\.md")
HABITS_RE = re.compile(r"\s*,?\s*habits?\s+(\d+(?:\s*(?:,|and|&)\s*\d+)*)")
SECTION_RE = re.compile(r"\s*,\s*(?:section\s+)?[\"“]([^\"”]+)[\"”]")
BACKTICK_RE = re.compile(r"`([^`\n]+)`")
LINK_RE = re.compile(r"\]\(([^)\s]+)\)")
NAME_RE = re.compile(r"[\w./-]+\.(?:md|hpp|cpp|py|sh)")


def style_guide(path):
    """(habit numbers, section titles) of the style guide at `path`."""
    habits, sections = set(), set()
    with open(path, encoding="utf-8") as f:
        for line in f:
            m = re.match(r"(\d+)\.\s", line)
            if m:
                habits.add(int(m.group(1)))
            m = re.match(r"#{2,}\s+(.*?)\s*$", line)
            if m:
                sections.add(m.group(1))
    return habits, sections


def flat_text(text):
    """The file's lines with leading comment markers (//, ///, #, *) removed, so that a citation
    wrapped over two comment lines reads as one."""
    return "\n".join(re.sub(r"^\s*(?:/{2,3}!?|#+|\*+|/\*+)?\s?", "", line)
                     for line in text.split("\n"))


def line_of(text, pos):
    return text.count("\n", 0, pos) + 1


def comment_spans(rel, text):
    """(line, text) of each comment of a source file; for Markdown, each line."""
    out = []
    lines = text.split("\n")
    if rel.endswith(CXX):
        in_block = False
        for i, line in enumerate(lines, 1):
            if in_block:
                end = line.find("*/")
                out.append((i, line if end < 0 else line[:end]))
                in_block = end < 0
                continue
            # A comment starts at // or /* outside a string literal (good enough: our sources do
            # not put // in strings before a comment on the same line).
            m = re.search(r'//|/\*', re.sub(r'"(?:\\.|[^"\\])*"', lambda s: " " * len(s.group()), line))
            if not m:
                continue
            rest = line[m.start() + 2:]
            if m.group() == "/*":
                end = rest.find("*/")
                in_block = end < 0
                rest = rest if end < 0 else rest[:end]
            out.append((i, rest))
    elif rel.endswith(HASH) or os.path.basename(rel) == "CMakeLists.txt":
        for i, line in enumerate(lines, 1):
            m = re.match(r"\s*#(.*)", line) or re.search(r"\s#\s(.*)", line)
            if m:
                out.append((i, m.group(1)))
        if rel.endswith(".py"):
            m = re.match(r'(?:#[^\n]*\n)*\s*(?:r?"""(.*?)"""|r?\'\'\'(.*?)\'\'\')', text, re.S)
            if m:
                doc = m.group(1) if m.group(1) is not None else m.group(2)
                first = line_of(text, m.start(1) if m.group(1) is not None else m.start(2))
                out.extend((first + k, l) for k, l in enumerate(doc.split("\n")))
    return out


def expand(pattern):
    """The glob patterns a cited path stands for: braces expanded, placeholders widened."""
    m = re.search(r"\{([^{}]*)\}", pattern)
    if m:
        return [p for alt in m.group(1).split(",")
                for p in expand(pattern[:m.start()] + alt + pattern[m.end():])]
    parts = []
    for part in pattern.split("/"):
        if part in ("...", "…"):
            parts.append("**")
        else:
            part = re.sub(r"\.\.\.|…", "*", part)
            parts.append(re.sub(r"(?<![A-Za-z])[A-Z][A-Z0-9_]+(?![a-z])", "*", part))
    return ["/".join(parts)]


def path_exists(root, cited):
    """Whether each path `cited` stands for names something in the tree under `root`."""
    def one(pattern):
        full = os.path.join(root, pattern)
        return any(glob.glob(full + s, recursive=True) for s in ("",) + SOURCE_SUFFIXES)
    return all(one(p) for p in expand(cited))


def clean_path(token):
    return token.rstrip(".,;:)'\"…") if not token.endswith(("...", "…")) else token


def check_file(root, rel, guide, names, problems):
    try:
        with open(os.path.join(root, rel), encoding="utf-8") as f:
            text = f.read()
    except (UnicodeDecodeError, FileNotFoundError, IsADirectoryError):
        return
    habits, sections = guide
    style_path = os.path.realpath(os.path.join(root, STYLE))
    if os.path.realpath(os.path.join(root, rel)) != style_path:
        flat = flat_text(text)
        for m in STYLE_RE.finditer(flat):
            where = f"{rel}:{line_of(flat, m.start())}"
            cited = m.group()
            here = os.path.join(root, os.path.dirname(rel), cited)
            if style_path not in (os.path.realpath(os.path.join(root, cited)),
                                  os.path.realpath(here)):
                problems.append(f"{where}: cites `{cited}`, which is not the repository's "
                                f"style guide ({STYLE})")
                continue
            tail = flat[m.end():m.end() + 200]
            h = HABITS_RE.match(tail)
            if h:
                for n in map(int, re.findall(r"\d+", h.group(1))):
                    if n not in habits:
                        problems.append(f"{where}: cites {STYLE} habit {n}, which {STYLE} does "
                                        f"not have (habits {min(habits)}–{max(habits)})")
            s = SECTION_RE.match(tail)
            if s and not h:
                title = " ".join(s.group(1).split())
                if title not in sections:
                    problems.append(f"{where}: cites {STYLE} section \"{title}\", which "
                                    f"{STYLE} does not have")

    if rel.endswith(".md"):
        # Bare names only in the specs and the docs: other READMEs cite other projects' files.
        bare_names = rel == "README.md" or os.path.dirname(rel) in ("proto", "docs", "")
        spans = []
        for i, line in enumerate(text.split("\n"), 1):
            for b in BACKTICK_RE.findall(line):
                spans.append((i, b))
                # A file named without its folder (`eiv.hpp`, `hil.sh`) must exist somewhere.
                if bare_names and NAME_RE.fullmatch(b) and not PATH_RE.match(b) \
                        and not b.startswith("..") \
                        and not any(n == b or n.endswith("/" + b) for n in names):
                    problems.append(f"{rel}:{i}: names `{b}`, which no file in the repository is")
            for target in LINK_RE.findall(line):
                target = target.split("#")[0]
                if not target or re.match(r"[a-z]+:", target):
                    continue
                local = os.path.normpath(os.path.join(os.path.dirname(rel), target))
                if not local.startswith("..") and not path_exists(root, local):
                    problems.append(f"{rel}:{i}: links to `{target}`, which does not exist "
                                    f"({local})")
    else:
        spans = comment_spans(rel, text)
    for i, span in spans:
        for m in PATH_RE.finditer(span):
            cited = clean_path(m.group())
            if not path_exists(root, cited):
                problems.append(f"{rel}:{i}: cites `{cited}`, which does not exist")


def tracked_files(root):
    try:
        out = subprocess.run(["git", "-C", root, "ls-files"], check=True, capture_output=True,
                             text=True).stdout.split("\n")
    except (OSError, subprocess.CalledProcessError):
        out = [os.path.relpath(os.path.join(d, f), root)
               for d, _, fs in os.walk(root) for f in fs]
    return sorted(f for f in out if f and not f.startswith(SKIP_PREFIXES)
                  and os.path.isfile(os.path.join(root, f)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                   "..", ".."))
    ap.add_argument("files", nargs="*", help="files to read, relative to --root (default: all)")
    args = ap.parse_args()
    root = os.path.abspath(args.root)
    if not os.path.isfile(os.path.join(root, STYLE)):
        print(f"check_refs: {STYLE} is missing under {root}")
        return 1
    guide = style_guide(os.path.join(root, STYLE))
    names = tracked_files(root)
    files = args.files or names
    problems = []
    for rel in files:
        found = []
        check_file(root, rel, guide, names, found)
        problems.extend(sorted(found, key=lambda p: int(p.split(":")[1])))  # by line
    for p in problems:
        print(p)
    print(f"check_refs: {len(files)} files, {len(guide[0])} habits and {len(guide[1])} sections "
          f"in {STYLE}, {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
