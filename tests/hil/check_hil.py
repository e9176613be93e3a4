#!/usr/bin/env python3
"""Checks one hardware-in-the-loop run (tests/hil/hil.sh) against the acceptance of the zero-g
firmware: the emulator's truth (what the robot really did, truth.csv), its summary (emu.json),
zerog-rt's summary (rt.json) and cycle records (rec/cycles.csv).

Cases (limits in lockstep, where the run depends on the seed only / in real time):
  push     the payload's velocity after a push of impulse J settles at J/m (1 % / 3 %)
  drift    with no push the part does not move in 10 s (0 / less than 1 mm)
  spin     free rotation keeps the angular momentum (world frame) over 10 s (0.5 % / 2 %)
  tumble   a spin near the intermediate principal axis follows Euler's equations
  fault_*  the documented reaction: hold, then the named fault with zero correction in the
           documented cycle (lockstep: exactly, computed from the threshold and the samples in
           flight; real time: within a window); black box dumped; every datagram answered
A lockstep run (emu.json has "lockstep") is also checked for the lockstep itself: every event
handled, no sample request without a sample, the sensor threads done in time.

Prints what it measured, one line per figure, and exits 1 if a check fails. Also writes
DIR/check.json with the figures (for the tables of docs/zerog-rt.md and the demo).
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
        self.lockstep = "lockstep" in self.emu
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


def end_of_run_fault(run):
    """zerog-rt's robot_late in its very last record, raised because the emulator's run had
    ended (the robot went silent: hil.sh starts zerog-rt with a duration that a slow VM start can
    make outlast the emulator's). Not a reaction to the injected fault."""
    trs = [t for t in run.rt["transitions"] if t["to"] == "fault"]
    if run.lockstep:  # zerog-rt stops on the emulator's `end`: the robot never goes silent
        return None
    if len(trs) != 1 or trs[0].get("fault") != "robot_late":
        return None
    last_emu_ipoc = run.first_ipoc + round((run.emu["cycles"] - 1) * run.cycle_s * 1e3)
    row = run.cycle_row(trs[0]["cycle"])
    if row is None or row != len(run.cycles["cycle"]) - 1 or run.cycles["ipoc"][row] < last_emu_ipoc:
        return None
    return trs[0]


def common_checks(run, expect_fault=False, push_after_trust=True):
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
        end = end_of_run_fault(run)
        if end is not None:
            print(f"  note: robot_late at cycle {end['cycle']}, the last one, after the emulator's "
                  "run ended (not judged)")
        check(run.rt["fault"] == "none" or end is not None,
              f"no fault in zerog-rt (fault: {run.rt['fault']})")
    if t_en is not None and FUSED["on"]:
        trusted_check(run, t_en, push_after_trust)
    return t_en


def rest_from(run, t):
    """Where the noise at rest is measured from: t, or the row from which zerog-rt trusts the
    contact if later (trusted_check): before it no push can be confirmed, and the rows still
    carry what the settling and the tare take out."""
    t_ok = getattr(run, "t_trusted", None)
    return t if t_ok is None else max(t, t_ok)


def trusted_check(run, t_en, push_after_trust=True):
    """When zerog-rt's contact became trusted (the estimator settled, the tare taken: the gate
    may open from that row on), printed; a push before it would be ignored, so the cases'
    first push must come after it (unless `push_after_trust` is False: case_hand)."""
    t = record_t(run)
    taring = flagged(run, FLAG_CONTACT_TARING)
    closed = flagged(run, FLAG_ESTIMATOR_SETTLING) | taring
    ok = np.nonzero((run.cycles["state"] == "zero_g") & (t >= t_en) & ~closed)[0]
    t_ok = float(t[ok[0]]) if len(ok) else None
    run.t_trusted = t_ok
    figure("contact_trusted_s", t_ok)
    taring = int(np.count_nonzero(taring))
    print(f"  the contact trusted from t = {t_ok if t_ok is not None else float('nan'):.3f} s "
          f"(zero-g at {t_en:.3f} s; {taring} rows taring)")
    pushes = run.emu.get("pushes", [])
    if pushes and push_after_trust:
        check(t_ok is not None and t_ok < pushes[0]["start_s"],
              f"the contact was trusted before the first push at {pushes[0]['start_s']:g} s")


AXES = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


# The cases run with zerog-rt's motion estimator ([filter] motion = "fused", CASE_fused.rt.toml):
# their contact noise at rest is held to 1.5x the F/T-only floor on every axis (issue 28).
FUSED_REST_LIMIT = 1.5
# While the part moves (spin: it turns freely after a push), 2x on every axis (issue 28).
FUSED_MOVING_LIMIT = 2.0
# On the elastic robot (CASE_elastic_fused) the estimator is held to stability (no fault, J/m
# within FUSED_ELASTIC_JM); its noise where contact_noise's hold_elastic says: at rest per axis
# over the drift's 10 s (with the contact's tare, from the row the contact is trusted) and the
# ten quiet minutes, moving per axis over the spin and the glide (proto/loop.md, "Motion
# estimator", "The tare", "The push loads the arm").
FUSED_ELASTIC_JM = 0.02
# The 1 N nudge on the elastic arm: the F/T noise over the open gate alone is 4.1 % of J in the
# norm (proto/loop.md, "The 1 N push"); with the IMU share's slow wander in the contact and the
# push's own load on the arm 5.5-25.0 % measured (seeds 11-20, contact_lowpass_hz 2; 4.5-21.6 %
# on seeds 11-15 before the arm carried the push), 20-48 % with the loop through the modes
# (lowpass off, which the check that the velocity stays catches: 73-97 %).
NUDGE_ELASTIC_JM = 0.30
FUSED = {"on": False, "elastic": False}


def contact_noise(run, t0, t1, what, hold_elastic=False):
    """The contact wrench's noise (measured − predicted, contact_* of cycles.csv) in
    zero-g between t0 and t1, against the F/T-only floor per cycle: the measured wrench's own
    white noise, from its second differences over the same cycles (1.4826 median|d| / √6, as
    zerog compare's; host/ident/include/zerog/ident/ft_floor.hpp). A figure for the IMU's path;
    a check for the motion estimator's (every axis within FUSED_REST_LIMIT at rest,
    FUSED_MOVING_LIMIT moving). On the elastic arm only where hold_elastic is True (every axis,
    as on the rigid one)."""
    c = run.cycles
    t = np.array([run.ipoc_to_t(i) for i in c["ipoc"]])
    sel = (c["state"] == "zero_g") & (t >= t0) & (t <= t1)
    if np.count_nonzero(sel) < 30:
        print(f"  contact noise ({what}): fewer than 30 zero-g cycles, not measured")
        return
    columns = [f"{a}_{'N' if a[0] == 'F' else 'Nm'}" for a in AXES]
    r = np.stack([c[f"contact_{k}"] for k in columns], axis=1)[sel]
    rms = np.sqrt(np.mean(r ** 2, axis=0))
    m = np.stack([c[f"eval_{k}"] for k in columns], axis=1)[sel]
    d = m[2:] - 2 * m[1:-1] + m[:-2]
    floor = 1.4826 * np.median(np.abs(d), axis=0) / np.sqrt(6.0)
    pooled = lambda v, k: float(np.sqrt(np.mean(v[k:k + 3] ** 2)))
    force_ratio, torque_ratio = pooled(rms, 0) / pooled(floor, 0), pooled(rms, 3) / pooled(floor, 3)
    figure(f"contact_rms_{what}", rms.tolist())
    figure(f"ft_floor_cycle_{what}", floor.tolist())
    figure(f"contact_over_floor_{what}", [force_ratio, torque_ratio])
    print(f"  contact wrench {what} ({np.count_nonzero(sel)} cycles), RMS: " +
          ", ".join(f"{a} {v:.3f}" for a, v in zip(AXES, rms)))
    print(f"  F/T-only floor per cycle (second differences of the measured wrench): " +
          ", ".join(f"{a} {v:.3f}" for a, v in zip(AXES, floor)))
    print(f"  contact noise against the floor: {force_ratio:.2f}x (force), {torque_ratio:.2f}x (torque)")
    if not FUSED["on"]:
        return
    held = hold_elastic if FUSED["elastic"] else True
    if not held:
        print(f"  (elastic arm: the motion estimator's noise limits are not held here)")
    if FUSED["elastic"]:
        mode_bands(run, t[sel], r, floor, what)
    if not held:
        return
    limit = FUSED_REST_LIMIT if what == "at_rest" else FUSED_MOVING_LIMIT
    worst = int(np.argmax(rms / floor))
    ratio = f"{AXES[worst]} {rms[worst] / floor[worst]:.2f}x"
    within = f"motion estimator: contact noise {what.replace('_', ' ')} within {limit}x the F/T floor"
    check(bool(np.all(rms <= limit * floor)), f"{within} on every axis (worst {ratio})")


# The half-width of the band around each joint's mode (mode_band_rows).
MODE_BAND_HZ = 1.0


def mode_band_rows(t, r, floor, joints):
    """The contact noise r (cycles × 6, at times t) in a band of ±MODE_BAND_HZ around each
    joint's mode below the cycles' Nyquist (`joints`: the rig's [[robot.joint]] tables, mode_hz),
    pooled per force and torque, with the share of that band the F/T floor's white noise would
    have (floor · √(band / Nyquist)). The spectrum is of the longest stretch of consecutive
    cycles, its mean removed. None if that stretch is shorter than 64 cycles."""
    dt = float(np.median(np.diff(t)))
    breaks = np.flatnonzero(np.diff(t) > 1.5 * dt)
    starts, ends = np.r_[0, breaks + 1], np.r_[breaks + 1, len(t)]
    k = int(np.argmax(ends - starts))
    x = r[starts[k]:ends[k]] - r[starts[k]:ends[k]].mean(axis=0)
    n = len(x)
    if n < 64:
        return None
    nyquist = 0.5 / dt
    freq = np.fft.rfftfreq(n, dt)
    # One-sided power per bin, so that the bins' sum is the mean square (Parseval).
    power = np.abs(np.fft.rfft(x, axis=0)) ** 2 / n ** 2
    power[1:] *= 2.0
    if n % 2 == 0:
        power[-1] /= 2.0
    pooled = lambda v, k: float(np.sqrt(np.mean(v[k:k + 3] ** 2)))
    rows = []
    for i, j in enumerate(joints):
        f0 = float(j.get("mode_hz", 0.0))
        if not 0.0 < f0 < nyquist:
            continue
        lo, hi = max(f0 - MODE_BAND_HZ, 0.0), min(f0 + MODE_BAND_HZ, nyquist)
        band = (freq >= lo) & (freq < hi)
        rms = np.sqrt(power[band].sum(axis=0))
        share = floor * math.sqrt((hi - lo) / nyquist)
        rows.append({"joint": f"A{i + 1}", "mode_hz": f0,
                     "force_N": pooled(rms, 0), "torque_Nm": pooled(rms, 3),
                     "floor_force_N": pooled(share, 0), "floor_torque_Nm": pooled(share, 3)})
    return rows


def mode_bands(run, t, r, floor, what):
    """Where the contact noise of the elastic arm sits (mode_band_rows on the rig's robot
    file): a band well above its floor's share names the mode the estimator leaves in the
    contact. Printed and written to check.json (mode_band_{what}), not held."""
    try:
        with open(f"{run.dir}/rig.rig.toml", "rb") as f:
            joints = tomllib.load(f).get("robot", {}).get("joint", [])
    except (OSError, tomllib.TOMLDecodeError) as e:
        print(f"  mode bands ({what}): the rig's robot file could not be read ({e})")
        return
    rows = mode_band_rows(t, r, floor, joints)
    if rows is None:
        print(f"  mode bands ({what}): fewer than 64 consecutive cycles, not measured")
        return
    figure(f"mode_band_{what}", rows)
    print(f"  contact noise {what} in its joints' mode bands (±{MODE_BAND_HZ:g} Hz; the F/T "
          f"floor's white share in brackets): " + "; ".join(
              f"{b['joint']} {b['mode_hz']:g} Hz {b['force_N']:.3f} N ({b['floor_force_N']:.3f}), "
              f"{b['torque_Nm']:.4f} N*m ({b['floor_torque_Nm']:.4f})" for b in rows))



def tool_json(run, tool):
    """The JSON `zerog TOOL --json` wrote beside the run (hil.sh ran it), or None after a failed
    check saying it is not there."""
    try:
        with open(f"{run.dir}/{tool}.json") as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        check(False, f"zerog {tool} wrote {tool}.json ({e})")
        return None


def gate_checks(run):
    """`zerog gate` on this run's cycles.csv (hil.sh ran it): the thresholds it advises, replayed
    on the same untouched run, confirm no push."""
    gate = tool_json(run, "gate")
    if gate is None:
        return
    check(gate.get("known") is True, f"zerog gate measured the noise at rest "
          f"({gate.get('cycles')} cycles{'' if gate.get('known') else ': ' + str(gate.get('note'))})")
    if not gate.get("known"):
        return
    f, m = gate["force_N"], gate["torque_Nm"]
    figure("gate_force_N", f["threshold"])
    figure("gate_torque_Nm", m["threshold"])
    print(f"  zerog gate: force {f['threshold']:.3f} N (sigma {f['sigma']:.3f}), torque "
          f"{m['threshold']:.3f} N*m (sigma {m['sigma']:.4f}), {gate['cycles']} cycles at rest")
    check(f["confirms_at_threshold"] == 0 and m["confirms_at_threshold"] == 0,
          f"the advised gate confirms no push on the untouched run (force "
          f"{f['confirms_at_threshold']}, torque {m['confirms_at_threshold']})")


def servo_checks(run):
    """`zerog servo` on this run's cycles.csv (hil.sh ran it): the emulator's servo bandwidth and
    its tick (the joints move from row k + 1 to k + 2 after the reply at row k) are found."""
    servo = tool_json(run, "servo")
    if servo is None:
        return
    truth = run.emu["robot"]["servo_bandwidth_hz"]
    check(servo.get("known") is True,
          f"zerog servo identified the servo ({servo.get('rows')} rows"
          f"{'' if servo.get('known') else ': ' + str(servo.get('note'))})")
    if not servo.get("known"):
        return
    hz, sigma, lo_hi = servo["servo_hz"], servo["servo_hz_sigma"], servo["quarters_hz"]
    figure("servo_hz", hz)
    figure("servo_hz_sigma", sigma)
    figure("servo_hz_quarters", lo_hi)
    figure("servo_truth_hz", truth)
    figure("servo_lag_rows", servo["lag_rows"])
    print(f"  zerog servo: {hz:.4g} Hz (emulator {truth:g} Hz; quarters {lo_hi[0]:.4g}-"
          f"{lo_hi[1]:.4g} Hz), lag {servo['lag_rows']} rows, residual {servo['rms_rad']['fit']:.3g} "
          f"rad against {servo['rms_rad']['instant']:.3g} rad for an instant servo")
    check(servo["lag_rows"] == servo["model_lag_rows"],
          f"zerog servo found the controller's tick ({servo['lag_rows']} rows, the model's "
          f"{servo['model_lag_rows']})")
    check(abs(hz - truth) < 0.02 * truth, f"and the emulator's bandwidth within 2 % "
          f"({hz:.4g} Hz against {truth:g} Hz)")
    if sigma is not None:
        check(abs(hz - truth) < max(4 * sigma, 0.005 * truth),
              f"within 4 sigma of its quoted uncertainty ({sigma:.2g} Hz)")


def case_servo(run):
    """The servo identified on a cell before its servo model: pushes, stops, twists."""
    common_checks(run)
    servo_checks(run)


def first_moving_cycle(run, t_from):
    """The first cycle from t_from on whose virtual body moves (body_v* of cycles.csv): where
    the gate confirmed the push (in lockstep the body is exactly still before)."""
    c = run.cycles
    t = np.array([run.ipoc_to_t(i) for i in c["ipoc"]])
    v = np.stack([c["body_vx_mps"], c["body_vy_mps"], c["body_vz_mps"]], axis=1)
    moving = np.nonzero((t >= t_from) & (np.linalg.norm(v, axis=1) > 0.0))[0]
    return (int(round((t[moving[0]] - t_from) / run.cycle_s)) if len(moving) else None)


def case_nudge(run):
    """The gentlest push (1 N for 0.5 s) with the gate at a third of today's: confirmed within
    the push, the part moves off at J/m within 2 % (issue 28). On the elastic arm
    (nudge_elastic_fused, with [limits] contact_lowpass_hz) the check is that the gate lets go:
    the velocity stays where the push left it (case_push's spread, 3 % of J/m), where an open gate
    closing a loop through the arm's modes kept pushing (73-97 %, proto/loop.md); J/m itself is
    held to NUDGE_ELASTIC_JM only, as the issue's 2 % is out of reach at this sensor's noise."""
    push = run.emu["pushes"][0]
    k = first_moving_cycle(run, push["start_s"])
    figure("nudge_confirm_cycle", k)
    print(f"  the push moved the body {k} cycles after it began")
    check(k is not None and k * run.cycle_s < push["duration_s"],
          "the gate confirmed the 1 N push while it lasted")
    case_push(run, limit=NUDGE_ELASTIC_JM if FUSED["elastic"] else 0.02)


def case_hand(run):
    """A hand on the part as zero-g starts, above the gate, while the estimator settles and the
    tare would be taken (hand_elastic_fused): the tare starts again once the hand lets go, so
    the contact is trusted only after that, and the part never moves: the hand's force was no
    part of the contact's zero (proto/loop.md, "The tare")."""
    t_en = common_checks(run, push_after_trust=False)
    if t_en is None:
        return
    hand = run.emu["pushes"][0]
    t_off = hand["start_s"] + hand["duration_s"]
    t_ok = getattr(run, "t_trusted", None)
    check(t_ok is not None and t_ok > t_off,
          f"the contact was trusted only after the hand let go at {t_off:g} s")
    if t_ok is not None:
        contact_noise(run, t_ok, float(run.t[-1]), "at_rest")
    sel = run.window(t_en, float(run.t[-1]))
    d = np.linalg.norm(run.p_com[sel] - run.p_com[sel][0], axis=1).max()
    k = first_moving_cycle(run, t_en)
    figure("hand_drift_mm", d * 1e3)
    check(k is None and d == 0.0,
          f"the part stayed where the hand left it ({d * 1e3:.3f} mm"
          f"{'' if k is None else f', moving from {t_en + k * run.cycle_s:.2f} s'})")


def case_quiet(run):
    """Ten minutes of zero-g, nobody touching the part, the gate at a third of today's: no
    contact confirmed, so the part does not move (lockstep: exactly)."""
    t_en = common_checks(run)
    if t_en is None:
        return
    # Ten minutes at rest: on the elastic arm too the estimator's limit at rest is held (the short
    # rest before a push is still in the IMU share's first seconds: printed, not held there).
    contact_noise(run, t_en + 1.0, float(run.t[-1]), "at_rest", hold_elastic=True)
    sel = run.window(t_en + 1.0, float(run.t[-1]))
    span = run.t[sel][-1] - run.t[sel][0]
    d = np.linalg.norm(run.p_com[sel] - run.p_com[sel][0], axis=1).max()
    k = first_moving_cycle(run, t_en + 1.0)
    figure("quiet_s", span)
    figure("quiet_drift_mm", d * 1e3)
    check(span >= 599.0, f"ten minutes of zero-g observed ({span:.1f} s)")
    check(k is None and d == 0.0, f"no false contact: the body never moved ({d * 1e3:.6f} mm"
          f"{'' if k is None else f', first at {t_en + 1.0 + k * run.cycle_s:.2f} s'})")


def case_push(run, limit=None):
    t_en = common_checks(run)
    push = run.emu["pushes"][0]
    if t_en is not None:
        # On the elastic arm printed, not held: with the tare the rest before the push is about
        # half a second (46 rows), too short for a figure that decides (the RMS and the floor
        # each ±10 %); drift and quiet hold the rest over 10 s and 10 min.
        contact_noise(run, rest_from(run, t_en + 0.5), push["start_s"] - 0.05, "at_rest")
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
    if limit is None:
        limit = 0.01 if run.lockstep else 0.03
        if FUSED["on"] and FUSED["elastic"]:
            limit = FUSED_ELASTIC_JM
    check(err < limit, f"velocity settles at J/m: error {100 * err:.2f} % (limit {100 * limit:g} %)")
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
    # The ROS 2 side: the rt/ topics read with types from rosbags' ROS 2 message definitions.
    try:
        with open(f"{run.dir}/ros2.status") as f:
            status = int(f.read().strip())
        with open(f"{run.dir}/ros2.txt") as f:
            report = f.read().strip().splitlines()
    except (OSError, ValueError):
        check(False, "ROS 2 telemetry: hil.sh ran no check_ros2_telemetry.py")
        return
    for line in report[-14:]:
        print(f"    {line}")
    check(status == 0, f"ROS 2 telemetry: every rt/ topic received as ROS 2's types, values match "
                       f"cycles.csv (check_ros2_telemetry.py exit {status})")


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
    t0 = rest_from(run, t_en + 1.0)
    contact_noise(run, t0, t0 + 10.0, "at_rest", hold_elastic=True)
    gate_checks(run)
    sel = run.window(t0, t0 + 10.0)
    span = run.t[sel][-1] - run.t[sel][0]
    p = run.p_com[sel]
    d = np.linalg.norm(p - p[0], axis=1).max()
    figure("drift_mm_in_10s", d * 1e3)
    check(span >= 9.9, f"10 s of zero-g observed ({span:.2f} s)")
    if run.lockstep:
        check(d == 0.0, f"drift with no push: {d * 1e3:.6f} mm in {span:.1f} s (must be 0)")
    else:
        check(d < 1e-3, f"drift with no push: {d * 1e3:.3f} mm in {span:.1f} s (limit 1 mm)")


def case_glide(run):
    """A guided glide: the push sends the part at about 0.5 m/s; while it glides, its speed
    stays J/m and the contact noise is held to the moving limit (the fused case)."""
    t_en = common_checks(run)
    push = run.emu["pushes"][0]
    if t_en is not None:
        contact_noise(run, rest_from(run, t_en + 0.5), push["start_s"] - 0.05, "at_rest")
    t0 = push["start_s"] + push["duration_s"] + 0.3
    t1 = float(run.t[-1]) - 0.2
    sel = run.window(t0, t1)
    J = np.array(push["integrated_impulse_N_s"])
    v_expected = J / run.mass
    v = run.v_com[sel]
    speed = np.linalg.norm(v, axis=1)
    err = float(np.max(np.linalg.norm(v - v_expected, axis=1)) / np.linalg.norm(v_expected))
    figure("glide_speed_mps", [float(speed.min()), float(speed.max())])
    figure("glide_velocity_error", err)
    print(f"  glide {t0:.1f}–{t1:.1f} s: speed {speed.min():.3f}–{speed.max():.3f} m/s, J/m "
          f"{np.linalg.norm(v_expected):.3f} m/s, largest deviation {100 * err:.2f} %")
    check(bool(np.all(speed > 0.45)), "the part glides at 0.5 m/s (over 0.45 m/s throughout)")
    check(err < 0.02, f"and keeps J/m within 2 % ({100 * err:.2f} %)")
    # On the elastic arm every axis since the arm carries the push as it carries the weight
    # (proto/loop.md, "The push loads the arm": worst axis 1.51-1.98x on seeds 11-15; pooled
    # before, 1.49-2.30x on the arm loaded by the weight alone).
    contact_noise(run, t0, t1, "moving", hold_elastic=True)


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
    # Held on the elastic arm too since the joints' load left the ringing out (proto/loop.md,
    # "The joints' load"; worst axis 1.24-1.57x on seeds 11-15 since "The deflection's
    # acceleration").
    contact_noise(run, t0, t0 + 10.0, "moving", hold_elastic=True)
    limit = 0.005 if run.lockstep else 0.02
    check(dev < limit, f"angular momentum (world) kept within {100 * dev:.3f} % over 10 s "
                       f"(limit {100 * limit:g} %)")


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


def lockstep_fault_cycle(run, kind, threshold):
    """The robot cycle (IPOC time / cycle) whose message raises the fault in lockstep, and why.
    proto/lockstep.md: at each datagram zerog-rt reads what the devices produced up to it, and
    the emulator switches a device fault on after the physics step at t_a (emu.json
    applied_start_s), before that step's events."""
    t_a = run.emu["faults"][0]["applied_start_s"]
    first = math.ceil(t_a / run.cycle_s - 1e-6)  # the first datagram at or after t_a
    if kind in ("ft_silent", "ft_critical", "ft_saturated"):
        # F/T samples are requested at the datagram: from datagram `first` on none is valid.
        return first + threshold - 1, f"first cycle without a sample {first} + {threshold} - 1"
    if kind == "imu_unplug":
        # The pty hangs up before `first` reads what was written to it: nothing from `first` on.
        return first + threshold - 1, f"first cycle without a sample {first} + {threshold} - 1"
    if kind in ("imu_garbage", "imu_crc", "imu_silent"):
        # The IMU datagram of the step at t_a was written before the fault: cycle `first` still
        # has a good one in flight, cycle first + 1 is the first without.
        return first + threshold, f"first cycle without a sample {first + 1} + {threshold} - 1"
    if kind == "robot_late":
        # The first late datagram still carries the old Delay; each after it a grown one.
        return first + threshold, f"first late datagram {first} + {threshold} grown Delays"
    if kind == "robot_reorder":
        # A stale (older) datagram is answered and skipped; the newer one of each pair carries a
        # Delay grown by the held one: pair k's newer datagram first + 1 + 2 k.
        return first + 1 + 2 * (threshold - 1), \
            f"newer datagram of pair {threshold} after the first held one {first}"
    raise ValueError(f"no lockstep expectation for {kind}")


def case_fault(run, name):
    """The faults of the loop: hold, then the documented fault (None if none was raised: failed)."""
    common_checks(run, expect_fault=True)
    wd = run.config["watchdog"]
    kind = run.scenario["fault"][0]["kind"]
    expected = {
        "robot_drop": ("robot_late", wd["robot_fault_cycles"]),
        "robot_malformed": ("robot_late", wd["robot_fault_cycles"]),
        "robot_late": ("robot_late", wd["robot_late_cycles"]),
        "robot_reorder": ("robot_late", wd["robot_late_cycles"]),
        "ft_silent": ("ft_stale", wd["ft_fault_cycles"]),
        "ft_critical": ("ft_critical", wd["ft_fault_cycles"]),
        "ft_saturated": ("ft_saturated", wd["ft_fault_cycles"]),
        "imu_garbage": ("imu_stale", wd["imu_fault_cycles"]),
        "imu_crc": ("imu_stale", wd["imu_fault_cycles"]),
        "imu_unplug": ("imu_stale", wd["imu_fault_cycles"]),
        "imu_silent": ("imu_stale", wd["imu_fault_cycles"]),
    }[kind]
    fault_name, threshold = expected
    injected = run.emu["faults"][0]
    t_inj = injected["applied_start_s"]
    tr = run.transition("fault")
    check(tr is not None and tr.get("fault") == fault_name,
          f"{kind} raises fault '{fault_name}' (got {tr.get('fault') if tr else 'no fault'})")
    if tr is None:
        return None
    row = run.cycle_row(tr["cycle"])
    t_fault = run.ipoc_to_t(run.cycles["ipoc"][row]) if row is not None else float("nan")
    cycles_after = round((t_fault - t_inj) / run.cycle_s)
    lost = kind in ("robot_drop", "robot_malformed")
    if lost:
        # Raised between messages, by the lost cycles themselves: the transition carries the
        # last good message's cycle, and no good message came between the injection and it.
        c = run.rt["cycles"]
        lost_seen = c["robot_timeouts"] + c["robot_malformed"]
        figure("robot_cycles_lost_counted", lost_seen)
        injected_cycles = run.scenario["fault"][0]["cycles"]
        if run.lockstep:
            # Exactly: a malformed datagram is one lost cycle; a silence of `gap` is as many
            # receive timeouts as fit in it (each restarts the wait; a datagram that comes at
            # the very moment of a timeout is received).
            if kind == "robot_malformed":
                want = {"robot_malformed": injected_cycles, "robot_timeouts": 0}
            else:
                gap = (injected_cycles + 1) * run.cycle_s
                timeout = run.emu["lockstep"]["rt_receive_timeout_s"]
                want = {"robot_malformed": 0,
                        "robot_timeouts": math.ceil(gap / timeout - 1e-9) - 1}
            got = {k: c[k] for k in want}
            figure("robot_lost_expected", want)
            check(got == want and sum(want.values()) >= threshold,
                  f"lost cycles counted exactly: {got} (computed {want}; fault at {threshold})")
        check(t_fault <= t_inj and lost_seen >= threshold,
              f"fault raised by {lost_seen} lost cycles before any further good datagram "
              f"(last good one at {t_fault:.3f} s)")
        faulted = np.nonzero(run.cycles["state"] == "fault")[0]
        t_first = run.ipoc_to_t(run.cycles["ipoc"][faulted[0]]) if len(faulted) else float("nan")
        cycles_after = round((t_first - t_inj) / run.cycle_s)
        check(cycles_after <= injected_cycles + 1,
              f"the robot's next datagram ({cycles_after} cycles after the injection) "
              f"is answered in fault")
    figure("fault", fault_name)
    figure("fault_cycles_after_injection", cycles_after)
    figure("fault_threshold_cycles", threshold)
    print(f"  injected at {t_inj:.3f} s, fault '{fault_name}' at {t_fault:.3f} s: {cycles_after} "
          f"robot cycles later (threshold {threshold})")
    if not lost and run.lockstep:
        want, why = lockstep_fault_cycle(run, kind, threshold)
        got = round(t_fault / run.cycle_s)
        figure("fault_cycle", got)
        figure("fault_cycle_expected", want)
        check(got == want, f"fault in the computed cycle: {got} ({why}: {want})")
    elif not lost:
        # Robot cycles from the injection to the fault. The robot watchdog counts lost cycles,
        # the sensor ones cycles without a valid sample; samples in flight and the delay of the
        # late datagrams add a few cycles on a real clock, documented in proto/loop.md.
        slack = {"robot_late": 6}.get(kind, 3)
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
        figure("black_box", f"dumped: {len(box['cycle'])} cycles, the last with `{box['fault'][-1]}`")
    if lost:
        figure("measured", f"fault `{fault_name}` at lost cycle {threshold}, before the next "
                           f"datagram; zero correction after")
    else:
        figure("measured", f"fault `{fault_name}` {cycles_after} cycles after the injection "
                           f"(threshold {threshold}); zero correction after")
    return tr, t_fault

# --- faults that are not faults of the loop, and the extra checks of some that are ------------

FLAG_FT_HELD, FLAG_IMU_HELD, FLAG_IPOC_GAP, FLAG_IPOC_STALE, FLAG_DELAY_GREW = 1, 2, 16, 32, 64
FLAG_TEMPERATURE_STALE = 32768  # loop::kTemperatureStale
# loop::kEstimatorSettling, kContactTaring ([filter] tare_s): zerog-rt's contact gate does not
# open on those rows.
FLAG_ESTIMATOR_SETTLING, FLAG_CONTACT_TARING = 65536, 131072
RKORR = ("rkorr_x_mm", "rkorr_y_mm", "rkorr_z_mm", "rkorr_a_deg", "rkorr_b_deg", "rkorr_c_deg")


def longest_run(mask):
    best = run_len = 0
    for m in mask:
        run_len = run_len + 1 if m else 0
        best = max(best, run_len)
    return best


def flagged(run, flag):
    return (run.cycles["flags"].astype(np.int64) & flag) != 0


def record_t(run):
    """Robot time of each record, from its IPOC (s since the emulator's first datagram)."""
    return run.ipoc_to_t(run.cycles["ipoc"])


def enable_cycle(run):
    tr = None
    for t in run.rt["transitions"]:
        if t["to"] == "zero_g":
            tr = t
    return tr


def stays_in_zero_g(run):
    """From the (last) enable on, every record in zero_g and no transition after it. Before the
    enable only the start-up faults that fault_peer.py reset as a PLC would are allowed."""
    tr = enable_cycle(run)
    if tr is None:
        check(False, "zero-g was never enabled")
        return None
    after = run.cycles["cycle"] >= tr["cycle"]
    states = run.cycles["state"][after]
    end = end_of_run_fault(run)
    later = [t for t in run.rt["transitions"] if t["cycle"] > tr["cycle"] and t is not end]
    if end is not None:
        states = run.cycles["state"][after & (run.cycles["cycle"] < end["cycle"])]
    earlier = [t for t in run.rt["transitions"] if t["cycle"] < tr["cycle"]]
    check(np.all(states == "zero_g") and not later,
          f"in zero_g in all {len(states)} cycles from the enable on, no transition after it "
          f"({[t.get('fault', t.get('command')) for t in later]})")
    if earlier:
        print(f"  note: before the enable (start-up, reset by the PLC): "
              f"{[t.get('fault', t.get('command')) for t in earlier]}")
    figure("startup_transitions", len(earlier))
    return tr


def no_fault_checks(run):
    t_en = common_checks(run)
    tr = stays_in_zero_g(run)
    end = end_of_run_fault(run)
    boxes = [b for b in run.rt["black_box_dumps"]
             if (tr is None or int(b.rsplit("blackbox-", 1)[1].split(".")[0]) >= tr["cycle"])
             and (end is None or not b.endswith(f"blackbox-{end['cycle']}.csv"))]
    check(not boxes, f"no black box dumped from the enable on ({boxes})")
    figure("fault", "none")
    figure("black_box", "none (no fault)")
    return t_en


def device_window(run):
    """Records whose IPOC falls in the device fault's time (from one cycle after its start, for
    the samples in flight), and as many cycles right before it in zero-g."""
    f = run.emu["faults"][0]
    t0, t1 = f["applied_start_s"], f["applied_end_s"]
    t_en = run.enabled_t()
    check(t_en is not None and t_en < t0, f"zero-g was on before the injection at {t0:.3f} s")
    t = record_t(run)
    during = (t >= t0 + run.cycle_s) & (t <= t1)
    before = (t >= max(t0 - (t1 - t0), t_en if t_en is not None else t0)) & (t < t0)
    return during, before


def case_ft_slow(run):
    """ft_slow within sample_timeout_ms: the samples come later, not fewer; at most a short hold,
    no fault, zero-g goes on."""
    no_fault_checks(run)
    f = run.emu["faults"][0]
    timeout = run.config["ft"]["sample_timeout_ms"]
    during, before = device_window(run)
    n_during = run.cycles["ft_samples"][during]
    n_before = run.cycles["ft_samples"][before]
    held = longest_run(flagged(run, FLAG_FT_HELD)[during])
    thr = run.config["watchdog"]["ft_fault_cycles"]
    figure("ft_response_delay_ms", f["response_delay_ms"])
    figure("ft_samples_per_cycle_before", float(n_before.mean()))
    figure("ft_samples_per_cycle_during", float(n_during.mean()))
    figure("ft_longest_hold_cycles", held)
    figure("ft_held_cycles", run.rt["cycles"]["ft_held_cycles"])
    figure("ft_timeouts", run.rt["devices"]["ft"]["timeouts"])
    check(f["response_delay_ms"] < timeout,
          f"the board answers {f['response_delay_ms']:g} ms late, inside sample_timeout_ms = {timeout:g}")
    with_sample = float(np.mean(n_during > 0)) if len(n_during) else 0.0
    figure("ft_cycles_with_sample_during", with_sample)
    check(len(n_during) > 50 and len(n_before) > 20,
          f"{len(n_during)} cycles during the slow answers, {len(n_before)} before")
    check(with_sample >= 0.5,
          f"the slow samples are used: {100 * with_sample:.0f} % of the cycles have one "
          f"({n_during.mean():.2f} per cycle during, {n_before.mean():.2f} before)")
    check(held < thr, f"longest F/T hold during it: {held} cycles (fault at {thr})")
    figure("measured", f"{n_during.mean():.2f} samples/cycle during ({n_before.mean():.2f} before); "
                       f"longest hold {held} cycles (fault at {thr}); no fault")


def case_ft_thermistor_silent(run):
    """The board leaves its thermistor reads unanswered, the samples go on: the held reading is
    used up to [ft] thermistor_max_age_s, then the model gets [model] temperature_C, every such
    cycle flagged kTemperatureStale and counted; the next answer makes it fresh again; no fault."""
    no_fault_checks(run)
    f = run.emu["faults"][0]
    t0, t1 = f["applied_start_s"], f["applied_end_s"]
    ft_cfg = run.config["ft"]
    period = ft_cfg.get("thermistor_period_s", 1.0)
    max_age = ft_cfg.get("thermistor_max_age_s", 3.0 * period)
    configured = run.config["model"].get("temperature_C", 25.0)
    t = record_t(run)
    stale = flagged(run, FLAG_TEMPERATURE_STALE)
    measured = run.cycles["temp_measured"] != 0
    ft = run.rt["devices"]["ft"]
    counted = run.rt["cycles"]["temperature_stale_cycles"]
    n = int(stale.sum())
    figure("thermistor_stale_cycles", n)
    figure("thermistor_expired", ft["thermistor_expired"])
    figure("thermistor_lost", ft["thermistor_lost"])
    check(n > 0, f"{n} cycles flagged kTemperatureStale")
    if n == 0:
        figure("measured", "no stale cycle")
        return
    idx = np.nonzero(stale)[0]
    t_first, t_last = t[idx[0]], t[idx[-1]]
    figure("thermistor_stale_after_s", t_first - t0)
    figure("thermistor_fresh_after_end_s", t_last - t1)
    check(idx[-1] - idx[0] + 1 == n, f"one stale spell: cycles {idx[0]}..{idx[-1]} all flagged")
    # The last reading before t0 came at most one period before it; stale max_age after it.
    check(t0 + max_age - period - 0.05 <= t_first <= t0 + max_age + 0.1,
          f"stale {t_first - t0:.3f} s after the reads stopped answering (max age {max_age:g} s, "
          f"read every {period:g} s)")
    # Answered again from t1 on: fresh with the next read, at most one period later.
    check(t1 - 0.05 <= t_last <= t1 + period + 0.1,
          f"fresh again {t_last - t1:.3f} s after the board answers again (read every {period:g} s)")
    check(counted == n, f"zerog-rt counted {counted} stale cycles, cycles.csv flags {n}")
    check(ft["thermistor_expired"] == 1 and ft["thermistor_lost"] >= int((t1 - t0) / period) - 1,
          f"thermistor_expired {ft['thermistor_expired']}, thermistor_lost {ft['thermistor_lost']}")
    temp = run.cycles["temp_C"]
    check(not measured[stale].any() and np.all(temp[stale] == configured),
          f"the stale cycles fed the configured {configured:g} °C, none measured")
    after = t > t_last
    check(after.any() and measured[after].all(),
          f"measured again in every cycle after the stale spell ({int(after.sum())} cycles)")
    before = (t > t0 - 1.0) & (t < t0)
    check(before.any() and measured[before].all() and not stale[before].any(),
          "measured, not stale, in the second before the injection")
    skipped = run.rt["recording"]["skipped_no_temperature"]
    check(skipped >= n, f"run.csv skipped the stale cycles ({skipped} rows without a temperature)")
    figure("measured", f"stale {t_first - t0:.2f} s after the reads stopped (max age {max_age:g} s), "
                       f"{n} cycles on the configured {configured:g} °C (counted {counted}, "
                       f"expired {ft['thermistor_expired']}); fresh {t_last - t1:.2f} s after they "
                       f"resumed; no fault")


def case_imu_gaps(run):
    """Every other STIM300 datagram left out: the gaps are counted, the rest averaged; no fault."""
    no_fault_checks(run)
    during, before = device_window(run)
    f = run.emu["faults"][0]
    imu = run.rt["devices"]["imu"]
    seconds = f["applied_end_s"] - f["applied_start_s"]
    n_during = run.cycles["imu_samples"][during]
    n_before = run.cycles["imu_samples"][before]
    check(len(n_during) > 50 and len(n_before) > 20,
          f"{len(n_during)} cycles during the gaps, {len(n_before)} before")
    ratio = n_during.mean() / n_before.mean() if len(n_during) and len(n_before) else float("nan")
    held = longest_run(flagged(run, FLAG_IMU_HELD)[during])
    thr = run.config["watchdog"]["imu_fault_cycles"]
    skipped = run.emu["devices"]["imu"]["skipped"]
    figure("imu_counter_gaps", imu["counter_gaps"])
    figure("imu_datagrams_missed", imu["datagrams_missed"])
    figure("imu_datagrams_left_out", skipped)
    figure("imu_samples_ratio", ratio)
    figure("imu_longest_hold_cycles", held)
    check(skipped >= 0.8 * 1000 * seconds, f"the emulator left out {skipped} datagrams in {seconds:.2f} s")
    check(imu["counter_gaps"] >= 0.8 * skipped and imu["datagrams_missed"] >= 0.8 * skipped
          and imu["crc_failures"] == 0,
          f"zerog-rt counted them: {imu['counter_gaps']} counter gaps, {imu['datagrams_missed']} "
          f"datagrams missed")
    check(0.35 <= ratio <= 0.65, f"and averaged the rest: {n_during.mean():.1f} IMU samples per cycle "
                                 f"during, {n_before.mean():.1f} before (×{ratio:.2f})")
    check(held < thr, f"longest IMU hold during it: {held} cycles (fault at {thr})")
    figure("measured", f"{imu['counter_gaps']} counter gaps, {imu['datagrams_missed']} datagrams "
                       f"missed counted; ×{ratio:.2f} samples/cycle; longest hold {held}; no fault")


def case_imu_crc(run):
    """Every datagram with a wrong CRC: counted, none used; held, then imu_stale."""
    res = case_fault(run, "fault_imu_crc")
    imu = run.rt["devices"]["imu"]
    bad = run.emu["devices"]["imu"]["bad_crc"]
    figure("imu_crc_failures", imu["crc_failures"])
    figure("imu_bad_crc_sent", bad)
    check(bad >= 1000, f"the emulator wrote {bad} datagrams with a wrong CRC")
    check(imu["crc_failures"] >= 0.8 * bad,
          f"zerog-rt counted {imu['crc_failures']} CRC failures of them")
    if res is None:
        return
    t_inj = run.emu["faults"][0]["applied_start_s"]
    t = record_t(run)
    _, t_fault = res
    sel = (t >= t_inj + 2 * run.cycle_s) & (t <= t_fault)
    used = int(run.cycles["imu_samples"][sel].sum())
    check(sel.any() and used == 0, f"none of them used: {used} IMU samples averaged in the "
                                   f"{int(sel.sum())} cycles from the injection to the fault")
    figure("measured", f"fault `imu_stale` {FIGURES.get('fault_cycles_after_injection')} cycles after; "
                       f"{imu['crc_failures']} CRC failures counted, 0 used")


def case_imu_unplug(run):
    """The tty hangs up: held, imu_stale, black box; then re-opened (counted), samples again."""
    res = case_fault(run, "fault_imu_unplug")
    imu = run.rt["devices"]["imu"]
    f = run.emu["faults"][0]
    figure("imu_disconnects", imu["thread_disconnects"])
    figure("imu_reopen_attempts", imu["reopen_attempts"])
    figure("imu_reopens", imu["reopens"])
    check(imu["disconnects"] >= 1 and imu["thread_disconnects"] >= 1,
          f"the hang-up seen: {imu['disconnects']} disconnects")
    check(imu["reopen_attempts"] >= 1 and imu["reopens"] >= 1,
          f"re-opened: {imu['reopen_attempts']} attempts, {imu['reopens']} re-opens")
    t = record_t(run)
    later = t >= f["applied_end_s"] + 0.3
    n_later = run.cycles["imu_samples"][later]
    check(len(n_later) > 20 and n_later.mean() > 5,
          f"samples again after the re-plug: {n_later.mean() if len(n_later) else 0:.1f} per cycle "
          f"in {len(n_later)} cycles")
    check(run.rt["fault"] == "imu_stale" and run.cycles["state"][-1] == "fault",
          "the fault stays until a reset")
    if res is not None:
        figure("measured", f"fault `imu_stale` {FIGURES.get('fault_cycles_after_injection')} cycles after; "
                           f"{imu['reopen_attempts']} re-open attempts, {imu['reopens']} re-opened, "
                           f"{n_later.mean():.1f} samples/cycle again")


def velocity(run, t0, t1):
    sel = run.window(t0, t1)
    return run.v_com[sel].mean(axis=0), int(sel.sum())


def case_robot_nofault(run, kind):
    """robot_duplicate, robot_reorder, robot_foreign during a float after a push: no fault,
    counted, every good datagram answered, and the part keeps J/m."""
    t_en = no_fault_checks(run)
    push = run.emu["pushes"][0]
    J = np.array(push["integrated_impulse_N_s"])
    v_exp = J / run.mass
    faults = [f for f in run.emu["faults"] if f["kind"] == kind]
    t_inj = faults[0]["applied_start_s"]
    t_end = max(f["applied_end_s"] for f in faults)
    check(t_en is not None and t_en < push["start_s"], "zero-g was on before the push")
    t_last = run.ipoc_to_t(run.cycles["ipoc"].max())
    v_before, _ = velocity(run, push["start_s"] + push["duration_s"] + 0.5, t_inj - 0.05)
    v_after, n_after = velocity(run, t_end + 0.3, min(t_end + 2.0, t_last))
    err = np.linalg.norm(v_after - v_exp) / np.linalg.norm(v_exp)
    err_before = np.linalg.norm(v_before - v_exp) / np.linalg.norm(v_exp)
    kick = np.linalg.norm(v_after - v_before) / np.linalg.norm(v_exp)
    figure("push_velocity_error_after", err)
    figure("velocity_change_by_the_fault", kick)
    if kind == "robot_reorder":
        # A swapped pair makes the robot catch up a missed step in one cycle: a jerk of the 100 kg
        # part whose inertial force the model does not cancel to the sample (F/T and IMU are
        # averaged over different sample sets), so some of it reaches the body as contact:
        # measured 0.2–1.1 % of J/m per pair (proto/loop.md). Bounded per pair.
        limit = 0.015 * len(faults)
        check(n_after > 50 and kick < limit,
              f"the pairs changed the part's velocity by {100 * kick:.2f} % of J/m (limit "
              f"{100 * limit:.1f} %: 1.5 % per pair; error to J/m {100 * err_before:.2f} % before, "
              f"{100 * err:.2f} % after)")
    else:
        check(n_after > 50 and err < 0.03,
              f"the part floats on at J/m after the fault: error {100 * err:.2f} % (limit 3 %; "
              f"before it {100 * err_before:.2f} %)")
    c = run.rt["cycles"]
    robot = run.rt["devices"]["robot"]
    rep = run.emu["replies"]
    stale = flagged(run, FLAG_IPOC_STALE)
    corr = np.stack([run.cycles[k] for k in RKORR], axis=1)
    prev_ipoc = np.concatenate([[0], run.cycles["ipoc"][:-1]])
    stale_zero = bool(np.all(corr[stale] == 0.0))
    stale_older = bool(np.all(run.cycles["ipoc"][stale] <= prev_ipoc[stale]))
    figure("ipoc_stale", c["ipoc_stale"])
    figure("ipoc_gaps", c["ipoc_gaps"])
    figure("datagrams_lost", c["datagrams_lost"])
    figure("foreign", robot["foreign"])
    if kind == "robot_duplicate":
        n = run.emu["datagrams"]["duplicated"]
        check(n == faults[0]["cycles"], f"the emulator sent {n} datagrams twice")
        check(c["ipoc_stale"] == n and int(stale.sum()) == n,
              f"each copy flagged IPOC stale: {c['ipoc_stale']} counted, {int(stale.sum())} records")
        check(stale_zero and stale_older, "every copy answered with a zero correction and its own "
                                          "(not newer) IPOC")
        check(rep["duplicate"] == n, f"the robot got a second reply for each: {rep['duplicate']}")
        check(c["ipoc_gaps"] == 0 and c["datagrams_lost"] == 0, "no IPOC gap, nothing lost")
        figure("measured", f"{c['ipoc_stale']} of {n} copies answered with zero (IPOC stale); "
                           f"velocity after {100 * err:.2f} % off J/m; no fault")
    elif kind == "robot_reorder":
        pairs = len(faults)
        held_ipocs = [run.first_ipoc + round(f["first_cycle"] * run.cycle_s * 1e3) for f in faults]
        rows = np.isin(run.truth["ipoc"].astype(np.int64), held_ipocs)
        late = int(np.sum(run.truth["reply"][rows] == "late"))
        grew = int(flagged(run, FLAG_DELAY_GREW).sum())
        check(all(f["cycles_affected"] == 1 for f in faults), f"{pairs} pairs swapped")
        check(c["ipoc_gaps"] == pairs and c["datagrams_lost"] == pairs,
              f"the newer one first: {c['ipoc_gaps']} IPOC gaps, {c['datagrams_lost']} datagrams "
              f"counted lost ({pairs} expected)")
        check(c["ipoc_stale"] == pairs and int(stale.sum()) == pairs and stale_zero and stale_older,
              f"the older one after it: {c['ipoc_stale']} IPOC stale, answered with zero")
        check(late == pairs, f"its reply reached the robot late: {late} of the {pairs} held "
                             f"datagrams answered late")
        check(longest_run(flagged(run, FLAG_DELAY_GREW)[~stale]) < run.config["watchdog"]["robot_late_cycles"],
              f"the robot's Delay grew in {grew} messages, never "
              f"{run.config['watchdog']['robot_late_cycles']} in a row")
        figure("replies_late_truth", late)
        figure("delay_grew", grew)
        figure("measured", f"{pairs} pairs: {c['ipoc_gaps']} gaps ({c['datagrams_lost']} lost), "
                           f"{c['ipoc_stale']} stale answered with zero, {late} late; the "
                           f"catch-up jerks changed the velocity by {100 * kick:.2f} % of J/m; "
                           f"no fault")
    elif kind == "robot_foreign":
        n = run.emu["datagrams"]["foreign"]
        check(n == faults[0]["cycles"], f"the emulator sent {n} datagrams from another port")
        check(robot["foreign"] == n, f"zerog-rt dropped and counted {robot['foreign']} of them")
        check(rep["to_foreign_socket"] == 0, f"none answered ({rep['to_foreign_socket']} replies "
                                              "to the foreign port)")
        check(c["ipoc_stale"] == 0 and c["ipoc_gaps"] == 0,
              f"none taken for the robot's (IPOC stale {c['ipoc_stale']}, gaps {c['ipoc_gaps']})")
        figure("measured", f"{robot['foreign']} of {n} dropped and counted, 0 answered; velocity "
                           f"after {100 * err:.2f} % off J/m; no fault")


def load_peer(run):
    try:
        with open(f"{run.dir}/plc.json") as f:
            peer = json.load(f)
    except OSError:
        check(False, "fault_peer.py wrote no plc.json")
        return None
    check(peer.get("ok"), f"fault_peer.py ran ({peer.get('error', 'all steps')})")
    return {s["step"]: s for s in peer.get("steps", [])} if peer.get("ok") else None


def cycle_window_checks(run, c0, c1, what):
    """Cycles c0..c1 (zerog-rt's cycle count, read over Modbus): zero-g, every datagram answered
    in time, no drift of the part."""
    sel = (run.cycles["cycle"] >= c0) & (run.cycles["cycle"] <= c1)
    ipocs = run.cycles["ipoc"][sel].astype(np.int64)
    rows = np.isin(run.truth["ipoc"].astype(np.int64), ipocs)
    replies = run.truth["reply"][rows]
    ok = int(np.sum(replies == "ok"))
    check(len(ipocs) > 20 and ok == len(replies),
          f"{what}: all {len(replies)} datagrams of cycles {c0}..{c1} answered in time ({ok} ok)")
    check(np.all(run.cycles["state"][sel] == "zero_g"), f"{what}: in zero_g throughout")
    t = run.ipoc_to_t(ipocs)
    p = run.p_com[run.window(t.min(), t.max())] if len(t) else np.zeros((1, 3))
    d = np.linalg.norm(p - p[0], axis=1).max()
    check(d < 1e-3, f"{what}: the part stays put ({d * 1e3:.3f} mm, limit 1 mm)")
    return len(replies), d


def case_peer(run, kind):
    """Modbus flood and stall, the DDS peer gone, the model file swapped: the cycle goes on."""
    no_fault_checks(run)
    steps = load_peer(run)
    if steps is None:
        return
    start, end = steps["before"]["cycle"], steps["end"]["cycle"]
    n, d = cycle_window_checks(run, start, end, "while the peer acts")
    figure("window_cycles", n)
    figure("window_drift_mm", d * 1e3)
    check(steps["end"]["state"] == 2 and steps["end"]["fault"] == 0,
          f"the PLC reads zero_g (2) and no fault at the end: state {steps['end']['state']}, "
          f"fault {steps['end']['fault']}")
    m = run.rt.get("modbus", {})
    figure("modbus", m)
    if kind == "modbus_flood":
        fl = steps["flood"]
        figure("flood_replies_per_s", fl["replies_per_s"])
        check(fl["replies_received"] >= 1000,
              f"the flood: {fl['replies_received']} replies in {fl['seconds']:.1f} s "
              f"({fl['replies_per_s']:.0f}/s)")
        check(fl["plc_reads_answered"] >= 10,
              f"the PLC answered during the flood: {fl['plc_reads_answered']} reads")
        check(m.get("requests", 0) >= fl["replies_received"],
              f"zerog-rt's server counted {m.get('requests')} requests")
        check(fl["extra_connections_closed_at_once"] == fl["extra_connections"] > 0
              and m.get("clients_refused_limit", 0) >= fl["extra_connections"],
              f"{fl['extra_connections']} connections beyond max_clients closed at once "
              f"({m.get('clients_refused_limit')} counted)")
        figure("measured", f"{fl['replies_received']} replies in {fl['seconds']:.1f} s "
                           f"({fl['replies_per_s']:.0f}/s), {m.get('clients_refused_limit')} "
                           f"connections refused; {n} cycles all answered in time, no fault")
    elif kind == "modbus_stall":
        st, deaf = steps["stall"], steps["deaf"]
        closed = st["closed_after_s"]
        rto = run.config["modbus"]["request_timeout_s"]
        ito = run.config["modbus"]["idle_timeout_s"]
        check(st["plc_reads_answered_during_stall"] >= 5,
              f"the PLC answered meanwhile: {st['plc_reads_answered_during_stall']} reads")
        halves = [closed.get("half_1"), closed.get("half_2")]
        check(all(isinstance(x, float) and rto - 0.1 <= x <= rto + 1.0 for x in halves),
              f"half requests closed after {halves} s (request_timeout_s = {rto:g})")
        sil = closed.get("silent")
        check(isinstance(sil, float) and ito - 0.1 <= sil <= ito + 1.5,
              f"the silent connection closed after {sil} s (idle_timeout_s = {ito:g})")
        check(m.get("request_timeouts", 0) >= 2 and m.get("idle_timeouts", 0) >= 1,
              f"counted: {m.get('request_timeouts')} request timeouts, {m.get('idle_timeouts')} "
              f"idle timeouts")
        check(deaf["plc_reads_answered"] >= 10,
              f"a client that never reads ({deaf['requests_sent']} requests) blocks no one: "
              f"{deaf['plc_reads_answered']} PLC reads answered meanwhile")
        figure("measured", f"half requests closed after {halves} s, silent after {sil} s; "
                           f"{m.get('send_errors')} send errors; PLC answered throughout; "
                           f"{n} cycles all in time, no fault")
    elif kind == "dds_peer_gone":
        k = steps["killed"]
        t = run.rt.get("telemetry", {})
        figure("telemetry", t)
        check(k["subscriber_was_running"] and k["bytes_received"] > 0,
              f"the subscriber received telemetry ({k['bytes_received']} bytes written), then "
              f"was killed")
        after = steps["after"]["after"]
        n2, _ = cycle_window_checks(run, k["before"]["cycle"], after["cycle"], "after the kill")
        pub, off = t.get("records_published", 0), t.get("records_offered", 0)
        check(off > 0 and pub >= 0.99 * off and t.get("write_errors", 1) == 0,
              f"zerog-rt went on publishing: {pub} of {off} records published, "
              f"{t.get('dropped')} dropped, {t.get('write_errors')} write errors")
        figure("measured", f"killed after receiving {k['bytes_received']} bytes of samples; "
                           f"{pub} of {off} records "
                           f"published, {t.get('dropped')} dropped; {n2} cycles after the kill "
                           f"all in time, no fault")
    elif kind == "model_swap":
        lo = steps["loaded"]
        crc = lo["file_crc32"]
        check(lo["register_crc32"] == crc, f"model_crc32 over Modbus = the deployed file's CRC "
                                           f"({lo['register_crc32']:#010x})")
        check(steps["overwritten"]["file_crc32"] != crc and steps["replaced"]["file_crc32"] != crc,
              "the file on disk changed twice (overwritten in place, then replaced)")
        regs = [steps["after_overwrite"]["model_crc32"], steps["after_replace"]["model_crc32"]]
        check(regs == [crc, crc], f"zerog-rt kept the model it loaded: model_crc32 "
                                  f"{[hex(r) for r in regs]} after each")
        check(all(steps[s]["state"] == 2 and steps[s]["fault"] == 0
                  for s in ("after_overwrite", "after_replace")), "in zero_g, no fault after each")
        figure("model_crc32", crc)
        figure("measured", f"model_crc32 {crc:#010x} before and after both swaps; part moved "
                           f"{d * 1e3:.3f} mm in {n} cycles; no fault")


EXTRA_FAULT_CASES = {
    "fault_ft_slow": case_ft_slow,
    "fault_ft_thermistor_silent": case_ft_thermistor_silent,
    "fault_imu_gaps": case_imu_gaps,
    "fault_imu_crc": case_imu_crc,
    "fault_imu_unplug": case_imu_unplug,
    "fault_robot_duplicate": lambda run: case_robot_nofault(run, "robot_duplicate"),
    "fault_robot_reorder": lambda run: case_robot_nofault(run, "robot_reorder"),
    "fault_robot_foreign": lambda run: case_robot_nofault(run, "robot_foreign"),
    "fault_modbus_flood": lambda run: case_peer(run, "modbus_flood"),
    "fault_modbus_stall": lambda run: case_peer(run, "modbus_stall"),
    "fault_dds_peer_gone": lambda run: case_peer(run, "dds_peer_gone"),
    "fault_model_swap": lambda run: case_peer(run, "model_swap"),
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", required=True)
    ap.add_argument("--dir", required=True)
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--rt-config", required=True)
    a = ap.parse_args()
    run = Run(a.dir, a.scenario, a.rt_config)
    print(f"{a.case}:")
    if len(run.cycles["cycle"]) == 0:
        check(False, "zerog-rt recorded no cycle")
    elif a.case in EXTRA_FAULT_CASES:
        EXTRA_FAULT_CASES[a.case](run)
    elif a.case.startswith("fault_"):
        case_fault(run, a.case)
    else:
        # CASE_elastic: the same scenario on the robot that is not rigid (proto/sim_robot.md),
        # held to the same checks.
        # CASE_fused: the same scenario with zerog-rt's motion estimator, and its noise check.
        FUSED["on"] = a.case.endswith("_fused")
        FUSED["elastic"] = a.case.endswith("_elastic_fused")
        base = a.case.removesuffix("_fused").removesuffix("_elastic")
        {"push": case_push, "drift": case_drift, "spin": case_spin, "tumble": case_tumble,
         "glide": case_glide, "nudge": case_nudge, "quiet": case_quiet,
         "supervisor": case_supervisor, "servo": case_servo, "hand": case_hand}[base](run)
        if FUSED["elastic"] and base in ("glide", "spin"):
            servo_checks(run)
    if run.lockstep:
        lockstep_checks(run, a.case)
    FIGURES["case"] = a.case
    FIGURES["mode"] = "lockstep" if run.lockstep else "realtime"
    FIGURES["passed"] = not FAILURES
    with open(f"{a.dir}/check.json", "w") as f:
        json.dump(FIGURES, f, indent=1)
    if FAILURES:
        print(f"{a.case}: {len(FAILURES)} check(s) failed")
        return 1
    print(f"{a.case}: passed")
    return 0


def lockstep_checks(run, case):
    """The lockstep itself (proto/lockstep.md): zerog-rt handled every event the emulator sent
    and stopped on its `end`; every F/T request had its sample; the sensor threads were done."""
    ls, le = run.rt.get("lockstep", {}), run.emu["lockstep"]
    check(ls.get("errors") == 0 and ls.get("ended") is True and ls.get("bad_messages") == 0,
          f"lockstep: zerog-rt handled every event and ended with the emulator "
          f"(errors {ls.get('errors')}, ended {ls.get('ended')}{', ' + ls['error'] if ls.get('error') else ''})")
    check(ls.get("events") == le["datagram_events"] + le["timeout_events"],
          f"lockstep: {ls.get('events')} events handled of {le['datagram_events']} datagrams + "
          f"{le['timeout_events']} timeouts sent")
    check(ls.get("sensor_waits_over") == 0, "lockstep: the sensor threads read every event's "
                                            f"production in time ({ls.get('sensor_waits_over')} late)")
    check(le["ft_queue_underruns"] == 0,
          f"lockstep: every F/T request had its sample ({le['ft_queue_underruns']} without)")
    ft = run.rt["devices"]["ft"]
    check(ft["timeouts"] == le["ft_requests_ignored"] and ft["stale_frames"] == 0,
          f"lockstep: an F/T request timed out only when the board ignored it ({ft['timeouts']} "
          f"timeouts, {le['ft_requests_ignored']} ignored, {ft['stale_frames']} stale frames)")
    if case != "fault_imu_unplug":
        check(ls.get("imu_rebases") == 0,
              f"lockstep: the IMU bytes read = the bytes written ({ls.get('imu_rebases')} re-based)")
    figure("lockstep_slowest_answer_s", le["slowest_answer_s"])
    figure("lockstep_receive_retries", ls.get("receive_retries"))


if __name__ == "__main__":
    sys.exit(main())
