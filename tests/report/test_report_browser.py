#!/usr/bin/env python3
"""The report's interactive page (host/report/interactive_report.py) in a real browser.

Run: .venv/bin/python tests/report/test_report_browser.py OUT_DIR [--require]
     (registered with ctest as report_browser; OUT_DIR, in the build tree, keeps the artifacts:
     the report, the screenshots interactive.png and interactive_zoomed.png, the mutants' pages)

Debian's chromium, headless, through Debian's chromedriver, driven by PyPI's selenium in the
project's .venv (scripts/install-deps.sh installs all three). No host name resolves in that
browser (--host-resolver-rules), so whatever a page would fetch from the network fails, as it
would offline.

On the page make_report.py writes (with this Python's plotly), through the page itself:
- no SEVERE console entry; both figures rendered (every visible trace drawn as SVG);
- Plotly.relayout of the time axis moves every panel's range (one linked axis), and a real
  mouse drag across the bottom panel zooms all panels to the dragged span;
- a real hover shows the nearest sample's time and pose in the pose line, as in data.csv;
- a real click on an axis button shows that axis only; a real pick in the dropdown puts that
  signal's values under all six residual panels.
Mutants, which the same checks must catch: the page with plotly.js from its CDN (offline it
renders nothing and the console says why), and the page with a script error.

Exit status 77 (skipped) without chromium, chromedriver, selenium or plotly; with --require (CI)
that is a failure naming what to install.
"""

import json
import math
import os
import re
import shutil
import subprocess
import sys
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..", "..")
MAKE_REPORT = os.path.join(ROOT, "host", "report", "make_report.py")
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(ROOT, "host", "report"))
from test_make_report import AXES, make_bundle  # noqa: E402  (the bundle of the unit tests)

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
N_SAMPLES = 6000          # 72 s at 0.012 s
LOAD_TIMEOUT_S = 120      # the real page; the demo's 873 s log draws in about 8 s here
MUTANT_TIMEOUT_S = 20     # a mutant that never renders
OUT = None                # OUT_DIR (main)

# True when both figures are drawn: plotly's layout exists and every visible trace has its SVG
# (a line path with a segment for the time series, marker paths for the scatter; a constant
# curve is one segment after plotly's line simplification).
RENDERED_JS = r"""
function drawn(id, sel, re) {
  var g = document.getElementById(id);
  if (!g || !g._fullLayout || !g._fullData || !g.querySelector('.main-svg')) return false;
  var visible = g._fullData.filter(function(t){ return t.visible === true; }).length;
  var n = 0;
  g.querySelectorAll('.scatterlayer .trace').forEach(function(tr){
    var p = tr.querySelectorAll(sel), ok = false;
    p.forEach(function(e){ if (re.test(e.getAttribute('d') || '')) ok = true; });
    if (ok) n++;
  });
  return visible > 0 && n === visible;
}
return document.readyState === 'complete' && drawn('timeseries', 'path.js-line', /^M.*L/) &&
       drawn('vs_signal', 'path.point', /^M.*Z/);
"""
STATE_JS = r"""
var s = {plotly: typeof Plotly};
['timeseries', 'vs_signal'].forEach(function(id){
  var g = document.getElementById(id);
  s[id] = !g ? 'no div' : !g._fullLayout ? 'no plot' :
          g.querySelectorAll('.scatterlayer .trace').length + ' traces drawn';
});
return JSON.stringify(s);
"""


def missing_tools():
    why = []
    for path, pkg in ((CHROMIUM, "chromium"), (CHROMEDRIVER, "chromium-driver")):
        if not os.access(path, os.X_OK):
            why.append("%s (Debian's %s)" % (path, pkg))
    for mod in ("selenium", "plotly", "numpy"):
        try:
            __import__(mod)
        except ImportError:
            why.append("%s for %s (PyPI, in .venv)" % (mod, sys.executable))
    return why


def start_browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
              "--window-size=1500,1400", "--host-resolver-rules=MAP * ~NOTFOUND",
              "--disable-extensions", "--mute-audio"):
        opts.add_argument(a)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    driver.set_script_timeout(60)
    return driver


def page_problems(driver, path, timeout):
    """What is wrong with the page at `path` once loaded: [] when both figures rendered and the
    console has no SEVERE entry."""
    from selenium.common.exceptions import TimeoutException
    from selenium.webdriver.support.ui import WebDriverWait
    driver.get_log("browser")  # the entries of an earlier page
    driver.get("file://" + os.path.abspath(path))
    problems = []
    try:
        WebDriverWait(driver, timeout, poll_frequency=0.5).until(
            lambda d: d.execute_script(RENDERED_JS))
    except TimeoutException:
        problems.append("the figures did not render in %d s: %s" % (
            timeout, driver.execute_script(STATE_JS)))
    problems += ["console: " + e["message"] for e in driver.get_log("browser")
                 if e["level"] == "SEVERE"]
    return problems


class BrowserTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        import numpy as np
        cls.np = np
        bundle = os.path.join(OUT, "bundle")
        cls.report = os.path.join(OUT, "report")
        s = make_bundle(bundle, n=N_SAMPLES)
        # a verdict with events, so that the page shades them too
        s["diagnosis"]["verdict"] = {"kind": "event", "effect": None, "command": None,
                                     "text": "Two spans are events, not physics."}
        s["diagnosis"]["events"] = [{"t0_s": 130.0, "t1_s": 131.5},
                                    {"t0_s": 150.0, "t1_s": 150.6}]
        with open(os.path.join(bundle, "summary.json"), "w") as f:
            json.dump(s, f)
        p = subprocess.run(["/usr/bin/python3", MAKE_REPORT, bundle, cls.report],
                           env=dict(os.environ, ZEROG_PYTHON=sys.executable),
                           capture_output=True, text=True, timeout=600)
        if p.returncode != 0 or p.stderr:
            raise AssertionError("make_report.py: exit %d\n%s" % (p.returncode, p.stderr))
        cls.page = os.path.join(cls.report, "interactive.html")
        with open(os.path.join(bundle, "data.csv")) as f:
            header = f.readline().strip().split(",")
        data = np.loadtxt(os.path.join(bundle, "data.csv"), delimiter=",", skiprows=1)
        cls.cols = {h: data[:, i] for i, h in enumerate(header)}
        cls.driver = start_browser()
        cls.load_problems = page_problems(cls.driver, cls.page, LOAD_TIMEOUT_S)
        cls.driver.save_screenshot(os.path.join(OUT, "interactive.png"))

    @classmethod
    def tearDownClass(cls):
        if getattr(cls, "driver", None):
            cls.driver.quit()

    def js(self, script, *args):
        return self.driver.execute_script(script, *args)

    def ranges(self):
        """The range of each time axis of the time-series figure, by name."""
        return self.js("var L = document.getElementById('timeseries')._fullLayout;"
                       "return Object.keys(L).filter(function(k){ return /^xaxis\\d*$/.test(k); })"
                       ".sort().map(function(k){ return [k, L[k].range]; });")

    def relayout(self, update):
        return self.driver.execute_async_script(
            "var done = arguments[arguments.length - 1];"
            "Plotly.relayout('timeseries', arguments[0]).then(function(){ done(true); },"
            " function(e){ done(String(e)); });", update)

    def master_axis(self):
        """The time axis the others match (make_subplots: the bottom one, with the labels)."""
        return self.js("var L = document.getElementById('timeseries')._fullLayout;"
                       "return L.xaxis.matches ? 'xaxis' + L.xaxis.matches.slice(1) : 'xaxis';")

    def test_1_page_renders_without_console_errors(self):
        self.assertEqual(self.load_problems, [])
        state = json.loads(self.js(STATE_JS))
        self.assertEqual(state["plotly"], "object")
        n_ts = self.js("return document.getElementById('timeseries')._fullData.filter("
                       "function(t){ return t.visible === true; }).length")
        self.assertEqual(n_ts, 3 * 6)  # measured, predicted, residual per axis
        # moving segments, held-out blocks and the two events are shapes of the layout
        names = self.js("return document.getElementById('timeseries')._fullLayout.shapes"
                        ".map(function(s){ return s.name; })")
        self.assertEqual(names.count("event (diagnosis)"), 2)
        self.assertGreater(names.count("moving segment"), 10)
        self.assertGreater(names.count("held-out block"), 10)

    def test_2_relayout_zooms_every_panel(self):
        master = self.master_axis()
        self.assertEqual(self.relayout({master + ".autorange": True}), True)
        t = self.cols["t_s"]
        full = self.ranges()
        for _, r in full:
            self.assertLess(abs(r[0] - t[0]), 1.0)
            self.assertLess(abs(r[1] - t[-1]), 1.0)
        self.assertEqual(len(full), 4)
        self.assertEqual(self.relayout({master + ".range": [120.0, 125.0]}), True)
        for name, r in self.ranges():
            self.assertEqual(r, [120.0, 125.0], name)

    def test_3_mouse_drag_zooms_to_the_dragged_span(self):
        from selenium.webdriver.common.action_chains import ActionChains
        from selenium.webdriver.common.by import By
        master = self.master_axis()
        self.assertEqual(self.relayout({master + ".autorange": True}), True)
        before = dict(self.ranges())[master]
        sub = "x%sy%s" % (master[5:], master[5:])   # the bottom panel, e.g. x4y4
        drag = self.driver.find_element(
            By.CSS_SELECTOR, "#timeseries .nsewdrag[data-subplot='%s']" % sub)
        self.driver.execute_script("arguments[0].scrollIntoView({block: 'center'});", drag)
        w = drag.size["width"]
        (ActionChains(self.driver)
         .move_to_element_with_offset(drag, -w // 4, 0).click_and_hold()
         .move_by_offset(w // 8, 2).move_by_offset(w // 8, 0).move_by_offset(w // 4, 0)
         .release().perform())
        after = self.ranges()
        r = dict(after)[master]
        # dragged from a quarter to three quarters of the width: the middle half of the span
        span = before[1] - before[0]
        self.assertAlmostEqual(r[1] - r[0], span / 2, delta=span * 0.03)
        self.assertAlmostEqual((r[0] + r[1]) / 2, (before[0] + before[1]) / 2,
                               delta=span * 0.03)
        for name, x in after:
            self.assertEqual(x, r, name)
        self.driver.save_screenshot(os.path.join(OUT, "interactive_zoomed.png"))

    def test_4_hover_shows_time_and_pose(self):
        from selenium.webdriver.common.action_chains import ActionChains
        from selenium.webdriver.common.by import By
        from selenium.webdriver.support.ui import WebDriverWait
        master = self.master_axis()
        self.assertEqual(self.relayout({master + ".range": [130.0, 140.0]}), True)
        sub = "x%sy%s" % (master[5:], master[5:])
        drag = self.driver.find_element(
            By.CSS_SELECTOR, "#timeseries .nsewdrag[data-subplot='%s']" % sub)
        self.driver.execute_script("arguments[0].scrollIntoView({block: 'center'});", drag)
        ActionChains(self.driver).move_to_element_with_offset(drag, 0, 0).perform()
        pose = self.driver.find_element(By.ID, "pose")
        WebDriverWait(self.driver, 10).until(lambda d: pose.text.startswith("t "))
        m = re.match(r"t (\S+) s \(sample (\d+)\)\s+(static|moving)", pose.text)
        self.assertTrue(m, pose.text)
        t_shown, k = float(m.group(1)), int(m.group(2)) - 1
        t = self.cols["t_s"]
        self.assertLess(abs(t_shown - t[k]), 1e-3)
        self.assertLess(abs(t[k] - 135.0), 0.5)   # the middle of the panel
        self.assertEqual(m.group(3), "moving" if self.cols["moving"][k] else "static")
        for j in range(1, 7):
            a = re.search(r"A%d (\S+) deg" % j, pose.text)
            self.assertTrue(a, pose.text)
            q = math.degrees(self.cols["q%d_rad" % j][k])
            self.assertAlmostEqual(float(a.group(1)), q, delta=1e-3 * max(1.0, abs(q)))
        w = re.search(r"\|dω/dt\| (\S+) rad/s²", pose.text)
        self.assertTrue(w, pose.text)
        self.assertAlmostEqual(float(w.group(1)), self.cols["omega_dot_norm_radps2"][k],
                               delta=1e-3 * max(1.0, abs(self.cols["omega_dot_norm_radps2"][k])))
        self.assertEqual("held-out" in pose.text, bool(self.cols["heldout"][k]))

    def _click_menu_item(self, div, label):
        from selenium.webdriver.common.by import By
        item = self.driver.find_element(
            By.XPATH, "//*[@id='%s']//*[name()='g'][contains(@class, 'updatemenu-button') or "
                      "contains(@class, 'updatemenu-dropdown-button')][.//*[name()='text' and "
                      "normalize-space(.)='%s']]" % (div, label))
        self.driver.execute_script("arguments[0].scrollIntoView({block: 'center'});", item)
        item.click()

    def test_5_axis_buttons_show_one_axis(self):
        def shown():
            return self.js("return document.getElementById('timeseries')._fullData.filter("
                           "function(t){ return t.visible === true; }).map(function(t){"
                           " return t.meta.axis; })")
        self._click_menu_item("timeseries", "Fy")
        self.assertEqual(shown(), ["Fy"] * 3)
        self._click_menu_item("timeseries", "torques")
        self.assertEqual(sorted(set(shown())), AXES[3:])
        self._click_menu_item("timeseries", "all axes")
        self.assertEqual(len(shown()), 18)

    def test_6_dropdown_picks_the_signal(self):
        from selenium.webdriver.common.by import By
        header = self.driver.find_element(
            By.CSS_SELECTOR, "#vs_signal .updatemenu-header-group")
        self.driver.execute_script("arguments[0].scrollIntoView({block: 'center'});", header)
        header.click()
        self._click_menu_item("vs_signal", "A6 angle (deg)")
        got = self.js("var g = document.getElementById('vs_signal'), L = g._fullLayout;"
                      "return [[1,2,3,4,5,6].map(function(p){"
                      "  return L['xaxis' + (p > 1 ? p : '')].title.text; }),"
                      " g._fullData.map(function(t){ return Array.from(t.x.slice(0, 50)); })]")
        titles, xs = got
        self.assertEqual(titles, ["A6 angle (deg)"] * 6)
        stride = max(1, -(-N_SAMPLES // 5000))
        want = [math.degrees(v) for v in self.cols["q6_rad"][::stride][:50]]
        for x in xs:
            self.assertEqual(len(x), 50)
            for a, b in zip(x, want):
                self.assertAlmostEqual(a, b, delta=1e-4 * max(1.0, abs(b)))
        self.assertEqual(self.load_problems + self.console_errors(), [])

    def console_errors(self):
        return ["console: " + e["message"] for e in self.driver.get_log("browser")
                if e["level"] == "SEVERE"]

    # -- mutants: the checks above must catch a page that is not self-contained or broken

    def test_7_mutant_cdn_does_not_render_offline(self):
        import numpy as np
        import plotly.graph_objects as go
        from plotly.subplots import make_subplots
        import interactive_report as ir
        import make_report as mr
        bundle = os.path.join(OUT, "bundle")
        s = mr.load_summary(os.path.join(bundle, "summary.json"))
        cols = mr.load_data(os.path.join(bundle, "data.csv"), np)
        html = ir.build(s, cols, np, go, make_subplots, plotlyjs="cdn")
        self.assertTrue(re.search(r'<script[^>]* src="https://cdn\.plot\.ly/', html))
        path = os.path.join(OUT, "mutant_cdn.html")
        with open(path, "w", encoding="utf-8") as f:
            f.write(html)
        problems = page_problems(self.driver, path, MUTANT_TIMEOUT_S)
        text = "\n".join(problems)
        self.assertIn("did not render", text)
        self.assertIn('"plotly":"undefined"', text)
        self.assertRegex(text, r"console: .*cdn\.plot\.ly.*ERR_NAME_NOT_RESOLVED")

    def test_8_mutant_script_error_is_caught(self):
        with open(self.page, encoding="utf-8") as f:
            html = f.read()
        path = os.path.join(OUT, "mutant_script_error.html")
        with open(path, "w", encoding="utf-8") as f:
            f.write(html.replace("</body>", "<script>zerogNoSuchFunction();</script></body>"))
        problems = page_problems(self.driver, path, LOAD_TIMEOUT_S)
        self.assertEqual(len(problems), 1, problems)
        self.assertRegex(problems[0], r"console: .*zerogNoSuchFunction is not defined")


def main(argv):
    global OUT
    require = "--require" in argv
    args = [a for a in argv if a != "--require"]
    if len(args) != 1:
        print("usage: test_report_browser.py OUT_DIR [--require]", file=sys.stderr)
        return 2
    missing = missing_tools()
    if missing:
        print("%s: report_browser needs %s: run scripts/install-deps.sh" % (
            "FAIL" if require else "SKIP", "; ".join(missing)), file=sys.stderr)
        return 1 if require else 77
    OUT = os.path.abspath(args[0])
    shutil.rmtree(OUT, ignore_errors=True)
    os.makedirs(OUT)
    r = unittest.main(argv=[sys.argv[0], "-v"], exit=False).result
    print("artifacts: %s (interactive.png, interactive_zoomed.png, report/)" % OUT)
    return 0 if r.wasSuccessful() else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
