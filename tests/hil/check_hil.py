#!/usr/bin/env python3
"""Checks one hardware-in-the-loop run (tests/hil/hil.sh) against the acceptance of the zero-g
firmware: the emulator's truth (what the robot really did, truth.csv), its summary (emu.json),
zerog-rt's summary (rt.json) and cycle records (rec/cycles.csv).

Cases:
  push     the payload's velocity after a push of impulse J settles at J/m (within 3 %)
  drift    with no push the part moves less than 1 mm in 10 s
  spin     free rotation keeps the angular momentum (world frame) within 2 % over 10 s
  tumble   a spin near the intermediate principal axis follows Euler's equations
  fault_*  the documented reaction: hold, then the named fault with zero correction within the
           documented number of cycles; black box dumped; every datagram answered with its IPOC

Prints what it measured, one line per figure, and exits 1 if a check fails. Also writes
DIR/check.json with the figures (for the README's tables and the demo).
"""
import argparse
import csv
import json
import math
import sys
import tomllib

import numpy as np

FAILURES = []
FIGURES = {}


def check(ok, what):
    print(("  ok    " if ok else "  FAIL  ") + what)
    if not ok:
        FAILURES.append(what)


def figure(name, value):
    FIGURES[name] = value


def load_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(line for line in f if not line.startswith("#")))
    header, body = rows[0], rows[1:]
    out = {}
    for k, name in enumerate(header):
        col = [r[k] for r in body]
        try:
            out[name] = np.array([float(v) for v in col])
        except ValueError:
            out[name] = np.array(col)
    return out


def quat_to_matrix(w, x, y, z):
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


class Run:
    def __init__(self, d, scenario, rt_config):
        self.dir = d
        self.truth = load_csv(f"{d}/truth.csv")
        with open(f"{d}/emu.json") as f:
            self.emu = json.load(f)
        with open(f"{d}/rt.json") as f:
            self.rt = json.load(f)
        self.cycles = load_csv(f"{d}/rec/cycles.csv")
        with open(scenario, "rb") as f:
            self.scenario = tomllib.load(f)
        with open(rt_config, "rb") as f:
            self.config = tomllib.load(f)
        self.cycle_s = self.emu["cycle_s"]
        self.first_ipoc = self.emu["first_ipoc"]
        body = self.config["body"]
        self.mass = body["mass_kg"]
        self.inertia = np.array(body["inertia_kgm2"], dtype=float)
        self.com_S = np.array(body["com_sensor_m"], dtype=float)
        t = self.truth
        self.t = t["t_s"]
        self.R = np.array([quat_to_matrix(*q) for q in zip(t["tcp_qw"], t["tcp_qx"], t["tcp_qy"],
                                                             t["tcp_qz"])])
        self.p = np.stack([t["tcp_x_m"], t["tcp_y_m"], t["tcp_z_m"]], axis=1)
        self.w = np.stack([t["tcp_wx_radps"], t["tcp_wy_radps"], t["tcp_wz_radps"]], axis=1)
        self.v_com = np.stack([t["com_vx_mps"], t["com_vy_mps"], t["com_vz_mps"]], axis=1)
        self.p_com = self.p + np.einsum("nij,j->ni", self.R, self.com_S)

    def ipoc_to_t(self, ipoc):
        return (ipoc - self.first_ipoc) * 1e-3

    def transition(self, to, fault=None):
        for tr in self.rt["transitions"]:
            if tr["to"] == to and (fault is None or tr.get("fault") == fault):
                return tr
        return None

    def cycle_row(self, cycle):
        idx = np.nonzero(self.cycles["cycle"] == cycle)[0]
        return int(idx[0]) if len(idx) else None

    def enabled_t(self):
        tr = self.transition("zero_g")
        if tr is None:
            return None
        row = self.cycle_row(tr["cycle"])
        return None if row is None else self.ipoc_to_t(self.cycles["ipoc"][row])

    def window(self, t0, t1):
        return (self.t >= t0) & (self.t <= t1)

    def angular_momentum(self):
        """L = R I Rᵀ ω about the centre of mass, world frame, with the virtual inertia (sensor
        axes = body axes)."""
        I_w = np.einsum("nij,jk,nlk->nil", self.R, self.inertia, self.R)
        return np.einsum("nij,nj->ni", I_w, self.w)


def common_checks(run, expect_fault=False):
    t_en = run.enabled_t()
    check(t_en is not None, f"zero-g enabled (at t = {t_en if t_en is not None else float('nan'):.3f} s)")
    rep = run.emu["replies"]
    check(rep["wrong_ipoc"] == 0, f"no reply with a wrong IPOC ({rep['wrong_ipoc']})")
    if not expect_fault:
        first = rep["first_ok_cycle"]
        # From zerog-rt's first reply to its last cycle (it stops before the emulator does).
        last_ipoc = run.cycles["ipoc"].max()
        upto = int(np.searchsorted(run.truth["ipoc"], last_ipoc, side="right"))
        after = run.truth["reply"][first:upto] if first >= 0 else np.array([])
        missing = int(np.sum(after == "none"))
        late = int(np.sum(after == "late"))
        figure("datagrams_after_first_reply", int(len(after)))
        figure("replies_late", late)
        figure("replies_missing", missing)
        check(first >= 0 and missing == 0,
              f"every datagram after the first reply answered ({len(after)} datagrams, "
              f"{missing} unanswered, {late} answered late)")
        check(run.rt["fault"] == "none", f"no fault in zerog-rt (fault: {run.rt['fault']})")
    return t_en


def case_push(run):
    t_en = common_checks(run)
    push = run.emu["pushes"][0]
    J = np.array(push["integrated_impulse_N_s"])
    t_end = push["start_s"] + push["duration_s"]
    check(t_en is not None and t_en < push["start_s"], "zero-g was on before the push")
    sel = run.window(t_end + 1.0, t_end + 2.5)
    v = run.v_com[sel].mean(axis=0)
    v_expected = J / run.mass
    err = np.linalg.norm(v - v_expected) / np.linalg.norm(v_expected)
    figure("push_impulse_N_s", J.tolist())
    figure("push_velocity_expected_mps", v_expected.tolist())
    figure("push_velocity_measured_mps", v.tolist())
    figure("push_velocity_error", err)
    print(f"  push J = ({J[0]:.3f}, {J[1]:.3f}, {J[2]:.3f}) N·s on m = {run.mass:g} kg: "
          f"J/m = ({v_expected[0]:.4f}, {v_expected[1]:.4f}, {v_expected[2]:.4f}) m/s")
    print(f"  payload centre-of-mass velocity {t_end + 1:.1f}–{t_end + 2.5:.1f} s: "
          f"({v[0]:.4f}, {v[1]:.4f}, {v[2]:.4f}) m/s")
    p_lin = run.mass * v
    print(f"  momentum m·v = ({p_lin[0]:.3f}, {p_lin[1]:.3f}, {p_lin[2]:.3f}) N·s against the "
          f"impulse J: the part floated off with {100 * np.linalg.norm(p_lin) / np.linalg.norm(J):.1f} % of it")
    check(err < 0.03, f"velocity settles at J/m: error {100 * err:.2f} % (limit 3 %)")
    spread = np.linalg.norm(run.v_com[sel] - v, axis=1).max() / np.linalg.norm(v_expected)
    figure("push_velocity_spread", spread)
    check(spread < 0.03, f"and stays there: largest deviation {100 * spread:.2f} % of J/m")


def check_telemetry_run(run):
    """The independent Python DDS subscriber's recording, compared with cycles.csv by
    check_telemetry.py in hil.sh (every topic, values per cycle)."""
    try:
        with open(f"{run.dir}/telemetry.status") as f:
            status = int(f.read().strip())
        with open(f"{run.dir}/telemetry.txt") as f:
            report = f.read().strip().splitlines()
    except (OSError, ValueError):
        check(False, "telemetry: hil.sh ran no check_telemetry.py")
        return
    for line in report[-12:]:
        print(f"    {line}")
    topics = {}
    with open(f"{run.dir}/telemetry.jsonl") as f:
        for line in f:
            name = json.loads(line).get("topic", "?")
            topics[name] = topics.get(name, 0) + 1
    figure("telemetry_samples_by_topic", topics)
    check(status == 0, f"telemetry: every topic received, values match cycles.csv "
                       f"(check_telemetry.py exit {status})")


def case_supervisor(run):
    """The PLC (mbpoll over Modbus TCP) sets the mass while idle, enables zero-g, is refused a
    mass change during zero-g; the push then moves the part with the PLC's mass."""
    try:
        with open(f"{run.dir}/plc.json") as f:
            plc = json.load(f)
    except OSError:
        check(False, "PLC: plc_supervisor.py wrote no plc.json")
        return
    for s in plc.get("steps", []):
        print(f"    PLC {s['step']}: exit {s['exit']} {s['values'] if s['values'] else ''}"
              f"{'' if s['exit'] == 0 else ' — ' + ' '.join(s['output'][-1:])}")
    check(plc.get("ok"), f"PLC: the session ran ({plc.get('error', 'all steps')})")
    if not plc.get("ok"):
        return
    written = plc["mass_raw_written"]
    check(plc["state_idle"] == [0], f"PLC: state read as idle (0) before enabling: {plc['state_idle']}")
    check(plc["mass_raw_before"] == [round(run.mass * 1000)],
          f"PLC: mass read as the configuration's {run.mass:g} kg: {plc['mass_raw_before']} (0.001 kg)")
    check(plc["write_idle_exit"] == 0 and plc["mass_raw_after_write"] == [written]
          and plc["proposal_status_after_write"] == [2],
          f"PLC: mass {written / 1000:g} kg written while idle, accepted (status "
          f"{plc['proposal_status_after_write']}) and read back {plc['mass_raw_after_write']}")
    check(plc["enable_exit"] == 0 and plc["state_after_enable"] == [2],
          f"PLC: zero-g enabled with coil 0, state read as zero_g (2): {plc['state_after_enable']}")
    refusal = " ".join(plc["write_zero_g_output"])
    check(plc["write_zero_g_exit"] != 0 and "busy" in refusal.lower(),
          f"PLC: mass write during zero-g refused with an exception: '{refusal}'")
    check(plc["mass_raw_after_refusal"] == [written] and plc["proposal_status_after_refusal"] == [3],
          f"PLC: and nothing changed: mass {plc['mass_raw_after_refusal']}, status "
          f"{plc['proposal_status_after_refusal']} (3 refused_state)")
    m = run.rt.get("modbus", {})
    figure("modbus_counters", m)
    check(m.get("writes_accepted") == 1 and m.get("exceptions_by_code", {}).get("6", 0) >= 1,
          f"zerog-rt's summary: 1 write accepted, {m.get('exceptions_by_code')} exceptions by code")
    # The part floats with the PLC's mass, not the configuration's.
    config_mass = run.mass
    run.mass = written / 1000.0
    check(abs(config_mass - run.mass) > 1.0, f"the PLC's mass ({run.mass:g} kg) differs from "
                                             f"the configuration's ({config_mass:g} kg)")
    case_push(run)
    check_telemetry_run(run)


def case_drift(run):
    t_en = common_checks(run)
    if t_en is None:
        return
    t0 = t_en + 1.0
    sel = run.window(t0, t0 + 10.0)
    span = run.t[sel][-1] - run.t[sel][0]
    p = run.p_com[sel]
    d = np.linalg.norm(p - p[0], axis=1).max()
    figure("drift_mm_in_10s", d * 1e3)
    check(span >= 9.9, f"10 s of zero-g observed ({span:.2f} s)")
    check(d < 1e-3, f"drift with no push: {d * 1e3:.3f} mm in {span:.1f} s (limit 1 mm)")


def free_window(run):
    push = run.emu["pushes"][0]
    t0 = push["start_s"] + push["duration_s"] + 0.5
    return t0, run.window(t0, t0 + 10.0)


def case_spin(run):
    common_checks(run)
    t0, sel = free_window(run)
    L = run.angular_momentum()[sel]
    L0 = L[0]
    dev = np.linalg.norm(L - L0, axis=1).max() / np.linalg.norm(L0)
    w = run.w[sel]
    turn = np.sum(np.linalg.norm(w, axis=1)) * run.cycle_s
    # The angular velocity is not along L (asymmetric body, tilted axis): it really precesses.
    wdir = w / np.linalg.norm(w, axis=1)[:, None]
    wander = math.degrees(math.acos(np.clip(np.min(wdir @ wdir[0]), -1, 1)))
    figure("spin_L0_Nms", L0.tolist())
    figure("spin_L_deviation", dev)
    figure("spin_turned_rad", turn)
    print(f"  |L| = {np.linalg.norm(L0):.4f} N·m·s, turned {math.degrees(turn):.0f}° in 10 s, "
          f"ω direction wandered {wander:.1f}°")
    check(turn > 1.0, f"the part really turned ({turn:.2f} rad)")
    check(dev < 0.02, f"angular momentum (world) kept within {100 * dev:.2f} % over 10 s (limit 2 %)")


def euler_rates(I, Iinv, w):
    return Iinv @ (-np.cross(w, I @ w))


def integrate_euler(I, w0, t):
    """ω(t) in body axes for a torque-free body: RK4 of I ω̇ = −ω × I ω on the grid t."""
    Iinv = np.linalg.inv(I)
    out = [w0]
    w = w0.copy()
    for k in range(1, len(t)):
        h = t[k] - t[k - 1]
        n = max(1, int(math.ceil(h / 1e-3)))
        dh = h / n
        for _ in range(n):
            k1 = euler_rates(I, Iinv, w)
            k2 = euler_rates(I, Iinv, w + 0.5 * dh * k1)
            k3 = euler_rates(I, Iinv, w + 0.5 * dh * k2)
            k4 = euler_rates(I, Iinv, w + dh * k3)
            w = w + dh / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(w.copy())
    return np.array(out)


def case_tumble(run):
    common_checks(run)
    t0, sel = free_window(run)
    t = run.t[sel]
    R = run.R[sel]
    w_body = np.einsum("nji,nj->ni", R, run.w[sel])  # Rᵀ ω
    evals, evecs = np.linalg.eigh(run.inertia)
    mid = evecs[:, 1]
    pred = integrate_euler(run.inertia, w_body[0], t)
    scale = np.linalg.norm(w_body[0])
    rms = np.sqrt(np.mean(np.sum((w_body - pred) ** 2, axis=1))) / scale
    # Off-axis part of the spin: how far ω is from the intermediate axis, measured and predicted.
    def off_axis(w):
        along = w @ mid
        return np.linalg.norm(w - np.outer(along, mid), axis=1)
    off_m, off_p = off_axis(w_body), off_axis(pred)
    growth_m, growth_p = off_m.max() / off_m[0], off_p.max() / off_p[0]
    lam = scale * math.sqrt((evals[1] - evals[0]) * (evals[2] - evals[1]) / (evals[0] * evals[2]))
    figure("tumble_rms_error", rms)
    figure("tumble_off_axis_growth_measured", growth_m)
    figure("tumble_off_axis_growth_predicted", growth_p)
    print(f"  principal moments {evals.round(3).tolist()} kg·m², spin |ω| = {scale:.3f} rad/s "
          f"{math.degrees(math.acos(min(1, abs(w_body[0] @ mid) / scale))):.1f}° off the "
          f"intermediate axis; instability rate √(...)·|ω| = {lam:.3f} 1/s")
    print(f"  off-axis part of ω grew ×{growth_m:.2f} (Euler's equations: ×{growth_p:.2f}) in 10 s")
    check(growth_p > 2.0, f"the prediction itself tumbles (off-axis part ×{growth_p:.2f})")
    check(rms < 0.10,
          f"ω in body axes follows Euler's equations: RMS error {100 * rms:.1f} % of |ω| (limit 10 %)")
    check(abs(math.log(growth_m / growth_p)) < math.log(1.25),
          f"growth of the off-axis part within 25 % of the prediction")


def case_fault(run, name):
    common_checks(run, expect_fault=True)
    wd = run.config["watchdog"]
    kind = run.scenario["fault"][0]["kind"]
    expected = {
        "robot_drop": ("robot_late", wd["robot_fault_cycles"]),
        "robot_malformed": ("robot_late", wd["robot_fault_cycles"]),
        "robot_late": ("robot_late", wd["robot_late_cycles"]),
        "ft_silent": ("ft_stale", wd["ft_fault_cycles"]),
        "ft_critical": ("ft_critical", wd["ft_fault_cycles"]),
        "ft_saturated": ("ft_saturated", wd["ft_fault_cycles"]),
        "imu_garbage": ("imu_stale", wd["imu_fault_cycles"]),
        "imu_silent": ("imu_stale", wd["imu_fault_cycles"]),
    }[kind]
    fault_name, threshold = expected
    injected = run.emu["faults"][0]
    t_inj = injected["applied_start_s"]
    tr = run.transition("fault")
    check(tr is not None and tr.get("fault") == fault_name,
          f"{kind} raises fault '{fault_name}' (got {tr.get('fault') if tr else 'no fault'})")
    if tr is None:
        return
    row = run.cycle_row(tr["cycle"])
    t_fault = run.ipoc_to_t(run.cycles["ipoc"][row]) if row is not None else float("nan")
    cycles_after = round((t_fault - t_inj) / run.cycle_s)
    lost = kind in ("robot_drop", "robot_malformed")
    if lost:
        # Raised between messages, by the lost cycles themselves: the transition carries the
        # last good message's cycle, and no good message came between the injection and it.
        # The count of lost cycles at the fault is the watchdog's threshold (unit-tested);
        # here: the fault came before the robot's next good datagram.
        c = run.rt["cycles"]
        lost_seen = c["robot_timeouts"] + c["robot_malformed"]
        figure("robot_cycles_lost_counted", lost_seen)
        check(t_fault <= t_inj and lost_seen >= threshold,
              f"fault raised by {lost_seen} lost cycles before any further good datagram "
              f"(last good one at {t_fault:.3f} s)")
        injected_cycles = run.scenario["fault"][0]["cycles"]
        faulted = np.nonzero(run.cycles["state"] == "fault")[0]
        t_first = run.ipoc_to_t(run.cycles["ipoc"][faulted[0]]) if len(faulted) else float("nan")
        cycles_after = round((t_first - t_inj) / run.cycle_s)
        check(cycles_after <= injected_cycles + 1,
              f"the robot's next datagram ({cycles_after} cycles after the injection) "
              f"is answered in fault")
    # Robot cycles from the injection to the fault. The robot watchdog counts lost cycles, the
    # sensor ones cycles without a valid sample; samples in flight and the delay of the late
    # datagrams add a few cycles, documented in proto/loop.md.
    slack = {"robot_late": 6}.get(kind, 3)
    figure("fault", fault_name)
    figure("fault_cycles_after_injection", cycles_after)
    figure("fault_threshold_cycles", threshold)
    print(f"  injected at {t_inj:.3f} s, fault '{fault_name}' at {t_fault:.3f} s: {cycles_after} "
          f"robot cycles later (threshold {threshold})")
    if not lost:
        check(threshold - 1 <= cycles_after <= threshold + slack,
              f"fault within the documented cycles: {cycles_after} in "
              f"[{threshold - 1}, {threshold + slack}]")
    # Before it: still zero-g (hold); from it: zero correction, IPOC echoed.
    before = (run.cycles["cycle"] < tr["cycle"]) & (run.cycles["ipoc"] >= run.first_ipoc + t_inj * 1e3)
    check(np.all(run.cycles["state"][before] == "zero_g"),
          f"held in zero-g for the {int(np.sum(before))} cycles before the fault")
    after = run.cycles["cycle"] >= tr["cycle"]
    corr = np.stack([run.cycles[c] for c in ("rkorr_x_mm", "rkorr_y_mm", "rkorr_z_mm", "rkorr_a_deg",
                                             "rkorr_b_deg", "rkorr_c_deg")], axis=1)[after]
    check(np.all(corr == 0.0), f"zero correction in all {int(np.sum(after))} cycles from the fault on")
    ipocs = set(run.cycles["ipoc"][after].astype(np.int64).tolist())
    tr_ipoc = run.truth["ipoc"].astype(np.int64)
    got = run.truth["reply"]
    t_fault_sel = run.truth["t_s"] >= t_fault
    applied = np.stack([run.truth[f"corr_{k}"] for k in range(1, 7)], axis=1)[t_fault_sel & (got == "ok")]
    check(np.all(applied == 0.0), "the robot received only zero corrections after the fault")
    after_rows = t_fault_sel & np.isin(tr_ipoc, list(ipocs))
    check(np.all(got[after_rows] != "none"), "every datagram after the fault was answered")
    boxes = run.rt["black_box_dumps"]
    check(len(boxes) >= 1, f"black box dumped ({boxes[0] if boxes else 'none'})")
    if boxes:
        box = load_csv(boxes[0])
        check(box["fault"][-1] == fault_name and len(box["cycle"]) > 50,
              f"black box: {len(box['cycle'])} cycles, the last one with fault '{box['fault'][-1]}'")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", required=True)
    ap.add_argument("--dir", required=True)
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--rt-config", required=True)
    ap.add_argument("--attempt", type=int, default=1, help="1, or 2 for hil.sh's retry")
    a = ap.parse_args()
    run = Run(a.dir, a.scenario, a.rt_config)
    print(f"{a.case}:")
    if a.case.startswith("fault_"):
        case_fault(run, a.case)
    else:
        {"push": case_push, "drift": case_drift, "spin": case_spin, "tumble": case_tumble,
         "supervisor": case_supervisor}[a.case](run)
    FIGURES["case"] = a.case
    FIGURES["attempt"] = a.attempt
    FIGURES["passed"] = not FAILURES
    with open(f"{a.dir}/check.json", "w") as f:
        json.dump(FIGURES, f, indent=1)
    if FAILURES:
        print(f"{a.case}: {len(FAILURES)} check(s) failed")
        return 1
    print(f"{a.case}: passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
