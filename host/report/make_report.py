#!/usr/bin/python3
"""Render a zerog report bundle (proto/report_bundle.md) into OUT_DIR/index.html + PNG figures.

Usage: /usr/bin/python3 make_report.py BUNDLE_DIR OUT_DIR

Run by `zerog report`. The script only draws what the bundle holds; it never refits. It needs
the standard library, numpy and matplotlib (Debian's python3). The interactive page beside
index.html (interactive.html: zoomable time series, residual against any signal) is plotly's,
a PyPI package in the project's .venv: interactive_report.py, installed beside this file, draws
it with $ZEROG_PYTHON (zerog report sets it to the .venv's python), else with this Python.
Without plotly there the report is the static one and says why (interactive_page below).
"""

import argparse
import csv
import html
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

BUNDLE_KIND = "zerog-report-bundle"
BUNDLE_VERSION = 3
# What a diagnosis or ladder was made for, against the model and log of the report.
MATCHES = ("same", "other", "unknown")
AXES = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
# Column suffixes of the true model's predictions: on the log's signals (meas − it: the
# true-model reference) and on noise-free signals (meas − it: the sensor floor).
TRUE_SUFFIXES = ("_true", "_true_clean")
UNITS = ["N", "N", "N", "N·m", "N·m", "N·m"]
MAX_PLOT_POINTS = 20000      # per curve in the time-series figure
MAX_SCATTER_POINTS = 5000    # per scatter panel
ZOOM_SAMPLES = 1500           # width of the zoomed time-series window
N_SIGNAL_BINS = 40
MAX_CORRELATED = 6
INTERACTIVE = "interactive.html"   # the interactive page, beside index.html
EXIT_NO_PLOTLY = 3                  # interactive_report.py: plotly is not installed there
AXIS_COLORS = ["tab:blue", "tab:orange", "tab:green", "tab:blue", "tab:orange", "tab:green"]

SHORT_SIGNALS = {
    "t": "t_s", "time": "t_s", "omega_norm": "omega_norm_radps", "|omega|": "omega_norm_radps",
    "omega_dot_norm": "omega_dot_norm_radps2", "|omega_dot|": "omega_dot_norm_radps2",
    "accel_norm": "accel_norm_mps2", "temp": "temp_C", "temperature": "temp_C",
}
for _j in range(1, 7):
    SHORT_SIGNALS["A%d" % _j] = "q%d_rad" % _j
    SHORT_SIGNALS["q%d" % _j] = "q%d_rad" % _j
    SHORT_SIGNALS["qd%d" % _j] = "qd%d_radps" % _j


class BundleError(Exception):
    """A malformed bundle or a refused output; the message names the file and the problem."""


# ---------------------------------------------------------------------------------------------
# Loading and validation


def _is_num(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool)


class _Checker:
    """Type checks on the parsed summary.json; errors name the file and the JSON path."""

    def __init__(self, path):
        self.path = path

    def fail(self, where, problem):
        raise BundleError("%s: %s: %s" % (self.path, where, problem))

    def obj(self, v, where, keys=()):
        if not isinstance(v, dict):
            self.fail(where, "expected an object, got %s" % _jtype(v))
        for k in keys:
            if k not in v:
                self.fail(where, "missing key '%s'" % k)
        return v

    def lst(self, v, where, n=None):
        if not isinstance(v, list):
            self.fail(where, "expected a list, got %s" % _jtype(v))
        if n is not None and len(v) != n:
            self.fail(where, "expected %d entries, got %d" % (n, len(v)))
        return v

    def num(self, v, where, nullable=True):
        if v is None and nullable:
            return None
        if not _is_num(v):
            self.fail(where, "expected a number%s, got %s" % (" or null" if nullable else "",
                                                               _jtype(v)))
        return float(v)

    def nums(self, v, where, n=None, nullable=True):
        self.lst(v, where, n)
        return [self.num(x, "%s[%d]" % (where, i), nullable) for i, x in enumerate(v)]

    def string(self, v, where, nullable=False):
        if v is None and nullable:
            return None
        if not isinstance(v, str):
            self.fail(where, "expected a string%s, got %s" % (" or null" if nullable else "",
                                                               _jtype(v)))
        return v

    def strings(self, v, where):
        self.lst(v, where)
        return [self.string(x, "%s[%d]" % (where, i)) for i, x in enumerate(v)]

    def rms6(self, v, where, nullable=False):
        if v is None and nullable:
            return None
        self.obj(v, where, ("force_rms", "torque_rms", "rms"))
        return {"force_rms": self.num(v["force_rms"], where + ".force_rms"),
                "torque_rms": self.num(v["torque_rms"], where + ".torque_rms"),
                "rms": self.nums(v["rms"], where + ".rms", 6)}

    def floors(self, v, where):
        """FLOORS: {"all": RMS6, "static": RMS6 or null, "moving": RMS6 or null}, or null."""
        if v is None:
            return None
        self.obj(v, where, ("all",))
        return {"all": self.rms6(v["all"], where + ".all"),
                "static": self.rms6(v.get("static"), where + ".static", True),
                "moving": self.rms6(v.get("moving"), where + ".moving", True)}


def _jtype(v):
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "a boolean"
    if _is_num(v):
        return "a number"
    if isinstance(v, str):
        return "a string"
    if isinstance(v, list):
        return "a list"
    return "an object"


def load_summary(path):
    if not os.path.isfile(path):
        raise BundleError("%s: missing file" % path)
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except json.JSONDecodeError as e:
        raise BundleError("%s: bad JSON at line %d column %d: %s" % (path, e.lineno, e.colno,
                                                                    e.msg))
    except (OSError, UnicodeDecodeError) as e:
        raise BundleError("%s: cannot read: %s" % (path, e))
    c = _Checker(path)
    c.obj(doc, "top level", ("kind", "version"))
    if doc["kind"] != BUNDLE_KIND:
        c.fail("kind", "expected '%s', got %s" % (BUNDLE_KIND, json.dumps(doc["kind"])))
    if doc["version"] != BUNDLE_VERSION or isinstance(doc["version"], bool):
        c.fail("version", "unsupported bundle version %s (this script reads version %d)"
               % (json.dumps(doc["version"]), BUNDLE_VERSION))
    c.obj(doc, "top level", ("title", "log", "model", "effects", "compare"))
    s = {"title": c.string(doc["title"], "title"),
         "log": c.string(doc["log"], "log"),
         "model": c.string(doc["model"], "model"),
         "effects": c.strings(doc["effects"], "effects")}

    # compare
    cmp_ = c.obj(doc["compare"], "compare", ("axes", "samples", "segments", "joint_bins"))
    axes = c.strings(cmp_["axes"], "compare.axes")
    if axes != AXES:
        c.fail("compare.axes", "expected %s, got %s" % (json.dumps(AXES), json.dumps(axes)))
    smp = c.obj(cmp_["samples"], "compare.samples", ("total", "static", "moving"))
    samples = {k: c.num(smp[k], "compare.samples." + k, nullable=False)
               for k in ("total", "static", "moving")}
    segs = c.obj(cmp_["segments"], "compare.segments", ("all", "static", "moving"))
    segments = {}
    for name in ("all", "static", "moving"):
        w = "compare.segments." + name
        g = c.obj(segs[name], w, ("rms", "max", "force_rms", "torque_rms"))
        segments[name] = {"rms": c.nums(g["rms"], w + ".rms", 6),
                          "max": c.nums(g["max"], w + ".max", 6),
                          "force_rms": c.num(g["force_rms"], w + ".force_rms"),
                          "torque_rms": c.num(g["torque_rms"], w + ".torque_rms")}
    joint_bins = []
    for i, jb in enumerate(c.lst(cmp_["joint_bins"], "compare.joint_bins")):
        w = "compare.joint_bins[%d]" % i
        c.obj(jb, w, ("joint", "edges_rad", "count", "rms"))
        edges = c.nums(jb["edges_rad"], w + ".edges_rad", nullable=False)
        k = len(edges) - 1
        if k < 1:
            c.fail(w + ".edges_rad", "needs at least 2 edges")
        if any(b <= a for a, b in zip(edges, edges[1:])):
            c.fail(w + ".edges_rad", "edges must increase")
        count = c.nums(jb["count"], w + ".count", k, nullable=False)
        rms = [c.nums(r, "%s.rms[%d]" % (w, b), 6)
               for b, r in enumerate(c.lst(jb["rms"], w + ".rms", k))]
        joint_bins.append({"joint": c.string(jb["joint"], w + ".joint"), "edges_rad": edges,
                           "count": count, "rms": rms})
    worst = cmp_.get("worst")
    if worst is not None:
        c.obj(worst, "compare.worst", ("axis", "segment", "joint", "bin_rad", "rms"))
        worst = {"axis": c.string(worst["axis"], "compare.worst.axis"),
                 "segment": c.string(worst["segment"], "compare.worst.segment"),
                 "joint": c.string(worst["joint"], "compare.worst.joint"),
                 "bin_rad": c.nums(worst["bin_rad"], "compare.worst.bin_rad", 2,
                                   nullable=False),
                 "rms": c.num(worst["rms"], "compare.worst.rms")}
    s["compare"] = {"samples": samples, "segments": segments, "joint_bins": joint_bins,
                    "worst": worst}

    # ladder
    lad = doc.get("ladder")
    if lad is not None:
        c.obj(lad, "ladder", ("steps",))
        steps = []
        for i, st in enumerate(c.lst(lad["steps"], "ladder.steps")):
            w = "ladder.steps[%d]" % i
            c.obj(st, w, ("effects", "added", "heldout", "bic"))
            steps.append({"effects": c.strings(st["effects"], w + ".effects"),
                          "added": c.string(st["added"], w + ".added", nullable=True),
                          "heldout": c.rms6(st["heldout"], w + ".heldout"),
                          "bic": c.num(st["bic"], w + ".bic")})
        ref, sensor = _ladder_floors(lad, c)
        lad = {"steps": steps, "true_model_reference": ref, "sensor_floor": sensor,
               "made_for": _made_for(doc, "ladder_for", c)}
    s["ladder"] = lad

    # diagnosis
    dg = doc.get("diagnosis")
    if dg is not None:
        c.obj(dg, "diagnosis", ("model", "baseline", "candidates", "verdict"))
        cands = []
        for i, cd in enumerate(c.lst(dg["candidates"], "diagnosis.candidates")):
            w = "diagnosis.candidates[%d]" % i
            c.obj(cd, w, ("effect", "heldout", "gain", "delta_bic"))
            cands.append({"effect": c.string(cd["effect"], w + ".effect"),
                          "heldout": c.rms6(cd["heldout"], w + ".heldout"),
                          "gain": c.num(cd["gain"], w + ".gain"),
                          "delta_bic": c.num(cd["delta_bic"], w + ".delta_bic")})
        v = c.obj(dg["verdict"], "diagnosis.verdict", ("kind", "text"))
        kind = c.string(v["kind"], "diagnosis.verdict.kind")
        if kind not in ("effect", "none", "nothing_left", "discovered", "event", "outliers"):
            c.fail("diagnosis.verdict.kind",
                   "expected \"effect\", \"none\", \"nothing_left\", \"discovered\", "
                   "\"event\" or \"outliers\", got %s" % json.dumps(kind))
        verdict = {"kind": kind,
                   "effect": c.string(v.get("effect"), "diagnosis.verdict.effect", True),
                   "text": c.string(v["text"], "diagnosis.verdict.text"),
                   "command": c.string(v.get("command"), "diagnosis.verdict.command", True)}
        if kind == "effect" and not verdict["effect"]:
            c.fail("diagnosis.verdict.effect", "must name the effect when kind is \"effect\"")
        # A law found in the signal dictionary (proto/user_effects.md): its terms in plain text.
        laws = []
        found = dg.get("discovery")
        if found is not None:
            c.obj(found, "diagnosis.discovery", ("terms",))
            for i, t in enumerate(c.lst(found["terms"], "diagnosis.discovery.terms")):
                c.obj(t, "diagnosis.discovery.terms[%d]" % i, ("law",))
                laws.append(c.string(t["law"], "diagnosis.discovery.terms[%d].law" % i))
        if kind == "discovered" and not laws:
            c.fail("diagnosis.discovery", "must hold the law's terms when kind is \"discovered\"")
        verdict["laws"] = laws
        # Spans the verdict calls events (diagnosis version 3; docs/insight-loop.md, "Events are
        # not physics"): shaded in the time series.
        events = []
        for i, ev in enumerate(c.lst(dg.get("events", []), "diagnosis.events")):
            we = "diagnosis.events[%d]" % i
            c.obj(ev, we, ("t0_s", "t1_s"))
            events.append((c.num(ev["t0_s"], we + ".t0_s"), c.num(ev["t1_s"], we + ".t1_s")))
        if kind == "event" and not events:
            c.fail("diagnosis.events", "must name the spans when kind is \"event\"")
        verdict["events"] = events
        corr = []
        for i, cs in enumerate(c.lst(dg.get("correlated_signals", []),
                                     "diagnosis.correlated_signals")):
            w = "diagnosis.correlated_signals[%d]" % i
            c.obj(cs, w, ("signal", "axis", "correlation"))
            ax = c.string(cs["axis"], w + ".axis")
            if ax not in AXES:
                c.fail(w + ".axis", "expected one of %s, got %s" % (", ".join(AXES),
                                                                     json.dumps(ax)))
            corr.append({"signal": c.string(cs["signal"], w + ".signal"), "axis": ax,
                         "correlation": c.num(cs["correlation"], w + ".correlation")})
        dg = {"model": c.strings(dg["model"], "diagnosis.model"),
              "baseline": c.rms6(dg["baseline"], "diagnosis.baseline"),
              "candidates": cands, "verdict": verdict, "correlated_signals": corr,
              "made_for": _made_for(doc, "diagnosis_for", c)}
    s["diagnosis"] = dg
    s["true_model_reference"] = c.floors(doc.get("true_model_reference"),
                                         "true_model_reference")
    s["sensor_floor"] = c.floors(doc.get("sensor_floor"), "sensor_floor")
    s["sensor_floor_note"] = c.string(doc.get("sensor_floor_note"), "sensor_floor_note", True)
    return s


def _made_for(doc, key, c):
    """{"match": "same" | "other" | "unknown", "text": str}: whether the diagnosis (ladder) was
    made for the model and log of the report (zerog report checked it). Only "same" makes the
    diagnosis the report's verdict."""
    c.obj(doc, "top level", (key,))
    f = c.obj(doc[key], key, ("match", "text"))
    match = c.string(f["match"], key + ".match")
    if match not in MATCHES:
        c.fail(key + ".match", "expected \"same\", \"other\" or \"unknown\", got %s"
               % json.dumps(match))
    return {"match": match, "text": c.string(f["text"], key + ".text")}


def _ladder_floors(lad, c):
    """(true-model reference, sensor floor) of a ladder document, each FLOORS or None. A ladder
    of version 1 (before the two floors) had only "noise_floor": the true-model reference over
    all held-out samples."""
    if "true_model_reference" in lad or "sensor_floor" in lad:
        return (c.floors(lad.get("true_model_reference"), "ladder.true_model_reference"),
                c.floors(lad.get("sensor_floor"), "ladder.sensor_floor"))
    old = c.rms6(lad.get("noise_floor"), "ladder.noise_floor", True)
    return ({"all": old, "static": None, "moving": None} if old else None), None


def load_data(path, np):
    """Returns {column: float array}. Errors name the file, line and column."""
    if not os.path.isfile(path):
        raise BundleError("%s: missing file" % path)
    try:
        f = open(path, encoding="utf-8", newline="")
    except OSError as e:
        raise BundleError("%s: cannot read: %s" % (path, e))
    with f:
        try:
            header_line = f.readline()
        except UnicodeDecodeError as e:
            raise BundleError("%s: line 1: not UTF-8 text: %s" % (path, e))
        if not header_line.strip():
            raise BundleError("%s: empty file (expected a header line)" % path)
        names = [n.strip() for n in next(csv.reader([header_line]))]
        seen = set()
        for n in names:
            if not n:
                raise BundleError("%s: line 1: empty column name" % path)
            if n in seen:
                raise BundleError("%s: line 1: duplicate column '%s'" % (path, n))
            seen.add(n)
        required = ["t_s", "moving"] + [a + "_meas" for a in AXES] + [a + "_pred" for a in AXES]
        missing = [n for n in required if n not in seen]
        if missing:
            raise BundleError("%s: missing required column%s %s" % (
                path, "s" if len(missing) > 1 else "", ", ".join("'%s'" % m for m in missing)))
        floor = []  # the true model's predictions: all six or none of each group
        for suffix in TRUE_SUFFIXES:
            group = [a + suffix for a in AXES]
            have = [n for n in group if n in seen]
            if have and len(have) != 6:
                raise BundleError("%s: the %s columns come all six or none; missing %s" % (
                    path, suffix, ", ".join("'%s'" % n for n in group if n not in seen)))
            floor += have
        try:
            arr = np.loadtxt(f, delimiter=",", ndmin=2, dtype=float, comments=None)
        except (ValueError, IndexError):
            f.seek(0)
            _find_bad_cell(path, f, len(names))
            raise BundleError("%s: cannot parse the numbers" % path)
    if arr.shape[0] == 0 or arr.size == 0:
        raise BundleError("%s: no data rows" % path)
    if arr.shape[1] != len(names):
        raise BundleError("%s: rows have %d cells, the header has %d columns" % (
            path, arr.shape[1], len(names)))
    cols = {n: np.ascontiguousarray(arr[:, i]) for i, n in enumerate(names)}
    for n in required + floor:
        bad = np.flatnonzero(~np.isfinite(cols[n]))
        if bad.size:
            raise BundleError("%s: line %d: column '%s' is not finite (%r)" % (
                path, bad[0] + 2, n, cols[n][bad[0]]))
    for n in ("moving", "heldout"):
        if n in cols:
            bad = np.flatnonzero((cols[n] != 0) & (cols[n] != 1))
            if bad.size:
                raise BundleError("%s: line %d: column '%s' must be 0 or 1, got %r" % (
                    path, bad[0] + 2, n, cols[n][bad[0]]))
    dt = np.diff(cols["t_s"])
    bad = np.flatnonzero(dt < 0)
    if bad.size:
        raise BundleError("%s: line %d: t_s decreases (%r after %r)" % (
            path, bad[0] + 3, cols["t_s"][bad[0] + 1], cols["t_s"][bad[0]]))
    return cols


def _find_bad_cell(path, f, ncols):
    """Slow scan to name the first bad line/cell after numpy refused the file."""
    for lineno, row in enumerate(csv.reader(f), start=1):
        if lineno == 1:
            continue
        if len(row) != ncols:
            raise BundleError("%s: line %d: %d cells, the header has %d columns" % (
                path, lineno, len(row), ncols))
        for i, cell in enumerate(row):
            if not cell.strip():
                raise BundleError("%s: line %d, column %d: empty cell" % (path, lineno, i + 1))
            try:
                float(cell)
            except ValueError:
                raise BundleError("%s: line %d, column %d: not a number: %r" % (
                    path, lineno, i + 1, cell))


# ---------------------------------------------------------------------------------------------
# Numbers and text


def finite(x):
    return x is not None and isinstance(x, (int, float)) and math.isfinite(x)


def fmt(x, digits=4):
    if not finite(x):
        return "—"
    if x == 0:
        return "0"
    a = abs(x)
    if a >= 10 ** digits:
        return "%.0f" % x
    if a < 1e-3:
        return "%.*e" % (digits - 1, x)
    return "%.*g" % (digits, x)


def fmt_pct(x):
    return "—" if not finite(x) else "%.1f %%" % (100.0 * x)


def fmt_bic(x):
    return "—" if not finite(x) else "%.1f" % x


def pooled(rms3):
    """Pooling rule of proto/report_bundle.md: sqrt(mean of squares) over three axes."""
    if any(not finite(r) for r in rms3):
        return None
    return math.sqrt(sum(r * r for r in rms3) / 3.0)


def esc(s):
    return html.escape(str(s), quote=True)


def signal_label(col):
    """Human label with unit for a data.csv column; joint angles are shown in degrees."""
    if col.startswith("q") and col.endswith("_rad") and col[1:-4].isdigit():
        return "A%s angle (deg)" % col[1:-4]
    if col.startswith("qd") and col.endswith("_radps") and col[2:-6].isdigit():
        return "A%s velocity (rad/s)" % col[2:-6]
    fixed = {"omega_norm_radps": "|ω| (rad/s)", "omega_dot_norm_radps2": "|ω̇| (rad/s²)",
             "accel_norm_mps2": "|f − g| (m/s²)", "temp_C": "temperature (°C)",
             "t_s": "time (s)"}
    if col in fixed:
        return fixed[col]
    for suffix, unit in (("_radps2", "rad/s²"), ("_radps", "rad/s"), ("_rad", "rad"),
                         ("_mps2", "m/s²"), ("_mps", "m/s"), ("_m", "m"), ("_C", "°C"),
                         ("_s", "s"), ("_Nm", "N·m"), ("_N", "N")):
        if col.endswith(suffix):
            return "%s (%s)" % (col[:-len(suffix)], unit)
    return "%s (unit as in data.csv)" % col


def signal_values(col, cols, np):
    v = cols[col]
    if col.startswith("q") and col.endswith("_rad") and col[1:-4].isdigit():
        return np.degrees(v)
    return v


def runs(np, mask, t):
    """(start, width) time spans where mask is true, each widened by half a sample period on
    both sides (broken_barh; the shaded spans of interactive_report.py)."""
    if not mask.any():
        return []
    m = mask.astype(np.int8)
    d = np.diff(np.concatenate(([0], m, [0])))
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1) - 1
    half = 0.5 * (float(np.median(np.diff(t))) if len(t) > 1 else 0.0)
    return [(t[a] - half, (t[b] - t[a]) + 2 * half) for a, b in zip(starts, ends)]


def minmax_idx(np, y, max_points):
    """Indices of y to plot, at most about max_points: all of them when y is short, else the
    first and last sample and the minimum and maximum of each of max_points/2 equal bins, so a
    spike survives the decimation (interactive_report.py decimates with it too)."""
    n = len(y)
    if n <= max_points:
        return np.arange(n)
    nb = max_points // 2
    size = -(-n // nb)
    pad = nb * size - n
    yy = np.concatenate((y, np.full(pad, y[-1]))) if pad else y
    yy = yy.reshape(nb, size)
    base = np.arange(nb) * size
    idx = np.concatenate((base + yy.argmin(axis=1), base + yy.argmax(axis=1), [0, n - 1]))
    return np.unique(np.minimum(idx, n - 1))


# ---------------------------------------------------------------------------------------------
# Figures


class Figures:
    def __init__(self, outdir, summary, cols, np, plt):
        self.out = outdir
        self.s = summary
        self.c = cols
        self.np = np
        self.plt = plt
        self.n = len(cols["t_s"])
        self.moving = cols["moving"] > 0.5
        self.heldout = cols["heldout"] > 0.5 if "heldout" in cols else None
        self.res = np.stack([cols[a + "_meas"] - cols[a + "_pred"] for a in AXES])
        # meas − true model on the log's signals (true-model reference) and on noise-free
        # signals (sensor floor: the F/T sensor's noise), when the bundle has them
        self.has_ref = (AXES[0] + "_true") in cols
        self.rres = (np.stack([cols[a + "_meas"] - cols[a + "_true"] for a in AXES])
                     if self.has_ref else None)
        self.has_clean = (AXES[0] + "_true_clean") in cols
        self.sres = (np.stack([cols[a + "_meas"] - cols[a + "_true_clean"] for a in AXES])
                     if self.has_clean else None)
        t = cols["t_s"]
        self.t0 = t[0] if abs(t[0]) > 1e5 else 0.0
        self.t = t - self.t0
        self.tlabel = "time since first sample (s)" if self.t0 else "time t_s (s)"

    def save(self, fig, name):
        fig.savefig(os.path.join(self.out, name), dpi=100)
        self.plt.close(fig)
        return name

    # -- helpers
    def _runs(self, mask, t):
        return runs(self.np, mask, t)

    def _minmax_idx(self, y, max_points):
        return minmax_idx(self.np, y, max_points)

    def _binned(self, x, ys, nbins=N_SIGNAL_BINS, min_count=5):
        """Binned mean and std of each row of ys against x; robust range (0.5..99.5 %)."""
        np = self.np
        ok = np.isfinite(x)
        x = x[ok]
        ys = ys[:, ok]
        if x.size < min_count:
            return None
        lo, hi = np.percentile(x, [0.5, 99.5])
        if not hi > lo:
            lo, hi = float(x.min()), float(x.max())
        if not hi > lo:
            return None
        edges = np.linspace(lo, hi, nbins + 1)
        b = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, nbins - 1)
        inside = (x >= lo) & (x <= hi)
        b = b[inside]
        cnt = np.bincount(b, minlength=nbins).astype(float)
        centers = 0.5 * (edges[:-1] + edges[1:])
        keep = cnt >= min_count
        means, stds = [], []
        for y in ys:
            y = y[inside]
            s1 = np.bincount(b, weights=y, minlength=nbins)
            s2 = np.bincount(b, weights=y * y, minlength=nbins)
            with np.errstate(invalid="ignore", divide="ignore"):
                m = s1 / cnt
                v = np.maximum(s2 / cnt - m * m, 0.0)
            means.append(m[keep])
            stds.append(np.sqrt(v[keep]))
        return centers[keep], means, stds, (lo, hi)

    def _ref_rms(self):
        return self.s["_ref"]["all"]["rms"] if self.s.get("_ref") else None

    def _sensor_rms(self):
        return self.s["_sensor"]["all"]["rms"] if self.s.get("_sensor") else None

    def _event_runs(self, t):
        """(start, width) of the diagnosis' events within the plotted times (this model's
        diagnosis only; t in the plot's time axis)."""
        dg = self.s.get("diagnosis")
        if not dg or dg["made_for"]["match"] != "same" or len(t) == 0:
            return []
        off = self.t0 or 0.0
        runs = []
        for a, b in dg["verdict"].get("events", []):
            a, b = max(a - off, float(t[0])), min(b - off, float(t[-1]))
            if b > a:
                runs.append((a, b - a))
        return runs

    # -- (3) measured vs predicted over time
    def timeseries(self):
        """Whole log; min/max-decimated when long. Returns (file, decimated)."""
        name = self._timeseries(slice(0, self.n), "timeseries.png")
        return name, self.n > MAX_PLOT_POINTS

    def zoom_window(self):
        """Index range of ZOOM_SAMPLES around the largest sustained residual, normalised per
        axis by the true-model reference (or the overall RMS). None when the log is short."""
        np = self.np
        if self.n <= 2 * ZOOM_SAMPLES:
            return None
        floor = self._ref_rms()
        score = np.zeros(self.n)
        for i in range(6):
            sc = floor[i] if floor and finite(floor[i]) and floor[i] > 0 else None
            if sc is None:
                sc = float(np.sqrt(np.mean(self.res[i] ** 2))) or 1.0
            score += (self.res[i] / sc) ** 2
        k = max(1, ZOOM_SAMPLES // 15)
        smooth = np.convolve(score, np.ones(k) / k, mode="same")
        c = int(np.argmax(smooth))
        a = min(max(0, c - ZOOM_SAMPLES // 2), self.n - ZOOM_SAMPLES)
        return a, a + ZOOM_SAMPLES

    def timeseries_zoom(self, window):
        return self._timeseries(slice(*window), "timeseries_zoom.png")

    def _timeseries(self, sl, fname):
        np, plt = self.np, self.plt
        from matplotlib.patches import Patch
        t = self.t[sl]
        fig = plt.figure(figsize=(13, 25))
        outer = fig.add_gridspec(6, 1, hspace=0.32)
        moving_runs = self._runs(self.moving[sl], t)
        held_runs = self._runs(self.heldout[sl], t) if self.heldout is not None else []
        event_runs = self._event_runs(t)
        seg = self.s["compare"]["segments"]
        first = None
        axes_list = []
        for i, (a, u) in enumerate(zip(AXES, UNITS)):
            inner = outer[i].subgridspec(2, 1, height_ratios=[3, 1.4], hspace=0.06)
            ax = fig.add_subplot(inner[0], sharex=first)
            first = first or ax
            axr = fig.add_subplot(inner[1], sharex=first)
            axes_list += [ax, axr]
            for x in (ax, axr):
                if moving_runs:
                    x.broken_barh(moving_runs, (0, 1), transform=x.get_xaxis_transform(),
                                  color="#dbe8f5", zorder=0)
            if held_runs:
                axr.broken_barh(held_runs, (0.0, 0.08), transform=axr.get_xaxis_transform(),
                                color="tab:purple", alpha=0.7, zorder=3)
            if event_runs:
                for x in (ax, axr):
                    x.broken_barh(event_runs, (0, 1), transform=x.get_xaxis_transform(),
                                  color="#f6c9c9", alpha=0.8, zorder=1)
            meas = self.c[a + "_meas"][sl]
            pred = self.c[a + "_pred"][sl]
            k = self._minmax_idx(meas, MAX_PLOT_POINTS)
            ax.plot(t[k], meas[k], color="#222222", lw=0.7, label="measured")
            k = self._minmax_idx(pred, MAX_PLOT_POINTS)
            ax.plot(t[k], pred[k], color="tab:orange", lw=1.0, alpha=0.9, label="predicted")
            if self.has_ref:
                fr = self.rres[i][sl]
                k = self._minmax_idx(fr, MAX_PLOT_POINTS)
                axr.plot(t[k], fr[k], color="#9a9a9a", lw=0.5,
                         label="measured − true model (true-model reference)")
            if self.has_clean:
                fr = self.sres[i][sl]
                k = self._minmax_idx(fr, MAX_PLOT_POINTS)
                axr.plot(t[k], fr[k], color="tab:green", lw=0.5, alpha=0.8,
                         label="measured − true model on noise-free signals (sensor floor)")
            r = self.res[i][sl]
            k = self._minmax_idx(r, MAX_PLOT_POINTS)
            axr.plot(t[k], r[k], color="tab:red", lw=0.7, label="residual meas − pred")
            axr.axhline(0, color="k", lw=0.5)
            ax.set_ylabel("%s (%s)" % (a, u))
            axr.set_ylabel("resid. (%s)" % u)
            ax.set_title("%s: residual RMS (whole log) %s %s all, %s static, %s moving" % (
                a, fmt(seg["all"]["rms"][i]), u, fmt(seg["static"]["rms"][i]),
                fmt(seg["moving"]["rms"][i])), fontsize=10, loc="left")
            ax.tick_params(labelbottom=False)
            if i < 5:
                axr.tick_params(labelbottom=False)
            ax.grid(alpha=0.3)
            axr.grid(alpha=0.3)
        axes_list[-1].set_xlabel(self.tlabel)
        axes_list[0].set_xlim(t[0], t[-1] if t[-1] > t[0] else t[0] + 1.0)
        h, l = axes_list[0].get_legend_handles_labels()
        h2, l2 = axes_list[1].get_legend_handles_labels()
        extra = [Patch(color="#dbe8f5", label="moving segment")]
        if held_runs:
            extra.append(Patch(color="tab:purple", alpha=0.7, label="held-out block"))
        if event_runs:
            extra.append(Patch(color="#f6c9c9", alpha=0.8, label="event (diagnosis)"))
        handles = h + h2 + extra
        fig.legend(handles, [x.get_label() for x in handles], loc="upper center",
                   ncol=min(6, len(handles)), frameon=False, fontsize=9,
                   bbox_to_anchor=(0.5, 0.997))
        fig.subplots_adjust(left=0.07, right=0.98, top=0.975, bottom=0.03)
        return self.save(fig, fname)

    # -- (4) residual histograms
    def histograms(self):
        np, plt = self.np, self.plt
        fig, axs = plt.subplots(2, 3, figsize=(13, 7.5))
        floor = self._ref_rms()
        sensor = self._sensor_rms()
        clipped = 0
        for i, (a, u) in enumerate(zip(AXES, UNITS)):
            ax = axs.flat[i]
            r = self.res[i]
            lo, hi = np.percentile(r, [0.1, 99.9])
            for other in (self.rres, self.sres):
                if other is not None:
                    flo, fhi = np.percentile(other[i], [0.1, 99.9])
                    lo, hi = min(lo, flo), max(hi, fhi)
            if not hi > lo:
                lo, hi = lo - 1e-9, hi + 1e-9
            clipped = max(clipped, int(np.count_nonzero((r < lo) | (r > hi))))
            bins = np.linspace(lo, hi, 61)
            data, labels, colors = [], [], []
            if (~self.moving).any():
                data.append(r[~self.moving])
                labels.append("static")
                colors.append("#7aa6d6")
            if self.moving.any():
                data.append(r[self.moving])
                labels.append("moving")
                colors.append("#e8945a")
            ax.hist(data, bins=bins, stacked=True, color=colors, label=labels)
            if self.has_ref:
                ax.hist(self.rres[i], bins=bins, histtype="step", color="k", lw=1.2,
                        label="meas − true model")
            if self.has_clean:
                ax.hist(self.sres[i], bins=bins, histtype="step", color="tab:green", lw=1.2,
                        label="meas − true model, noise-free signals")
            if floor and finite(floor[i]):
                for sgn in (-1, 1):
                    ax.axvline(sgn * floor[i], color="k", ls="--", lw=0.9,
                               label="± true-model reference RMS" if sgn > 0 else None)
            if sensor and finite(sensor[i]):
                for sgn in (-1, 1):
                    ax.axvline(sgn * sensor[i], color="tab:green", ls=":", lw=1.1,
                               label="± sensor floor RMS" if sgn > 0 else None)
            ax.axvline(0, color="k", lw=0.4)
            mean, std = float(r.mean()), float(r.std())
            ax.set_title("%s: mean %s, std %s %s" % (a, fmt(mean, 3), fmt(std, 3), u),
                         fontsize=10)
            ax.set_xlabel("residual meas − pred, %s (%s)" % (a, u))
            ax.set_ylabel("samples (count)")
            ax.grid(alpha=0.3)
            if i == 0:
                ax.legend(fontsize=8)
        fig.tight_layout()
        return self.save(fig, "residual_hist.png"), clipped

    # -- (5a) residual vs the diagnosis' correlated signals
    def diagnosis_signals(self, corr):
        np, plt = self.np, self.plt
        panels, skipped = [], []
        for cs in corr[:MAX_CORRELATED]:
            col = cs["signal"] if cs["signal"] in self.c else SHORT_SIGNALS.get(cs["signal"])
            if col is None or col not in self.c:
                skipped.append((cs, "not in data.csv"))
                continue
            x = signal_values(col, self.c, np)
            if np.count_nonzero(np.isfinite(x)) < 5 or np.nanmax(x) <= np.nanmin(x):
                skipped.append((cs, "constant or empty"))
                continue
            panels.append((cs, col, x))
        if not panels:
            return None, skipped
        n = len(panels)
        ncols = min(3, n)
        nrows = -(-n // ncols)
        fig, axs = plt.subplots(nrows, ncols, figsize=(4.4 * ncols + 0.5, 3.6 * nrows),
                                squeeze=False)
        rng = np.random.default_rng(0)
        floor = self._ref_rms()
        for p, (cs, col, x) in enumerate(panels):
            ax = axs.flat[p]
            i = AXES.index(cs["axis"])
            r = self.res[i]
            ok = np.flatnonzero(np.isfinite(x))
            sel = ok if ok.size <= MAX_SCATTER_POINTS else rng.choice(ok, MAX_SCATTER_POINTS,
                                                                      replace=False)
            ax.scatter(x[sel], r[sel], s=3, alpha=0.25, color="#555555", linewidths=0,
                       rasterized=True, label="samples")
            b = self._binned(x, r[None, :])
            if b:
                xc, m, sd, _ = b
                ax.plot(xc, m[0], color="tab:red", lw=1.6, label="binned mean")
                ax.fill_between(xc, m[0] - sd[0], m[0] + sd[0], color="tab:red", alpha=0.15,
                                label="± std")
            if floor and finite(floor[i]):
                ax.axhspan(-floor[i], floor[i], color="tab:green", alpha=0.15,
                           label="± true-model reference")
            ax.axhline(0, color="k", lw=0.5)
            ax.set_xlabel(signal_label(col))
            ax.set_ylabel("%s residual (%s)" % (cs["axis"], UNITS[i]))
            ax.set_title("%s vs %s (r = %s)" % (cs["axis"], col, "—" if not finite(
                cs["correlation"]) else "%+.2f" % cs["correlation"]), fontsize=10)
            ax.grid(alpha=0.3)
            if p == 0:
                ax.legend(fontsize=8, markerscale=3)
        for q in range(n, nrows * ncols):
            axs.flat[q].set_visible(False)
        fig.tight_layout()
        return self.save(fig, "diagnosis_signals.png"), skipped

    # -- (5b) residual vs the standard signals
    def residual_vs_signals(self):
        np, plt = self.np, self.plt
        wanted = ["q4_rad", "q5_rad", "q6_rad", "omega_norm_radps", "omega_dot_norm_radps2"]
        rows, skipped = [], []
        for col in wanted:
            if col not in self.c:
                skipped.append((col, "not in data.csv"))
                continue
            x = signal_values(col, self.c, np)
            b = self._binned(x, self.res)
            if b is None:
                skipped.append((col, "constant or empty"))
                continue
            rows.append((col, b))
        if not rows:
            return None, skipped
        fig, axs = plt.subplots(len(rows), 2, figsize=(13, 2.9 * len(rows) + 0.4),
                                squeeze=False)
        floor = self.s.get("_ref")
        for r_i, (col, (xc, means, stds, _)) in enumerate(rows):
            for side in range(2):
                ax = axs[r_i, side]
                idx = range(3 * side, 3 * side + 3)
                unit = UNITS[3 * side]
                if floor:
                    fl = floor["all"]["force_rms" if side == 0 else "torque_rms"]
                    if finite(fl):
                        ax.axhspan(-fl, fl, color="#cfcfcf", alpha=0.6,
                                   label="± true-model reference (pooled)")
                for i in idx:
                    ax.plot(xc, means[i], color=AXIS_COLORS[i], lw=1.4, label=AXES[i])
                    ax.fill_between(xc, means[i] - stds[i], means[i] + stds[i],
                                    color=AXIS_COLORS[i], alpha=0.12)
                ax.axhline(0, color="k", lw=0.5)
                ax.set_xlabel(signal_label(col))
                ax.set_ylabel("%s residual (%s)" % ("force" if side == 0 else "torque", unit))
                ax.grid(alpha=0.3)
                if r_i == 0:
                    ax.legend(fontsize=8, ncol=4, loc="upper right")
        fig.tight_layout()
        return self.save(fig, "residual_vs_signals.png"), skipped

    # -- (6) RMS by joint-angle bin
    def joint_bins(self):
        np, plt = self.np, self.plt
        import matplotlib.colors as mcolors
        from matplotlib.patches import Rectangle
        jbs = self.s["compare"]["joint_bins"]
        if not jbs:
            return None
        worst = self.s["compare"]["worst"]
        fig, axs = plt.subplots(2, 1, figsize=(13, 2 * (0.55 * len(jbs) + 1.3)))
        for side, (ax, name, unit) in enumerate(zip(axs, ("force", "torque"), ("N", "N·m"))):
            vals = []
            for jb in jbs:
                v = [pooled(r[3 * side:3 * side + 3]) if cnt > 0 else None
                     for r, cnt in zip(jb["rms"], jb["count"])]
                vals.append(np.array([np.nan if x is None else x for x in v], dtype=float))
            allv = np.concatenate(vals)
            allv = allv[np.isfinite(allv)]
            vmax = float(allv.max()) if allv.size else 1.0
            norm = mcolors.Normalize(vmin=0.0, vmax=vmax if vmax > 0 else 1.0)
            cmap = plt.get_cmap("viridis")
            mesh = None
            for row, (jb, v) in enumerate(zip(jbs, vals)):
                e = np.degrees(np.asarray(jb["edges_rad"]))
                mesh = ax.pcolormesh(e, [row, row + 1], np.ma.masked_invalid(v)[None, :],
                                     cmap=cmap, norm=norm, edgecolors="white", linewidth=0.5)
                if len(v) <= 30:
                    for b in range(len(v)):
                        if np.isfinite(v[b]):
                            rgba = cmap(norm(v[b]))
                            lum = 0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2]
                            ax.text(0.5 * (e[b] + e[b + 1]), row + 0.5, fmt(v[b], 2),
                                    ha="center", va="center", fontsize=7,
                                    color="k" if lum > 0.5 else "w")
                if (worst and worst["joint"] == jb["joint"]
                        and (worst["axis"] in AXES[3 * side:3 * side + 3])):
                    lo, hi = np.degrees(worst["bin_rad"])
                    ax.add_patch(Rectangle((lo, row), hi - lo, 1, fill=False, ec="red", lw=2.5,
                                           zorder=5, label="worst bin (%s, %s)" % (
                                               worst["axis"], worst["segment"])))
            ax.set_facecolor("#e6e6e6")
            ax.set_yticks([r + 0.5 for r in range(len(jbs))])
            ax.set_yticklabels([jb["joint"] for jb in jbs])
            ax.set_ylim(len(jbs), 0)
            ax.set_xlabel("joint angle (deg)")
            ax.set_ylabel("joint")
            ax.set_title("%s RMS per joint-angle bin (pooled over %s; grey: no samples)" % (
                name.capitalize(), "Fx, Fy, Fz" if side == 0 else "Mx, My, Mz"), fontsize=10)
            cb = fig.colorbar(mesh, ax=ax, pad=0.01)
            cb.set_label("%s RMS (%s)" % (name, unit))
            if ax.get_legend_handles_labels()[0]:
                ax.legend(loc="upper right", fontsize=8)
        fig.tight_layout()
        return self.save(fig, "joint_bins.png")

    # -- (7) ladder
    def ladder(self):
        np, plt = self.np, self.plt
        lad = self.s["ladder"]
        steps = lad["steps"]
        if not steps:
            return None
        lines = [(lad["true_model_reference"] or self.s.get("_ref"), "true-model reference",
                  "k", "--"),
                 (lad["sensor_floor"] or self.s.get("_sensor"), "sensor floor", "tab:green",
                  ":")]
        labels = []
        for k, st in enumerate(steps):
            if st["added"]:
                labels.append("+ " + st["added"])
            else:
                labels.append("start:\n" + "\n".join(st["effects"][:4])
                              + ("\n…" if len(st["effects"]) > 4 else ""))
        x = np.arange(len(steps))
        fig, axs = plt.subplots(1, 2, figsize=(13, 4.8))
        for side, (ax, key, unit) in enumerate(zip(axs, ("force_rms", "torque_rms"),
                                                   ("N", "N·m"))):
            y = np.array([st["heldout"][key] if finite(st["heldout"][key]) else np.nan
                          for st in steps])
            ax.plot(x, y, "o-", color="tab:blue" if side == 0 else "tab:orange", lw=1.8)
            for xi, yi in zip(x, y):
                if np.isfinite(yi):
                    ax.annotate(fmt(yi, 3), (xi, yi), textcoords="offset points",
                                xytext=(0, 7), ha="center", fontsize=8)
            drawn = []
            for fls, name, color, ls in lines:
                fl = fls["all"][key] if fls else None
                if finite(fl):
                    ax.axhline(fl, color=color, ls=ls, lw=1.1,
                               label="%s %s %s" % (name, fmt(fl, 3), unit))
                    drawn.append(fl)
            if drawn:
                ax.legend(fontsize=8)
            good = y[np.isfinite(y)]
            posv = np.concatenate((good, drawn))
            posv = posv[posv > 0]
            if posv.size and posv.max() / posv.min() > 20:
                ax.set_yscale("log")
            else:
                ax.set_ylim(bottom=0)
            ax.set_xticks(x)
            ax.set_xticklabels(labels, fontsize=8, rotation=30, ha="right")
            ax.set_ylabel("held-out %s RMS (%s)" % ("force" if side == 0 else "torque", unit))
            ax.set_xlabel("ladder step (effect added)")
            ax.grid(alpha=0.3, which="both")
        fig.tight_layout()
        return self.save(fig, "ladder.png")

    # -- (8) diagnosis candidates
    def candidates(self):
        np, plt = self.np, self.plt
        dg = self.s["diagnosis"]
        cands = sorted(dg["candidates"],
                       key=lambda c: -(c["gain"] if finite(c["gain"]) else -math.inf))
        if not cands:
            return None
        chosen = dg["verdict"]["effect"] if dg["verdict"]["kind"] == "effect" else None
        fig, ax = plt.subplots(figsize=(11, 0.42 * len(cands) + 1.6))
        y = np.arange(len(cands))
        g = np.array([100.0 * c["gain"] if finite(c["gain"]) else 0.0 for c in cands])
        colors = []
        for c in cands:
            if c["effect"] == chosen:
                colors.append("tab:green")
            elif finite(c["delta_bic"]) and c["delta_bic"] < 0:
                colors.append("tab:blue")
            else:
                colors.append("#b0b0b0")
        ax.barh(y, g, color=colors)
        span = max(1e-9, float(np.max(np.abs(g))) if g.size else 1.0)
        for yi, gi, c in zip(y, g, cands):
            ax.text(max(gi, 0.0) + 0.01 * span, yi,
                    " %s   ΔBIC %s" % (fmt_pct(c["gain"]), fmt_bic(c["delta_bic"])),
                    va="center", ha="left", fontsize=8)
        ax.set_yticks(y)
        ax.set_yticklabels([c["effect"] for c in cands])
        ax.set_ylim(len(cands) - 0.5, -0.5)
        ax.axvline(0, color="k", lw=0.6)
        ax.set_xlim(min(0.0, float(g.min()) * 1.3), max(1.0, float(g.max())) * 1.45)
        ax.set_xlabel("gain: held-out mean-square error removed by adding the effect (%)")
        ax.set_ylabel("candidate effect")
        from matplotlib.patches import Patch
        handles = [Patch(color="tab:blue", label="ΔBIC < 0 (supported)"),
                   Patch(color="#b0b0b0", label="ΔBIC ≥ 0 (not supported)")]
        if chosen:
            handles.insert(0, Patch(color="tab:green", label="verdict: %s" % chosen))
        ax.legend(handles=handles, fontsize=8, loc="lower right")
        ax.grid(alpha=0.3, axis="x")
        fig.tight_layout()
        return self.save(fig, "diagnosis.png")


# ---------------------------------------------------------------------------------------------
# HTML

CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0 auto;
 max-width:1340px;padding:0 18px 40px;color:#1d1d1d;line-height:1.45}
h1{margin:18px 0 4px;font-size:1.6em}
h2{margin-top:34px;border-bottom:2px solid #ddd;padding-bottom:3px}
table{border-collapse:collapse;margin:8px 0 6px;font-size:.92em}
th,td{border:1px solid #d4d4d4;padding:3px 8px;text-align:right}
th{background:#f2f2f2}
td.l,th.l{text-align:left}
tr.pool td{font-weight:600;background:#fafafa}
.meta td{text-align:left;border:none;padding:1px 10px 1px 0}
.chip{display:inline-block;background:#eef3fa;border:1px solid #c9d8ee;border-radius:10px;
 padding:0 8px;margin:1px 2px;font-size:.9em}
.verdict{border-left:6px solid #999;background:#f6f6f6;padding:10px 14px;margin:14px 0;
 font-size:1.05em}
.verdict.effect{border-color:#2e8b3a;background:#eef8ef}
.verdict.none{border-color:#c98a12;background:#fdf6e7}
.verdict.nothing_left{border-color:#3a6fb0;background:#edf3fb}
.verdict.discovered{border-color:#7a3ab0;background:#f5eefb}
.foreign{border-left:6px dashed #8a8a8a;background:#f4f4f4;padding:8px 14px;margin:14px 0}
code,pre{background:#f1f1f1;border-radius:3px;padding:1px 4px;font-size:.95em}
pre{padding:6px 10px;white-space:pre-wrap}
figure{margin:10px 0 18px}
figure img{max-width:100%;border:1px solid #e2e2e2}
figcaption{color:#444;font-size:.92em;max-width:1100px}
.warn{background:#fff3f3;border:1px solid #e7b7b7;padding:6px 12px;border-radius:4px}
.r-good{background:#e6f4e6}.r-mid{background:#fff5d6}.r-bad{background:#fbe0e0}
nav a{margin-right:14px}
.muted{color:#666}
"""


def _img(name, alt, caption):
    return ('<figure><a href="%s"><img src="%s" alt="%s"></a><figcaption>%s</figcaption>'
            "</figure>" % (esc(name), esc(name), esc(alt), caption))


def _label(what, made_for):
    """The heading of a diagnosis or ladder: its own when made for this model and log, else
    one that says it is not."""
    return {("diagnosis", "same"): "Diagnosis: which effect is missing",
            ("diagnosis", "other"): "Diagnosis of another model or log",
            ("diagnosis", "unknown"): "Diagnosis made for an unknown model",
            ("ladder", "same"): "Ladder of effects",
            ("ladder", "other"): "Ladder of another log",
            ("ladder", "unknown"): "Ladder made for an unknown log"}[(what, made_for["match"])]


def _foreign_box(what, made_for, tail=""):
    """The label of a diagnosis or ladder not made for this model and log."""
    return '<div class="foreign"><b>%s</b>: %s.%s</div>' % (
        esc(_label(what, made_for)), esc(made_for["text"]), tail)


def _ratio_class(r):
    if not finite(r):
        return ""
    return "r-good" if r < 1.5 else ("r-mid" if r < 3 else "r-bad")


def _floors_table(s, seg):
    """The residual beside the two yardsticks, force and torque, all / static / moving; and
    what each means (docs/insight-loop.md, "Sensor floor and true-model
    reference")."""
    floor, sensor = s.get("_ref"), s.get("_sensor")
    if not floor and not sensor:
        return ('<p class="muted">No true-model reference and no sensor floor in this bundle '
                "(both need the truth of a simulated run).</p>")
    out = ['<table><tr><th class="l" rowspan="2">RMS</th><th colspan="3">force (N)</th>'
           '<th colspan="3">torque (N·m)</th><th class="l" rowspan="2">source</th></tr><tr>'
           + "<th>all</th><th>static</th><th>moving</th>" * 2 + "</tr>"]
    rows = [("residual meas − pred (this model)",
             {g: seg[g] for g in ("all", "static", "moving")}, "summary.json compare")]
    if floor:
        rows.append(("true-model reference", floor, s.get("_ref_source")))
    if sensor:
        rows.append(("sensor floor", sensor, s.get("_sensor_source")))
    for label, f, src in rows:
        cells = "".join("<td>%s</td>" % fmt(f[g][key] if f.get(g) else None)
                        for key in ("force_rms", "torque_rms")
                        for g in ("all", "static", "moving"))
        out.append('<tr><td class="l">%s</td>%s<td class="l">%s</td></tr>' % (
            esc(label), cells, esc(src or "")))
    out.append("</table>")
    cap = []
    if floor:
        cap.append("<b>True-model reference</b>: the true model with the true parameters on the "
                   "same noisy signals; what a perfect fit of the complete model leaves. Not a "
                   "lower bound: the IMU's noise enters through the model (mass × accelerometer "
                   "noise, inertia × differenced gyro), and a model that uses the IMU otherwise "
                   "can beat it.")
    if sensor:
        cap.append("<b>Sensor floor</b>: the true model on noise-free signals against the same "
                   "noisy wrench: the F/T sensor's own noise and quantisation; no model of the "
                   "signals beats it on average.")
    else:
        cap.append("No sensor floor: %s." % esc(
            s.get("sensor_floor_note") or "the bundle has none (it needs the noise-free log of "
            "a simulated run)"))
    out.append('<p class="muted">%s</p>' % " ".join(cap))
    return "".join(out)


def build_html(s, cols, figs, notes, warnings):
    cmp_ = s["compare"]
    seg = cmp_["segments"]
    floor = s.get("_ref")
    sensor = s.get("_sensor")
    out = []
    w = out.append
    w("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">")
    w("<title>%s</title><style>%s</style></head><body>" % (esc(s["title"]), CSS))
    w("<h1>%s</h1>" % esc(s["title"]))
    w('<table class="meta">')
    w('<tr><td class="muted">log</td><td><code>%s</code></td></tr>' % esc(s["log"]))
    w('<tr><td class="muted">model</td><td><code>%s</code></td></tr>' % esc(s["model"]))
    w('<tr><td class="muted">effects</td><td>%s</td></tr>' % (
        " ".join('<span class="chip">%s</span>' % esc(e) for e in s["effects"]) or "—"))
    smp = cmp_["samples"]
    w('<tr><td class="muted">samples</td><td>%d total: %d static, %d moving%s</td></tr>' % (
        smp["total"], smp["static"], smp["moving"],
        "" if "heldout" not in cols else "; %d in held-out blocks" % int(cols["heldout"].sum())))
    w("</table>")

    dg = s["diagnosis"]
    own = bool(dg) and dg["made_for"]["match"] == "same"
    if own:
        v = dg["verdict"]
        head = {"effect": "Missing effect: <b>%s</b>" % esc(v["effect"] or ""),
                "none": "No single effect explains the rest",
                "nothing_left": "Nothing left to explain",
                "discovered": "No library effect; discovered law: <b>%s</b>"
                              % esc("; ".join(v.get("laws", []))),
                "outliers": "Outlier poses of the table (left out of the fit it proposes)",
                "event": "Events, not physics: <b>%d span%s</b> (shaded red in the time series)"
                         % (len(v.get("events", [])), "" if len(v.get("events", [])) == 1
                            else "s")}[v["kind"]]
        w('<div class="verdict %s" id="verdict"><div>%s</div><div>%s</div>' % (
            v["kind"], head, esc(v["text"])))
        if v["command"]:
            w('<div style="margin-top:6px">Next: <pre>%s</pre></div>' % esc(v["command"]))
        w("</div>")
    elif dg:  # not this model's verdict: labelled, never the "Missing effect" box
        w(_foreign_box("diagnosis", dg["made_for"], ' Shown under <a href="#diagnosis">'
                       "Diagnosis</a>, not as this model's verdict."))
    if warnings:
        w('<div class="warn"><b>Warnings</b><ul>%s</ul></div>' % "".join(
            "<li>%s</li>" % esc(x) for x in warnings))

    nav = [("residuals", "Residual table"), ("time", "Time series"), ("hist", "Histograms"),
           ("where", "Where it fails")]
    if figs.get("interactive"):
        w('<p class="interactive"><a href="%s"><b>Interactive page</b></a>: the time series '
          "zoomable on one linked time axis (hover for the pose, one wrench axis at a time) "
          "and the residual against any signal; works offline.</p>" % esc(figs["interactive"]))
    else:
        w('<p class="muted" id="no-interactive">No interactive page: %s.</p>'
          % esc(notes.get("no_interactive", "not made").rstrip(".")))
    if s["ladder"]:
        nav.append(("ladder", "Ladder" if s["ladder"]["made_for"]["match"] == "same"
                     else _label("ladder", s["ladder"]["made_for"])))
    if dg:
        nav.append(("diagnosis", "Diagnosis" if own else _label("diagnosis", dg["made_for"])))
    w("<nav>%s</nav>" % "".join('<a href="#%s">%s</a>' % (a, b) for a, b in nav))

    # (2) residual table
    w('<h2 id="residuals">Residual meas − pred</h2>')
    w("<table><tr><th class=\"l\" rowspan=\"2\">axis</th><th rowspan=\"2\">unit</th>"
      "<th colspan=\"2\">all</th><th colspan=\"2\">static</th><th colspan=\"2\">moving</th>")
    if floor:
        w("<th rowspan=\"2\">true-model reference RMS</th>"
          "<th rowspan=\"2\">all RMS / reference</th>")
    if sensor:
        w("<th rowspan=\"2\">sensor floor RMS</th>")
    w("</tr><tr>" + "<th>RMS</th><th>max |r|</th>" * 3 + "</tr>")
    for i, (a, u) in enumerate(zip(AXES, UNITS)):
        w("<tr><td class=\"l\">%s</td><td>%s</td>" % (a, u))
        for g in ("all", "static", "moving"):
            w("<td>%s</td><td>%s</td>" % (fmt(seg[g]["rms"][i]), fmt(seg[g]["max"][i])))
        if floor:
            fl = floor["all"]["rms"][i]
            r = seg["all"]["rms"][i] / fl if finite(fl) and fl > 0 and finite(
                seg["all"]["rms"][i]) else None
            w("<td>%s</td><td class=\"%s\">%s</td>" % (fmt(fl), _ratio_class(r), fmt(r, 3)))
        if sensor:
            w("<td>%s</td>" % fmt(sensor["all"]["rms"][i]))
        w("</tr>")
    for key, label, unit in (("force_rms", "force (pooled)", "N"),
                             ("torque_rms", "torque (pooled)", "N·m")):
        w("<tr class=\"pool\"><td class=\"l\">%s</td><td>%s</td>" % (label, unit))
        for g in ("all", "static", "moving"):
            w("<td>%s</td><td></td>" % fmt(seg[g][key]))
        if floor:
            fl = floor["all"][key]
            r = seg["all"][key] / fl if finite(fl) and fl > 0 and finite(seg["all"][key]) else None
            w("<td>%s</td><td class=\"%s\">%s</td>" % (fmt(fl), _ratio_class(r), fmt(r, 3)))
        if sensor:
            w("<td>%s</td>" % fmt(sensor["all"][key]))
        w("</tr>")
    w("</table>")
    cap = ("Pooled = sqrt of the mean of the three squared per-axis RMS. max |r| is the largest "
           "absolute residual.")
    if floor:
        cap += (" Ratio colours: green &lt; 1.5, yellow &lt; 3, red ≥ 3 times the true-model "
                "reference.")
    w('<p class="muted">%s</p>' % cap)
    w(_floors_table(s, seg))
    wo = cmp_["worst"]
    if wo:
        unit = UNITS[AXES.index(wo["axis"])] if wo["axis"] in AXES else ""
        lo, hi = wo["bin_rad"]
        w("<p><b>Worst:</b> %s while %s, with %s in [%s, %s] rad (%s° … %s°): RMS %s %s.</p>" % (
            esc(wo["axis"]), esc(wo["segment"]), esc(wo["joint"]), fmt(lo, 3), fmt(hi, 3),
            fmt(math.degrees(lo), 3), fmt(math.degrees(hi), 3), fmt(wo["rms"]), unit))
    if "heldout" in cols and notes.get("heldout_rms"):
        fit_r, ho_r = notes["heldout_rms"]
        w("<p>Recomputed from data.csv, fit samples vs held-out samples:</p>")
        w("<table><tr><th class=\"l\">part</th>%s</tr>" % "".join(
            "<th>%s RMS (%s)</th>" % (a, u) for a, u in zip(AXES, UNITS)))
        for label, r in (("fit", fit_r), ("held-out", ho_r)):
            w("<tr><td class=\"l\">%s</td>%s</tr>" % (label, "".join(
                "<td>%s</td>" % fmt(x) for x in r)))
        w("</table>")

    # (3) time series
    w('<h2 id="time">Measured vs predicted over time</h2>')
    cap = ("Per axis: measured (black) and predicted (orange); below it the residual meas − pred "
           "(red)%s%s. Blue shading: moving segments%s." % (
               ", measured − true model in grey (what a perfect fit leaves on these signals)"
               if "_ref_cols" in notes else "",
               ", measured − true model on noise-free signals in green (the F/T sensor's noise)"
               if "_sensor_cols" in notes else "",
               "; purple marks along the bottom of each residual panel: held-out blocks"
               if "heldout" in cols else ""))
    if notes["decimated"]:
        cap += (" <b>Decimated for plotting:</b> %d samples drawn with min/max decimation to "
                "about %d points per curve (every local extreme kept)." % (
                    len(cols["t_s"]), MAX_PLOT_POINTS))
    if figs.get("interactive"):
        cap += (' To zoom, hover and pick axes: the <a href="%s">interactive page</a>.'
                % esc(figs["interactive"]))
    w(_img(figs["timeseries"], "measured vs predicted per axis", cap))
    if figs.get("zoom"):
        a, b, ta, tb = notes["zoom"]
        w(_img(figs["zoom"], "zoom on the largest residual",
               "Zoom on rows %d–%d of data.csv (t_s %s … %s s, %d samples, not decimated): the "
               "window with the largest sustained residual, each axis weighted by %s. Same "
               "layout and colours as above." % (
                   a + 1, b + 1, fmt(ta, 7), fmt(tb, 7), b - a + 1,
                   "its true-model reference" if floor else "its overall RMS")))

    # (4) histograms
    w('<h2 id="hist">Residual distribution</h2>')
    cap = "Residual meas − pred per axis; static and moving samples stacked."
    if "_ref_cols" in notes:
        cap += (" Black outline: measured − true model on the same signals, the spread a perfect "
                "fit leaves.")
    if "_sensor_cols" in notes:
        cap += (" Green outline: measured − true model on noise-free signals, the F/T sensor's "
                "own noise.")
    if floor:
        cap += " Dashed: ± true-model reference RMS."
    if sensor:
        cap += " Dotted green: ± sensor floor RMS."
    cap += " The x range spans the 0.1–99.9 percentiles"
    cap += (" (%d samples outside on the worst axis are not shown)." % notes["hist_clipped"]
            if notes["hist_clipped"] else ".")
    w(_img(figs["hist"], "residual histograms", cap))

    # (5) + (6) where it fails
    w('<h2 id="where">Where the model fails</h2>')
    if dg:
        if figs.get("diag_signals"):
            w(_img(figs["diag_signals"], "residual vs correlated signals",
                   "Residual of the flagged axis against the signals the diagnosis%s found "
                   "most correlated with it (scatter of at most %d random samples, binned mean "
                   "± std in red%s)." % (
                       "" if own else {"other": " (made for another model or log, see below)",
                                       "unknown": " (made for an unknown model, see below)"}[
                                           dg["made_for"]["match"]],
                       MAX_SCATTER_POINTS,
                       ", green band ± true-model reference" if floor else "")))
        elif not dg["correlated_signals"]:
            w("<p class=\"muted\">The diagnosis lists no correlated signals.</p>")
        if notes["diag_skipped"]:
            w("<p class=\"muted\">Not plotted: %s.</p>" % "; ".join(
                "%s vs %s (%s)" % (esc(cs["axis"]), esc(cs["signal"]), esc(why))
                for cs, why in notes["diag_skipped"]))
    if figs.get("signals"):
        w(_img(figs["signals"], "residual vs joint angles and rates",
               "Residual against wrist joint angles A4–A6 and the payload's angular rate |ω| and "
               "angular acceleration |ω̇|: binned mean per axis, shaded ± one standard deviation "
               "(%d bins over the 0.5–99.5 percentile range; bins with fewer than 5 samples "
               "left out)%s. A model that fits leaves flat lines at zero." % (
                   N_SIGNAL_BINS,
                   "; grey band: ± pooled true-model reference" if floor else "")))
    if notes["sig_skipped"]:
        w("<p class=\"muted\">Not plotted: %s.</p>" % "; ".join(
            "%s (%s)" % (esc(c), esc(why)) for c, why in notes["sig_skipped"]))
    if figs.get("joint_bins"):
        w(_img(figs["joint_bins"], "RMS per joint-angle bin",
               "RMS of the residual (all samples) in bins of each joint angle, force and torque "
               "pooled over their three axes. A model that fits is uniform here; a hot row points "
               "at the joint whose angle the error follows.%s" % (
                   " Red outline: the worst bin." if cmp_["worst"] else "")))
    else:
        w("<p class=\"muted\">No joint-angle bins in this bundle.</p>")

    # (7) ladder
    lad = s["ladder"]
    if lad:
        w('<h2 id="ladder">%s</h2>' % esc(_label("ladder", lad["made_for"])))
        if lad["made_for"]["match"] != "same":
            w(_foreign_box("ladder", lad["made_for"], " Its floors are not used in this report."))
        if figs.get("ladder"):
            lf = lad["true_model_reference"] or floor
            ls = lad["sensor_floor"] or sensor
            w(_img(figs["ladder"], "ladder of effects",
                   "Held-out force and torque RMS of the model at each step, labelled with the "
                   "effect that step added%s%s." % (
                       "; dashed: true-model reference" if lf else "",
                       "; dotted green: sensor floor" if ls else "")))
        if not lad["steps"]:
            w("<p class=\"muted\">The ladder has no steps.</p>")
        else:
            w("<table><tr><th>step</th><th class=\"l\">added</th><th>held-out force RMS (N)</th>"
              "<th>held-out torque RMS (N·m)</th>%s<th>BIC</th><th>ΔBIC</th></tr>" % "".join(
                  "<th>%s (%s)</th>" % (a, u) for a, u in zip(AXES, UNITS)))
            prev = None
            for k, st in enumerate(lad["steps"]):
                d = st["bic"] - prev if finite(st["bic"]) and finite(prev) else None
                w("<tr><td>%d</td><td class=\"l\">%s</td><td>%s</td><td>%s</td>%s<td>%s</td>"
                  "<td>%s</td></tr>" % (
                      k, esc(st["added"]) if st["added"] else "start: " + esc(", ".join(
                          st["effects"])), fmt(st["heldout"]["force_rms"]),
                      fmt(st["heldout"]["torque_rms"]),
                      "".join("<td>%s</td>" % fmt(x) for x in st["heldout"]["rms"]),
                      fmt_bic(st["bic"]), fmt_bic(d) if d is not None else ""))
                prev = st["bic"]
            w("</table>")

    # (8) diagnosis
    if dg:
        w('<h2 id="diagnosis">%s</h2>' % esc(_label("diagnosis", dg["made_for"])))
        if not own:
            v = dg["verdict"]
            w(_foreign_box("diagnosis", dg["made_for"]))
            w("<p>Its verdict, for the model it was made for and not necessarily for this one: "
              "%s</p>" % esc(v["text"]))
            if v["command"]:
                w("<p>It suggested, for that model:</p><pre>%s</pre>" % esc(v["command"]))
        w("<p>Diagnosed model: %s. Held-out baseline RMS: force %s N, torque %s N·m.</p>" % (
            " ".join('<span class="chip">%s</span>' % esc(e) for e in dg["model"]) or "—",
            fmt(dg["baseline"]["force_rms"]), fmt(dg["baseline"]["torque_rms"])))
        if figs.get("diagnosis"):
            w(_img(figs["diagnosis"], "diagnosis candidates",
                   "Each candidate effect was added to the model and refitted; bars show the "
                   "fraction of held-out mean-square error it removed. ΔBIC = BIC(with) − "
                   "BIC(without), negative favours the effect."))
        cands = sorted(dg["candidates"],
                       key=lambda c: -(c["gain"] if finite(c["gain"]) else -math.inf))
        if cands:
            w("<table><tr><th class=\"l\">candidate</th><th>gain</th><th>ΔBIC</th>"
              "<th>held-out force RMS (N)</th><th>held-out torque RMS (N·m)</th></tr>")
            for c in cands:
                w("<tr><td class=\"l\">%s</td><td>%s</td><td>%s</td><td>%s</td><td>%s</td>"
                  "</tr>" % (esc(c["effect"]), fmt_pct(c["gain"]), fmt_bic(c["delta_bic"]),
                             fmt(c["heldout"]["force_rms"]), fmt(c["heldout"]["torque_rms"])))
            w("</table>")
        else:
            w("<p class=\"muted\">No candidates were tried.</p>")
        if dg["correlated_signals"]:
            w("<p>Signals most correlated with the residual:</p><table><tr>"
              "<th class=\"l\">signal</th><th class=\"l\">axis</th><th>correlation</th></tr>")
            for cs in dg["correlated_signals"]:
                w("<tr><td class=\"l\">%s</td><td class=\"l\">%s</td><td>%s</td></tr>" % (
                    esc(cs["signal"]), esc(cs["axis"]),
                    "—" if not finite(cs["correlation"]) else "%+.3f" % cs["correlation"]))
            w("</table>")
    w('<p class="muted" style="margin-top:30px">Generated by make_report.py from a zerog '
      "report bundle, version %d.</p>" % BUNDLE_VERSION)
    w("</body></html>\n")
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------
# Driver


def render(bundle, outdir_tmp, s, cols, np, plt):
    warnings = []
    n = len(cols["t_s"])
    if int(s["compare"]["samples"]["total"]) != n:
        warnings.append("data.csv has %d rows but summary.json says %d samples."
                        % (n, int(s["compare"]["samples"]["total"])))
    # Both yardsticks: summary > ladder (held-out blocks) > computed from the true model's
    # columns of data.csv.
    moving = cols["moving"] > 0.5

    def from_columns(suffix):
        out = {}
        for g, sel in (("all", np.ones(n, dtype=bool)), ("static", ~moving), ("moving", moving)):
            if not sel.any():
                out[g] = None
                continue
            rms = [float(np.sqrt(np.mean((cols[a + "_meas"][sel] - cols[a + suffix][sel]) ** 2)))
                   for a in AXES]
            out[g] = {"rms": rms, "force_rms": pooled(rms[:3]), "torque_rms": pooled(rms[3:])}
        return out

    for key, name, suffix in (("_ref", "true_model_reference", "_true"),
                              ("_sensor", "sensor_floor", "_true_clean")):
        if s[name]:
            s[key], s[key + "_source"] = s[name], "summary.json"
        elif s["ladder"] and s["ladder"]["made_for"]["match"] == "same" and s["ladder"][name]:
            s[key], s[key + "_source"] = s["ladder"][name], "the ladder (held-out blocks)"
        elif (AXES[0] + suffix) in cols:
            s[key], s[key + "_source"] = from_columns(suffix), "computed from data.csv"
        else:
            s[key], s[key + "_source"] = None, None

    figs_obj = Figures(outdir_tmp, s, cols, np, plt)
    res_rms = np.sqrt(np.mean(figs_obj.res ** 2, axis=1))
    for i, a in enumerate(AXES):
        ref = s["compare"]["segments"]["all"]["rms"][i]
        if finite(ref) and abs(res_rms[i] - ref) > 0.02 * max(abs(ref), 1e-12) + 1e-12:
            warnings.append("RMS of %s recomputed from data.csv is %s, summary.json says %s."
                            % (a, fmt(float(res_rms[i])), fmt(ref)))
    notes = {}
    if (AXES[0] + "_true") in cols:
        notes["_ref_cols"] = True
    if (AXES[0] + "_true_clean") in cols:
        notes["_sensor_cols"] = True
    if figs_obj.heldout is not None and figs_obj.heldout.any() and (~figs_obj.heldout).any():
        h = figs_obj.heldout
        notes["heldout_rms"] = (
            [float(x) for x in np.sqrt(np.mean(figs_obj.res[:, ~h] ** 2, axis=1))],
            [float(x) for x in np.sqrt(np.mean(figs_obj.res[:, h] ** 2, axis=1))])
    figs = {}
    figs["timeseries"], notes["decimated"] = figs_obj.timeseries()
    window = figs_obj.zoom_window()
    if window:
        figs["zoom"] = figs_obj.timeseries_zoom(window)
        t = cols["t_s"]
        notes["zoom"] = (window[0], window[1] - 1, float(t[window[0]]), float(t[window[1] - 1]))
    figs["hist"], notes["hist_clipped"] = figs_obj.histograms()
    notes["diag_skipped"] = []
    if s["diagnosis"]:
        figs["diag_signals"], notes["diag_skipped"] = figs_obj.diagnosis_signals(
            s["diagnosis"]["correlated_signals"])
    figs["signals"], notes["sig_skipped"] = figs_obj.residual_vs_signals()
    figs["joint_bins"] = figs_obj.joint_bins()
    if s["ladder"]:
        figs["ladder"] = figs_obj.ladder()
    if s["diagnosis"]:
        figs["diagnosis"] = figs_obj.candidates()
    figs["interactive"], notes["no_interactive"] = interactive_page(bundle, outdir_tmp)
    if notes["no_interactive"]:
        print("make_report: note: no interactive page: %s" % notes["no_interactive"],
              file=sys.stderr)
    page = build_html(s, cols, figs, notes, warnings)
    with open(os.path.join(outdir_tmp, "index.html"), "w", encoding="utf-8") as f:
        f.write(page)
    for wmsg in warnings:
        print("make_report: warning: %s" % wmsg, file=sys.stderr)


def interactive_page(bundle, outdir):
    """Writes OUT_DIR/interactive.html with interactive_report.py (plotly) run by $ZEROG_PYTHON
    (zerog report: the project's .venv python), else by this Python. Returns (its file name,
    None) or (None, why there is none): plotly not installed there, no such Python, or a
    failure of the script (then the static report is written all the same)."""
    script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "interactive_report.py")
    python = os.environ.get("ZEROG_PYTHON") or sys.executable
    out = os.path.join(outdir, INTERACTIVE)
    if not os.path.isfile(script):
        return None, "%s is missing (it is installed beside make_report.py)" % script
    try:
        p = subprocess.run([python, script, bundle, out], capture_output=True, text=True,
                           timeout=900)
    except OSError as e:
        return None, ("cannot run %s (%s): scripts/install-deps.sh makes the project's .venv "
                      "with plotly" % (python, e.strerror or e))
    except subprocess.TimeoutExpired:
        return None, "%s did not finish in 900 s" % script
    if p.returncode == 0 and os.path.isfile(out):
        return INTERACTIVE, None
    for leftover in (out, out + ".tmp"):
        if os.path.exists(leftover):
            os.remove(leftover)
    lines = p.stderr.strip().splitlines()
    if p.returncode == EXIT_NO_PLOTLY and lines:
        return None, lines[-1]
    return None, "%s failed (exit status %d): %s" % (
        os.path.basename(script), p.returncode, " / ".join(lines[-3:]) or "no message")


def _inside(child, parent):
    child, parent = os.path.realpath(child), os.path.realpath(parent)
    return child == parent or child.startswith(parent.rstrip(os.sep) + os.sep)


def ladder_plot(ladder_json, out_png):
    """`zerog ladder --plot`: only the ladder chart, from the ladder JSON, written atomically."""
    try:
        with open(ladder_json, encoding="utf-8") as f:
            lad = json.load(f)
    except (OSError, ValueError) as e:
        print("make_report: error: %s: %s" % (ladder_json, e), file=sys.stderr)
        return 1
    if not isinstance(lad, dict) or lad.get("kind") != "zerog-ladder" or not lad.get("steps"):
        print("make_report: error: %s: not a zerog-ladder document with steps" % ladder_json,
              file=sys.stderr)
        return 1
    os.environ.setdefault("MPLBACKEND", "Agg")
    import numpy as np
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    try:
        ref, sensor = _ladder_floors(lad, _Checker(ladder_json))
    except BundleError as e:
        print("make_report: error: %s" % e, file=sys.stderr)
        return 1
    lad = {"steps": lad["steps"], "true_model_reference": ref, "sensor_floor": sensor}
    out_png = os.path.abspath(out_png)
    if os.path.exists(out_png) and not os.path.isfile(out_png):
        print("make_report: error: %s: exists and is not a regular file; refusing to replace it"
              % out_png, file=sys.stderr)
        return 1
    tmp = tempfile.mkdtemp(prefix=".ladder-plot-", dir=os.path.dirname(out_png))
    try:
        figs = Figures.__new__(Figures)  # the ladder chart needs no samples
        figs.out, figs.s, figs.np, figs.plt = tmp, {"ladder": lad}, np, plt
        name = figs.ladder()
        os.replace(os.path.join(tmp, name), out_png)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


def main(argv):
    if argv and argv[0] == "--ladder-plot":
        if len(argv) != 3:
            print("usage: make_report.py --ladder-plot LADDER_JSON OUT_PNG", file=sys.stderr)
            return 2
        return ladder_plot(argv[1], argv[2])
    ap = argparse.ArgumentParser(
        prog="make_report.py",
        description="Render a zerog report bundle (proto/report_bundle.md) into "
                    "OUT_DIR/index.html and PNG figures.")
    ap.add_argument("bundle_dir", metavar="BUNDLE_DIR")
    ap.add_argument("out_dir", metavar="OUT_DIR")
    args = ap.parse_args(argv)
    bundle = args.bundle_dir
    out = os.path.abspath(args.out_dir)
    try:
        if not os.path.isdir(bundle):
            raise BundleError("%s: bundle directory does not exist" % bundle)
        if _inside(bundle, out):
            raise BundleError("%s: refusing to write the report over its own bundle %s "
                              "(choose another OUT_DIR)" % (args.out_dir, bundle))
        if os.path.exists(out) and not os.path.isdir(out):
            raise BundleError("%s: exists and is not a directory" % args.out_dir)
        import numpy as np
        s = load_summary(os.path.join(bundle, "summary.json"))
        cols = load_data(os.path.join(bundle, "data.csv"), np)
    except BundleError as e:
        print("make_report: error: %s" % e, file=sys.stderr)
        return 1

    os.environ.setdefault("MPLBACKEND", "Agg")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    parent = os.path.dirname(out)
    try:
        os.makedirs(parent, exist_ok=True)
    except OSError as e:
        print("make_report: error: %s: cannot create: %s" % (parent, e), file=sys.stderr)
        return 1
    tmp = tempfile.mkdtemp(prefix="." + os.path.basename(out) + ".tmp-", dir=parent)
    try:
        os.chmod(tmp, 0o755)
        render(bundle, tmp, s, cols, np, plt)
        old = None
        if os.path.exists(out):
            old = tempfile.mkdtemp(prefix="." + os.path.basename(out) + ".old-", dir=parent)
            os.rmdir(old)
            os.rename(out, old)
        try:
            os.rename(tmp, out)
        except OSError:
            if old:
                os.rename(old, out)
            raise
        if old:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException as e:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(e, (KeyboardInterrupt, SystemExit)):
            raise
        if isinstance(e, BundleError):
            print("make_report: error: %s" % e, file=sys.stderr)
            return 1
        if isinstance(e, OSError):
            print("make_report: error: %s" % e, file=sys.stderr)
            return 1
        raise
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
