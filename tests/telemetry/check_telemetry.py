#!/usr/bin/env python3
"""Checks what dds_subscriber.py received against the cycles.csv zerog-rt logged.

Every topic must have arrived; each high-rate sample is matched to its cycles.csv row by
`cycle` and every field compared (the CSV holds the shortest text that reads back exactly, so
the tolerance is that of the unit conversions only). Health's and the model's content are
checked too. Fails with a message naming topic, field and cycle. Standard library only.
"""
import argparse
import csv
import json
import math
import sys

AXES = ["Fx_N", "Fy_N", "Fz_N", "Mx_Nm", "My_Nm", "Mz_Nm"]
STATES = ["idle", "collecting", "zero_g", "fault"]
FAULTS = ["none", "ft_stale", "ft_critical", "ft_saturated", "imu_stale", "robot_late",
          "contact_over_limit", "model_invalid"]
MODEL_STATUS = ["ok", "saturated", "non_finite", "not_configured"]
RAD_PER_DEG = math.pi / 180.0
FLAG_IPOC_GAP, FLAG_DELAY_GREW, FLAG_ROBOT_LOST = 1 << 4, 1 << 6, 1 << 10


class Mismatch(Exception):
    pass


def close(a, b, rel=1e-12, abs_=1e-12):
    return abs(a - b) <= abs_ + rel * max(abs(a), abs(b))


def check(topic, cycle, field, got, want, rel=1e-12):
    if isinstance(want, list):
        if len(got) != len(want):
            raise Mismatch(f"{topic}.{field} at cycle {cycle}: {len(got)} values, expected {len(want)}")
        for i, (g, w) in enumerate(zip(got, want)):
            check(topic, cycle, f"{field}[{i}]", g, w, rel)
        return
    if isinstance(want, float):
        if not close(float(got), want, rel):
            raise Mismatch(f"{topic}.{field} at cycle {cycle}: got {got!r}, cycles.csv says {want!r}")
    elif got != want:
        raise Mismatch(f"{topic}.{field} at cycle {cycle}: got {got!r}, cycles.csv says {want!r}")


def floats(row, names, scale=1.0):
    return [float(row[n]) * scale for n in names]


def check_sample(topic, s, row):
    c = s["cycle"]
    f = lambda field, want, rel=1e-12: check(topic, c, field, s[field], want, rel)
    f("t_s", float(row["t_s"]))
    if topic == "wrench":
        f("measured", floats(row, AXES))
        f("ft_samples", int(row["ft_samples"]))
        f("t_eval_s", float(row["t_eval_s"]))
        f("measured_at_eval", floats(row, ["eval_" + a for a in AXES]))
        f("predicted", floats(row, ["pred_" + a for a in AXES]))
        f("contact", floats(row, ["contact_" + a for a in AXES]))
        f("model_status", MODEL_STATUS.index(row["model_status"]))
        f("flags", int(row["flags"]))
    elif topic == "imu":
        f("specific_force_imu_mps2", floats(row, ["imu_fx_mps2", "imu_fy_mps2", "imu_fz_mps2"]))
        f("rate_imu_radps", floats(row, ["imu_wx_radps", "imu_wy_radps", "imu_wz_radps"]))
        f("imu_samples", int(row["imu_samples"]))
    elif topic == "robot":
        f("ipoc", int(row["ipoc"]))
        f("joints_rad", floats(row, [f"q{i}_rad" for i in range(1, 7)]))
        f("p_base_sensor_m", floats(row, ["px_m", "py_m", "pz_m"]))
        f("q_base_sensor_wxyz", floats(row, ["qw", "qx", "qy", "qz"]))
    elif topic == "command":
        f("dt_s", float(row["dt_s"]))
        f("axis_reply", row["axis_reply"] == "1")
        f("rkorr_translation_m", floats(row, ["rkorr_x_mm", "rkorr_y_mm", "rkorr_z_mm"], 1e-3), 1e-9)
        f("rkorr_abc_rad", floats(row, ["rkorr_a_deg", "rkorr_b_deg", "rkorr_c_deg"], RAD_PER_DEG), 1e-9)
        f("akorr_rad", floats(row, [f"akorr_a{i}_deg" for i in range(1, 7)], RAD_PER_DEG), 1e-9)
        f("v_world_mps", floats(row, ["body_vx_mps", "body_vy_mps", "body_vz_mps"]))
        f("limit_flags", int(row["limit_flags"]))
        if not all(math.isfinite(w) for w in s["omega_world_radps"]):
            raise Mismatch(f"command.omega_world_radps at cycle {c}: not finite")
    elif topic == "body":
        v = floats(row, ["body_vx_mps", "body_vy_mps", "body_vz_mps"])
        f("p_world_m", floats(row, ["body_px_m", "body_py_m", "body_pz_m"]))
        f("q_world_body_wxyz", floats(row, ["body_qw", "body_qx", "body_qy", "body_qz"]))
        f("v_world_mps", v)
        f("L_world_kgm2ps", floats(row, ["body_Lx_kgm2ps", "body_Ly_kgm2ps", "body_Lz_kgm2ps"]))
        m = s["mass_kg"]
        f("momentum_world_kgmps", [m * x for x in v], 1e-9)
        # The rotational part needs the inertia (not in cycles.csv): at least the linear part.
        linear = 0.5 * m * sum(x * x for x in v)
        if not (s["kinetic_energy_J"] >= linear * (1 - 1e-9)):
            raise Mismatch(f"body.kinetic_energy_J at cycle {c}: {s['kinetic_energy_J']} below "
                           f"the linear part {linear}")
    elif topic == "timing":
        flags = int(row["flags"])
        f("ipoc", int(row["ipoc"]))
        f("dt_s", float(row["dt_s"]))
        f("compute_s", int(row["compute_ns"]) * 1e-9, 1e-9)
        f("ipoc_gap", bool(flags & FLAG_IPOC_GAP))
        f("robot_late", bool(flags & FLAG_DELAY_GREW))
        f("robot_lost", bool(flags & FLAG_ROBOT_LOST))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--received", required=True, help="dds_subscriber.py --out")
    ap.add_argument("--cycles", required=True, help="the cycles.csv zerog-rt (or the replay) wrote")
    ap.add_argument("--min-fraction", type=float, default=0.9,
                    help="of the cycles every high-rate topic must have delivered (best-effort)")
    ap.add_argument("--expect-crc", type=lambda x: int(x, 0), default=None)
    args = ap.parse_args()

    with open(args.cycles, newline="") as fh:
        rows = {int(r["cycle"]): r for r in csv.DictReader(fh)}
    if not rows:
        sys.exit(f"check_telemetry: {args.cycles} has no rows")
    got = {}
    with open(args.received) as fh:
        for line_no, line in enumerate(fh, 1):
            item = json.loads(line)
            got.setdefault(item["topic"], []).append(item["sample"])
    errors = []
    for topic in ["wrench", "imu", "robot", "command", "body", "timing"]:
        samples = got.get(topic, [])
        seen = set()
        for s in samples:
            row = rows.get(s["cycle"])
            if row is None:
                errors.append(f"{topic}: cycle {s['cycle']} is not in {args.cycles}")
                continue
            try:
                check_sample(topic, s, row)
            except Mismatch as e:
                errors.append(str(e))
            seen.add(s["cycle"])
        fraction = len(seen) / len(rows)
        print(f"check_telemetry: {topic}: {len(seen)} of {len(rows)} cycles ({100 * fraction:.1f} %)")
        if fraction < args.min_fraction:
            errors.append(f"{topic}: only {len(seen)} of {len(rows)} cycles arrived "
                          f"(< {100 * args.min_fraction:.0f} %)")
    health = got.get("health", [])
    if not health:
        errors.append("health: no sample arrived")
    else:
        last = max(health, key=lambda h: h["health_seq"])
        row = rows.get(last["cycle"])
        if row is None:
            errors.append(f"health: last sample names cycle {last['cycle']}, not in {args.cycles}")
        else:
            for field, names in (("state", STATES), ("fault", FAULTS)):
                if names[last[field]] != row[field]:
                    errors.append(f"health.{field} at cycle {last['cycle']}: got "
                                  f"{names[last[field]]}, cycles.csv says {row[field]}")
        if last["cycle"] != max(rows):
            errors.append(f"health: the last sample is of cycle {last['cycle']}, the log ends at {max(rows)}")
        if last["records_published"] + last["telemetry_drops"] != last["records_offered"]:
            errors.append("health: records_published + telemetry_drops != records_offered")
        print(f"check_telemetry: health: {len(health)} samples, last {last}")
    models = got.get("model", [])
    if not models:
        errors.append("model: no sample arrived")
    else:
        m = models[-1]
        if not m["rig_name"] or not m["effects"]:
            errors.append(f"model: rig name or effects empty: {m}")
        if args.expect_crc is not None and m["deploy_crc32"] != args.expect_crc:
            errors.append(f"model.deploy_crc32: got {m['deploy_crc32']:#010x}, expected {args.expect_crc:#010x}")
        print(f"check_telemetry: model: rig {m['rig_name']}, effects {m['effects']}, crc {m['deploy_crc32']:#010x}")
    if errors:
        for e in errors[:20]:
            print("check_telemetry: FAIL: " + e, file=sys.stderr)
        if len(errors) > 20:
            print(f"check_telemetry: ... and {len(errors) - 20} more", file=sys.stderr)
        return 1
    print("check_telemetry: OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
