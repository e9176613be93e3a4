#!/usr/bin/python3
"""The documentation's hardware-in-the-loop figures from the check.json files of HIL runs.

tests/hil/check_hil.py writes one check.json per case. The blocks are looked up in the
documentation set of the README given (that README.md and every docs/*.md beside it; a block is
written in the one file that holds it: docs/zerog-rt.md), with scripts/figures.py's block
functions.

    tests/hil/figures.py RESULTS_DIR...                          # print the blocks
    tests/hil/figures.py --readme README.md RESULTS_DIR...       # write them into the docs
    tests/hil/figures.py --check [--readme README.md] RESULTS_DIR...   # compare (ctest
                                                                 # hil_readme_figures)

Blocks: hil (the motion cases: the figures of seed 11, the lowest seed in the runs, and the
range over all seeds), faults ("Fault injection": one row per fault of issue 6), supervisor
(the PLC and telemetry run) and feel (per motion path, the contact noise against the F/T floor
and the gate zerog gate advises: the smallest push that moves the part; issue 28) and servo
(`zerog servo` on the elastic fused runs against the emulator's servo); feel-readme, the
README's line of the feel block. A block is written only when the runs have every case it needs.

--check compares exactly: a lockstep run depends on its seed only (tests/hil/determinism.sh).
The cases with a peer on the wall clock (a `# plc =` scenario: the Modbus and DDS peers, the PLC
supervisor; hil.sh runs them --lockstep-paced) are not reproducible to the number: in their rows
any number stands for a number (the text around it, the thresholds in the reaction column and
the verdict must agree).

RESULTS_DIR: a folder with one sub-folder per case (<build>/tests/hil/results/hil_motion_seed11).
"""
import argparse
import glob
import json
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "scripts"))
import figures as blocks  # noqa: E402  (scripts/figures.py: the documentation's blocks)

# The "Fault injection" table (docs/zerog-rt.md): one row per fault of issue 6, in this order.
# Per case: the fault, how the emulator or tests/hil/fault_peer.py injects it, and the reaction
# that proto/loop.md ("Watchdogs", "Faults that are not faults of the loop") documents; {thr} is
# the case's watchdog threshold (from its check.json). The measured column comes from check.json.
FAULTS = [
    ("fault_ft_silent", "F/T sensor silent", "the board answers nothing for 1 s",
     "hold, then `ft_stale` at {thr} cycles without a valid sample; zero correction"),
    ("fault_ft_slow", "F/T sensor slow", "each answer 2 ms late for 1 s (sample_timeout_ms 3 ms)",
     "samples used as they come; a hold shorter than the threshold at most; no fault"),
    ("fault_ft_saturated", "F/T sensor saturated", "gauge SG0 at its rail for 1 s",
     "hold, then `ft_saturated` at {thr} cycles without a valid sample; zero correction"),
    ("fault_ft_critical", "F/T critical status", "status word with a critical bit for 1 s",
     "hold, then `ft_critical` at {thr} cycles without a valid sample; zero correction"),
    ("fault_ft_thermistor_silent", "F/T thermistor silent",
     "the board leaves its thermistor reads (0x9) unanswered for 5 s; samples go on",
     "the reading held up to `thermistor_max_age_s`, then the configured `temperature_C` "
     "(`kTemperatureStale`, counted) until the board answers again; no fault"),
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
    """{case: {seed: check.json}}; a run without --seed has seed None (the scenario's own)."""
    cases = {}
    for d in dirs:
        for f in sorted(glob.glob(os.path.join(d, "*", "check.json"))):
            with open(f) as fh:
                c = json.load(fh)
            m = re.fullmatch(re.escape(c["case"]) + r"(?:-seed(\d+))?",
                             os.path.basename(os.path.dirname(f)))
            if not m:
                continue  # a mutant's run (CASE-MUTANT) is no figure
            cases.setdefault(c["case"], {})[int(m.group(1)) if m.group(1) else None] = c
    return cases


def wall_clock(case):
    """A case with a peer on the wall clock (hil.sh: --lockstep-paced)."""
    with open(os.path.join(HERE, "cases", case + ".toml")) as f:
        return any(line.startswith("# plc = ") for line in f)


def verdict(runs):
    failed = [s for s, c in runs.items() if not c["passed"]]
    if not failed:
        return "yes" if len(runs) == 1 else f"yes, all {len(runs)}"
    return "**no**" + (f" (seed {', '.join(str(s) for s in failed)})" if len(runs) > 1 else "")


def pct(x):
    return f"{100 * x:.2f} %"


def mode_of(runs):
    modes = {c["mode"] for c in runs.values()}
    if len(modes) != 1:
        raise SystemExit(f"figures.py: runs of modes {sorted(modes)} mixed")
    return modes.pop()


# The limits of tests/hil/check_hil.py, in lockstep / in real time.
LIMITS = {"lockstep": {"push": "1 %", "drift": "0 (none at all)", "spin": "0.5 %",
                       "tumble": "10 %"},
          "realtime": {"push": "3 %", "drift": "1 mm", "spin": "2 %", "tumble": "10 %"}}


def motion_markdown(cases):
    """The hil block: one row per motion case, the figures of the lowest seed and the range over
    all seeds."""
    if not all(k in cases for k in ("push", "drift", "spin", "tumble")):
        return None
    runs = {k: cases[k] for k in ("push", "drift", "spin", "tumble")}
    seeds = sorted(runs["push"])
    if any(sorted(r) != seeds for r in runs.values()):
        raise SystemExit("figures.py: the motion cases ran with different seeds")
    first = seeds[0]
    mode = mode_of(runs["push"])
    limits = LIMITS[mode]

    def over(k, key, scale, decimals, unit):
        return blocks.span([scale * runs[k][s][key] for s in seeds],
                           lambda x: f"{x:.{decimals}f}") + unit

    push_all = "error " + over("push", "push_velocity_error", 100, 2, " %")
    drift_all = over("drift", "drift_mm_in_10s", 1, 3, " mm")
    spin_all = "largest deviation " + over("spin", "spin_L_deviation", 100, 2, " %")
    tumble_all = "RMS error " + over("tumble", "tumble_rms_error", 100, 2, " %")

    rows = []
    c = runs["push"][first]
    J, v, e = (c["push_impulse_N_s"], c["push_velocity_measured_mps"],
               c["push_velocity_expected_mps"])
    rows.append(("push: velocity after an impulse J on 100 kg vs J/m",
                 f"J = ({J[0]:.2f}, {J[1]:.2f}, {J[2]:.2f}) N·s; v = ({v[0]:.4f}, {v[1]:.4f}, "
                 f"{v[2]:.4f}) m/s vs J/m = ({e[0]:.4f}, {e[1]:.4f}, {e[2]:.4f}); error "
                 f"{pct(c['push_velocity_error'])}",
                 push_all, limits["push"], "push"))
    rows.append(("drift: no push, 10 s of zero-g",
                 f"{runs['drift'][first]['drift_mm_in_10s']:.3f} mm", drift_all, limits["drift"],
                 "drift"))
    c = runs["spin"][first]
    rows.append(("spin: angular momentum (world) over 10 s of free rotation",
                 f"largest deviation {pct(c['spin_L_deviation'])}, turned "
                 f"{c['spin_turned_rad']:.2f} rad", spin_all, limits["spin"], "spin"))
    c = runs["tumble"][first]
    rows.append(("tumble: ω in body axes vs Euler's equations, 10 s",
                 f"RMS error {pct(c['tumble_rms_error'])}; off-axis part ×"
                 f"{c['tumble_off_axis_growth_measured']:.2f} (predicted ×"
                 f"{c['tumble_off_axis_growth_predicted']:.2f})", tumble_all, limits["tumble"],
                 "tumble"))
    seed_text = f"seed {first}" if first is not None else "the scenario's seed"
    contiguous = None not in seeds and seeds == list(range(seeds[0], seeds[-1] + 1))
    seed_list = (f"{seeds[0]}–{seeds[-1]}" if contiguous and len(seeds) > 2
                 else ", ".join(str(s) for s in seeds))
    out = [f"| case | measured ({seed_text}, {mode}) | seeds {seed_list} | limit | passed |",
           "|---|---|---|---|---|"]
    for name, measured, all_seeds, limit, k in rows:
        out.append(f"| {name} | {measured} | {all_seeds} | {limit} | {verdict(runs[k])} |")
    return "\n".join(out)


def fault_markdown(cases):
    """The faults block: one row per fault of issue 6 (every case needed)."""
    if not all(f[0] in cases for f in FAULTS):
        return None
    out = ["| fault | injected how | documented reaction (proto/loop.md) | measured | black box "
           "| passed |", "|---|---|---|---|---|---|"]
    for k, fault, how, reaction in FAULTS:
        runs = cases[k]
        c = runs[min(runs, key=lambda s: -1 if s is None else s)]
        reaction = reaction.format(thr=c.get("fault_threshold_cycles", "?"))
        measured = c.get("measured", "(not measured: the check failed early)")
        box = c.get("black_box", "?")
        if wall_clock(k):
            measured, box = blocks.vary_numbers(measured), blocks.vary_numbers(box)
        out.append(f"| {fault} | {how} | {reaction} | {measured} | {box} | {verdict(runs)} |")
    return "\n".join(out)


def supervisor_markdown(cases):
    """The supervisor block: the PLC session, the push with the PLC's mass, the telemetry."""
    if "supervisor" not in cases:
        return None
    runs = cases["supervisor"]
    c = runs[min(runs, key=lambda s: -1 if s is None else s)]
    J = c["push_impulse_N_s"]
    e = c["push_velocity_expected_mps"]
    mass = (sum(x * x for x in J) / sum(x * x for x in e)) ** 0.5
    topics = c["telemetry_samples_by_topic"]
    per_cycle = [n for t, n in topics.items() if t not in ("health", "model")]
    limit = LIMITS[mode_of(runs)]["push"]
    v = blocks.vary_numbers
    text = (f"A push of J = ({J[0]:.2f}, {J[1]:.2f}, {J[2]:.2f}) N·s then moves the part at "
            f"J / {mass:.0f} kg (error {v(pct(c['push_velocity_error']))}, limit {limit}), and the "
            f"independent subscriber received every topic, "
            f"{v(blocks.span(per_cycle, lambda n: f'{n:,}'))} samples per per-cycle topic "
            f"({len(per_cycle)} topics), each value matching zerog-rt's `cycles.csv`; passed: "
            f"{verdict(runs)}.")
    return text


def seeds_text(seeds):
    return f"{seeds[0]}–{seeds[-1]}" if len(seeds) > 2 else ", ".join(map(str, seeds))


def gate_span(cases, k, key, seeds, decimals):
    """The range over the seeds of the gate `zerog gate` advised (gate_force_N, …) in case k."""
    return blocks.span([cases[k][s][key] for s in seeds], lambda x: f"{x:.{decimals}f}")


def feel_markdown(cases):
    """The feel block (issue 28): per motion path, the contact wrench's noise against the F/T-only
    floor of the cycle at rest (drift) and while the part turns (spin), and the gate `zerog gate`
    advises from the drift's zero-g at rest: the smallest push that moves the part."""
    paths = (("the IMU as it comes (`motion = \"imu\"`, the default)", ""),
             ("the motion estimator (`motion = \"fused\"`)", "_fused"))
    need = [f"{k}{suffix}" for _, suffix in paths for k in ("drift", "spin")]
    if not all(k in cases for k in need):
        return None
    seeds = sorted(cases["drift"])
    if any(sorted(cases[k]) != seeds for k in need):
        raise SystemExit("figures.py: the feel block's cases ran with different seeds")
    mode = mode_of(cases["drift"])

    def ratio(k, key, i):
        return blocks.span([cases[k][s][key][i] for s in seeds], lambda x: f"{x:.2f}") + "×"

    def gate(k, key, unit, decimals):
        return gate_span(cases, k, key, seeds, decimals) + f" {unit}"

    out = [f"| motion path ({mode}, seeds {seeds_text(seeds)}) | contact noise at rest / F/T floor "
           "(force, torque) | turning (spin) | smallest push that moves the part (`zerog gate`: "
           "force, torque) |", "|---|---|---|---|"]
    for name, suffix in paths:
        d, sp = f"drift{suffix}", f"spin{suffix}"
        out.append(f"| {name} | {ratio(d, 'contact_over_floor_at_rest', 0)}, "
                   f"{ratio(d, 'contact_over_floor_at_rest', 1)} | "
                   f"{ratio(sp, 'contact_over_floor_moving', 0)}, "
                   f"{ratio(sp, 'contact_over_floor_moving', 1)} | "
                   f"{gate(d, 'gate_force_N', 'N', 2)}, {gate(d, 'gate_torque_Nm', 'N·m', 3)} |")
    return "\n".join(out)


SERVO_CASES = (("servo_elastic_fused", "pushes, stops and twists, no servo model set"),
               ("glide_elastic_fused", "the 0.5 m/s glide"),
               ("spin_elastic_fused", "the spin"))


def servo_markdown(cases):
    """The servo block: `zerog servo` on the elastic fused runs against the emulator's servo."""
    if not all(k in cases for k, _ in SERVO_CASES):
        return None
    out = ["| recording (elastic arm, lockstep) | seeds | emulator's servo | `zerog servo` finds "
           "| largest error | quoted σ (quarters) | controller's tick |", "|---|---|---|---|---|---|---|"]
    for case, what in SERVO_CASES:
        runs = cases[case]
        seeds = sorted(runs)
        truth = {runs[s]["servo_truth_hz"] for s in seeds}
        if len(truth) != 1 or any("servo_hz" not in runs[s] for s in seeds):
            raise SystemExit(f"figures.py: {case}: zerog servo's figures are missing or differ")
        t = truth.pop()
        found = [runs[s]["servo_hz"] for s in seeds]
        err = max(abs(f - t) / t for f in found)
        sig = [runs[s]["servo_hz_sigma"] for s in seeds if runs[s]["servo_hz_sigma"] is not None]
        lags = sorted({runs[s]["servo_lag_rows"] for s in seeds})
        out.append(f"| {what} (`{case}`) | {seeds[0]}–{seeds[-1]} | {t:g} Hz | "
                   f"{blocks.span(found, lambda x: f'{x:.3f}')} Hz | {100 * err:.2f} % | "
                   f"{blocks.span(sig, lambda x: f'{x:.4f}')} Hz | "
                   f"{', '.join(f'k + {L - 1} to k + {L}' for L in lags)} |")
    return "\n".join(out)


def feel_readme(cases):
    """The README's line of the feel block: the smallest push that moves the part, per path."""
    if not all(k in cases for k in ("drift", "drift_fused")):
        return None
    seeds = sorted(cases["drift"])

    def gate(k, key, decimals):
        return gate_span(cases, k, key, seeds, decimals)

    return (f"The smallest push that moves the floating part (the gate `zerog gate` sets from the "
            f"noise at rest; emulated rig, {mode_of(cases['drift'])}, seeds {seeds_text(seeds)}): "
            f"{gate('drift', 'gate_force_N', 2)} N or {gate('drift', 'gate_torque_Nm', 3)} N·m "
            f"with the IMU as it comes (the default), {gate('drift_fused', 'gate_force_N', 2)} N "
            f"or {gate('drift_fused', 'gate_torque_Nm', 3)} N·m with the motion estimator "
            f"(`[filter] motion = \"fused\"`, the rigid arm). Measure your cell's: ["
            f"\"Setting the contact gate\"](docs/zerog-rt.md#setting-the-contact-gate).")


# Every block this script writes (--check requires them all).
BLOCKS = ("hil", "faults", "supervisor", "feel", "servo", "feel-readme")


def markdown(cases):
    """{block: text} of the blocks these runs have every case for."""
    out = {"hil": motion_markdown(cases), "faults": fault_markdown(cases),
           "supervisor": supervisor_markdown(cases), "feel": feel_markdown(cases),
           "servo": servo_markdown(cases), "feel-readme": feel_readme(cases)}
    return {k: v for k, v in out.items() if v is not None}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--readme", help="README.md whose documentation set (it and the docs/*.md "
                    "beside it) is written (or, with --check, compared)")
    ap.add_argument("--check", action="store_true",
                    help="compare the documentation's blocks with these runs; exit 1 on a "
                         "difference")
    ap.add_argument("dirs", nargs="+")
    a = ap.parse_args()
    cases = load(a.dirs)
    texts = markdown(cases)
    if not texts:
        raise SystemExit(f"figures.py: no block has all its cases in {' '.join(a.dirs)}")
    if a.check:
        missing = [b for b in BLOCKS if b not in texts]
        if missing:
            print(f"figures.py: the runs lack cases of the block(s) {', '.join(missing)}")
            return 1
        return blocks.check_readme(a.readme or blocks.README, texts,
                                   "exact; rows of wall-clock peers: any number")
    if not a.readme:
        for name, text in texts.items():
            print(f"<!-- {name} -->\n{blocks.plain(text)}\n")
        return 0
    blocks.write_readme(a.readme, texts)
    return 0


if __name__ == "__main__":
    sys.exit(main())
