#!/usr/bin/python3
"""Tests of host/report/make_report.py: synthesise a bundle, render it, check the output.

Run: /usr/bin/python3 tests/report/test_make_report.py   (registered with ctest as report_script)
Set ZEROG_REPORT_KEEP=DIR to keep the rendered full report in DIR for a look.

The interactive page (interactive.html, plotly) is drawn by the Python in $ZEROG_PYTHON. The
tests give make_report.py one that cannot import plotly, unless they test the page: those use
the project's .venv python (ZEROG_TEST_VENV_PYTHON, else .venv/bin/python of this tree) and are
skipped without plotly there, but fail instead when ZEROG_REQUIRE_VENV=1 (CI; CMakeLists.txt).
The page in a real browser: test_report_browser.py.
"""

import html
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, "..", "..", "host", "report", "make_report.py")
INTERACTIVE_SCRIPT = os.path.join(HERE, "..", "..", "host", "report", "interactive_report.py")
PYTHON = "/usr/bin/python3"
AXES = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
VENV_PYTHON = os.environ.get("ZEROG_TEST_VENV_PYTHON") or os.path.join(
    HERE, "..", "..", ".venv", "bin", "python")
REQUIRE_VENV = os.environ.get("ZEROG_REQUIRE_VENV") == "1"
NO_INTERACTIVE = "make_report: note: no interactive page: "
_NO_PLOTLY = []  # the Python without plotly (setUpModule)


def setUpModule():
    # Debian's python3 without its site packages: cannot import plotly even where Debian's
    # python3-plotly is installed (nor numpy: interactive_report.py says it cannot import them).
    d = tempfile.mkdtemp(prefix="zerog-report-noplotly-")
    path = os.path.join(d, "python-without-plotly")
    with open(path, "w") as f:
        f.write('#!/bin/sh\nexec %s -S "$@"\n' % PYTHON)
    os.chmod(path, 0o755)
    _NO_PLOTLY[:] = [d, path]


def tearDownModule():
    shutil.rmtree(_NO_PLOTLY[0], ignore_errors=True)


def venv_with_plotly(test):
    """The .venv python when it imports plotly; else skips `test` (fails it in CI)."""
    why = None
    if not os.access(VENV_PYTHON, os.X_OK):
        why = "%s is missing" % VENV_PYTHON
    elif subprocess.run([VENV_PYTHON, "-c", "import plotly, numpy"],
                        capture_output=True).returncode != 0:
        why = "%s cannot import plotly" % VENV_PYTHON
    if why:
        why += " (scripts/install-deps.sh installs plotly into .venv)"
        if REQUIRE_VENV:
            test.fail(why)
        test.skipTest(why)
    return VENV_PYTHON


def rms(v):
    return math.sqrt(sum(x * x for x in v) / len(v)) if v else None


def pooled(r3):
    return math.sqrt(sum(x * x for x in r3) / 3.0)


def make_bundle(path, n=1500, floor=True, optional=True, ladder=True, diagnosis=True,
                sensor=True):
    """A 100 kg payload rotated by the wrist; the fitted model misses the rotational inertia,
    so Fy/Mx residuals grow with |omega_dot| while moving. Deterministic (fixed LCG noise).
    floor: the true model's columns (_true) and the true-model reference; sensor (with floor):
    the true model on noise-free signals (_true_clean) and the sensor floor."""
    sensor = sensor and floor
    os.makedirs(path, exist_ok=True)
    seed = [12345]

    def noise():
        seed[0] = (1103515245 * seed[0] + 12345) % (2 ** 31)
        return (seed[0] / 2 ** 31 - 0.5) * 0.6

    header = ["t_s", "moving"] + [a + "_meas" for a in AXES] + [a + "_pred" for a in AXES]
    if floor:
        header += [a + "_true" for a in AXES]
    if sensor:
        header += [a + "_true_clean" for a in AXES]
    if optional:
        header += ["q%d_rad" % j for j in range(1, 7)] + ["qd%d_radps" % j for j in range(1, 7)]
        header += ["omega_norm_radps", "omega_dot_norm_radps2", "accel_norm_mps2", "temp_C",
                   "heldout"]
    rows = []
    res = {"all": [[] for _ in AXES], "static": [[] for _ in AXES],
           "moving": [[] for _ in AXES]}
    q5s = []
    for k in range(n):
        t = 100.0 + 0.012 * k
        moving = 1 if (k // 150) % 2 == 1 else 0
        q = [0.1 * j + 0.3 * math.sin(0.01 * k + j) for j in range(6)]
        if moving:
            q[4] = 1.2 * math.sin(0.05 * k)
            q[5] = 2.0 * math.sin(0.03 * k)
        qd = [0.0] * 6
        if moving:
            qd[4] = 1.2 * 0.05 / 0.012 * math.cos(0.05 * k)
            qd[5] = 2.0 * 0.03 / 0.012 * math.cos(0.03 * k)
        w = math.hypot(qd[4], qd[5])
        wd = (abs(1.2 * (0.05 / 0.012) ** 2 * math.sin(0.05 * k)) if moving else 0.0)
        true = [-981.0 * math.sin(q[4]) * math.cos(q[5]), -981.0 * math.sin(q[5]),
                -981.0 * math.cos(q[4]), 40.0 * math.sin(q[5]), 60.0 * math.sin(q[4]), 0.5]
        missing = [0.0, 0.8 * wd, 0.0, 0.15 * wd, 0.0, 0.02 * wd]
        truth = [true[i] + missing[i] for i in range(6)]
        meas = [truth[i] + noise() * (1.0 if i < 3 else 0.05) for i in range(6)]
        pred = [true[i] + 0.2 for i in range(6)]
        row = [t, moving] + meas + pred
        if floor:
            row += truth
        if sensor:
            row += [truth[i] + 0.5 * noise() * (1.0 if i < 3 else 0.05) for i in range(6)]
        if optional:
            row += q + qd + [w, wd, 0.3 * wd, 25.0 + 0.001 * k, 1 if (k // 100) % 5 == 4 else 0]
        rows.append(row)
        for i in range(6):
            r = meas[i] - pred[i]
            res["all"][i].append(r)
            res["moving" if moving else "static"][i].append(r)
        q5s.append(q[4])
    with open(os.path.join(path, "data.csv"), "w") as f:
        f.write(",".join(header) + "\n")
        for row in rows:
            f.write(",".join("%.9g" % x for x in row) + "\n")

    def seg(name):
        if not res[name][0]:
            return {"rms": [None] * 6, "max": [None] * 6, "force_rms": None, "torque_rms": None}
        r = [rms(res[name][i]) for i in range(6)]
        return {"rms": r, "max": [max(abs(x) for x in res[name][i]) for i in range(6)],
                "force_rms": pooled(r[:3]), "torque_rms": pooled(r[3:])}

    n_mov = len(res["moving"][0])
    joint_bins = []
    for j in range(6):
        edges = [-math.pi + 2 * math.pi * b / 12 for b in range(13)]
        cnt, rr = [], []
        for b in range(12):
            cnt.append(40 if 3 <= b <= 8 else 0)
            v = 0.5 + (2.0 if j == 4 and b == 5 else 0.1 * b)
            rr.append([v, 3 * v, v, 0.1 * v, 0.1 * v, 0.02 * v] if cnt[-1] else
                      [None] * 6)
        joint_bins.append({"joint": "A%d" % (j + 1), "edges_rad": edges, "count": cnt,
                           "rms": rr})
    def rms6(f, t):
        return {"force_rms": f, "torque_rms": t, "rms": [f] * 3 + [t] * 3}
    ref = {"all": rms6(0.1732, 0.008660), "static": rms6(0.1701, 0.008512),
           "moving": rms6(0.1763, 0.008805)}
    sen = {"all": rms6(0.08123, 0.004321), "static": rms6(0.08011, 0.004298),
           "moving": rms6(0.08234, 0.004345)}
    summary = {
        "kind": "zerog-report-bundle", "version": 3,
        "title": "Test report <KR210 & payload>",
        "log": "logs/sim_payload100.csv", "model": "fits/payload100.model.json",
        "effects": ["bias", "gravity", "linear_inertia"],
        "compare": {
            "axes": AXES, "units": ["N", "N", "N", "N*m", "N*m", "N*m"],
            "samples": {"total": n, "static": n - n_mov, "moving": n_mov},
            "segments": {"all": seg("all"), "static": seg("static"), "moving": seg("moving")},
            "joint_bins": joint_bins,
            "worst": {"axis": "Fy", "segment": "moving", "joint": "A5",
                      "bin_rad": [-math.pi / 6, 0.0], "rms": 7.875},
        },
        "ladder": None, "diagnosis": None, "ladder_for": None, "diagnosis_for": None,
        "true_model_reference": ref if floor else None,
        "sensor_floor": sen if sensor else None,
        "sensor_floor_note": None if sensor or not floor else
        "run.truth.json names no noise-free log (extra.clean_signals_log: a truth from an "
        "older zerog sim, or not simulated)",
    }
    if ladder:
        steps = []
        names = [None, "gravity", "linear_inertia", "rotational_inertia", "crosstalk"]
        fr = [412.5, 36.25, 9.125, 0.2125, 0.1875]
        tr = [61.5, 4.375, 1.625, 0.0125, 0.01125]
        eff = ["bias"]
        for k, a in enumerate(names):
            if a:
                eff = eff + [a]
            steps.append({"effects": list(eff), "added": a,
                          "heldout": {"force_rms": fr[k], "torque_rms": tr[k],
                                      "rms": [fr[k]] * 3 + [tr[k]] * 3},
                          "bic": 90000.5 - 20000 * k})
        summary["ladder"] = {"steps": steps, "true_model_reference": ref,
                             "sensor_floor": sen if sensor else None}
        summary["ladder_for"] = {"match": "same",
                                 "text": "made for this log: on logs/sim_payload100.csv"}
    if diagnosis:
        def h(f, t):
            return {"force_rms": f, "torque_rms": t, "rms": [f] * 3 + [t] * 3}
        summary["diagnosis"] = {
            "model": ["bias", "gravity", "linear_inertia"],
            "baseline": h(9.125, 1.625),
            "candidates": [
                {"effect": "imu_time_offset", "heldout": h(8.5, 1.5), "gain": 0.125,
                 "delta_bic": -310.5},
                {"effect": "rotational_inertia", "heldout": h(0.2125, 0.0125), "gain": 0.9625,
                 "delta_bic": -51234.5},
                {"effect": "cable", "heldout": h(9.2, 1.7), "gain": -0.015, "delta_bic": 42.0},
            ],
            "verdict": {"kind": "effect", "effect": "rotational_inertia",
                        "text": "Residual follows the angular acceleration: add rotational "
                                "inertia.",
                        "command": "zerog fit logs/sim_payload100.csv --effects "
                                   "bias,gravity,linear_inertia,rotational_inertia"},
            "correlated_signals": [
                {"signal": "omega_dot_norm_radps2", "axis": "Fy", "correlation": 0.93},
                {"signal": "A5", "axis": "Mx", "correlation": -0.41},
                {"signal": "not_a_column", "axis": "Mz", "correlation": 0.2},
            ],
        }
        summary["diagnosis_for"] = {
            "match": "same",
            "text": "made for this model and log: model fits/payload100.model.json "
                    "[bias,gravity,linear_inertia] on logs/sim_payload100.csv"}
    with open(os.path.join(path, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    return summary


def make_bundle_with(bundle, keys):
    """The full bundle with `keys` of its summary.json replaced."""
    make_bundle(bundle)
    path = os.path.join(bundle, "summary.json")
    with open(path) as f:
        s = json.load(f)
    s.update(keys)
    with open(path, "w") as f:
        json.dump(s, f)


def run(bundle, out, python=None):
    """make_report.py BUNDLE OUT; its interactive page drawn by `python` (default: one without
    plotly, so the report is the static one)."""
    env = dict(os.environ, ZEROG_PYTHON=python or _NO_PLOTLY[1])
    return subprocess.run([PYTHON, SCRIPT, bundle, out], capture_output=True, text=True,
                          timeout=300, env=env)


def plotly_figure(page, div_id):
    """(data, layout) of the figure plotly's to_html wrote into `page` for the div `div_id`."""
    m = re.search(r'Plotly\.newPlot\(\s*"%s",\s*' % re.escape(div_id), page)
    if not m:
        raise AssertionError("no Plotly.newPlot for %s" % div_id)
    dec = json.JSONDecoder()
    data, i = dec.raw_decode(page, m.end())
    while page[i] in ", \t\r\n":
        i += 1
    return data, dec.raw_decode(page, i)[0]


def other_stderr(p):
    """stderr without the note that the report has no interactive page."""
    return "".join(x + "\n" for x in p.stderr.splitlines() if not x.startswith(NO_INTERACTIVE))


class ReportTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="zerog-report-test-")
        self.bundle = os.path.join(self.tmp, "bundle")
        self.out = os.path.join(self.tmp, "out", "report")

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def assertReportOk(self, p, interactive=False):
        self.assertEqual(p.returncode, 0, "script failed:\n" + p.stderr)
        index = os.path.join(self.out, "index.html")
        self.assertTrue(os.path.isfile(index))
        with open(index, encoding="utf-8") as f:
            page = f.read()
        pngs = re.findall(r'src="([^"]+)"', page)
        self.assertTrue(pngs, "the page shows no figures")
        for name in set(pngs):
            self.assertTrue(name.endswith(".png"), name)
            self.assertNotIn("/", name, "figures must sit beside index.html")
            path = os.path.join(self.out, name)
            self.assertTrue(os.path.isfile(path), "missing figure " + name)
            self.assertGreater(os.path.getsize(path), 1000, name)
            with open(path, "rb") as f:
                self.assertEqual(f.read(8), PNG_MAGIC, name + " is not a PNG")
        # every PNG written is referenced, and nothing else was left behind
        on_disk = set(os.listdir(self.out))
        self.assertEqual(on_disk, set(pngs) | {"index.html"} |
                         ({"interactive.html"} if interactive else set()))
        self.assertEqual('href="interactive.html"' in page, interactive)
        self.assertEqual('id="no-interactive"' in page, not interactive)
        self.assertEqual(os.listdir(os.path.dirname(self.out)), ["report"],
                         "temporary folders left beside OUT_DIR")
        return page, set(pngs)

    def assertFailsCleanly(self, p, *words):
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("make_report: error:", p.stderr)
        for w in words:
            self.assertIn(w, p.stderr)
        self.assertNotIn("Traceback", p.stderr)
        self.assertFalse(os.path.exists(self.out), "OUT_DIR created on failure")
        parent = os.path.dirname(self.out)
        self.assertEqual(os.listdir(parent) if os.path.isdir(parent) else [], [],
                         "leftovers beside OUT_DIR")

    def test_full_bundle(self):
        s = make_bundle(self.bundle)
        p = run(self.bundle, self.out)
        page, pngs = self.assertReportOk(p)
        self.assertEqual(pngs, {"timeseries.png", "residual_hist.png", "diagnosis_signals.png",
                                "residual_vs_signals.png", "joint_bins.png", "ladder.png",
                                "diagnosis.png"})
        self.assertEqual(other_stderr(p), "", "no warnings expected on a consistent bundle")
        # header, verdict, command (escaped), paths
        self.assertIn("Test report &lt;KR210 &amp; payload&gt;", page)
        self.assertIn("logs/sim_payload100.csv", page)
        self.assertIn("fits/payload100.model.json", page)
        self.assertIn("linear_inertia", page)
        self.assertIn(s["diagnosis"]["verdict"]["text"], page)
        self.assertIn(s["diagnosis"]["verdict"]["command"], page)
        # made for this model and log: the diagnosis is the verdict, nothing is labelled foreign
        self.assertIn('<div class="verdict effect" id="verdict">', page)
        self.assertIn("Missing effect: <b>rotational_inertia</b>", page)
        self.assertIn("Diagnosis: which effect is missing", page)
        self.assertNotIn('class="foreign"', page)
        # key numbers (formatted with 4 significant digits)
        seg = s["compare"]["segments"]
        for g in ("all", "static", "moving"):
            self.assertIn("%.4g" % seg[g]["force_rms"], page)
            self.assertIn("%.4g" % seg[g]["torque_rms"], page)
            self.assertIn("%.4g" % seg[g]["rms"][1], page)
        self.assertIn("%.4g" % seg["all"]["max"][2], page)
        self.assertIn("0.1732", page)        # true-model reference, all
        self.assertIn("0.1763", page)        # true-model reference, moving force
        self.assertIn("0.08123", page)       # sensor floor, all
        self.assertIn("0.004345", page)      # sensor floor, moving torque
        self.assertIn("True-model reference", page)
        self.assertIn("Sensor floor", page)
        self.assertNotIn("noise floor", page.lower())
        self.assertIn("7.875", page)         # worst bin RMS
        self.assertIn("412.5", page)         # ladder step 0
        self.assertIn("0.2125", page)        # ladder step 3 / best candidate
        self.assertIn("96.2 %", page)        # best gain
        self.assertIn("-51234.5", page)      # its delta BIC
        self.assertIn("rotational_inertia", page)
        self.assertIn("not_a_column", page)  # listed as not plotted
        self.assertNotIn("Decimated for plotting", page)

    def test_minimal_bundle(self):
        make_bundle(self.bundle, floor=False, optional=False, ladder=False, diagnosis=False)
        page, pngs = self.assertReportOk(run(self.bundle, self.out))
        self.assertEqual(pngs, {"timeseries.png", "residual_hist.png", "joint_bins.png"})
        self.assertIn("No true-model reference and no sensor floor", page)
        self.assertNotIn('id="ladder"', page)
        self.assertNotIn('id="verdict"', page)

    def test_static_only_with_nulls(self):
        s = make_bundle(self.bundle, n=300)
        path = os.path.join(self.bundle, "data.csv")
        with open(path) as f:
            lines = f.read().splitlines()
        h = lines[0].split(",")
        out = [lines[0]]
        for k, line in enumerate(lines[1:]):
            c = line.split(",")
            for name in ("moving", "omega_norm_radps", "omega_dot_norm_radps2"):
                c[h.index(name)] = "0"
            if k == 3:
                c[h.index("temp_C")] = "nan"   # allowed outside the required columns
            out.append(",".join(c))
        with open(path, "w") as f:
            f.write("\n".join(out) + "\n")
        s["compare"]["segments"]["moving"] = {"rms": [None] * 6, "max": [None] * 6,
                                              "force_rms": None, "torque_rms": None}
        s["compare"]["samples"]["total"] = 301       # mismatch: a warning, not an error
        s["compare"]["joint_bins"] = []
        s["compare"]["worst"] = None
        s["ladder"] = {"steps": [], "true_model_reference": None, "sensor_floor": None}
        s["diagnosis"]["candidates"] = []
        s["diagnosis"]["correlated_signals"] = []
        s["diagnosis"]["verdict"] = {"kind": "nothing_left", "effect": None,
                                     "text": "The residual is at the noise level.",
                                     "command": None}
        with open(os.path.join(self.bundle, "summary.json"), "w") as f:
            json.dump(s, f)
        p = run(self.bundle, self.out)
        page, pngs = self.assertReportOk(p)
        self.assertIn("warning", p.stderr)
        self.assertIn("301", page)
        self.assertIn("The residual is at the noise level.", page)
        self.assertIn("The ladder has no steps", page)
        self.assertIn("No joint-angle bins", page)
        self.assertNotIn("ladder.png", pngs)

    def test_discovered_law_in_the_verdict(self):
        # The verdict "discovered" (proto/json_output.md): its law is shown; without terms it is
        # an error that names the key.
        make_bundle(self.bundle)
        with open(os.path.join(self.bundle, "summary.json")) as f:
            s = json.load(f)
        law = "Mz += 1.499 ± 0.00053 N*m · tanh(qd6/0.02)"
        s["diagnosis"]["verdict"] = {"kind": "discovered", "effect": None,
                                     "effect_file": "discovered.toml",
                                     "text": "No library effect explains the remaining structure.",
                                     "command": "zerog fit run.csv --effects bias,@discovered.toml"}
        s["diagnosis"]["discovery"] = {"terms": [{"law": law}]}
        with open(os.path.join(self.bundle, "summary.json"), "w") as f:
            json.dump(s, f)
        page, _ = self.assertReportOk(run(self.bundle, self.out))
        self.assertIn('class="verdict discovered"', page)
        self.assertIn(html.escape(law), page)
        self.assertIn("bias,@discovered.toml", page)
        s["diagnosis"]["discovery"] = None
        with open(os.path.join(self.bundle, "summary.json"), "w") as f:
            json.dump(s, f)
        p = run(self.bundle, self.out + "2")
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("diagnosis.discovery", p.stderr)

    def _with(self, **keys):
        """The full bundle with `keys` of summary.json replaced; returns the rendered page."""
        make_bundle_with(self.bundle, keys)
        page, _ = self.assertReportOk(run(self.bundle, self.out))
        return page

    def test_diagnosis_of_another_model_is_labelled_not_the_verdict(self):
        text = ("made for model fits/other.json [bias,gravity] on logs/sim_payload100.csv; "
                "this report is for model fits/payload100.model.json "
                "[bias,gravity,linear_inertia] on logs/sim_payload100.csv")
        page = self._with(diagnosis_for={"match": "other", "text": text})
        self.assertNotIn('id="verdict"', page)
        self.assertNotIn('class="verdict', page)
        self.assertNotIn("Missing effect: <b>", page)
        self.assertNotIn("Diagnosis: which effect is missing", page)
        self.assertIn('<div class="foreign"><b>Diagnosis of another model or log</b>: '
                      + html.escape(text, quote=True), page)
        self.assertIn('<h2 id="diagnosis">Diagnosis of another model or log</h2>', page)
        # its verdict, labelled as that model's
        self.assertIn("Its verdict, for the model it was made for and not necessarily for this "
                      "one: Residual follows the angular acceleration", page)
        self.assertIn("made for another model or log, see below", page)

    def test_diagnosis_made_for_an_unknown_model_is_labelled(self):
        text = ("it does not say which model and log it was made for (written by an older "
                "zerog); this report is for model fits/payload100.model.json "
                "[bias,gravity,linear_inertia] on logs/sim_payload100.csv")
        page = self._with(diagnosis_for={"match": "unknown", "text": text})
        self.assertNotIn('id="verdict"', page)
        self.assertNotIn("Missing effect: <b>", page)
        self.assertIn("<b>Diagnosis made for an unknown model</b>: " + html.escape(text), page)
        self.assertIn('<h2 id="diagnosis">Diagnosis made for an unknown model</h2>', page)

    def test_ladder_of_another_log_is_labelled_and_gives_no_floors(self):
        # Without floors in summary.json the ladder's are the report's yardsticks, but only when
        # the ladder was made on this log; else they come from data.csv.
        for match, source in (("same", "the ladder (held-out blocks)"),
                              ("other", "computed from data.csv")):
            page = self._with(true_model_reference=None, sensor_floor=None,
                              ladder_for={"match": match, "text": "made on logs/x.csv"})
            self.assertEqual(page.count('<td class="l">%s</td>' % source), 2, match)
            self.assertEqual("Ladder of another log" in page, match == "other")
            shutil.rmtree(self.out)

    def test_diagnosis_for_is_required_with_a_diagnosis(self):
        make_bundle(self.bundle)
        path = os.path.join(self.bundle, "summary.json")
        with open(path) as f:
            s = json.load(f)
        for bad, words in ((None, ("diagnosis_for", "expected an object")),
                           ({"match": "mine", "text": "x"}, ("diagnosis_for.match", "mine"))):
            s["diagnosis_for"] = bad
            with open(path, "w") as f:
                json.dump(s, f)
            self.assertFailsCleanly(run(self.bundle, self.out), *words)

    def test_decimation_and_speed(self):
        make_bundle(self.bundle, n=30000)
        t0 = time.time()
        page, pngs = self.assertReportOk(run(self.bundle, self.out))
        self.assertIn("timeseries_zoom.png", pngs)
        self.assertIn("Decimated for plotting", page)
        self.assertIn("30000 samples", page)
        self.assertLess(time.time() - t0, 60)
        keep = os.environ.get("ZEROG_REPORT_KEEP")
        if keep:
            shutil.rmtree(keep, ignore_errors=True)
            shutil.copytree(self.out, keep)

    def test_replaces_existing_out_dir(self):
        make_bundle(self.bundle, ladder=False)
        os.makedirs(self.out)
        with open(os.path.join(self.out, "stale.png"), "w") as f:
            f.write("old")
        self.assertReportOk(run(self.bundle, self.out))
        self.assertFalse(os.path.exists(os.path.join(self.out, "stale.png")))

    def test_failure_keeps_existing_out_dir(self):
        make_bundle(self.bundle)
        os.makedirs(self.out)
        with open(os.path.join(self.out, "index.html"), "w") as f:
            f.write("previous report")
        with open(os.path.join(self.bundle, "summary.json")) as f:
            s = json.load(f)
        s["version"] = 1
        with open(os.path.join(self.bundle, "summary.json"), "w") as f:
            json.dump(s, f)
        p = run(self.bundle, self.out)
        self.assertNotEqual(p.returncode, 0)
        with open(os.path.join(self.out, "index.html")) as f:
            self.assertEqual(f.read(), "previous report")
        self.assertEqual(os.listdir(os.path.dirname(self.out)), ["report"])

    def test_missing_column(self):
        make_bundle(self.bundle)
        path = os.path.join(self.bundle, "data.csv")
        with open(path) as f:
            lines = f.read().splitlines()
        drop = lines[0].split(",").index("Fy_pred")
        with open(path, "w") as f:
            for line in lines:
                cells = line.split(",")
                del cells[drop]
                f.write(",".join(cells) + "\n")
        self.assertFailsCleanly(run(self.bundle, self.out), "data.csv", "Fy_pred", "missing")

    def test_wrong_version(self):
        make_bundle(self.bundle)
        path = os.path.join(self.bundle, "summary.json")
        with open(path) as f:
            s = json.load(f)
        s["version"] = 1  # before the two floors: noise_floor is gone
        with open(path, "w") as f:
            json.dump(s, f)
        self.assertFailsCleanly(run(self.bundle, self.out), "summary.json", "version", "1")

    def test_reference_without_sensor_floor(self):
        # A truth that names no noise-free log: the reference only, and the page says why.
        s = make_bundle(self.bundle, sensor=False)
        page, _ = self.assertReportOk(run(self.bundle, self.out))
        self.assertIn("0.1732", page)
        self.assertNotIn("0.08123", page)
        self.assertNotIn("sensor floor RMS", page)
        self.assertIn("No sensor floor: " + s["sensor_floor_note"], page)

    def test_floors_computed_from_columns(self):
        # Without the floors in summary.json or the ladder, both come from the _true columns.
        make_bundle(self.bundle, ladder=False)
        path = os.path.join(self.bundle, "summary.json")
        with open(path) as f:
            s = json.load(f)
        s["true_model_reference"] = s["sensor_floor"] = None
        with open(path, "w") as f:
            json.dump(s, f)
        page, _ = self.assertReportOk(run(self.bundle, self.out))
        self.assertEqual(page.count('<td class="l">computed from data.csv</td>'), 2)
        self.assertNotIn("0.1732", page)
        with open(os.path.join(self.bundle, "data.csv")) as f:
            rows = f.read().splitlines()
        h = rows[0].split(",")
        for suffix in ("_true", "_true_clean"):
            ss = 0.0
            for line in rows[1:]:
                c = [float(x) for x in line.split(",")]
                ss += sum((c[h.index(a + "_meas")] - c[h.index(a + suffix)]) ** 2
                          for a in AXES[:3])
            self.assertIn("%.4g" % math.sqrt(ss / (3 * (len(rows) - 1))), page, suffix)

    def test_true_columns_all_six_or_none(self):
        make_bundle(self.bundle)
        path = os.path.join(self.bundle, "data.csv")
        with open(path) as f:
            lines = f.read().splitlines()
        drop = lines[0].split(",").index("Mz_true_clean")
        with open(path, "w") as f:
            for line in lines:
                cells = line.split(",")
                del cells[drop]
                f.write(",".join(cells) + "\n")
        self.assertFailsCleanly(run(self.bundle, self.out), "data.csv", "_true_clean",
                                "Mz_true_clean")

    def test_ladder_plot_reads_both_floors_and_version_1(self):
        # zerog ladder --plot: version 2 has both floors; a version-1 ladder's noise_floor is
        # read as the true-model reference.
        s = make_bundle(self.bundle)
        png = os.path.join(self.tmp, "ladder.png")
        for doc in ({"kind": "zerog-ladder", "version": 2, **s["ladder"]},
                    {"kind": "zerog-ladder", "version": 1, "steps": s["ladder"]["steps"],
                     "noise_floor": s["ladder"]["true_model_reference"]["all"]}):
            path = os.path.join(self.tmp, "ladder.json")
            with open(path, "w") as f:
                json.dump(doc, f)
            p = subprocess.run([PYTHON, SCRIPT, "--ladder-plot", path, png],
                               capture_output=True, text=True, timeout=120)
            self.assertEqual(p.returncode, 0, p.stderr)
            with open(png, "rb") as f:
                self.assertEqual(f.read(8), PNG_MAGIC)
            os.remove(png)

    def test_missing_file(self):
        make_bundle(self.bundle)
        os.remove(os.path.join(self.bundle, "data.csv"))
        self.assertFailsCleanly(run(self.bundle, self.out), "data.csv", "missing file")

    def test_bad_json(self):
        make_bundle(self.bundle)
        with open(os.path.join(self.bundle, "summary.json"), "w") as f:
            f.write('{"kind": "zerog-report-bundle", "version": 1,,}')
        self.assertFailsCleanly(run(self.bundle, self.out), "summary.json", "bad JSON", "line 1")

    def test_malformed_key(self):
        make_bundle(self.bundle)
        path = os.path.join(self.bundle, "summary.json")
        with open(path) as f:
            s = json.load(f)
        s["compare"]["segments"]["moving"]["rms"] = [1.0, 2.0]
        with open(path, "w") as f:
            json.dump(s, f)
        self.assertFailsCleanly(run(self.bundle, self.out), "summary.json",
                                "compare.segments.moving.rms", "expected 6")

    def test_bad_cell(self):
        make_bundle(self.bundle)
        path = os.path.join(self.bundle, "data.csv")
        with open(path) as f:
            lines = f.read().splitlines()
        cells = lines[5].split(",")
        cells[3] = "abc"
        lines[5] = ",".join(cells)
        with open(path, "w") as f:
            f.write("\n".join(lines) + "\n")
        self.assertFailsCleanly(run(self.bundle, self.out), "data.csv", "line 6", "abc")

    def test_refuses_bundle_as_out_dir(self):
        make_bundle(self.bundle)
        before = sorted(os.listdir(self.bundle))
        p = run(self.bundle, self.bundle)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("refusing", p.stderr)
        self.assertEqual(sorted(os.listdir(self.bundle)), before)
        p = run(self.bundle, self.tmp)  # OUT_DIR containing the bundle would delete it
        self.assertNotEqual(p.returncode, 0)
        self.assertTrue(os.path.isfile(os.path.join(self.bundle, "summary.json")))

    # -- the interactive page (interactive.html; in a browser: test_report_browser.py)

    def test_without_plotly_the_static_report_says_why(self):
        # (the minimal bundle: fewer figures to draw)
        make_bundle(self.bundle, floor=False, optional=False, ladder=False, diagnosis=False)
        p = run(self.bundle, self.out)
        page, pngs = self.assertReportOk(p)
        self.assertIn("timeseries.png", pngs)
        self.assertEqual(p.stderr.count(NO_INTERACTIVE), 1, p.stderr)
        for words in ("cannot import plotly", "scripts/install-deps.sh"):
            self.assertIn(words, p.stderr)
            self.assertIn(html.escape(words), page)
        self.assertNotIn("Traceback", p.stderr)

    def test_a_failing_interactive_page_leaves_the_static_report(self):
        make_bundle(self.bundle, floor=False, optional=False, ladder=False, diagnosis=False)
        for python, words in (("/nonexistent/python", "cannot run /nonexistent/python"),
                              ("/bin/false", "interactive_report.py failed (exit status 1)")):
            p = run(self.bundle, self.out, python)
            page, _ = self.assertReportOk(p)
            self.assertIn(NO_INTERACTIVE + words, p.stderr)
            self.assertIn(html.escape(words), page)
            shutil.rmtree(self.out)

    def _interactive(self, **summary):
        """interactive.html of the full bundle (summary.json's keys replaced by `summary`),
        written by interactive_report.py alone with the .venv's plotly."""
        python = venv_with_plotly(self)
        make_bundle_with(self.bundle, summary)
        out = os.path.join(self.tmp, "interactive.html")
        p = subprocess.run([python, INTERACTIVE_SCRIPT, self.bundle, out], capture_output=True,
                           text=True, timeout=300)
        self.assertEqual((p.returncode, p.stderr), (0, ""))
        with open(out, encoding="utf-8") as f:
            return f.read()

    def test_interactive_page_is_self_contained(self):
        # through make_report.py, as zerog report runs it: the page beside index.html, linked
        make_bundle(self.bundle)
        p = run(self.bundle, self.out, venv_with_plotly(self))
        page, _ = self.assertReportOk(p, interactive=True)
        self.assertEqual(p.stderr, "")
        with open(os.path.join(self.out, "interactive.html"), encoding="utf-8") as f:
            ia = f.read()
        # plotly.js is in the page; no script, style or font comes from elsewhere (offline)
        self.assertRegex(ia, r"plotly\.js v\d+\.\d+")
        self.assertIsNone(re.search(r"<script[^>]*\ssrc\s*=", ia), "a script loaded by src")
        self.assertFalse('src="http' in ia)
        self.assertIsNone(re.search(r"<link[^>]*href", ia), "a stylesheet loaded by href")
        self.assertIsNone(re.search(r"@import|url\(\s*['\"]?https?:", ia))
        self.assertLess(os.path.getsize(os.path.join(self.out, "interactive.html")), 8e6)
        # both figures, the pose line and the way back
        for needle in ('id="timeseries"', 'id="vs_signal"', 'id="pose"', 'id="zerog-pose"',
                       'href="index.html"', "Test report &lt;KR210 &amp; payload&gt;",
                       "all 1500 samples"):
            self.assertTrue(needle in ia, needle)
        # the index links it above the tables and under the time series
        self.assertEqual(page.count('href="interactive.html"'), 2)

    def test_interactive_page_shades_what_the_bundle_marks(self):
        # moving segments and held-out blocks from data.csv; the events of a diagnosis of this
        # model only (as in timeseries.png), clipped to the log
        def shapes(ia):
            out = {}
            for sh in plotly_figure(ia, "timeseries")[1]["shapes"]:
                out.setdefault(sh["name"], []).append(sh)
            return out
        ia = self._interactive()
        sh = shapes(ia)
        self.assertEqual(sorted(sh), ["held-out block", "moving segment"])
        half = 0.006  # half a sample period: a run covers its samples' whole periods
        self.assertEqual([(round(x["x0"], 6), round(x["x1"], 6)) for x in sh["moving segment"]],
                         [(round(100 + 0.012 * a - half, 6), round(100 + 0.012 * b + half, 6))
                          for a, b in ((150, 299), (450, 599), (750, 899), (1050, 1199),
                                       (1350, 1499))])
        self.assertEqual(len(sh["held-out block"]), 2 * 3)  # rows 400-499, 900-999, 1400-1499
        self.assertEqual({x["yref"] for x in sh["held-out block"]}, {"y2 domain", "y4 domain"})
        self.assertEqual([x["showlegend"] for x in sh["moving segment"]], [True] + [False] * 4)
        events = [{"t0_s": 105.0, "t1_s": 106.5}, {"t0_s": 110.0, "t1_s": 999.0},
                  {"t0_s": 10.0, "t1_s": 20.0}]   # the last one before the log
        verdict = {"kind": "event", "effect": None, "command": None,
                   "text": "Two spans are events, not physics."}
        with open(os.path.join(self.bundle, "summary.json")) as f:
            dg = json.load(f)["diagnosis"]
        dg.update(verdict=verdict, events=events)
        ia = self._interactive(diagnosis=dg)
        ev = shapes(ia)["event (diagnosis)"]
        self.assertEqual([(x["x0"], round(x["x1"], 6)) for x in ev],
                         [(105.0, 106.5), (110.0, round(100 + 0.012 * 1499, 6))])
        self.assertTrue("the diagnosis' events (red, 2)" in ia)
        ia = self._interactive(diagnosis=dg, diagnosis_for={"match": "other", "text": "x"})
        self.assertNotIn("event (diagnosis)", shapes(ia))

    def test_interactive_dropdown_offers_every_signal(self):
        ia = self._interactive()
        menu = plotly_figure(ia, "timeseries")[1]["updatemenus"][0]["buttons"]
        self.assertEqual([b["label"] for b in menu], ["all axes", "forces", "torques"] + AXES)
        data = plotly_figure(ia, "timeseries")[0]
        for b in menu[3:]:  # each axis button shows that axis' traces and hides the others
            self.assertEqual([v is not False for v in b["args"][0]["visible"]],
                             [d["meta"]["axis"] == b["label"] for d in data], b["label"])
        _, layout = plotly_figure(ia, "vs_signal")
        signals = [b["label"] for b in layout["updatemenus"][0]["buttons"]]
        # the diagnosis' correlated signals first (its missing column left out), then the
        # joint angles and velocities, the IMU's norms, temperature, time
        self.assertEqual(signals[:2], ["|ω̇| (rad/s²)", "A5 angle (deg)"])
        for x in ("A1 angle (deg)", "A6 velocity (rad/s)", "|ω| (rad/s)", "|f − g| (m/s²)",
                  "temperature (°C)", "time t_s (s)"):
            self.assertIn(x, signals)
        self.assertEqual(len(signals), len(set(signals)))
        self.assertFalse([x for x in signals if "not_a_column" in x or "_meas" in x])


if __name__ == "__main__":
    unittest.main(verbosity=2)
