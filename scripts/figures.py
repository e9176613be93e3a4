#!/usr/bin/python3
"""The figures of README.md and docs/*.md, written from the runs that produce them, and checked.

Every number in README.md and docs/*.md (the documentation set) that comes from a run stands
between <!-- NAME:begin --> and <!-- NAME:end --> and is written by this module (or by
tests/hil/figures.py, which uses its block functions) from the JSON that run wrote. A block is
looked up by its name in the whole set: the name must occur in exactly one of its files, and the
block is written in that file. With --check nothing is written: the blocks are computed from the
given (fresh) run and compared with the documentation's; any difference is printed and the exit
status is 1.

    scripts/figures.py demo OUT_DIR             # scripts/demo.sh's run (demo.sh --write-readme)
    scripts/figures.py discovery ZEROG          # runs zerog sim + diagnose itself (about a minute)
    scripts/figures.py speed --run BENCH_DIR    # runs the Google Benchmark programs (ten minutes
                                                # or so: ident_bench's 10^6-sample logs)
    scripts/figures.py speed --run BENCH_DIR --program loop_bench   # one program: its blocks only
    scripts/figures.py speed BENCH_JSON...      # or takes their --benchmark_format=json output
    scripts/figures.py speed --check --bench-dir BENCH_DIR   # the documented timings, see below
    scripts/figures.py tool-change --gtest IDENT_TEST   # ident_test's ToolChange case
    scripts/figures.py soak SOAK_JSON           # zerog-soak --report (ctest soak_hour)
    scripts/figures.py results RESULTS_MD       # zerog results' table and JSON (scripts/results.sh)
    scripts/figures.py first-run JSON           # scripts/fresh_machine.sh's times of the two commands
  options: --readme README.md (default: the repository's; the documentation set is that README
           and every docs/*.md beside it), --check

How a block is compared (--check):
  - Figures of deterministic runs (simulation and fit with a fixed seed, lockstep HIL) are
    compared exactly, as printed: the runs are bit-reproducible (the same JSON twice).
  - Times (wall clock: how long a step or a benchmark took) and figures of a run paced by the wall
    clock are marked where they are generated; --check requires the same text with any number in
    their place.
  - Benchmark timings cannot be compared across machines or runs on a shared machine, so the speed
    blocks carry the values they were written from (an HTML comment, the JSON's own numbers):
    --check rewrites each block from those values and requires the same text, and requires every
    benchmark they name to exist, under that name, in the built benchmark programs (the same
    benchmark set).
"""
import argparse
import difflib
import glob
import json
import math
import os
import re
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
README = os.path.join(HERE, "..", "README.md")

# --- Blocks between markers -------------------------------------------------------------------

# A varying figure (a time, or a value of a run on the wall clock) is generated between these two
# characters: written without them, matched as "any number" by --check.
VARY_BEGIN, VARY_END = "\x01", "\x02"
NUMBER = r"(?<![\w.])[-+−]?[0-9][0-9,]*(?:\.[0-9]+)?"


def vary(value, spec=""):
    """`value` formatted with `spec`, marked as varying from run to run."""
    return f"{VARY_BEGIN}{format(value, spec)}{VARY_END}"


def vary_numbers(text):
    """Marks every number in `text` as varying."""
    return re.sub(NUMBER, lambda m: vary(m.group(0)), text)


def plain(text):
    return text.replace(VARY_BEGIN, "").replace(VARY_END, "")


def matches(expected, actual):
    """True if `actual` is `expected` with any numbers in place of its varying parts."""
    parts = re.split(f"{VARY_BEGIN}(.*?){VARY_END}", expected, flags=re.S)
    pattern = []
    for i, part in enumerate(parts):
        if i % 2 == 0:
            pattern.append(re.escape(part))
        else:  # the varying part: its numbers may be any numbers, the rest as it is
            pattern.append(NUMBER.join(re.escape(p) for p in re.split(NUMBER, part)))
    return re.fullmatch("".join(pattern), actual, flags=re.S) is not None


def markers(name):
    return f"<!-- {name}:begin -->", f"<!-- {name}:end -->"


def read_block(text, name, readme="README.md"):
    """The text between a block's markers (without the newlines next to them)."""
    begin, end = markers(name)
    if text.count(begin) != 1 or text.count(end) != 1 or text.index(begin) > text.index(end):
        raise SystemExit(f"{readme}: needs exactly one '{begin}' followed by one '{end}'")
    return text.split(begin, 1)[1].split(end, 1)[0].strip("\n")


def replace_block(text, name, body, readme="README.md"):
    read_block(text, name, readme)
    begin, end = markers(name)
    head, rest = text.split(begin, 1)
    tail = rest.split(end, 1)[1]
    return f"{head}{begin}\n{plain(body).strip(chr(10))}\n{end}{tail}"


# --- The documentation set: README.md and docs/*.md ---------------------------------------------

def doc_set(readme):
    """The files of `readme`'s documentation set: the README itself, then every docs/*.md in the
    folder beside it (sorted)."""
    folder = os.path.dirname(os.path.abspath(readme))
    return [readme] + sorted(glob.glob(os.path.join(folder, "docs", "*.md")))


def shown(readme, path):
    """`path` as the documentation names it: relative to the README's folder (docs/speed.md)."""
    return os.path.relpath(os.path.abspath(path), os.path.dirname(os.path.abspath(readme)))


def read_docs(readme):
    """{path: text} of every file of `readme`'s documentation set."""
    docs = {}
    for path in doc_set(readme):
        with open(path, encoding="utf-8") as f:
            docs[path] = f.read()
    return docs


def block_file(docs, name, readme):
    """The file of the documentation set `docs` ({path: text}) that holds the block `name`: the
    one whose text has its begin or end marker. None or several is an error naming them."""
    holders = [p for p, text in docs.items() if any(m in text for m in markers(name))]
    if len(holders) != 1:
        where = ("none of them" if not holders else
                 f"{len(holders)} of them: {', '.join(shown(readme, p) for p in holders)}")
        raise SystemExit(f"{readme}: the block '{name}' must be in exactly one file of README.md "
                         f"and docs/*.md; it is in {where}")
    return holders[0]


def read_doc_block(docs, name, readme):
    """(the path of the file that holds block `name`, the block's text)."""
    path = block_file(docs, name, readme)
    return path, read_block(docs[path], name, shown(readme, path))


def block_names(readme):
    """{name: path} of every block in `readme`'s documentation set (a begin marker on a line of
    its own), in the order of the files."""
    names = {}
    for path, text in read_docs(readme).items():
        for name in re.findall(r"^<!-- ([\w.-]+):begin -->$", text, flags=re.M):
            names.setdefault(name, path)
    return names


def write_file(path, text):
    """Writes `text` to `path` atomically (a temporary file beside it, then rename), keeping its
    mode."""
    fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.",
                               dir=os.path.dirname(os.path.abspath(path)))
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, os.stat(path).st_mode & 0o777)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def write_readme(readme, blocks):
    """Replaces the blocks {name: text} in `readme`'s documentation set, each in the file that
    holds it, atomically (per file: a temporary file, then rename). The files are read just
    before they are written: other parts of them may be edited meanwhile. Every block is found
    and replaced before any file is written."""
    docs = read_docs(readme)
    changed = {}
    for name, body in blocks.items():
        path = block_file(docs, name, readme)
        docs[path] = replace_block(docs[path], name, body, shown(readme, path))
        changed.setdefault(path, []).append(name)
    for path, names in changed.items():
        write_file(path, docs[path])
        print(f"figures.py: wrote {', '.join(names)} in {shown(readme, path)}")


def check_readme(readme, blocks, how):
    """Compares the blocks {name: text} with those of `readme`'s documentation set; prints what
    differs. `how` says how the figures are compared (printed with the verdict). Returns the exit
    status."""
    docs = read_docs(readme)
    status = 0
    for name, body in blocks.items():
        path, have = read_doc_block(docs, name, readme)
        shown_name = shown(readme, path)
        want = body.strip("\n")
        if matches(want, have):
            print(f"figures.py: {name}: {shown_name} agrees with the run ({how})")
            continue
        status = 1
        print(f"figures.py: {name}: {shown_name} DIFFERS from the run ({how}); "
              f"-{shown_name} +run (varying figures marked «»):")
        shown_text = want.replace(VARY_BEGIN, "«").replace(VARY_END, "»")
        have_lines, want_lines = have.splitlines(), want.splitlines()
        if len(have_lines) == len(want_lines):
            # Line by line: only the lines that differ (a varying figure matches any number).
            for i, (h, w) in enumerate(zip(have_lines, want_lines)):
                if not matches(w, h):
                    print(f"  line {i + 1}:\n  -{h}\n  +{shown_text.splitlines()[i]}")
            continue
        for line in difflib.unified_diff(have_lines, shown_text.splitlines(), shown_name, "run",
                                         lineterm="", n=0):
            print("  " + line)
    return status


def finish(args, blocks, how):
    if args.check:
        return check_readme(args.readme, blocks, how)
    write_readme(args.readme, blocks)
    return 0


# --- Number formatting -------------------------------------------------------------------------

def sig(x, n=4):
    """`x` with `n` significant digits, trailing zeros kept, never in exponent notation."""
    if x == 0:
        return "0"
    decimals = max(0, n - 1 - math.floor(math.log10(abs(x))))
    return f"{x:.{decimals}f}"


def pct(x, n=2):
    return f"{sig(100 * x, n)} %" if abs(100 * x) >= 1 else f"{100 * x:.{n - 1}f} %"


def span(values, fmt):
    lo, hi = fmt(min(values)), fmt(max(values))
    return lo if lo == hi else f"{lo}–{hi}"


def load(path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


# --- demo: scripts/demo.sh's run ----------------------------------------------------------------

def wrench(stats):
    return f"{sig(stats['force_rms'])} N / {sig(stats['torque_rms'])} N·m"


def truth_value(truth, effect, name):
    """The true value of a library parameter (0 where the truth lacks the effect, as zerog fit
    --truth prints it)."""
    return truth["parameters"].get(effect, {}).get(name, {}).get("value", 0.0)


def parameter_z(fit, truth):
    """(est − truth)/std of every fitted parameter: library parameters, then user-effect terms
    against the truth's outside-the-library laws (0 where the truth has no such term)."""
    z = []
    for effect, params in fit["parameters"].items():
        for name, p in params.items():
            if p.get("std"):
                z.append((p["value"] - truth_value(truth, effect, name)) / p["std"])
    outside = [t for e in truth["extra"].get("outside_model", {}).values() if e["enabled"]
               for t in e["terms"]]
    for u in fit.get("user_effects", []):
        for term in u["terms"]:
            true = next((t["coefficient"] for t in outside
                         if t["axis"] == term["axis"] and t["basis"] == term["basis"]), 0.0)
            if term.get("std"):
                z.append((term["value"] - true) / term["std"])
    return z


def value_pm(value, std, unit):
    decimals = max(0, -math.floor(math.log10(std)))
    return f"{value:.{decimals}f} ± {std:.{decimals}f} {unit}"


def demo_blocks(out):
    """The blocks of scripts/demo.sh's run in `out` (out/demo): the table, the ladder and
    parameters (README.md), the yardsticks in "Sensor floor and true-model reference"
    (docs/insight-loop.md) and the noise estimates in "Calibrating a real rig"
    (docs/calibrating.md)."""
    diag = load(os.path.join(out, "diagnosis.json"))
    diag_fixed = load(os.path.join(out, "diagnosis_fixed.json"))
    ladder = load(os.path.join(out, "ladder.json"))
    fit = load(os.path.join(out, "fit_fixed.json"))
    truth = load(os.path.join(out, "run.truth.json"))
    timing = load(os.path.join(out, "timing.json"))
    hidden = timing["hidden"]
    verdict = diag["verdict"]
    if verdict["kind"] == "effect":
        added = verdict["effect"]
        ranked = diag["candidates"]
        chosen = next(c for c in ranked if c["effect"] == added)
        others = [c for c in ranked if c["effect"] != added]
        after = chosen["heldout"]
        named = (f"`{added}`, {pct(chosen['gain'], 2)} of the error removed"
                 + (f"; next best `{others[0]['effect']}` {pct(others[0]['gain'], 1)}"
                    if others else ""))
    elif verdict["kind"] == "discovered":
        added = "@" + os.path.splitext(os.path.basename(verdict["effect_file"]))[0]
        after = diag["discovery"]["heldout"]
        named = (f"the law discovery found, "
                 f"{'; '.join(t['law'] for t in diag['discovery']['terms'])}: "
                 f"{pct(diag['discovery']['gain'], 2)} of the error removed")
    else:
        raise SystemExit(f"figures.py: {out}: diagnose named nothing to add ({verdict['kind']})")
    reference = ladder["true_model_reference"]
    floor = ladder["sensor_floor"]
    if reference is None or floor is None:
        raise SystemExit(f"figures.py: {out}/ladder.json has no true-model reference or sensor "
                         f"floor (zerog ladder --truth, with the clean log)")
    table = "\n".join([
        "| step | held-out force RMS | held-out torque RMS |",
        "|---|---|---|",
        f"| default model (`{hidden}` hidden in the truth) | "
        f"{sig(diag['baseline']['force_rms'])} N | {sig(diag['baseline']['torque_rms'])} N·m |",
        f"| after adding what diagnose named ({named}) | {sig(after['force_rms'])} N | "
        f"{sig(after['torque_rms'])} N·m |",
        f"| true-model reference (true model, true parameters, same noisy signals) | "
        f"{sig(reference['all']['force_rms'])} N | {sig(reference['all']['torque_rms'])} N·m |",
        f"| sensor floor (true model on noise-free signals against the same noisy wrench: the F/T "
        f"sensor's noise and quantisation) | {sig(floor['all']['force_rms'])} N | "
        f"{sig(floor['all']['torque_rms'])} N·m |",
    ])
    steps = ladder["steps"]
    climb = [f"{' + '.join(steps[0]['effects'])} {wrench(steps[0]['heldout'])}"]
    climb += [f"`+ {s['added']}` {wrench(s['heldout'])}" for s in steps[1:]]
    z = parameter_z(fit, truth)
    mass = fit["parameters"]["gravity"]["mass"]
    true_mass = truth_value(truth, "gravity", "mass")
    ladder_text = (
        f"The ladder from bias + gravity on the same run (held-out RMS): {' → '.join(climb)}. "
        f"With `{added}` added, every one of the {len(z)} fitted parameters lies within "
        f"{max(abs(v) for v in z):.2f} standard deviations of the truth (mass "
        f"{value_pm(mass['value'], mass['std'], 'kg')} against {true_mass:g}). Steps 1–9 of the "
        f"demo took {vary(timing['steps_1_to_9_s'], '.0f')} s after the build.")

    def segment(s, name):
        return f"{name} {wrench(s)}"

    floors = (
        f"On the demo's run (held-out blocks, `zerog ladder --truth`): sensor floor "
        f"{wrench(floor['all'])} ({segment(floor['static'], 'static')}, "
        f"{segment(floor['moving'], 'moving')}), true-model reference {wrench(reference['all'])} "
        f"({segment(reference['static'], 'static')}, {segment(reference['moving'], 'moving')}).")
    noise = diag_fixed["noise_rms"]
    pooled = [math.sqrt(sum(v * v for v in noise[k:k + 3]) / 3) for k in (0, 3)]
    sigma = fit["extra"]["fit"]["sigma"]
    estimates = (
        f"On the demo's run, with `{added}` added (`zerog diagnose` of that model): the "
        f"diagnosis's noise estimate is {sig(pooled[0])} N / {sig(pooled[1])} N·m against a "
        f"true-model reference of {wrench(reference['all'])} and a sensor floor of "
        f"{wrench(floor['all'])}; the fit's estimate from the dwells is "
        f"{span(sigma[:3], lambda v: sig(v, 2))} N and {span(sigma[3:], lambda v: sig(v, 2))} N·m "
        f"per axis.")
    return {"demo": table, "demo-ladder": ladder_text, "demo-floors": floors,
            "demo-noise": estimates}


def cmd_demo(args):
    return finish(args, demo_blocks(args.out),
                  "exact; the demo's run time: any number")


# --- discovery: laws outside the library --------------------------------------------------------

OUTSIDE_EFFECTS = ["joint6_friction", "swivel_viscous", "hose_drag", "dress_pack_bend"]


def run(*cmd):
    return subprocess.run(cmd, check=True, capture_output=True, text=True).stdout


def law(terms):
    return "; ".join(f"{t['axis']} += {t['coefficient']:.4g} · {t['basis']}" for t in terms)


def discovery_blocks(zerog):
    """The discovery table: for each simulated effect outside the library, the demo's calibration
    run (seed 42) with it hidden, the default model diagnosed; and the signals the residual of the
    first follows (before discovery)."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        design = os.path.join(tmp, "design.csv")
        run(zerog, "design", "--kind", "oa", "--out", design)
        for effect in OUTSIDE_EFFECTS:
            log = os.path.join(tmp, effect + ".csv")
            run(zerog, "sim", "--design", design, "--effects", effect, "--seed", "42", "--out", log,
                "-q")
            truth = load(os.path.join(tmp, effect + ".truth.json"))
            true_terms = truth["extra"]["outside_model"][effect]["terms"]
            d = json.loads(run(zerog, "diagnose", log, "--json", "-q", "--discovered-out",
                               os.path.join(tmp, effect + ".toml")))
            if effect == OUTSIDE_EFFECTS[0]:
                first = d
            found = d["discovery"]
            base = d["baseline"]
            if found is None:
                rows.append(f"| `{effect}` | {law(true_terms)} | (nothing: verdict "
                            f"{d['verdict']['kind']}) | {base['force_rms']:.3f} N / "
                            f"{base['torque_rms']:.3f} N·m | | |")
                continue
            laws = "; ".join(t["law"] for t in found["terms"])
            after = found["heldout"]
            rows.append(f"| `{effect}` | {law(true_terms)} | {laws} | {base['force_rms']:.3f} N / "
                        f"{base['torque_rms']:.3f} N·m | {after['force_rms']:.3f} N / "
                        f"{after['torque_rms']:.3f} N·m | {vary(found['seconds'], '.1f')} s |")
            columns = found["dictionary_size"]
            z = found["z_threshold"]
    table = "\n".join([
        f"Written by `scripts/figures.py discovery` from `zerog sim` (seed 42, the demo's path) "
        f"and `zerog diagnose --json` of the default model; {columns} basis-axis columns searched, "
        f"every term |z| > {z:.1f}. Errors are held-out RMS (force pooled over Fx, Fy, Fz; torque "
        f"likewise); \"after\" is the model refitted with the discovered effect on the training "
        f"blocks.",
        "",
        "| hidden effect | true law | discovered (± std) | before | after | discovery |",
        "|---|---|---|---|---|---|",
        *rows,
    ])
    signals = first["correlated_signals"]
    top = signals[0]
    follows = (
        f"With `{OUTSIDE_EFFECTS[0]}` hidden (a torque that flips with the direction of joint A6, "
        f"not in the library; the demo's run, seed 42), diagnose says "
        + ("no library effect explains it"
           if first["verdict"]["kind"] in ("discovered", "none") else
           f"`{first['verdict']['effect']}` explains it")
        + f" and that the {top['axis']} residual follows \"{top['signal']}\" "
        f"(ρ = {top['correlation']:.2f}) — and then finds the law itself (next section).")
    return {"discovery": table, "discovery-signals": follows}


def cmd_discovery(args):
    return finish(args, discovery_blocks(args.zerog),
                  "exact; the discovery's run time: any number")


# --- speed: Google Benchmark programs -----------------------------------------------------------

BENCH_PROGRAMS = ["ident_bench", "infer_bench", "rtio_bench", "loop_bench", "telemetry_bench",
                  "modbus_bench"]
UNIT_S = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}


class Bench:
    """The values of Google Benchmark runs ({program: JSON}); records which values a text uses,
    so that a block can carry them (and be rewritten from them by --check)."""

    def __init__(self, runs):
        self.runs = runs
        self.used = {}

    @staticmethod
    def from_json(docs):
        runs = {}
        for doc in docs:
            program = os.path.basename(doc["context"]["executable"])
            # A benchmark run with repetitions stands for its median repetition (by real time;
            # every value from that one repetition), so one slow moment of a shared machine does
            # not make a figure.
            repetitions = {}
            for b in doc["benchmarks"]:
                if b.get("run_type", "iteration") != "iteration":
                    continue
                e = {k: v for k, v in b.items() if isinstance(v, (int, float, str))}
                e["real_time_s"] = b["real_time"] * UNIT_S[b["time_unit"]]
                e["cpu_time_s"] = b["cpu_time"] * UNIT_S[b["time_unit"]]
                repetitions.setdefault(b["name"], []).append(e)
            entries = {}
            for name, runs_ in repetitions.items():
                runs_.sort(key=lambda e: e["real_time_s"])
                entries[name] = dict(runs_[(len(runs_) - 1) // 2])
                entries[name]["repetitions"] = len(runs_)
            ctx = doc["context"]
            runs[program] = {"date": ctx["date"], "num_cpus": ctx["num_cpus"],
                             "build": doc.get("zerog_build", ""), "benchmarks": entries}
        return Bench(runs)

    def _find(self, program, name):
        entries = self.runs[program]["benchmarks"]
        hits = [n for n in entries if n == name or n.startswith(name + "/")]
        if len(hits) != 1:
            raise SystemExit(f"figures.py: {program}: {len(hits)} benchmarks named {name}")
        return hits[0]

    def __call__(self, program, name, field):
        if program not in self.runs:
            raise SystemExit(f"figures.py: no run of {program} given")
        full = self._find(program, name)
        value = self.runs[program]["benchmarks"][full][field]
        run_ = self.used.setdefault(program, {k: v for k, v in self.runs[program].items()
                                              if k != "benchmarks"})
        run_.setdefault("benchmarks", {}).setdefault(full, {})[field] = value
        return value

    def context(self, program, key):
        self.used.setdefault(program, {k: v for k, v in self.runs[program].items()
                                       if k != "benchmarks"}).setdefault("benchmarks", {})
        return self.runs[program][key]

    def data_line(self):
        return ("<!-- figures.py speed: written from these values of the benchmark runs "
                "(Google Benchmark JSON, times in s): "
                + json.dumps(self.used, sort_keys=True, ensure_ascii=False,
                             separators=(",", ":")) + " -->")


def ns(x):
    return f"{x * 1e9:,.0f} ns"


def us(x):
    return f"{x:.1f} µs" if x < 100 else f"{x:,.0f} µs"


def seconds(x):
    return f"{x * 1e3:.1f} ms" if x < 0.1 else f"{x:.2f} s"


def ratio(x):
    return f"{x:.2f}×"


# How cost grows with the log's length: ident_bench's BM_Scale* benchmarks, argument `samples`,
# each size with its own model-evaluation reference and the peak memory of each step.
SCALE_REFERENCE = "BM_ScaleModelEvaluation"
SCALE_STEPS = [("BM_ScaleFitFullEffectList/covariance:0", "`zerog fit`, full list, no covariance"),
               ("BM_ScaleFitFullEffectList/covariance:1", "with covariance"),
               ("BM_ScaleFitDefaultModel", "`zerog fit`, default model"),
               ("BM_ScaleDiagnose", "`zerog diagnose`"),
               ("BM_ScaleLadder", "`zerog ladder`")]


def scale_sizes(b):
    """The log lengths of ident_bench's BM_Scale* benchmarks in the run (none in a run made
    before them)."""
    if "ident_bench" not in b.runs:
        return []
    pattern = re.compile(re.escape(SCALE_REFERENCE) + r"/samples:([0-9]+)")
    names = b.runs["ident_bench"]["benchmarks"]
    return sorted(int(m.group(1)) for m in map(pattern.fullmatch, names) if m)


def speed_scale(b, sizes):
    """The table of time (× the reference of the same size) and peak memory per log length."""
    def at(name, n, field):
        return b("ident_bench", f"{name}/samples:{n}", field)

    ladder_steps = at("BM_ScaleLadder", sizes[-1], "steps")
    heads = [label for _, label in SCALE_STEPS]
    heads[-1] += f", {ladder_steps:.0f} steps"
    lines = [
        "How the cost grows with the log (`BM_Scale*`, the same simulated path, longer for a "
        "longer log): each time with its ratio to the model evaluation over the same samples; "
        "peak RSS is the largest resident size the three fits, and any of the steps, reached "
        "with its log in memory (a long log's columns spilled to disk, host/ident's spill.hpp; in "
        "brackets: the most a step added above the resident size at its start).",
        "",
        "| samples | model evaluation (reference) | " + " | ".join(heads) +
        " | peak RSS: fits / any step |",
        "|---" * (len(heads) + 3) + "|",
    ]
    for n in sizes:
        ref = at(SCALE_REFERENCE, n, "real_time_s")
        cells = []
        for name, _ in SCALE_STEPS:
            t = at(name, n, "real_time_s")
            cells.append(f"{seconds(t)} ({t / ref:.0f}×)")
        names = [SCALE_REFERENCE] + [name for name, _ in SCALE_STEPS]
        fits = [name for name, _ in SCALE_STEPS[:3]]
        peak_fit = max(at(name, n, "peak_rss_MB") for name in fits)
        peak = max(at(name, n, "peak_rss_MB") for name in names)
        growth = max(at(name, n, "peak_growth_MB") for name in names)
        lines.append(f"| {n:,} | {seconds(ref)} | " + " | ".join(cells) +
                     f" | {peak_fit:,.0f} MB / {peak:,.0f} MB (+{growth:,.0f} MB) |")
    if len(sizes) >= 2:
        small, large = sizes[-2], sizes[-1]

        def growth_of(name):
            return at(name, large, "real_time_s") / at(name, small, "real_time_s")

        work = large / small
        full = growth_of(SCALE_STEPS[0][0])
        fits_peak = max(at(name, large, "peak_rss_MB") for name, _ in SCALE_STEPS[:3])
        lines += ["", (
            f"From {small:,} to {large:,} samples ({work:.0f}× the work) the reference "
            f"took {growth_of(SCALE_REFERENCE):.1f}× as long, the full fit "
            f"{full:.1f}× (with covariance "
            f"{growth_of(SCALE_STEPS[1][0]):.1f}×), the default fit "
            f"{growth_of(SCALE_STEPS[2][0]):.1f}×, diagnose {growth_of(SCALE_STEPS[3][0]):.1f}× "
            f"and the ladder {growth_of(SCALE_STEPS[4][0]):.1f}×. Against issue 16's aims for "
            f"{large:,} samples: the full fit's time is "
            f"{'linear' if abs(full / work - 1) <= 0.1 else 'not linear'} within 10 % "
            f"({full / work:.2f} of {work:.0f}×), and the fits' peak RSS, {fits_peak:,.0f} MB, is "
            f"{'under' if fits_peak < 200 else 'not under'} 200 MB.")]
    return lines


def speed_ident(b):
    ref = b("ident_bench", "BM_ModelEvaluationAllSamples", "real_time_s")
    samples = b("ident_bench", "BM_ModelEvaluationAllSamples", "samples")
    fit0 = b("ident_bench", "BM_FitFullEffectList/covariance:0", "real_time_s")
    fit1 = b("ident_bench", "BM_FitFullEffectList/covariance:1", "real_time_s")
    full_params = b("ident_bench", "BM_FitFullEffectList/covariance:0", "parameters")
    default = b("ident_bench", "BM_FitDefaultModel", "real_time_s")
    default_params = b("ident_bench", "BM_FitDefaultModel", "parameters")
    diag = b("ident_bench", "BM_DiagnoseAllCandidates", "real_time_s")
    candidates = b("ident_bench", "BM_DiagnoseAllCandidates", "candidates")
    # Issue 16's aims, as ratios to the reference of the same run.
    aim_fit, aim_cov, aim_diag = 25, 30, 50
    reps = b("ident_bench", "BM_FitFullEffectList/covariance:0", "repetitions")

    def against(what, x, aim):
        return f"{what} {x:.1f}× ({'meets' if x <= aim else 'misses'} ≤ {aim}×)"

    return "\n".join([
        f"`ident_bench` ({b.context('ident_bench', 'build')} build, "
        f"{b.context('ident_bench', 'num_cpus')} CPUs, {b.context('ident_bench', 'date')[:10]}): "
        f"{samples:,.0f} simulated samples with every truth effect on. The reference in the same "
        f"run is one `double` evaluation of the full model over all samples; "
        + (f"each time is the median of {reps:.0f} repetitions." if reps > 1 else
           "each time is of a single run."),
        "",
        "| benchmark | time | aim (issue 16) | × reference |",
        "|---|---|---|---|",
        f"| model evaluation, {samples:,.0f} samples (reference) | {seconds(ref)} | | 1 |",
        f"| `zerog fit`, full effect list ({full_params:.0f} parameters), without / with "
        f"covariance | {seconds(fit0)} / {seconds(fit1)} | ≤ {aim_fit}× / ≤ {aim_cov}× | "
        f"{fit0 / ref:.1f} / {fit1 / ref:.1f} |",
        f"| `zerog fit`, default model ({default_params:.0f} parameters) | {seconds(default)} | | "
        f"{default / ref:.1f} |",
        f"| `zerog diagnose`, default model, all {candidates:.0f} candidates | {seconds(diag)} | "
        f"≤ {aim_diag}× | {diag / ref:.1f} |",
        "",
        "Against the aims: " + "; ".join([
            against("full fit", fit0 / ref, aim_fit),
            against("with covariance", fit1 / ref, aim_cov),
            against("diagnose", diag / ref, aim_diag)]) + ".",
    ] + (["", *speed_scale(b, sizes)] if (sizes := scale_sizes(b)) else []))


def discovery_speed(b):
    ref = b("ident_bench", "BM_ModelEvaluationAllSamples", "real_time_s")
    disc = "BM_DiagnoseWithDiscovery"
    disc_s = b("ident_bench", disc, "discovery_s")
    return (
        f"Measured by `ident_bench` (`{disc}`, the same run): on "
        f"{b('ident_bench', disc, 'samples'):,.0f} samples, discovery over the full dictionary "
        f"({b('ident_bench', disc, 'columns'):,.0f} columns) took "
        f"{b('ident_bench', disc, 'discovery_search_s'):.2f} s for the search and {disc_s:.2f} s "
        f"with the final refit (aim: under 5 s), {disc_s / ref:.0f}× the model-evaluation "
        f"reference of the same run ({ref * 1e3:.1f} ms); the whole diagnose (library candidates "
        f"first) took {b('ident_bench', disc, 'real_time_s'):.1f} s.")


INFER_NAMES = {"bp_21_8_sigmoid": "21-8-6 sigmoid (paper-bp size)",
               "residual_24_32_32_tanh": "24-32-32-6 tanh (residual size)",
               "zp_9_45_90_leaky_relu": "9-45-90-6 leaky ReLU (paper-zp size)",
               "max_50_128x3_leaky_relu": "50-128-128-128-6 leaky ReLU (the widest allowed)"}


def speed_infer(b):
    rows = [f"| physics only | {ns(b('infer_bench', 'BM_PhysicsOnly/0', 'real_time_s'))} | | |"]
    for i in range(4):
        label = b("infer_bench", f"BM_Ratio/{i}", "label")
        rows.append(f"| {INFER_NAMES.get(label, label)} | "
                    f"{ns(b('infer_bench', f'BM_Quantised/{i}', 'real_time_s'))} | "
                    f"{ns(b('infer_bench', f'BM_FloatReference/{i}', 'real_time_s'))} | "
                    f"{b('infer_bench', f'BM_Ratio/{i}', 'quantised/float'):.2f} |")
    return "\n".join([
        f"`infer_bench` ({b.context('infer_bench', 'date')[:10]}), per sample; the last column "
        f"times both on the same samples (`BM_Ratio`):",
        "",
        "| network | physics + quantised (int16) | physics + float reference | quantised / float |",
        "|---|---|---|---|",
        *rows,
    ])


def speed_rsi(b):
    rsi = "BM_RsiEndpointRoundTrip"
    echo_p50 = b("rtio_bench", "BM_BareUdpEcho", "p50_us")
    return (
        f"**RSI round trip** (`rtio_bench`, {b('rtio_bench', rsi, 'iterations'):,.0f} loopback "
        f"datagrams): `RsiEndpoint` (parse, reply with the IPOC) against a bare UDP echo in the "
        f"same run: {ratio(b('rtio_bench', rsi, 'ratio_p50'))} at the median, "
        f"{ratio(b('rtio_bench', rsi, 'ratio_p999'))} at the 99.9th percentile (the tail is the "
        f"machine's, not the parser's); the echo's median was {us(echo_p50)} in this run.")


def speed_loop(b):
    rt0 = "BM_ZerogRtRoundTrip/0"
    echo_p50 = b("rtio_bench", "BM_BareUdpEcho", "p50_us")
    physics = b("loop_bench", "BM_CycleStep/0", "real_time_s")
    residual = b("loop_bench", "BM_CycleStep/1", "real_time_s")
    share = 100 * max(physics, residual) / 0.012
    return (
        f"**zerog-rt's cycle.** `loop_bench` ({b.context('loop_bench', 'build')} build): one "
        f"`Cycle::step` in zero-g after 6 F/T and 24 IMU samples were handed in takes "
        f"{ns(physics)} with the physics model (the model evaluation alone: "
        f"{ns(b('loop_bench', 'BM_ModelOnly/0', 'real_time_s'))}; the rest is the virtual body's "
        f"RK4 attitude, the limits, the corrections and the 0.7 KB black-box record) and "
        f"{ns(residual)} with a 24-32-32 tanh residual (model alone "
        f"{ns(b('loop_bench', 'BM_ModelOnly/1', 'real_time_s'))}): {share:.2g} % of a 12 ms cycle "
        f"at most. `rtio_bench`'s `BM_ZerogRtRoundTrip` times zerog-rt's whole cycle thread on "
        f"loopback (datagram in, samples taken from the rings, `Cycle::step` in zero-g, reply out) "
        f"against the bare UDP echo of the same run: "
        f"**{ratio(b('rtio_bench', rt0, 'ratio_p50'))} at the median and "
        f"{ratio(b('rtio_bench', rt0, 'ratio_p999'))} at the 99.9th percentile** (aim: within 2×; "
        f"{us(b('rtio_bench', rt0, 'p50_us'))} median, the echo {us(echo_p50)}).")


def speed_fused(b):
    fused = [b("loop_bench", f"BM_CycleStepFused/{k}", "real_time_s") for k in (0, 1)]
    today = [b("loop_bench", f"BM_CycleStepSi/{k}", "real_time_s") for k in (0, 1)]
    aim = 10e-6
    verdict = "within it" if max(fused) < aim else "**not within it**"
    return (
        f"**The cycle with the motion estimator** (`[filter] motion = \"fused\"` on the elastic "
        f"KR 210 with the servo model and the contact's tare, [`proto/loop.md`](../proto/loop.md)): "
        f"`loop_bench`'s `BM_CycleStepFused` against `BM_CycleStepSi`, the same cycle with the IMU "
        f"path, in the "
        f"same run ({b.context('loop_bench', 'build')} build, {b.context('loop_bench', 'date')[:10]}): "
        f"{ns(fused[0])} against {ns(today[0])} with the physics model "
        f"(**{ratio(fused[0] / today[0])}**), {ns(fused[1])} against {ns(today[1])} with the "
        f"24-32-32 residual ({ratio(fused[1] / today[1])}). Aim (issue 28): under 10 µs; "
        f"{verdict}.")


def speed_peers(b):
    modes = [f"BM_ZerogRtRoundTrip/{m}" for m in range(5)]
    reply = [b("rtio_bench", m, "reply_p50_us") for m in modes]
    to_plain = [b("rtio_bench", m, "plain_reply_p50") for m in modes[1:]]
    p99 = [b("rtio_bench", m, "plain_reply_p99") for m in modes[1:]]
    compute = [b("rtio_bench", m, "plain_compute_p99") for m in modes[1:]]
    no_server = b("modbus_bench", "BM_CycleNoServer", "real_time_s")
    flood = b("modbus_bench", "BM_CycleModbusFlood", "real_time_s")
    rate = b("modbus_bench", "BM_CycleModbusFlood", "modbus_req_per_s")
    offer = b("telemetry_bench", "BM_OfferNoDds", "real_time_s")
    offer_dds = b("telemetry_bench", "BM_OfferWithPublisher", "real_time_s")
    push = b("telemetry_bench", "BM_ReferenceRingPush", "real_time_s")
    return (
        f"Reply median {span(reply, lambda v: f'{v:.1f}')} µs in all five (ratios "
        f"{span(to_plain, lambda v: f'{v:.2f}')} to the plain cycle), reply p99 "
        f"{span(p99, lambda v: f'{v:.2f}')}×, compute p99 {span(compute, lambda v: f'{v:.2f}')}× "
        f"({us(b('rtio_bench', modes[0], 'compute_p99_us'))} plain; single-µs noise on this "
        f"shared machine). `offer()` itself costs {ns(offer)} without DDS and {ns(offer_dds)} "
        f"with the publisher on the other core, against {ns(push)} for a plain ring push "
        f"(`telemetry_bench`); a Modbus client flooding {rate:,.0f} "
        f"requests/s changed one cycle's time from {ns(no_server)} to {ns(flood)} "
        f"(`modbus_bench`).")


# The speed blocks and their texts; each block carries the values its own text uses.
SPEED_BLOCKS = {"speed-ident": speed_ident, "discovery-speed": discovery_speed,
                "speed-infer": speed_infer, "speed-rsi": speed_rsi, "speed-loop": speed_loop,
                "speed-fused": speed_fused, "speed-peers": speed_peers}
# The benchmark programs each block reads.
SPEED_NEEDS = {"speed-ident": ["ident_bench"], "discovery-speed": ["ident_bench"],
               "speed-infer": ["infer_bench"], "speed-rsi": ["rtio_bench"],
               "speed-loop": ["loop_bench", "rtio_bench"], "speed-fused": ["loop_bench"],
               "speed-peers": ["rtio_bench", "modbus_bench", "telemetry_bench"]}
DATA = re.compile(r"<!-- figures\.py speed: [^{]*(\{.*\}) -->")


def speed_blocks(runs, names=SPEED_BLOCKS):
    """{block: text}, each block's first line the values it was written from."""
    blocks = {}
    for name in names:
        b = Bench(runs)
        text = SPEED_BLOCKS[name](b)
        blocks[name] = b.data_line() + "\n" + text
    return blocks


def bench_build(bench_dir):
    """'RelWithDebInfo' or the like, from the CMake cache of the build holding `bench_dir`."""
    d = os.path.abspath(bench_dir)
    while d != "/":
        cache = os.path.join(d, "CMakeCache.txt")
        if os.path.exists(cache):
            with open(cache) as f:
                for line in f:
                    if line.startswith("CMAKE_BUILD_TYPE:"):
                        return line.split("=", 1)[1].strip() or "default"
        d = os.path.dirname(d)
    return "unknown"


# loop_bench's cycles are short enough to be timed three times: its figures are the medians.
BENCH_ARGS = {"loop_bench": ["--benchmark_repetitions=3"]}


def run_benchmarks(bench_dir, save, programs):
    os.makedirs(save, exist_ok=True)
    docs = []
    for program in programs:
        path = os.path.join(save, program + ".json")
        print(f"figures.py: running {program} (its JSON in {path})", file=sys.stderr)
        subprocess.run([os.path.join(bench_dir, program), "--benchmark_format=json",
                        f"--benchmark_out={path}", "--benchmark_out_format=json",
                        *BENCH_ARGS.get(program, [])], check=True,
                       stdout=subprocess.DEVNULL)
        doc = load(path)
        doc["zerog_build"] = bench_build(bench_dir)
        with open(path, "w") as f:
            json.dump(doc, f, indent=1)
        docs.append(doc)
    return docs


def check_speed(args):
    """Each block rewritten from the values it carries must be the documentation's text, and each
    benchmark it names must exist in the built programs (the same benchmark set)."""
    docs = read_docs(args.readme)
    status = 0
    listed = {}
    for program in BENCH_PROGRAMS:
        out = run(os.path.join(args.bench_dir, program), "--benchmark_list_tests=true")
        listed[program] = set(out.split())
    for name in SPEED_BLOCKS:
        _, have = read_doc_block(docs, name, args.readme)
        m = DATA.match(have.splitlines()[0])
        if not m:
            print(f"figures.py: {name}: the block's first line does not carry its values")
            status = 1
            continue
        data = json.loads(m.group(1))
        for program, run_ in data.items():
            missing = sorted(set(run_["benchmarks"]) - listed[program])
            if missing:
                print(f"figures.py: {name}: {program} has no benchmark {', '.join(missing)} "
                      f"(written from another benchmark set: run figures.py speed --run again)")
                status = 1
        try:
            want = speed_blocks(data, [name])
        except (KeyError, SystemExit) as e:
            print(f"figures.py: {name}: cannot be rewritten from the values it carries ({e})")
            status = 1
            continue
        status |= check_readme(args.readme, want, "rewritten from the values it carries; "
                               "their benchmarks exist in the built programs")
    return status


def cmd_speed(args):
    if args.check:
        if not args.bench_dir:
            raise SystemExit("figures.py speed --check needs --bench-dir")
        return check_speed(args)
    if args.run:
        docs = run_benchmarks(args.run, args.save, args.program or BENCH_PROGRAMS)
    else:
        docs = [load(p) for p in args.json]
        for doc, path in zip(docs, args.json):
            doc.setdefault("zerog_build", bench_build(os.path.dirname(path)))
    runs = Bench.from_json(docs).runs
    # Some programs only: write the blocks that need no other program, and say which not.
    names = [n for n in SPEED_BLOCKS if set(SPEED_NEEDS[n]) <= set(runs)]
    for n in SPEED_BLOCKS:
        if n not in names:
            print(f"figures.py: {n} not written (needs a run of {', '.join(SPEED_NEEDS[n])})",
                  file=sys.stderr)
    return finish(args, speed_blocks(runs, names), "")


# --- tool change: ident_test's ToolChange case --------------------------------------------------

TOOL_CHANGE_TEST = "ToolChange.RecoversMassAndCentreOfMassWithTheSensorModelFrozen"


def tool_change_blocks(gtest_json):
    doc = load(gtest_json)
    case = next(t for s in doc["testsuites"] for t in s["testsuite"]
                if f"{s['name']}.{t['name']}" == TOOL_CHANGE_TEST)
    if case.get("failures"):
        raise SystemExit(f"figures.py: {TOOL_CHANGE_TEST} failed")
    p = {k: float(v) for k, v in case.items() if k.startswith("fig_")}
    seeds = sorted({int(k.split("_")[1][4:]) for k in p if k.startswith("fig_seed")})

    def worst(what):
        return max(abs(p[f"fig_seed{s}_{what}"]) for s in seeds)

    def spread(what):
        return [abs(p[f"fig_seed{s}_{what}"]) for s in seeds]

    shift = [p[f"fig_com_shift_{a}_mm"] for a in "xyz"]
    text = (
        f"A simulated {p['fig_tool_mass_kg']:g} kg tool, centre of mass moved by "
        f"({', '.join(f'{v:g}' for v in shift)}) mm, seeds {seeds[0]}–{seeds[-1]}: mass within "
        f"{worst('mass_error_pct'):.2g} %, centre of mass within {worst('com_error_mm'):.2g} mm "
        f"(largest component; acceptance 1 % and 2 mm; the paper: 8.5 %). The error grows with how "
        f"wrong the frozen zero point is: a zero drift of {p['fig_drift_force_N']:g} N / "
        f"{p['fig_drift_torque_Nm']:g} N·m per axis since the calibration (signs for the largest "
        f"mass error) gives {span(spread('drift_mass_error_pct'), lambda v: f'{v:.2f}')} % and "
        f"{span(spread('drift_com_error_mm'), lambda v: f'{v:.2f}')} mm.")
    return {"tool-change": text}


def cmd_tool_change(args):
    with tempfile.TemporaryDirectory() as tmp:
        path = args.json or os.path.join(tmp, "tool_change.json")
        if args.gtest:
            subprocess.run([args.gtest, f"--gtest_filter={TOOL_CHANGE_TEST}",
                            f"--gtest_output=json:{path}"], check=True, stdout=subprocess.DEVNULL)
        return finish(args, tool_change_blocks(path), "exact")


# --- soak: zerog-soak --report -----------------------------------------------------------------

def soak_blocks(report):
    """The soak's figures. zerog-soak's pushes, faults and disturbances come from its seed, but
    when they land depends on how its threads and the recorder keep up on the wall clock, so two
    runs of the same seed count differently: only the configuration (seed, length, cycle, robot
    periods, bounds) is compared exactly, every count and time is marked as varying; that every
    injected fault was raised as itself is the soak's own check (it must have passed)."""
    s = load(report)
    if not s["passed"]:
        raise SystemExit(f"figures.py: {report}: the soak failed: {s['failures']}")
    v = vary
    mem = s["memory"]
    injected = s["faults_injected"]
    raised = sum(s["faults_raised"].values())
    stale = s["messages"] - s["run_csv_rows"]
    length = "hour" if s["simulated_s"] == 3600 else f"{s['simulated_s']:g} s"
    text = (
        f"`zerog-soak` (ctest `soak_hour`, seed {s['seed']}) runs a simulated {length} at "
        f"{1e3 * s['cycle_s']:g} ms through zerog-rt's own threads and the real RSI endpoint: "
        f"{s['robot_periods']:,} robot periods in {v(s['wall_s'], '.1f')} s "
        f"({v(s['speed_up'], '.0f')}× real time), {v(s['messages'], ',')} messages, "
        f"{v(s['sessions'])} zero-g sessions, {v(s['pushes'])} pushes, "
        f"{v(sum(injected.values()))} injected faults of {v(len(injected))} kinds and "
        f"{v(sum(s['disturbances'].values()))} disturbances that must not fault; {v(raised)} "
        f"faults raised, each the injected one, with {v(s['black_boxes'])} black boxes. "
        f"cycles.csv has {v(s['cycles_csv_rows'], ',')} rows in order, "
        f"{v(s['records_dropped'])} dropped, run.csv {v(s['run_csv_rows'], ',')} (the {v(stale)} "
        f"stale IPOCs have no row). Heap grew {v(mem['heap_growth_mib'], '.2f')} MiB and RSS "
        f"{v(mem['rss_growth_mib'], '.2f')} MiB after the warm-up minute (bounds "
        f"{mem['heap_bound_mib']:g} and {mem['rss_bound_mib']:g} MiB); `Cycle::step` took "
        f"{v(s['compute_ns']['median'] / 1e3, '.2f')} µs median, "
        f"{v(s['compute_ns']['p99'] / 1e3, '.1f')} µs p99. Two runs of the same seed differ in "
        f"these counts: when a push or fault lands depends on the threads' timing.")
    return {"soak": text}


def cmd_soak(args):
    return finish(args, soak_blocks(args.report),
                  "the configuration exactly; counts, times and memory growth: any number")


# --- results: zerog results' table --------------------------------------------------------------

def results_blocks(table_md, results_json):
    """zerog results' Markdown (its training times, the last column of the methods' table,
    marked as varying) and, from its JSON, paper-zp's least-squares tool load."""
    with open(table_md, encoding="utf-8") as f:
        lines = f.read().strip("\n").splitlines()
    out = []
    training = False  # in the table whose last column is "training"
    for line in lines:
        cells = line.split("|")
        if not line.startswith("|"):
            training = False
        elif cells[-2].strip() == "training":
            training = True
        elif training:
            cells[-2] = vary_numbers(cells[-2])
        out.append("|".join(cells))
    r = load(results_json)
    tool = r["details"]["tool_load"]
    cog = tool["cog_sensor_m"]
    where = ", ".join(f"{c:.3g}" for c in cog)
    load_text = (
        f"paper-zp's least-squares tool load (001_… eq. 13–14) on this run: "
        f"{tool['mass_kg']:.2g} kg with its centre of gravity at ({where}) m in the sensor frame, "
        f"{math.sqrt(sum(c * c for c in cog)):.2g} m away: the zero-point network took up the "
        f"payload's gravity.")
    return {"results": "\n".join(out), "results-tool-load": load_text}


def cmd_results(args):
    results_json = args.json or os.path.splitext(args.table)[0] + ".json"
    return finish(args, results_blocks(args.table, results_json),
                  "exact; training times: any number")


# --- command line -------------------------------------------------------------------------------

# --- first-run: scripts/fresh_machine.sh's measurement ----------------------------------------

def first_run_blocks(report):
    """The README's first-run block from scripts/fresh_machine.sh's JSON: how long the two
    commands took from a fresh clone (times vary from run to run: any number with --check)."""
    r = load(report)
    d, c = r["demo"], r["ci"]
    minutes = lambda s: vary(s / 60, ".1f")  # noqa: E731
    stages = ", ".join(f"{name} {vary(sec, 'd')} s" for name, sec in c["stages"])
    text = (
        f"Measured by `scripts/fresh_machine.sh` on {r['date']} ({r['cores']} cores, "
        f"{r['machine']}): from a fresh clone of commit `{r['commit']}`, no build tree and no "
        f"compiler cache ({r['packages']}). **`scripts/demo.sh`: {minutes(d['total_s'])} min** "
        f"(exit {d['status']}): install {vary(d['install_s'], 'd')} s, build of its three "
        f"programs {vary(d['build_s'], 'd')} s, steps 1–9 {vary(d['steps_1_to_9_s'], 'd')} s, "
        f"the live step {vary(d['live_s'], 'd')} s. **`.ci/run` (`scripts/test.sh`): "
        f"{minutes(c['total_s'])} min** (exit {c['status']}; CI allows 90): {stages}.")
    return {"first-run": text}


def cmd_first_run(args):
    return finish(args, first_run_blocks(args.report), "the text exactly; times: any number")


def main():
    # --readme and --check before or after the subcommand.
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--readme", default=argparse.SUPPRESS,
                        help="README.md whose documentation set (it and the docs/*.md beside it) "
                             "is written or checked")
    common.add_argument("--check", action="store_true", default=argparse.SUPPRESS,
                        help="compare with the documentation instead of writing it; exit 1 on a "
                             "difference")
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0], parents=[common])
    sub = ap.add_subparsers(dest="what", required=True)
    p = sub.add_parser("demo", parents=[common],
                       help="scripts/demo.sh's figures")
    p.add_argument("out", help="the demo's output folder (out/demo)")
    p.set_defaults(func=cmd_demo)
    p = sub.add_parser("discovery", parents=[common],
                       help="the discovery table (runs zerog)")
    p.add_argument("zerog", help="the zerog program")
    p.set_defaults(func=cmd_discovery)
    p = sub.add_parser("speed", parents=[common],
                       help="the speed figures (Google Benchmark)")
    p.add_argument("json", nargs="*", help="--benchmark_format=json output of the programs")
    p.add_argument("--run", metavar="BENCH_DIR", help="run the programs in BENCH_DIR first")
    p.add_argument("--save", default="out/bench", help="with --run: where their JSON goes")
    p.add_argument("--program", action="append", choices=BENCH_PROGRAMS,
                   help="with --run: only this program (repeatable); only the blocks it "
                        "alone writes are written")
    p.add_argument("--bench-dir", help="with --check: the built programs")
    p.set_defaults(func=cmd_speed)
    p = sub.add_parser("tool-change", parents=[common],
                       help="the tool-change figures (ident_test)")
    p.add_argument("--gtest", help="the ident_test program: run its ToolChange case")
    p.add_argument("--json", help="or its --gtest_output=json file")
    p.set_defaults(func=cmd_tool_change)
    p = sub.add_parser("soak", parents=[common],
                       help="the soak's figures (zerog-soak --report)")
    p.add_argument("report")
    p.set_defaults(func=cmd_soak)
    p = sub.add_parser("results", parents=[common],
                       help="the results table (zerog results' Markdown)")
    p.add_argument("table", help="zerog results' Markdown (out/results/results.md)")
    p.add_argument("--json", help="its --json-out (default: beside it, .json)")
    p.set_defaults(func=cmd_results)
    p = sub.add_parser("first-run", parents=[common],
                       help="the two commands' times from a fresh clone (fresh_machine.sh)")
    p.add_argument("report", help="scripts/fresh_machine.sh's fresh_machine.json")
    p.set_defaults(func=cmd_first_run)
    args = ap.parse_args()
    args.readme = getattr(args, "readme", README)
    args.check = getattr(args, "check", False)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
