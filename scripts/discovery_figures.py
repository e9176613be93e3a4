#!/usr/bin/python3
"""Writes the README's discovery table (between <!-- discovery:begin --> and <!-- discovery:end -->)
from runs of the `zerog` program: for each simulated effect outside the model library, simulate the
demo's calibration run (seed 42), diagnose the default model, and tabulate the true law, the law
discovery found, and the held-out error before and after adding it.

Usage: scripts/discovery_figures.py ZEROG_BINARY [README.md]   (about a minute)
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


def main():
    zerog = sys.argv[1]
    readme = sys.argv[2] if len(sys.argv) > 2 else os.path.join(os.path.dirname(__file__), "..",
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
        "<!-- discovery:begin -->",
        f"Written by `scripts/discovery_figures.py` from `zerog sim` (seed 42, the demo's path) and "
        f"`zerog diagnose --json` of the default model; {columns} basis-axis columns searched, "
        f"every term |z| > {z:.1f}. Errors are held-out RMS (force pooled over Fx, Fy, Fz; torque "
        f"likewise); \"after\" is the model refitted with the discovered effect on the training "
        f"blocks.",
        "",
        "| hidden effect | true law | discovered (± std) | before | after | discovery |",
        "|---|---|---|---|---|---|",
        *rows,
        "<!-- discovery:end -->",
    ]
    text = open(readme).read()
    new, n = re.subn(r"<!-- discovery:begin -->.*?<!-- discovery:end -->", "\n".join(table), text,
                     flags=re.S)
    if n != 1:
        sys.exit(f"{readme}: no <!-- discovery:begin --> ... <!-- discovery:end --> markers")
    tmp_path = readme + ".tmp"
    with open(tmp_path, "w") as f:
        f.write(new)
    os.replace(tmp_path, readme)
    print("\n".join(table))


if __name__ == "__main__":
    main()
