#!/usr/bin/env python3
"""zerog-rt's recording (--record DIR) -> one MCAP file with ROS 2's message types.

`zerog export-mcap` runs this with the project's venv python (PyPI's `mcap` writes the file,
`rosbags` serialises the messages and gives the ROS 2 message definitions; no ROS installation).
proto/ros2_bags.md ("MCAP from a recording") is the reference: every cycle of cycles.csv on the
same ROS topics and types as zerog-rt's live rt/ topics (proto/telemetry.md, "ROS 2 topics"),
header stamps the cycle's robot time t_s to the nanosecond, the sensor pose also on /tf (so that
`zerog import --bag FILE --tf BASE:SENSOR` reads it back), the IMU's mounting on /tf_static, the
rig file (and the deployed model, --model) as MCAP attachments and the session's identity as MCAP
metadata. Errors name the file and line; never writes over a file unless --force.
"""
import argparse
import csv
import hashlib
import math
import os
import sys
import tomllib
from pathlib import Path

try:
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore
except ImportError as e:  # pragma: no cover - the message is the point
    sys.exit(f"record_to_mcap: {e.name} is missing: run scripts/install-deps.sh (it installs "
             "PyPI's mcap and rosbags into the project's .venv)")

STORE = Stores.ROS2_HUMBLE
AXES = ["Fx_N", "Fy_N", "Fz_N", "Mx_Nm", "My_Nm", "Mz_Nm"]


class ExportError(Exception):
    pass


def stamp_ns(t_s):
    """telemetry::ros_time: the nearest nanosecond of robot time t_s."""
    return math.floor(t_s * 1e9 + 0.5)


class Out:
    """The MCAP writer with one channel per topic (schemas: rosbags' ROS 2 definitions)."""

    def __init__(self, fh, typestore):
        self.ts = typestore
        # Uncompressed: every MCAP reader opens it without a codec package.
        self.w = Writer(fh, compression=CompressionType.NONE)
        self.w.start(profile="ros2", library="zerog export-mcap")
        self.schemas, self.channels, self.counts = {}, {}, {}

    def channel(self, topic, msgtype, qos=""):
        if topic not in self.channels:
            if msgtype not in self.schemas:
                text, _ = self.ts.generate_msgdef(msgtype, ros_version=2)
                self.schemas[msgtype] = self.w.register_schema(
                    name=msgtype, encoding="ros2msg", data=text.encode())
            meta = {"offered_qos_profiles": qos} if qos else {}
            self.channels[topic] = self.w.register_channel(
                topic=topic, message_encoding="cdr", schema_id=self.schemas[msgtype],
                metadata=meta)
            self.counts[topic] = 0
        return self.channels[topic]

    def write(self, topic, msgtype, msg, ns, qos=""):
        data = bytes(self.ts.serialize_cdr(msg, msgtype))
        self.w.add_message(channel_id=self.channel(topic, msgtype, qos), log_time=ns,
                           publish_time=ns, data=data, sequence=self.counts[topic])
        self.counts[topic] += 1


# rosbag2's QoS metadata (YAML), so `ros2 bag play` offers what zerog-rt offers live.
SENSOR_QOS = ("- history: 1\n  depth: 5\n  reliability: 2\n  durability: 2\n  deadline:\n"
              "    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n"
              "    nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n"
              "    sec: 2147483647\n    nsec: 4294967295\n  avoid_ros_namespace_conventions: false\n")
LATCHED_QOS = SENSOR_QOS.replace("depth: 5", "depth: 1").replace("reliability: 2",
                                                                  "reliability: 1").replace(
    "durability: 2", "durability: 1")


def read_cycles(path):
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None:
            raise ExportError(f"{path}:1: empty (no header)")
        rows = []
        for line_no, cells in enumerate(reader, 2):
            if len(cells) != len(header):
                raise ExportError(f"{path}:{line_no}: {len(cells)} cells, the header has "
                                  f"{len(header)}")
            rows.append((line_no, dict(zip(header, cells))))
    need = ["cycle", "t_s", "state", "fault", "flags", "qw", "qx", "qy", "qz", "px_m", "body_qw",
            "body_vx_mps", "imu_fx_mps2", "q1_rad", "eval_Fx_N"] + AXES
    missing = [c for c in need if c not in header]
    if missing:
        raise ExportError(f"{path}:1: no column {', '.join(missing)} (not a zerog-rt cycles.csv?)")
    return rows


def convert(a):
    record = Path(a.record)
    cycles_path, rig_path = record / "cycles.csv", record / "run.rig.toml"
    for p in (cycles_path, rig_path):
        if not p.is_file():
            raise ExportError(f"{p}: missing (a zerog-rt --record folder has cycles.csv, run.csv "
                              "and run.rig.toml)")
    out = Path(a.out) if a.out else record / "run.mcap"
    if out.exists() and not a.force:
        raise ExportError(f"{out}: exists already; zerog export-mcap never writes over a file "
                          "(--force, or -o another file)")
    rig_bytes = rig_path.read_bytes()
    try:
        rig = tomllib.loads(rig_bytes.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ExportError(f"{rig_path}: {e}")
    rows = read_cycles(cycles_path)
    if not rows:
        raise ExportError(f"{cycles_path}: no cycles")
    model_bytes = Path(a.model).read_bytes() if a.model else None
    joint_names = a.joint_names.split(",")
    if len(joint_names) != 6:
        raise ExportError(f"--joint-names: {len(joint_names)} names, A1..A6 need 6")

    ts = get_typestore(STORE)
    T = ts.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    V3, Wrench = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Wrench"]
    Point, Quat, Pose = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"], \
        T["geometry_msgs/msg/Pose"]
    Transform, TS = T["geometry_msgs/msg/Transform"], T["geometry_msgs/msg/TransformStamped"]
    KV, DS = T["diagnostic_msgs/msg/KeyValue"], T["diagnostic_msgs/msg/DiagnosticStatus"]
    import numpy as np

    ns_prefix = a.namespace.rstrip("/") + "/"
    WS, IMU, JS, PS = ("geometry_msgs/msg/WrenchStamped", "sensor_msgs/msg/Imu",
                       "sensor_msgs/msg/JointState", "geometry_msgs/msg/PoseStamped")
    TF, DA = "tf2_msgs/msg/TFMessage", "diagnostic_msgs/msg/DiagnosticArray"
    TEMP = "sensor_msgs/msg/Temperature"

    def header(ns, frame):
        return Header(stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000),
                      frame_id=frame)

    def transform(parent, child, ns, p, q_wxyz):
        return TS(header=header(ns, parent), child_frame_id=child,
                  transform=Transform(translation=V3(x=p[0], y=p[1], z=p[2]),
                                      rotation=Quat(x=q_wxyz[1], y=q_wxyz[2], z=q_wxyz[3],
                                                    w=q_wxyz[0])))

    tmp = out.with_name(out.name + ".partial")
    with open(tmp, "wb") as fh:
        o = Out(fh, ts)
        # The session's identity; the rig and the model as attachments (byte for byte).
        first_ns = stamp_ns(float(rows[0][1]["t_s"]))
        o.w.add_metadata(name="zerog", data={
            "source": "zerog-rt --record", "record_dir": str(record.resolve()),
            "rig_name": str(rig.get("name", "")), "cycles": str(len(rows)),
            "stamps": "robot time t_s since the first datagram (proto/telemetry.md)",
            "ros_distro_definitions": STORE.name.lower(),
            "base_frame": a.base_frame, "sensor_frame": a.sensor_frame, "imu_frame": a.imu_frame,
            "model_file": os.path.basename(a.model) if a.model else "",
            "model_sha256": hashlib.sha256(model_bytes).hexdigest() if model_bytes else ""})
        o.w.add_attachment(create_time=0, log_time=first_ns, name="run.rig.toml",
                           media_type="application/toml", data=rig_bytes)
        if model_bytes is not None:
            o.w.add_attachment(create_time=0, log_time=first_ns, name=os.path.basename(a.model),
                               media_type="application/octet-stream", data=model_bytes)
        # The IMU's mounting in S (proto/frames.md). Not the sensor's on the flange: in a TF tree a
        # frame has one parent, and the sensor's is the base (the recorded pose on /tf, which
        # the robot's kinematics cannot reproduce to the digit); the rig attachment has it.
        static = []
        for key, parent, child in (("sensor_imu", a.sensor_frame, a.imu_frame),):
            if key in rig:
                static.append(transform(parent, child, first_ns, rig[key]["p_m"],
                                        rig[key]["q_wxyz"]))
        if static:
            o.write("/tf_static", TF, T[TF](transforms=static), first_ns, LATCHED_QOS)

        # A test hook only (tests/hil/mcap_roundtrip.py --mutant): the wrench's Fx and Fy
        # swapped, which the round trip must catch.
        swap = os.environ.get("ZEROG_MCAP_TEST_MUTANT") == "swap_fx_fy"
        last_state = None
        for line_no, r in rows:
            try:
                f = lambda col: float(r[col])
                ns = stamp_ns(f("t_s"))
                for topic, pre in (("wrench", ""), ("wrench_at_eval", "eval_"),
                                   ("wrench_predicted", "pred_"), ("wrench_contact", "contact_")):
                    w = [f(pre + c) for c in AXES]
                    if swap and topic == "wrench":
                        w[0], w[1] = w[1], w[0]
                    o.write(ns_prefix + topic, WS, T[WS](
                        header=header(ns, a.sensor_frame),
                        wrench=Wrench(force=V3(x=w[0], y=w[1], z=w[2]),
                                      torque=V3(x=w[3], y=w[4], z=w[5]))), ns, SENSOR_QOS)
                cov = np.zeros(9)
                no_orientation = cov.copy()
                no_orientation[0] = -1.0
                o.write(ns_prefix + "imu", IMU, T[IMU](
                    header=header(ns, a.imu_frame), orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=no_orientation,
                    angular_velocity=V3(x=f("imu_wx_radps"), y=f("imu_wy_radps"),
                                        z=f("imu_wz_radps")),
                    angular_velocity_covariance=cov,
                    linear_acceleration=V3(x=f("imu_fx_mps2"), y=f("imu_fy_mps2"),
                                           z=f("imu_fz_mps2")),
                    linear_acceleration_covariance=cov), ns, SENSOR_QOS)
                o.write(ns_prefix + "joint_states", JS, T[JS](
                    header=header(ns, ""), name=joint_names,
                    position=np.array([f(f"q{i}_rad") for i in range(1, 7)]),
                    velocity=np.zeros(0), effort=np.zeros(0)), ns, SENSOR_QOS)
                p = [f("px_m"), f("py_m"), f("pz_m")]
                q = [f("qw"), f("qx"), f("qy"), f("qz")]
                o.write(ns_prefix + "sensor_pose", PS, T[PS](
                    header=header(ns, a.base_frame),
                    pose=Pose(position=Point(x=p[0], y=p[1], z=p[2]),
                              orientation=Quat(x=q[1], y=q[2], z=q[3], w=q[0]))), ns, SENSOR_QOS)
                o.write("/tf", TF, T[TF](transforms=[transform(a.base_frame, a.sensor_frame, ns,
                                                               p, q)]), ns)
                o.write(ns_prefix + "body_pose", PS, T[PS](
                    header=header(ns, a.base_frame),
                    pose=Pose(position=Point(x=f("body_px_m"), y=f("body_py_m"),
                                             z=f("body_pz_m")),
                              orientation=Quat(x=f("body_qx"), y=f("body_qy"), z=f("body_qz"),
                                               w=f("body_qw")))), ns, SENSOR_QOS)
                if r.get("temp_measured") == "1":  # the F/T sensor's thermistor, when read
                    o.write(ns_prefix + "temperature", TEMP, T[TEMP](
                        header=header(ns, a.sensor_frame), temperature=f("temp_C"),
                        variance=0.0), ns, SENSOR_QOS)
                state = (r["state"], r["fault"])
                if state != last_state:  # the diagnostics zerog-rt publishes on every change
                    values = [KV(key=k, value=r[k]) for k in ("cycle", "t_s", "state", "fault",
                                                               "flags")]
                    level = 2 if r["state"] == "fault" else 0
                    o.write(ns_prefix + "diagnostics", DA, T[DA](
                        header=header(ns, ""),
                        status=[DS(level=level, name="zerog-rt: health",
                                   message=f"state {r['state']}, fault {r['fault']}",
                                   hardware_id=str(rig.get("name", "")), values=values)]),
                        ns, LATCHED_QOS)
                    last_state = state
            except (KeyError, ValueError) as e:
                raise ExportError(f"{cycles_path}:{line_no}: {e}")
        o.w.finish()
    tmp.replace(out)
    print(f"record_to_mcap: {out}: {len(rows)} cycles, " +
          ", ".join(f"{t} {n}" for t, n in o.counts.items()) +
          f"; attachments run.rig.toml{', ' + os.path.basename(a.model) if a.model else ''}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("record", help="zerog-rt's --record folder (cycles.csv, run.rig.toml)")
    ap.add_argument("-o", "--out", default="", help="the MCAP file (default: RECORD/run.mcap)")
    ap.add_argument("--force", action="store_true", help="write over --out")
    ap.add_argument("--model", default="", help="the deployed model zerog-rt ran (attached)")
    ap.add_argument("--namespace", default="/zerog")
    ap.add_argument("--base-frame", default="base_link")
    ap.add_argument("--sensor-frame", default="ft_sensor")
    ap.add_argument("--imu-frame", default="imu_link")
    ap.add_argument("--joint-names", default="joint_a1,joint_a2,joint_a3,joint_a4,joint_a5,joint_a6")
    a = ap.parse_args()
    try:
        convert(a)
    except (ExportError, OSError) as e:
        sys.stderr.write(f"zerog export-mcap: {e}\n")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
