#!/usr/bin/python3
"""scripts/figures.py's documentation set (README.md and docs/*.md) on a copy of the repository's.

Every block of the set is read and written back through write_readme, one at a time and all at
once: the files must stay byte-identical. check_readme must agree with every block, and
check_speed with the speed blocks (the benchmark programs replaced by the lists their blocks
name), and tests/hil/figures.py's --check and --readme with the HIL blocks (its runs replaced by
the blocks' own text). A block written with new text changes only the file that holds it, atomically (same mode,
no temporary file left). A block in two files, or in none, is an error naming the files.

    tests/figures/doc_set_test.py [--readme README.md]     # exit 0: passed
"""
import argparse
import contextlib
import glob
import importlib.util
import io
import json
import os
import shutil
import stat
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "scripts"))
import figures  # noqa: E402

failures = []


def expect(ok, what):
    print(f"{'ok  ' if ok else 'FAIL'} {what}")
    if not ok:
        failures.append(what)


def snapshot(folder):
    """{relative path: bytes} of every file under `folder`."""
    out = {}
    for root, _, files in os.walk(folder):
        for f in files:
            p = os.path.join(root, f)
            with open(p, "rb") as fh:
                out[os.path.relpath(p, folder)] = fh.read()
    return out


def copy_set(readme, into):
    """README.md and docs/*.md copied into `into`; returns the copy's README path."""
    os.makedirs(os.path.join(into, "docs"))
    for path in figures.doc_set(readme):
        rel = figures.shown(readme, path)
        shutil.copy2(path, os.path.join(into, rel))
    return os.path.join(into, "README.md")


def quiet(fn, *args):
    """fn(*args) with its stdout captured: (result or the SystemExit, stdout)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            return fn(*args), out.getvalue()
        except SystemExit as e:
            return e, out.getvalue()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--readme", default=figures.README)
    readme = ap.parse_args().readme
    names = figures.block_names(readme)
    expect(len(names) > 0, f"{len(names)} blocks in {len(figures.doc_set(readme))} files")
    for name, path in names.items():
        print(f"     {name}: {figures.shown(readme, path)}")

    with tempfile.TemporaryDirectory() as tmp:
        copy = copy_set(readme, os.path.join(tmp, "repo"))
        before = snapshot(os.path.dirname(copy))
        docs = figures.read_docs(copy)
        bodies = {n: figures.read_doc_block(docs, n, copy)[1] for n in names}

        # Round trip, one block at a time, then all at once.
        for name, body in bodies.items():
            quiet(figures.write_readme, copy, {name: body})
            same = snapshot(os.path.dirname(copy)) == before
            expect(same, f"write_readme({name}) with its own text leaves every file "
                         f"byte-identical")
        quiet(figures.write_readme, copy, bodies)
        expect(snapshot(os.path.dirname(copy)) == before,
               f"write_readme of all {len(bodies)} blocks at once leaves every file "
               f"byte-identical")

        # check_readme agrees with every block, naming the file that holds it.
        status, out = quiet(figures.check_readme, copy, bodies, "exact")
        expect(status == 0, "check_readme agrees with every block")
        for name, path in names.items():
            expect(f"figures.py: {name}: {figures.shown(readme, path)} agrees" in out,
                   f"check_readme names {figures.shown(readme, path)} for {name}")

        # check_speed reads the speed blocks from the set (the programs' lists from the blocks).
        speed = [n for n in figures.SPEED_BLOCKS if n in names]
        if speed:
            listed = {}
            for name in speed:
                m = figures.DATA.match(bodies[name].splitlines()[0])
                for program, run_ in json.loads(m.group(1)).items():
                    listed.setdefault(program, set()).update(run_["benchmarks"])
            real_run = figures.run
            figures.run = lambda program, *a: "\n".join(
                sorted(listed.get(os.path.basename(program), ())))
            try:
                args = argparse.Namespace(readme=copy, bench_dir="/bench")
                status, out = quiet(figures.check_speed, args)
            finally:
                figures.run = real_run
            expect(status == 0 and out.count(" agrees ") == len(speed),
                   f"check_speed agrees with the {len(speed)} speed blocks")
        expect(snapshot(os.path.dirname(copy)) == before, "checking wrote nothing")

        # New text goes into the file that holds the block, and only there, atomically.
        for name, path in names.items():
            rel = figures.shown(readme, path)
            target = os.path.join(os.path.dirname(copy), rel)
            os.chmod(target, 0o640)
            quiet(figures.write_readme, copy, {name: "changed\n\x01" "42" "\x02 s"})
            after = snapshot(os.path.dirname(copy))
            changed = sorted(k for k in after if after[k] != before.get(k))
            begin, end = figures.markers(name)
            text = after[rel].decode("utf-8")
            expect(changed == [rel] and f"{begin}\nchanged\n42 s\n{end}" in text
                   and stat.S_IMODE(os.stat(target).st_mode) == 0o640
                   and set(after) == set(before),
                   f"write_readme({name}) with new text changes {rel} only (mode kept, no "
                   f"temporary file left)")
            quiet(figures.write_readme, copy, {name: bodies[name]})
            os.chmod(target, stat.S_IMODE(os.stat(path).st_mode))
            expect(snapshot(os.path.dirname(copy)) == before, f"{name} written back")

        # tests/hil/figures.py's command line on the same set: --check agrees, writing leaves the
        # files as they are (its runs replaced by the blocks' own text).
        spec = importlib.util.spec_from_file_location(
            "hil_figures", os.path.join(HERE, "..", "hil", "figures.py"))
        hil = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(hil)
        hil_blocks = {n: bodies[n] for n in hil.BLOCKS if n in bodies}
        if hil_blocks:
            hil.load = lambda dirs: {}
            hil.markdown = lambda cases: dict(hil_blocks)
            for argv, what in ((["--check", "--readme", copy, "runs"], "--check"),
                               (["--readme", copy, "runs"], "--readme (write)")):
                saved, sys.argv = sys.argv, ["figures.py"] + argv
                try:
                    status, out = quiet(hil.main)
                finally:
                    sys.argv = saved
                expect(status == 0 and snapshot(os.path.dirname(copy)) == before,
                       f"tests/hil/figures.py {what}: status 0, every file byte-identical "
                       f"({out.strip().splitlines()[-1] if out.strip() else ''})")

        # A block in two files, or in none: an error naming the files; nothing written.
        name, path = next(iter(names.items()))
        begin, end = figures.markers(name)
        extra = os.path.join(os.path.dirname(copy), "docs", "zz-duplicate.md")
        with open(extra, "w", encoding="utf-8") as f:
            f.write(f"# A copy\n\n{begin}\n{bodies[name]}\n{end}\n")
        state = snapshot(os.path.dirname(copy))
        err, _ = quiet(figures.write_readme, copy, {name: bodies[name]})
        msg = str(err)
        expect(isinstance(err, SystemExit) and figures.shown(readme, path) in msg
               and "docs/zz-duplicate.md" in msg and "exactly one file" in msg,
               f"a block in two files is refused, naming both: {msg}")
        err, _ = quiet(figures.check_readme, copy, {name: bodies[name]}, "exact")
        expect(isinstance(err, SystemExit) and "docs/zz-duplicate.md" in str(err),
               "check_readme refuses it too")
        expect(snapshot(os.path.dirname(copy)) == state, "nothing written")
        os.unlink(extra)
        err, _ = quiet(figures.write_readme, copy, {"no-such-block": "x"})
        expect(isinstance(err, SystemExit) and "no-such-block" in str(err)
               and "none of them" in str(err), f"a block in no file is refused: {err}")
        expect(not glob.glob(os.path.join(tmp, "repo", "**", ".*"), recursive=True),
               "no temporary file left anywhere")

    print(f"doc_set_test: {'passed' if not failures else f'{len(failures)} FAILED'}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
