#!/usr/bin/env python3
"""Checks what ros2_subscriber.py received on the rt/ topics against zerog-rt's cycles.csv.

Every topic must have delivered (best-effort streams: at least --min-fraction of the cycles);
each message is matched to its cycles.csv row by its header stamp (the cycle's t_s to the
nanosecond, proto/telemetry.md) and every field compared with the row: wrenches (measured, at
the model's row, predicted, contact) in the sensor frame, the IMU's specific force and rate, the
joints by name, the sensor's and the virtual body's pose and the body's velocity, each frame id,
and the diagnostics' last state and fault and the model's identity. Fails with a message naming
topic, field and cycle. Standard library only.
"""
import argparse
import csv
import json
import math
import sys

AXES = ["Fx_N", "Fy_N", "Fz_N", "Mx_Nm", "My_Nm", "Mz_Nm"]
STREAMS = ["wrench", "wrench_at_eval", "wrench_predicted", "wrench_contact", "imu",
           "joint_states", "sensor_pose", "body_pose", "body_twist"]
WRENCH_COLUMNS = {"wrench": "", "wrench_at_eval": "eval_", "wrench_predicted": "pred_",
                  "wrench_contact": "contact_"}


class Mismatch(Exception):
    pass


def stamp_ns(t_s):
    """The header stamp zerog-rt writes for robot time t_s (telemetry::ros_time)."""
    return math.floor(t_s * 1e9 + 0.5)


def same(topic, cycle, field, got, want):
    # cycles.csv holds the shortest text that reads back exactly: the values must be equal.
    if isinstance(want, float):
        if not (isinstance(got, (int, float)) and float(got) == want):
            raise Mismatch(f"{topic}.{field} at cycle {cycle}: got {got!r}, cycles.csv says {want!r}")
    elif got != want:
        raise Mismatch(f"{topic}.{field} at cycle {cycle}: got {got!r}, expected {want!r}")


def vec(m, names):
    return [m[n] for n in names]


def check_message(topic, m, row, frames, joint_names):
    c = row["cycle"]
    f = lambda field, got, want: same(topic, c, field, got, want)
    num = lambda col: float(row[col])
    h = m["header"]
    expect_frame = {"imu": frames["imu"], "joint_states": ""}.get(
        topic, frames["sensor"] if topic.startswith("wrench") else frames["base"])
    f("header.frame_id", h["frame_id"], expect_frame)
    if topic in WRENCH_COLUMNS:
        p = WRENCH_COLUMNS[topic]
        for i, axis in enumerate("xyz"):
            f(f"wrench.force.{axis}", m["wrench"]["force"][axis], num(p + AXES[i]))
            f(f"wrench.torque.{axis}", m["wrench"]["torque"][axis], num(p + AXES[3 + i]))
    elif topic == "imu":
        for axis in "xyz":
            f(f"linear_acceleration.{axis}", m["linear_acceleration"][axis],
              num(f"imu_f{axis}_mps2"))
            f(f"angular_velocity.{axis}", m["angular_velocity"][axis], num(f"imu_w{axis}_radps"))
        f("orientation_covariance[0]", m["orientation_covariance"][0], -1.0)
    elif topic == "joint_states":
        f("name", m["name"], joint_names)
        if len(m["position"]) != 6:
            raise Mismatch(f"joint_states.position at cycle {c}: {len(m['position'])} values, not 6")
        for i in range(6):
            f(f"position[{i}] ({joint_names[i]})", m["position"][i], num(f"q{i + 1}_rad"))
    elif topic in ("sensor_pose", "body_pose"):
        pre = "" if topic == "sensor_pose" else "body_"
        pos = ["px_m", "py_m", "pz_m"] if topic == "sensor_pose" else \
              ["body_px_m", "body_py_m", "body_pz_m"]
        for axis, col in zip("xyz", pos):
            f(f"pose.position.{axis}", m["pose"]["position"][axis], num(col))
        for axis in "xyzw":  # ROS's order (x, y, z, w); cycles.csv's qw, qx, qy, qz
            f(f"pose.orientation.{axis}", m["pose"]["orientation"][axis], num(f"{pre}q{axis}"))
    elif topic == "body_twist":
        for axis in "xyz":
            f(f"twist.linear.{axis}", m["twist"]["linear"][axis], num(f"body_v{axis}_mps"))
            if not math.isfinite(m["twist"]["angular"][axis]):
                raise Mismatch(f"body_twist.twist.angular.{axis} at cycle {c}: not finite")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--received", required=True, help="ros2_subscriber.py --out")
    ap.add_argument("--cycles", required=True, help="the cycles.csv zerog-rt wrote")
    ap.add_argument("--min-fraction", type=float, default=0.9)
    ap.add_argument("--expect-crc", type=lambda x: int(x, 0), default=None)
    ap.add_argument("--base-frame", default="base_link")
    ap.add_argument("--sensor-frame", default="ft_sensor")
    ap.add_argument("--imu-frame", default="imu_link")
    ap.add_argument("--joint-names", default="joint_a1,joint_a2,joint_a3,joint_a4,joint_a5,joint_a6")
    args = ap.parse_args()
    frames = {"base": args.base_frame, "sensor": args.sensor_frame, "imu": args.imu_frame}
    joint_names = args.joint_names.split(",")

    with open(args.cycles, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        sys.exit(f"check_ros2_telemetry: {args.cycles} has no rows")
    by_stamp = {}
    for r in rows:
        by_stamp.setdefault(stamp_ns(float(r["t_s"])), []).append(r)
    got = {}
    with open(args.received) as fh:
        for line in fh:
            item = json.loads(line)
            got.setdefault(item["topic"], []).append(item["msg"])
    errors = []
    for topic in STREAMS:
        seen = set()
        for m in got.get(topic, []):
            st = m["header"]["stamp"]
            ns = st["sec"] * 1_000_000_000 + st["nanosec"]
            candidates = by_stamp.get(ns)
            if not candidates:
                errors.append(f"{topic}: stamp {st['sec']}.{st['nanosec']:09d} is no cycle's t_s "
                              f"in {args.cycles}")
                continue
            failures = []
            for row in candidates:  # a stamp twice (a lost cycle keeps t_s): either row
                try:
                    check_message(topic, m, row, frames, joint_names)
                    seen.add(row["cycle"])
                    failures = []
                    break
                except Mismatch as e:
                    failures.append(str(e))
            errors.extend(failures[:1])
        fraction = len(seen) / len(rows)
        print(f"check_ros2_telemetry: rt {topic}: {len(got.get(topic, []))} messages, "
              f"{len(seen)} of {len(rows)} cycles ({100 * fraction:.1f} %)")
        if not got.get(topic):
            errors.append(f"{topic}: no message arrived (a type name or QoS ROS 2 would not match?)")
        elif fraction < args.min_fraction:
            errors.append(f"{topic}: only {len(seen)} of {len(rows)} cycles arrived "
                          f"(< {100 * args.min_fraction:.0f} %)")

    diagnostics = got.get("diagnostics", [])
    if not diagnostics:
        errors.append("diagnostics: no message arrived")
    else:
        last = diagnostics[-1]
        names = [s["name"] for s in last["status"]]
        if names != ["zerog-rt: health", "zerog-rt: model"]:
            errors.append(f"diagnostics: statuses {names}, expected zerog-rt: health and model")
        else:
            health = {kv["key"]: kv["value"] for kv in last["status"][0]["values"]}
            model = {kv["key"]: kv["value"] for kv in last["status"][1]["values"]}
            final = rows[-1]
            if health.get("cycle") != final["cycle"]:
                errors.append(f"diagnostics: the last message is of cycle {health.get('cycle')}, "
                              f"the log ends at {final['cycle']}")
            for key in ("state", "fault"):
                if health.get(key) != final[key]:
                    errors.append(f"diagnostics.{key} at cycle {final['cycle']}: got "
                                  f"{health.get(key)}, cycles.csv says {final[key]}")
            if int(health["records_published"]) + int(health["telemetry_drops"]) != \
                    int(health["records_offered"]):
                errors.append("diagnostics: records_published + telemetry_drops != records_offered")
            level = last["status"][0]["level"]
            if (final["state"] == "fault") != (level == 2):
                errors.append(f"diagnostics: level {level} in state {final['state']}")
            if args.expect_crc is not None and int(model.get("deploy_crc32", "0"), 16) != args.expect_crc:
                errors.append(f"diagnostics: model deploy_crc32 {model.get('deploy_crc32')}, "
                              f"expected {args.expect_crc:#010x}")
            if not model.get("rig_name") or not model.get("effects"):
                errors.append(f"diagnostics: model rig name or effects empty: {model}")
            print(f"check_ros2_telemetry: rt diagnostics: {len(diagnostics)} messages, last: "
                  f"{last['status'][0]['message']}, model {model.get('deploy_file')} "
                  f"{model.get('deploy_crc32')}")
    if errors:
        for e in errors[:20]:
            print("check_ros2_telemetry: FAIL: " + e, file=sys.stderr)
        if len(errors) > 20:
            print(f"check_ros2_telemetry: ... and {len(errors) - 20} more", file=sys.stderr)
        return 1
    print("check_ros2_telemetry: OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
