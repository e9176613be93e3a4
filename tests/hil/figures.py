#!/usr/bin/env python3
"""Tables of the hardware-in-the-loop figures from the check.json files of HIL runs
(tests/hil/check_hil.py writes one per case), for the README.

    tests/hil/figures.py RESULTS_DIR...                 # print the Markdown
    tests/hil/figures.py --readme README.md RESULTS_DIR...   # replace the hil and faults blocks

The hil:begin/end block gets the motion cases, the faults:begin/end block ("Fault injection")
one row per fault of issue 6; a block is left as it is when the runs have no case for it.

RESULTS_DIR: a folder with one sub-folder per case (e.g. build/ci/tests/hil/results/hil_motion).
"""
import argparse
import glob
import json
import os
import sys

# The README's "Fault injection" table: one row per fault of issue 6, in this order. Per case:
# the fault, how the emulator or tests/hil/fault_peer.py injects it, and the reaction that
# proto/loop.md ("Watchdogs", "Faults that are not faults of the loop") documents; {thr} is the
# case's watchdog threshold (from its check.json). The measured column comes from check.json.
FAULTS = [
    ("fault_ft_silent", "F/T sensor silent", "the board answers nothing for 1 s",
     "hold, then `ft_stale` at {thr} cycles without a valid sample; zero correction"),
    ("fault_ft_slow", "F/T sensor slow", "each answer 2 ms late for 1 s (sample_timeout_ms 3 ms)",
     "samples used as they come; a hold shorter than the threshold at most; no fault"),
    ("fault_ft_saturated", "F/T sensor saturated", "gauge SG0 at its rail for 1 s",
     "hold, then `ft_saturated` at {thr} cycles without a valid sample; zero correction"),
    ("fault_ft_critical", "F/T critical status", "status word with a critical bit for 1 s",
     "hold, then `ft_critical` at {thr} cycles without a valid sample; zero correction"),
    ("fault_imu_garbage", "IMU garbage", "the STIM300 writes random bytes for 1 s",
     "hold, then `imu_stale` at {thr} cycles without a valid sample; zero correction"),
    ("fault_imu_crc", "IMU CRC errors", "every datagram with a wrong CRC for 1 s",
     "counted, none used: hold, then `imu_stale` at {thr} cycles; zero correction"),
    ("fault_imu_gaps", "IMU counter gaps", "every other datagram left out for 1 s",
     "gaps counted, the datagrams that come averaged; no fault"),
    ("fault_imu_unplug", "IMU tty unplugged", "the pty hangs up; 1 s later a new one",
     "hold, then `imu_stale` at {thr} cycles; re-open every 0.1 s (counted); fault kept until "
     "reset"),
    ("fault_robot_late", "robot datagrams late", "6 datagrams 30 ms late (the robot's Delay grows)",
     "`robot_late` at {thr} messages in a row whose Delay grew; zero correction"),
    ("fault_robot_drop", "robot datagrams lost", "nothing sent for 6 cycles",
     "`robot_late` at {thr} lost cycles in a row (nothing to answer before); zero correction"),
    ("fault_robot_malformed", "robot datagrams malformed", "6 malformed datagrams instead",
     "as lost: `robot_late` at {thr} in a row; zero correction"),
    ("fault_robot_duplicate", "robot datagrams duplicated", "each datagram twice, 50 cycles",
     "the copy answered at once with a zero correction and its IPOC (`kIpocStale`, counted); "
     "nothing else changes; no fault"),
    ("fault_robot_reorder", "robot datagrams reordered", "3 pairs, the newer one first",
     "the newer: IPOC gap, 1 datagram counted lost; the older: stale, answered with zero; "
     "no fault"),
    ("fault_robot_reorder_burst", "robot datagrams reordered, back to back", "4 pairs in a row",
     "each older one answered late, so the robot's Delay grows: `robot_late` at {thr} messages "
     "in a row whose Delay grew; zero correction"),
    ("fault_robot_foreign", "robot datagrams from a foreign address",
     "50 copies from another source port (IPOC + 5·10⁸)",
     "dropped and counted (RSI accepts only the configured robot); no fault"),
    ("fault_dds_peer_gone", "DDS peer gone", "the telemetry subscriber killed (SIGKILL)",
     "no effect on the cycle; publishing goes on (drops counted); no fault"),
    ("fault_modbus_flood", "Modbus client flooding",
     "3 s of pipelined reads on 3 connections, more connections than max_clients",
     "no effect on the cycle; connections beyond max_clients closed at once (counted)"),
    ("fault_modbus_stall", "Modbus client stalling",
     "half requests, a silent connection, a client that never reads",
     "no effect on the cycle nor on other clients; closed after request_timeout_s / "
     "idle_timeout_s (counted)"),
    ("fault_model_swap", "model file swapped on disk", "overwritten in place, then replaced",
     "the loaded model kept (model_crc32 unchanged); no fault"),
]


def load(dirs):
    cases = {}
    for d in dirs:
        for f in sorted(glob.glob(os.path.join(d, "*", "check.json"))):
            with open(f) as fh:
                c = json.load(fh)
            cases[c["case"]] = c
    return cases


def verdict(c):
    if c.get("inconclusive"):
        return f"not verified: the emulated rig stood still {1e3 * c['rig_worst_lag_s']:.0f} ms"
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
    return "\n".join(out)


def fault_markdown(cases):
    rows = [f for f in FAULTS if f[0] in cases]
    if not rows:
        return ""
    out = ["| fault | injected how | documented reaction (proto/loop.md) | measured | black box "
           "| passed |", "|---|---|---|---|---|---|"]
    for k, fault, how, reaction in rows:
        c = cases[k]
        reaction = reaction.format(thr=c.get("fault_threshold_cycles", "?"))
        measured = c.get("measured", "(not measured: the check failed early)")
        box = c.get("black_box", "?")
        out.append(f"| {fault} | {how} | {reaction} | {measured} | {box} | {verdict(c)} |")
    missing = [f[1] for f in FAULTS if f[0] not in cases]
    if missing:
        out.append("")
        out.append("Not in these runs: " + ", ".join(missing) + ".")
    out.append("")
    return "\n".join(out)


def replace_block(readme, name, text):
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    i, j = readme.index(begin) + len(begin), readme.index(end)
    return readme[:i] + "\n" + text + "\n" + readme[j:]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--readme")
    ap.add_argument("dirs", nargs="+")
    a = ap.parse_args()
    cases = load(a.dirs)
    text, faults = markdown(cases), fault_markdown(cases)
    if not a.readme:
        print(text)
        print(faults)
        return 0
    with open(a.readme) as f:
        readme = f.read()
    # A block is replaced only when these runs have something for it.
    if text:
        readme = replace_block(readme, "hil", text)
    if faults:
        readme = replace_block(readme, "faults", faults)
    tmp = a.readme + ".tmp"
    with open(tmp, "w") as f:
        f.write(readme)
    os.replace(tmp, a.readme)
    return 0


if __name__ == "__main__":
    sys.exit(main())
