#!/usr/bin/env python3
"""Tables of the hardware-in-the-loop figures from the check.json files of HIL runs
(tests/hil/check_hil.py writes one per case), for the README.

    tests/hil/figures.py RESULTS_DIR...                 # print the Markdown
    tests/hil/figures.py --readme README.md RESULTS_DIR...   # replace the hil:begin/end block

RESULTS_DIR: a folder with one sub-folder per case (e.g. build/ci/tests/hil/results/hil_motion).
"""
import argparse
import glob
import json
import os
import sys

FAULT_REACTION = {
    "fault_robot_drop": "robot sends nothing for 6 cycles",
    "fault_robot_malformed": "6 malformed datagrams instead of good ones",
    "fault_robot_late": "6 datagrams sent 30 ms late (our replies arrive late: Delay grows)",
    "fault_ft_silent": "F/T board answers nothing for 1 s",
    "fault_ft_critical": "F/T status word with a critical bit for 1 s",
    "fault_imu_garbage": "STIM300 writes random bytes for 1 s",
}


def load(dirs):
    cases = {}
    for d in dirs:
        for f in sorted(glob.glob(os.path.join(d, "*", "check.json"))):
            with open(f) as fh:
                c = json.load(fh)
            cases[c["case"]] = c
    return cases


def verdict(c):
    if not c["passed"]:
        return "**no**"
    return "yes" if c.get("attempt", 1) == 1 else "yes, on the retry"


def pct(x):
    return f"{100 * x:.2f} %"


def markdown(cases):
    out = []
    motion = []
    if "push" in cases:
        c = cases["push"]
        J = c["push_impulse_N_s"]
        v = c["push_velocity_measured_mps"]
        e = c["push_velocity_expected_mps"]
        motion.append(("push: velocity after an impulse J on 100 kg vs J/m",
                       f"J = ({J[0]:.2f}, {J[1]:.2f}, {J[2]:.2f}) N·s; v = ({v[0]:.4f}, {v[1]:.4f}, "
                       f"{v[2]:.4f}) m/s vs J/m = ({e[0]:.4f}, {e[1]:.4f}, {e[2]:.4f}); "
                       f"error {pct(c['push_velocity_error'])}", "3 %", verdict(c)))
    if "drift" in cases:
        c = cases["drift"]
        motion.append(("drift: no push, 10 s of zero-g", f"{c['drift_mm_in_10s']:.3f} mm", "1 mm",
                       verdict(c)))
    if "spin" in cases:
        c = cases["spin"]
        motion.append(("spin: angular momentum (world) over 10 s of free rotation",
                       f"largest deviation {pct(c['spin_L_deviation'])}, turned "
                       f"{c['spin_turned_rad']:.1f} rad", "2 %", verdict(c)))
    if "tumble" in cases:
        c = cases["tumble"]
        motion.append(("tumble: ω in body axes vs Euler's equations, 10 s",
                       f"RMS error {pct(c['tumble_rms_error'])}; off-axis part ×"
                       f"{c['tumble_off_axis_growth_measured']:.2f} (predicted ×"
                       f"{c['tumble_off_axis_growth_predicted']:.2f})", "10 %", verdict(c)))
    if motion:
        out.append("| case | measured | limit | passed |")
        out.append("|---|---|---|---|")
        for name, measured, limit, ok in motion:
            out.append(f"| {name} | {measured} | {limit} | {ok} |")
        out.append("")
    faults = [k for k in FAULT_REACTION if k in cases]
    if faults:
        out.append("| injected fault | zerog-rt's reaction | cycles to the fault (threshold) | passed |")
        out.append("|---|---|---|---|")
        for k in faults:
            c = cases[k]
            cycles = c.get("fault_cycles_after_injection", "?")
            if k in ("fault_robot_drop", "fault_robot_malformed"):
                cycles = f"at lost cycle {c['fault_threshold_cycles']}, before the next datagram"
            else:
                cycles = f"{cycles} ({c.get('fault_threshold_cycles', '?')})"
            out.append(f"| {FAULT_REACTION[k]} | hold, then fault `{c.get('fault', '?')}`: zero "
                       f"correction, black box dumped | {cycles} | {verdict(c)} |")
        out.append("")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--readme")
    ap.add_argument("dirs", nargs="+")
    a = ap.parse_args()
    text = markdown(load(a.dirs))
    if not a.readme:
        print(text)
        return 0
    with open(a.readme) as f:
        readme = f.read()
    begin, end = "<!-- hil:begin -->", "<!-- hil:end -->"
    i, j = readme.index(begin) + len(begin), readme.index(end)
    readme = readme[:i] + "\n" + text + "\n" + readme[j:]
    tmp = a.readme + ".tmp"
    with open(tmp, "w") as f:
        f.write(readme)
    os.replace(tmp, a.readme)
    return 0


if __name__ == "__main__":
    sys.exit(main())
