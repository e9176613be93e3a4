#!/usr/bin/env python3
"""`zerog report` writes the interactive page with the project's .venv python.

Run: .venv/bin/python tests/report/report_cli_test.py ZEROG WORK_DIR   (ctest: report_cli)

make_report.py runs on Debian's python3, which has no plotly; zerog report names the .venv's
python to it in ZEROG_PYTHON (host/cli/report_script.cpp), unless the user set it. On a short
simulated run: without ZEROG_PYTHON the report has interactive.html, linked from index.html;
with ZEROG_PYTHON naming a Python that does not exist, zerog report keeps it (the user's
choice), writes the static report all the same and says why. Needs the .venv with plotly (the
CMake registration skips or, in CI, fails without it).
"""

import os
import shutil
import subprocess
import sys


def run(args, env=None, what=""):
    p = subprocess.run(args, capture_output=True, text=True, timeout=600, env=env)
    if p.returncode != 0:
        sys.exit("FAIL: %s: exit %d\n%s" % (what or " ".join(args), p.returncode, p.stderr))
    return p


def main(argv):
    if len(argv) != 2:
        print("usage: report_cli_test.py ZEROG WORK_DIR", file=sys.stderr)
        return 2
    zerog, work = argv
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    log = os.path.join(work, "run.csv")
    run([zerog, "sim", "--kind", "random", "--points", "20", "--speed", "1", "--dwell", "0.5",
         "--seed", "3", "--out", log])
    model = os.path.join(work, "fit.json")
    run([zerog, "fit", log, "-q", "--out", model])
    env = {k: v for k, v in os.environ.items() if k != "ZEROG_PYTHON"}
    failures = []

    def check(ok, what):
        print("%s: %s" % ("ok" if ok else "FAIL", what))
        if not ok:
            failures.append(what)

    out = os.path.join(work, "report")
    p = run([zerog, "report", log, "--model", model, "--out", out], env, "zerog report")
    page = open(os.path.join(out, "index.html"), encoding="utf-8").read()
    check(os.path.isfile(os.path.join(out, "interactive.html")),
          "without ZEROG_PYTHON: interactive.html written with the .venv's plotly")
    check('href="interactive.html"' in page, "index.html links it")
    check("no interactive page" not in p.stderr, "no note on stderr (%r)" % p.stderr.strip())

    out2 = os.path.join(work, "report_other_python")
    missing = os.path.join(work, "no-such-python")
    p = run([zerog, "report", log, "--model", model, "--out", out2],
            dict(env, ZEROG_PYTHON=missing), "zerog report with ZEROG_PYTHON")
    page = open(os.path.join(out2, "index.html"), encoding="utf-8").read()
    check(not os.path.exists(os.path.join(out2, "interactive.html")),
          "ZEROG_PYTHON=%s kept: no interactive page" % missing)
    check("make_report: note: no interactive page: cannot run " + missing in p.stderr,
          "stderr says why (%r)" % p.stderr.strip())
    check('id="no-interactive"' in page and os.path.isfile(os.path.join(out2, "timeseries.png")),
          "the static report, saying why")
    print("%d passed, %d failed" % (6 - len(failures), len(failures)))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
