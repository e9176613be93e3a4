#!/usr/bin/python3
"""Writes the README's discovery table (between <!-- discovery:begin --> and <!-- discovery:end -->)
from runs of the `zerog` program: for each simulated effect outside the model library, simulate the
demo's calibration run (seed 42), diagnose the default model, and tabulate the true law, the law
discovery found, and the held-out error before and after adding it.

With --bench IDENT_BENCH it also writes the discovery speed line (between
<!-- discovery-speed:begin --> and <!-- discovery-speed:end -->) from one run of the Google Benchmark
binary: BM_DiagnoseWithDiscovery on 100,000 samples against the model-evaluation reference of the
same run.

Usage: scripts/discovery_figures.py ZEROG_BINARY [--bench IDENT_BENCH] [README.md]
(about a minute, two with --bench)
"""
import json
import os
import re
import subprocess
import sys
import tempfile

EFFECTS = ["joint6_friction", "swivel_viscous", "hose_drag", "dress_pack_bend"]


def run(*args):
    return subprocess.run(args, check=True, capture_output=True, text=True).stdout


def law(terms):
    out = []
    for t in terms:
        out.append(f"{t['axis']} += {t['coefficient']:.4g} · {t['basis']}")
    return "; ".join(out)


def replace_between(text, name, lines, readme):
    new, n = re.subn(rf"<!-- {name}:begin -->.*?<!-- {name}:end -->",
                     "\n".join([f"<!-- {name}:begin -->", *lines, f"<!-- {name}:end -->"]), text,
                     flags=re.S)
    if n != 1:
        sys.exit(f"{readme}: no <!-- {name}:begin --> ... <!-- {name}:end --> markers")
    return new


def speed_lines(bench):
    out = json.loads(run(bench, "--benchmark_filter=ModelEvaluation|Discovery",
                         "--benchmark_format=json"))
    by = {b["name"].split("/")[0]: b for b in out["benchmarks"]}
    ref = by["BM_ModelEvaluationAllSamples"]
    disc = by["BM_DiagnoseWithDiscovery"]
    unit = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}
    ref_s = ref["real_time"] * unit[ref["time_unit"]]
    return [
        f"Measured by `ident_bench` (`BM_DiagnoseWithDiscovery`, written by "
        f"`scripts/discovery_figures.py --bench`): on {int(disc['samples']):,} samples, discovery "
        f"over the full dictionary ({int(disc['columns']):,} columns) took "
        f"{disc['discovery_search_s']:.2f} s for the search and {disc['discovery_s']:.2f} s with "
        f"the final refit (aim: under 5 s), {disc['discovery_s'] / ref_s:.0f}× the "
        f"model-evaluation reference of the same run ({ref_s * 1e3:.1f} ms); the whole diagnose "
        f"(library candidates first) took {disc['real_time'] * unit[disc['time_unit']]:.1f} s."
    ]


def main():
    args = sys.argv[1:]
    bench = None
    if "--bench" in args:
        i = args.index("--bench")
        bench = args[i + 1]
        del args[i:i + 2]
    zerog = args[0]
    readme = args[1] if len(args) > 1 else os.path.join(os.path.dirname(__file__), "..",
                                                          "README.md")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        design = os.path.join(tmp, "design.csv")
        run(zerog, "design", "--kind", "oa", "--out", design)
        for effect in EFFECTS:
            log = os.path.join(tmp, effect + ".csv")
            run(zerog, "sim", "--design", design, "--effects", effect, "--seed", "42", "--out", log,
                "-q")
            truth = json.load(open(os.path.join(tmp, effect + ".truth.json")))
            true_terms = truth["extra"]["outside_model"][effect]["terms"]
            d = json.loads(run(zerog, "diagnose", log, "--json", "-q", "--discovered-out",
                               os.path.join(tmp, effect + ".toml")))
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
                        f"{after['torque_rms']:.3f} N·m | {found['seconds']:.1f} s |")
            columns = found["dictionary_size"]
            z = found["z_threshold"]
    table = [
        f"Written by `scripts/discovery_figures.py` from `zerog sim` (seed 42, the demo's path) and "
        f"`zerog diagnose --json` of the default model; {columns} basis-axis columns searched, "
        f"every term |z| > {z:.1f}. Errors are held-out RMS (force pooled over Fx, Fy, Fz; torque "
        f"likewise); \"after\" is the model refitted with the discovered effect on the training "
        f"blocks.",
        "",
        "| hidden effect | true law | discovered (± std) | before | after | discovery |",
        "|---|---|---|---|---|---|",
        *rows,
    ]
    text = replace_between(open(readme).read(), "discovery", table, readme)
    if bench:
        lines = speed_lines(bench)
        text = replace_between(text, "discovery-speed", lines, readme)
        table += lines
    new = text
    tmp_path = readme + ".tmp"
    with open(tmp_path, "w") as f:
        f.write(new)
    os.replace(tmp_path, readme)
    print("\n".join(table))


if __name__ == "__main__":
    main()
