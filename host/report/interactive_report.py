#!/usr/bin/env python3
"""The interactive page of a zerog report: OUT_DIR/interactive.html beside index.html.

Usage: PYTHON interactive_report.py BUNDLE_DIR OUT_HTML

make_report.py runs it with $ZEROG_PYTHON, which `zerog report` sets to the project's venv
python (.venv/bin/python, the Python of `zerog import --bag` too): plotly is a PyPI package that
scripts/install-deps.sh installs there, while make_report.py runs on Debian's python3 with its
matplotlib. The bundle is read with make_report.py's own loaders (installed beside this file),
so both pages show the same validated data.

What the page holds (proto/report_bundle.md, "The interactive page"):
- the time series: measured and predicted force and torque, and the residual meas - pred, on
  one linked time axis (zoom one panel, all follow); moving segments, held-out blocks and the
  diagnosis' events shaded; buttons to show one wrench axis or all; hover shows the values and,
  in the pose line above the plot, the joint angles, |w|, |dw/dt| and the segment at that time;
- the residual of each axis against a signal chosen in a dropdown (any numeric column of
  data.csv: joint angles and velocities, |w|, |dw/dt|, |f - g|, temperature, time, the columns
  the diagnosis names).
plotly.js is embedded in the file (no CDN): the page works offline and can be copied with the
report folder.

Exit status: 0 written; 3 plotly (or numpy) cannot be imported for this Python, nothing written
(the message says what to install); 1 a malformed bundle or an unwritable OUT_HTML.
"""

import base64
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import make_report as mr  # noqa: E402  (beside this file, in the source tree and installed)

EXIT_NO_PLOTLY = 3
# Per time-series curve: up to this many samples are given to plotly one by one; a longer log
# is min/max decimated per bin beyond it (make_report.minmax_idx: spikes survive). 100,000 keeps
# the demo's 873 s log (72,762 samples) at full resolution, so a zoom shows every sample.
# The traces are SVG (go.Scatter), not WebGL (go.Scattergl): plotly simplifies an SVG line to
# what the pixels show on every redraw, and in headless Chromium (software WebGL, as on a
# machine without a GPU) the demo's page drew in 8 s as SVG against 60 s as WebGL.
MAX_TS_POINTS = 100000
# The curves of the true model (meas - true, meas - true on noise-free signals: the two
# yardsticks, off until clicked) show the width of the noise, not single samples: fewer points.
MAX_REF_POINTS = 10000
# Per residual-vs-signal panel: an even stride through the log (the shape of the dependence,
# not single samples; the time series has every sample).
MAX_VS_POINTS = 5000
# Forces in one panel pair, torques in the other; a colour per axis.
AXIS_COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#1f77b4", "#ff7f0e", "#2ca02c"]
# Plotly's config for both figures: wheel zoom, no logo.
CONFIG = {"scrollZoom": True, "displaylogo": False,
          "toImageButtonOptions": {"format": "png", "scale": 2}}
PAGE_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0 auto;
 max-width:1500px;padding:0 18px 40px;color:#1d1d1d;line-height:1.45}
h1{margin:18px 0 4px;font-size:1.5em}
h2{margin-top:26px;border-bottom:2px solid #ddd;padding-bottom:3px}
.muted{color:#666}
#pose{position:sticky;top:0;z-index:10;background:#f6f8fb;border:1px solid #d5deea;
 padding:4px 10px;font-family:ui-monospace,monospace;font-size:.9em;min-height:1.4em}
"""


def _typed(np, a, dtype):
    """plotly.js's typed-array form {dtype, bdata}, base64 of the little-endian values, as plotly
    writes numpy arrays in traces; for the data outside traces (the dropdown's arguments, the
    pose line), which plotly would write as JSON text three times the size."""
    a = np.ascontiguousarray(a, dtype=np.dtype(dtype).newbyteorder("<"))
    return {"dtype": {"float32": "f4", "float64": "f8", "uint8": "u1"}[np.dtype(dtype).name],
            "bdata": base64.b64encode(a.tobytes()).decode("ascii")}


class Page:
    def __init__(self, s, cols, np, go, make_subplots):
        self.s, self.c, self.np, self.go, self.sub = s, cols, np, go, make_subplots
        t = cols["t_s"]
        self.n = len(t)
        # The static figures' time axis (make_report.Figures): time since the first sample when
        # t_s is a wall-clock time, else t_s itself.
        self.t0 = float(t[0]) if abs(t[0]) > 1e5 else 0.0
        self.t = t - self.t0
        self.tlabel = "time since first sample (s)" if self.t0 else "time t_s (s)"
        # Times as float32 when that resolves a hundredth of the sample period (a third less
        # data than float64), else float64.
        dt = float(np.median(np.diff(self.t))) if self.n > 1 else 1.0
        tmax = float(np.max(np.abs(self.t))) if self.n else 0.0
        self.tdtype = "float32" if tmax * 2.0 ** -23 < 0.01 * max(dt, 1e-12) else "float64"
        self.moving = cols["moving"] > 0.5
        self.heldout = cols["heldout"] > 0.5 if "heldout" in cols else None
        self.res = [cols[a + "_meas"] - cols[a + "_pred"] for a in mr.AXES]
        self.decimated = self.n > MAX_TS_POINTS
        # Evenly sampled (to a hundredth of the period): a curve drawn at every sample gives its
        # times as plotly's x0 + k dx instead of one array per curve (half the page's data).
        self.dt = dt
        self.uniform = self.n > 1 and float(np.max(np.abs(
            self.t - (self.t[0] + dt * np.arange(self.n))))) < 0.01 * dt

    # -- time series
    def _line(self, y, name, i, row, dash=None, width=1.0, color=None, visible=True,
              group_title=False, max_points=MAX_TS_POINTS):
        np = self.np
        k = mr.minmax_idx(np, y, max_points)
        a = mr.AXES[i]
        if self.uniform and len(k) == self.n:
            x = {"x0": float(self.t[0]), "dx": self.dt}
        else:
            x = {"x": self.t[k].astype(self.tdtype)}
        return self.go.Scatter(
            **x, y=y[k].astype(np.float32),
            mode="lines", name="%s %s" % (a, name), legendgroup=a,
            legendgrouptitle_text=a if group_title else None, visible=visible,
            line={"color": color or AXIS_COLORS[i], "width": width, "dash": dash},
            hovertemplate="%s %s: %%{y:.5g} %s<extra></extra>" % (a, name, mr.UNITS[i]),
            meta={"axis": a, "row": row})

    def timeseries(self):
        fig = self.sub(rows=4, cols=1, shared_xaxes=True, vertical_spacing=0.035,
                       row_heights=[0.3, 0.2, 0.3, 0.2],
                       subplot_titles=("force: measured (solid) and predicted (dashed)",
                                       "force residual meas − pred",
                                       "torque: measured (solid) and predicted (dashed)",
                                       "torque residual meas − pred"))
        has_ref = (mr.AXES[0] + "_true") in self.c
        has_clean = (mr.AXES[0] + "_true_clean") in self.c
        for i, a in enumerate(mr.AXES):
            top = 1 if i < 3 else 3
            fig.add_trace(self._line(self.c[a + "_meas"], "measured", i, top, group_title=True),
                          row=top, col=1)
            fig.add_trace(self._line(self.c[a + "_pred"], "predicted", i, top, dash="dash",
                                     width=1.4), row=top, col=1)
            if has_ref:  # context, off until clicked in the legend (as in timeseries.png)
                fig.add_trace(self._line(self.c[a + "_meas"] - self.c[a + "_true"],
                                         "meas − true model", i, top + 1, width=0.8,
                                         color="#9a9a9a", visible="legendonly",
                                         max_points=MAX_REF_POINTS),
                              row=top + 1, col=1)
            if has_clean:
                fig.add_trace(self._line(self.c[a + "_meas"] - self.c[a + "_true_clean"],
                                         "meas − true on noise-free signals", i, top + 1,
                                         width=0.8, color="#2e8b3a", visible="legendonly",
                                         max_points=MAX_REF_POINTS),
                              row=top + 1, col=1)
            fig.add_trace(self._line(self.res[i], "residual", i, top + 1), row=top + 1, col=1)
        shapes = self._shapes()
        fig.update_layout(
            height=1150, hovermode="x unified", shapes=shapes, template="plotly_white",
            margin={"l": 70, "r": 20, "t": 90, "b": 50},
            legend={"groupclick": "toggleitem", "tracegroupgap": 12},
            updatemenus=[self._axis_buttons(fig)])
        fig.update_yaxes(title_text="force (N)", row=1, col=1)
        fig.update_yaxes(title_text="resid. (N)", row=2, col=1)
        fig.update_yaxes(title_text="torque (N·m)", row=3, col=1)
        fig.update_yaxes(title_text="resid. (N·m)", row=4, col=1)
        fig.update_xaxes(title_text=self.tlabel, row=4, col=1)
        fig.update_xaxes(showspikes=True, spikemode="across", spikethickness=1)
        return fig

    def _axis_buttons(self, fig):
        """One button per wrench axis (and all, forces, torques): shows that axis' traces in
        every panel. The legend toggles single traces."""
        metas = [tr.meta["axis"] for tr in fig.data]
        default = [tr.visible if tr.visible is not None else True for tr in fig.data]

        def vis(keep):
            return [d if m in keep else False for m, d in zip(metas, default)]
        buttons = [{"label": "all axes", "method": "restyle", "args": [{"visible": default}]},
                   {"label": "forces", "method": "restyle",
                    "args": [{"visible": vis(mr.AXES[:3])}]},
                   {"label": "torques", "method": "restyle",
                    "args": [{"visible": vis(mr.AXES[3:])}]}]
        buttons += [{"label": a, "method": "restyle", "args": [{"visible": vis([a])}]}
                    for a in mr.AXES]
        return {"type": "buttons", "direction": "right", "buttons": buttons, "x": 0.0,
                "xanchor": "left", "y": 1.075, "yanchor": "bottom", "showactive": True,
                "pad": {"r": 4, "t": 0}}

    def _shapes(self):
        """Moving segments (blue, all panels), held-out blocks (purple strip at the foot of both
        residual panels), the diagnosis' events (red, all panels); each kind one legend entry
        that shows and hides it."""
        np = self.np
        shapes = []

        def band(kind, x0, x1, first, **kw):
            d = {"type": "rect", "xref": "x", "x0": float(x0), "x1": float(x1),
                 "line": {"width": 0}, "legendgroup": kind, "name": kind,
                 "showlegend": first}
            d.update(kw)
            shapes.append(d)
        for k, (a, w) in enumerate(mr.runs(np, self.moving, self.t)):
            band("moving segment", a, a + w, k == 0, yref="paper", y0=0, y1=1,
                 fillcolor="#dbe8f5", opacity=0.6, layer="below")
        if self.heldout is not None:
            for k, (a, w) in enumerate(mr.runs(np, self.heldout, self.t)):
                for j, yref in enumerate(("y2 domain", "y4 domain")):
                    band("held-out block", a, a + w, k == 0 and j == 0, yref=yref, y0=0,
                         y1=0.07, fillcolor="#9467bd", opacity=0.75, layer="above")
        for k, (a, b) in enumerate(self.events()):
            band("event (diagnosis)", a, b, k == 0, yref="paper", y0=0, y1=1,
                 fillcolor="#e06666", opacity=0.3, layer="below")
        return shapes

    def events(self):
        """The verdict's event spans in the plot's time axis (a diagnosis made for this model
        and log only, as in timeseries.png)."""
        dg = self.s.get("diagnosis")
        if not dg or dg["made_for"]["match"] != "same" or not self.n:
            return []
        lo, hi = float(self.t[0]), float(self.t[-1])
        out = []
        for a, b in dg["verdict"].get("events", []):
            a, b = max(a - self.t0, lo), min(b - self.t0, hi)
            if b > a:
                out.append((a, b))
        return out

    # -- residual against a signal
    def signals(self):
        """(column, label) of every signal the dropdown offers: the diagnosis' correlated
        signals first (the ones data.csv has), then joint angles and velocities, the IMU's
        norms, temperature, any other numeric column, time."""
        wrench = {a + sfx for a in mr.AXES for sfx in ("_meas", "_pred") + mr.TRUE_SUFFIXES}
        skip = wrench | {"moving", "heldout", "t_s"}
        order = []
        dg = self.s.get("diagnosis")
        for cs in (dg["correlated_signals"] if dg else []):
            col = cs["signal"] if cs["signal"] in self.c else mr.SHORT_SIGNALS.get(cs["signal"])
            if col and col in self.c and col not in skip:
                order.append(col)
        known = (["q%d_rad" % j for j in range(1, 7)] + ["qd%d_radps" % j for j in range(1, 7)]
                 + ["omega_norm_radps", "omega_dot_norm_radps2", "accel_norm_mps2", "temp_C"])
        order += [c for c in known if c in self.c]
        order += sorted(c for c in self.c if c not in skip)
        order.append("t_s")
        out, seen = [], set()
        for col in order:
            if col in seen:
                continue
            seen.add(col)
            x = self._signal_x(col)
            if self.np.count_nonzero(self.np.isfinite(x)) >= 2 and \
                    self.np.nanmax(x) > self.np.nanmin(x):
                out.append((col, mr.signal_label(col) if col != "t_s" else self.tlabel))
        return out

    def _signal_x(self, col):
        return self.t if col == "t_s" else mr.signal_values(col, self.c, self.np)

    def vs_signal(self):
        np, go = self.np, self.go
        sigs = self.signals()
        stride = max(1, -(-self.n // MAX_VS_POINTS))
        k = np.arange(0, self.n, stride)
        fig = self.sub(rows=2, cols=3, horizontal_spacing=0.06, vertical_spacing=0.14,
                       subplot_titles=["%s residual (%s)" % (a, u)
                                       for a, u in zip(mr.AXES, mr.UNITS)])
        col0, label0 = sigs[0]
        x0 = self._signal_x(col0)[k].astype(np.float32)
        for i, a in enumerate(mr.AXES):
            fig.add_trace(go.Scatter(
                x=x0, y=self.res[i][k].astype(np.float32), mode="markers",
                name=a, legendgroup=a, marker={"size": 3, "opacity": 0.35,
                                               "color": AXIS_COLORS[i]},
                hovertemplate="%%{x:.4g}<br>%s residual %%{y:.4g} %s<extra></extra>" % (
                    a, mr.UNITS[i]),
                meta={"axis": a}), row=i // 3 + 1, col=i % 3 + 1)
        # The dropdown: each entry gives all six traces the signal's values (one copy: restyle
        # applies a one-element list to every trace) and names it under every panel.
        buttons = []
        for col, label in sigs:
            xs = _typed(np, self._signal_x(col)[k], "float32")
            titles = {"xaxis%s.title.text" % ("" if p == 0 else p + 1): label for p in range(6)}
            buttons.append({"label": label, "method": "update",
                            "args": [{"x": [xs]}, titles]})
        fig.update_layout(
            height=720, template="plotly_white", showlegend=False,
            margin={"l": 60, "r": 20, "t": 110, "b": 50},
            updatemenus=[{"type": "dropdown", "buttons": buttons, "active": 0, "x": 0.0,
                          "xanchor": "left", "y": 1.2, "yanchor": "bottom",
                          "name": "signal"}],
            annotations=list(fig.layout.annotations) + [
                {"text": "signal:", "x": 0.0, "xref": "paper", "y": 1.2, "yref": "paper",
                 "xanchor": "right", "yanchor": "bottom", "showarrow": False}])
        for p in range(6):
            fig.update_xaxes(title_text=label0, row=p // 3 + 1, col=p % 3 + 1)
        return fig, stride

    # -- the pose line: one copy of the pose, looked up by time on hover
    def pose_data(self, stride):
        """The pose line's data: each sample's joint angles, |ω|, |ω̇| and segment (one copy,
        looked up by time on hover), and the residual-vs-signal figure's stride."""
        np = self.np
        cols = {}
        for j in range(1, 7):
            if "q%d_rad" % j in self.c:
                cols["A%d" % j] = ("deg", np.degrees(self.c["q%d_rad" % j]))
        for col, name, unit in (("omega_norm_radps", "|ω|", "rad/s"),
                                ("omega_dot_norm_radps2", "|dω/dt|", "rad/s²")):
            if col in self.c:
                cols[name] = (unit, self.c[col])
        seg = self.moving.astype(np.uint8)
        if self.heldout is not None:
            seg = seg + 2 * self.heldout.astype(np.uint8)
        # The times once: as x0 + k dx when evenly sampled (as the curves give them).
        times = ({"x0": float(self.t[0]), "dx": self.dt} if self.uniform else
                 {"t": _typed(np, self.t, "float64")})
        return {"times": times, "segment": _typed(np, seg, "uint8"),
                "columns": [{"name": n, "unit": u, "v": _typed(np, v, "float32")}
                            for n, (u, v) in cols.items()], "vs_stride": stride}


POSE_JS = r"""
(function(){
  var data = JSON.parse(document.getElementById('zerog-pose').textContent);
  var types = {f8: Float64Array, f4: Float32Array, u1: Uint8Array};
  function dec(s){  // {dtype, bdata}: base64 of little-endian values
    var b = atob(s.bdata), u = new Uint8Array(b.length);
    for (var i = 0; i < b.length; i++) u[i] = b.charCodeAt(i);
    return new types[s.dtype](u.buffer);
  }
  var tm = data.times, seg = dec(data.segment), n = seg.length;
  var tt = tm.t ? dec(tm.t) : null;
  function t(k){ return tt ? tt[k] : tm.x0 + k * tm.dx; }
  var cols = data.columns.map(function(c){ return {name: c.name, unit: c.unit, v: dec(c.v)}; });
  var line = document.getElementById('pose');
  function sampleAt(x){  // the sample nearest to time x
    var lo = 0, hi = n - 1;
    while (hi - lo > 1) { var m = (lo + hi) >> 1; if (t(m) <= x) lo = m; else hi = m; }
    return Math.abs(t(hi) - x) < Math.abs(x - t(lo)) ? hi : lo;
  }
  function show(k){
    var parts = ['t ' + t(k).toFixed(3) + ' s (sample ' + (k + 1) + ')',
                 (seg[k] & 1) ? 'moving' : 'static'];
    if (seg[k] & 2) parts.push('held-out');
    cols.forEach(function(c){
      parts.push(c.name + ' ' + c.v[k].toPrecision(4) + ' ' + c.unit);
    });
    line.textContent = parts.join('   ');
  }
  var ts = document.getElementById('timeseries'), vs = document.getElementById('vs_signal');
  ts.on('plotly_hover', function(ev){ if (ev.points.length) show(sampleAt(ev.points[0].x)); });
  vs.on('plotly_hover', function(ev){
    if (ev.points.length) show(Math.min(n - 1, ev.points[0].pointIndex * data.vs_stride));
  });
})();
"""


def build(s, cols, np, go, make_subplots, plotlyjs=True):
    """The page's HTML. plotlyjs: plotly's include_plotlyjs (True: embedded; the tests' offline
    mutant passes "cdn")."""
    p = Page(s, cols, np, go, make_subplots)
    ts = p.timeseries()
    vs, stride = p.vs_signal()
    ts_html = ts.to_html(full_html=False, include_plotlyjs=plotlyjs, div_id="timeseries",
                         config=CONFIG)
    vs_html = vs.to_html(full_html=False, include_plotlyjs=False, div_id="vs_signal",
                         config=CONFIG)
    esc = mr.esc
    if p.decimated:
        res = ("%d samples; each curve min/max decimated to about %d points (the extremes of "
               "every bin kept)" % (p.n, MAX_TS_POINTS))
    else:
        res = "all %d samples" % p.n
    pose = json.dumps(p.pose_data(stride)).replace("</", "<\\/")
    events = p.events()
    return "".join([
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">",
        "<title>%s: interactive</title><style>%s</style></head><body>" % (
            esc(s["title"]), PAGE_CSS),
        "<h1>%s: interactive</h1>" % esc(s["title"]),
        "<p class=\"muted\">log <code>%s</code>, model <code>%s</code>. "
        "<a href=\"index.html\">The report</a> (tables, diagnosis, printable figures).</p>" % (
            esc(s["log"]), esc(s["model"])),
        "<h2 id=\"timeseries-h\">Time series</h2>",
        "<p class=\"muted\">Drag to zoom (one panel zooms all: one time axis), double-click to "
        "zoom out, the wheel zooms too. The buttons show one wrench axis; a click on a legend "
        "entry hides or shows that curve or shading (meas − true model: the true-model "
        "reference, off until clicked). Shaded: moving segments (blue), held-out blocks "
        "(purple, at the foot of the residual panels)%s. Drawn: %s.</p>" % (
            ", the diagnosis' events (red, %d)" % len(events) if events else "", res),
        "<div id=\"pose\">hover a curve: time and pose here</div>",
        ts_html,
        "<h2 id=\"vs-signal-h\">Residual against a signal</h2>",
        "<p class=\"muted\">Choose the signal in the dropdown. Every %s sample (%d points per "
        "panel); hover a point for its time and pose above.</p>" % (
            "" if stride == 1 else "%s" % _ordinal(stride), -(-p.n // stride)),
        vs_html,
        "<script type=\"application/json\" id=\"zerog-pose\">%s</script>" % pose,
        "<script>%s</script>" % POSE_JS,
        "</body></html>\n"])


def _ordinal(k):
    return "%d%s" % (k, "th" if 10 <= k % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(
        k % 10, "th"))


def main(argv):
    if len(argv) != 2:
        print("usage: interactive_report.py BUNDLE_DIR OUT_HTML", file=sys.stderr)
        return 2
    try:
        import numpy as np
        import plotly.graph_objects as go
        from plotly.subplots import make_subplots
    except ImportError as e:
        print("%s cannot import plotly and numpy (%s): scripts/install-deps.sh installs them "
              "into the project's .venv, whose python zerog report uses (by hand: "
              "ZEROG_PYTHON=.venv/bin/python)" % (sys.executable, e), file=sys.stderr)
        return EXIT_NO_PLOTLY
    bundle, out = argv
    try:
        s = mr.load_summary(os.path.join(bundle, "summary.json"))
        cols = mr.load_data(os.path.join(bundle, "data.csv"), np)
    except mr.BundleError as e:
        print("interactive_report: error: %s" % e, file=sys.stderr)
        return 1
    page = build(s, cols, np, go, make_subplots)
    tmp = out + ".tmp"
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(page)
        os.replace(tmp, out)
    except OSError as e:
        if os.path.exists(tmp):
            os.remove(tmp)
        print("interactive_report: error: %s: %s" % (out, e), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
