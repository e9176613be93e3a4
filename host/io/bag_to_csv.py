#!/usr/bin/env python3
"""ROS 2 bag (sqlite3 or MCAP) -> plain CSV files and a zerog import mapping (TOML).

`zerog import --bag` runs this with the project's venv python (rosbags from PyPI, no ROS
installation; scripts/install-deps.sh installs it) into a temporary directory, then imports the
mapping it writes (proto/ros2_bags.md).

Topics and what is taken from them (ROS messages are SI: N, N*m, m/s^2, rad/s, rad, m):
  --wrench  geometry_msgs/msg/WrenchStamped  force, torque in header.frame_id (the sensor frame)
                                             -> wrench.csv, the master file (its rows = log rows)
  --imu     sensor_msgs/msg/Imu              linear_acceleration (an accelerometer's specific
                                             force, +g up at rest), angular_velocity -> imu.csv
  --joints  sensor_msgs/msg/JointState       position of 6 joints (--joint-names, else the first
                                             six of the message) -> joints.csv
  --tf BASE:SENSOR  tf2_msgs/msg/TFMessage   on /tf and /tf_static: the chain from BASE to SENSOR,
                                             composed (dynamic links interpolated: linear and
                                             slerp) -> pose.csv (quaternion x, y, z, w as ROS)
Times are the messages' header.stamp (s); a zero stamp falls back to the bag's receive time.

Exit status: 0 written; 2 the bag or a topic cannot be used (message on stderr); 3 rosbags is
missing.
"""

import argparse
import bisect
import math
import sys
from pathlib import Path

try:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
except ImportError:  # pragma: no cover - exercised by zerog's error path
    sys.stderr.write(
        "bag_to_csv: the Python package 'rosbags' is missing from this interpreter "
        f"({sys.executable}); run scripts/install-deps.sh (it installs rosbags into the "
        "project's .venv)\n")
    sys.exit(3)

WRENCH = "geometry_msgs/msg/WrenchStamped"
IMU = "sensor_msgs/msg/Imu"
JOINTS = "sensor_msgs/msg/JointState"
TF = "tf2_msgs/msg/TFMessage"


class BagError(Exception):
    pass


def stamp_s(msg, receive_ns):
    st = msg.header.stamp
    if st.sec == 0 and st.nanosec == 0:
        return receive_ns * 1e-9
    return st.sec + st.nanosec * 1e-9


def connections(reader, topic, msgtype):
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        have = ", ".join(sorted(f"{c.topic} ({c.msgtype})" for c in reader.connections))
        raise BagError(f"topic {topic} is not in the bag; it has: {have}")
    for c in conns:
        if c.msgtype != msgtype:
            raise BagError(f"topic {topic} holds {c.msgtype}, not {msgtype}")
    return conns


def read_topic(reader, topic, msgtype):
    out = []
    for conn, t_ns, raw in reader.messages(connections=connections(reader, topic, msgtype)):
        out.append((t_ns, reader.deserialize(raw, conn.msgtype)))
    if not out:
        raise BagError(f"topic {topic} has no messages")
    return out


def strictly_increasing(rows, topic):
    rows.sort(key=lambda r: r[0])
    kept = [rows[0]]
    for r in rows[1:]:
        if r[0] > kept[-1][0]:
            kept.append(r)
    if len(kept) < len(rows):
        sys.stderr.write(f"bag_to_csv: {topic}: {len(rows) - len(kept)} messages with a repeated "
                         "stamp dropped\n")
    return kept


def write_csv(path, header, rows):
    with open(path, "w", encoding="utf-8") as f:
        f.write(",".join(header) + "\n")
        for r in rows:
            f.write(",".join(repr(float(v)) for v in r) + "\n")


def frame_of(messages, topic):
    frames = sorted({m.header.frame_id for _, m in messages})
    if len(frames) > 1:
        raise BagError(f"topic {topic} changes its header.frame_id: {frames}")
    return frames[0]


# --- quaternions (x, y, z, w as ROS) ---------------------------------------------------------
def qmul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def qrot(q, v):
    x, y, z, w = qmul(qmul(q, (v[0], v[1], v[2], 0.0)), (-q[0], -q[1], -q[2], q[3]))
    return (x, y, z)


def slerp(a, b, s):
    d = sum(x * y for x, y in zip(a, b))
    if d < 0:
        b, d = tuple(-x for x in b), -d
    if d > 0.9995:
        q = tuple(x + s * (y - x) for x, y in zip(a, b))
    else:
        th = math.acos(d)
        q = tuple((math.sin((1 - s) * th) * x + math.sin(s * th) * y) / math.sin(th)
                  for x, y in zip(a, b))
    n = math.sqrt(sum(x * x for x in q))
    return tuple(x / n for x in q)


class Edge:
    """One parent -> child transform: static, or a time series."""

    def __init__(self):
        self.t, self.p, self.q = [], [], []
        self.static = False

    def add(self, t, p, q, static):
        self.static = self.static or static
        self.t.append(t)
        self.p.append(p)
        self.q.append(q)

    def finish(self):
        order = sorted(range(len(self.t)), key=lambda i: self.t[i])
        self.t = [self.t[i] for i in order]
        self.p = [self.p[i] for i in order]
        self.q = [self.q[i] for i in order]

    def at(self, t):
        if self.static or len(self.t) == 1:
            return self.p[-1], self.q[-1]
        if t < self.t[0] or t > self.t[-1]:
            return None
        k = bisect.bisect_left(self.t, t)
        if self.t[k] == t:
            return self.p[k], self.q[k]
        s = (t - self.t[k - 1]) / (self.t[k] - self.t[k - 1])
        p = tuple(a + s * (b - a) for a, b in zip(self.p[k - 1], self.p[k]))
        return p, slerp(self.q[k - 1], self.q[k], s)


def tf_chain(reader, base, sensor):
    edges, parent = {}, {}
    for topic, static in (("/tf", False), ("/tf_static", True)):
        conns = [c for c in reader.connections if c.topic == topic]
        for c in conns:
            if c.msgtype != TF:
                raise BagError(f"topic {topic} holds {c.msgtype}, not {TF}")
        for conn, t_ns, raw in reader.messages(connections=conns):
            for ts in reader.deserialize(raw, conn.msgtype).transforms:
                p_name, c_name = ts.header.frame_id.lstrip("/"), ts.child_frame_id.lstrip("/")
                if parent.get(c_name, p_name) != p_name:
                    raise BagError(f"frame {c_name} has two parents: {parent[c_name]} and "
                                   f"{p_name}")
                parent[c_name] = p_name
                tr, ro = ts.transform.translation, ts.transform.rotation
                edges.setdefault((p_name, c_name), Edge()).add(
                    stamp_s(ts, t_ns), (tr.x, tr.y, tr.z), (ro.x, ro.y, ro.z, ro.w), static)
    if not edges:
        raise BagError("--tf: the bag has no /tf or /tf_static messages")
    chain, frame = [], sensor
    while frame != base:
        if frame not in parent:
            known = ", ".join(sorted(set(parent) | set(parent.values())))
            raise BagError(f"--tf {base}:{sensor}: no transform chain from {base} to {sensor} "
                           f"(stops at {frame}); frames in the bag: {known}")
        chain.append(edges[(parent[frame], frame)])
        frame = parent[frame]
        if len(chain) > 64:
            raise BagError("--tf: the transform tree has a cycle")
    chain.reverse()  # base first
    for e in chain:
        e.finish()
    return chain


def compose(chain, t):
    p, q = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)
    for e in chain:
        pq = e.at(t)
        if pq is None:
            return None
        ep, eq = pq
        r = qrot(q, ep)
        p = (p[0] + r[0], p[1] + r[1], p[2] + r[2])
        q = qmul(q, eq)
    return p, q


MAPPING_HEAD = """# Written by zerog import --bag (host/io/bag_to_csv.py) from {bag}
format = "zerog-import"
version = 1
master = "wrench"
"""


def convert(a):
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    notes = []
    with AnyReader([Path(a.bag)], default_typestore=typestore) as reader:
        wrench = read_topic(reader, a.wrench, WRENCH)
        wrench_frame = frame_of(wrench, a.wrench)
        rows = [(stamp_s(m, t), m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
                 m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z) for t, m in wrench]
        rows = strictly_increasing(rows, a.wrench)
        write_csv(out / "wrench.csv", ["t_s", "fx", "fy", "fz", "tx", "ty", "tz"], rows)
        t_first, t_last = rows[0][0], rows[-1][0]
        mapping = MAPPING_HEAD.format(bag=a.bag)
        mapping += f"""
# {a.wrench}: {len(rows)} messages, frame '{wrench_frame}'
[files.wrench]
path = "wrench.csv"
time = {{ column = "t_s", unit = "s" }}
force = {{ columns = ["fx", "fy", "fz"], unit = "N" }}
torque = {{ columns = ["tx", "ty", "tz"], unit = "N*m" }}
"""
        if a.imu:
            imu = read_topic(reader, a.imu, IMU)
            imu_frame = frame_of(imu, a.imu)
            rows = [(stamp_s(m, t), m.linear_acceleration.x, m.linear_acceleration.y,
                     m.linear_acceleration.z, m.angular_velocity.x, m.angular_velocity.y,
                     m.angular_velocity.z) for t, m in imu]
            rows = strictly_increasing(rows, a.imu)
            write_csv(out / "imu.csv", ["t_s", "ax", "ay", "az", "wx", "wy", "wz"], rows)
            if imu_frame and wrench_frame and imu_frame != wrench_frame:
                notes.append(f"the IMU is in frame '{imu_frame}', the wrench in "
                             f"'{wrench_frame}': the rig's IMU mounting must describe "
                             f"'{imu_frame}' in '{wrench_frame}'")
            mapping += f"""
# {a.imu}: {len(rows)} messages, frame '{imu_frame}'
[files.imu]
path = "imu.csv"
time = {{ column = "t_s", unit = "s" }}
specific_force = {{ columns = ["ax", "ay", "az"], unit = "m/s^2" }}
angular_rate = {{ columns = ["wx", "wy", "wz"], unit = "rad/s" }}
"""
        if a.joints:
            joints = read_topic(reader, a.joints, JOINTS)
            names = a.joint_names.split(",") if a.joint_names else list(joints[0][1].name[:6])
            if len(names) != 6:
                raise BagError(f"{a.joints}: zerog takes 6 joints (A1..A6); the message names "
                               f"{list(joints[0][1].name)} (choose with --joint-names)")
            rows = []
            for t, m in joints:
                index = {n: i for i, n in enumerate(m.name)}
                missing = [n for n in names if n not in index]
                if missing:
                    raise BagError(f"{a.joints}: joints {missing} not in a message that names "
                                   f"{list(m.name)}")
                rows.append((stamp_s(m, t), *(m.position[index[n]] for n in names)))
            rows = strictly_increasing(rows, a.joints)
            write_csv(out / "joints.csv", ["t_s"] + [f"q{i + 1}" for i in range(6)], rows)
            mapping += f"""
# {a.joints}: {len(rows)} messages, joints A1..A6 = {names}
[files.joints]
path = "joints.csv"
time = {{ column = "t_s", unit = "s" }}
joints = {{ columns = ["q1", "q2", "q3", "q4", "q5", "q6"], unit = "rad" }}
"""
        if a.tf:
            base, _, sensor = a.tf.partition(":")
            if not base or not sensor:
                raise BagError(f"--tf wants BASE:SENSOR (two frame names), not '{a.tf}'")
            if wrench_frame and wrench_frame.lstrip("/") == base:
                raise BagError(f"the wrench is in the base frame '{base}' already: zerog import "
                               "reads wrenches in the sensor frame (record the sensor's own "
                               "frame)")
            if wrench_frame and wrench_frame.lstrip("/") != sensor:
                raise BagError(f"--tf {a.tf}: the wrench is measured in frame "
                               f"'{wrench_frame}', not '{sensor}': give --tf "
                               f"{base}:{wrench_frame} (the pose is of the wrench's frame)")
            chain = tf_chain(reader, base, sensor)
            dynamic = [e for e in chain if not e.static and len(e.t) > 1]
            # Rows at the stamps of the dynamic links (all of them: each link is interpolated at
            # the others' stamps); a chain of static links gives a constant pose over the wrench.
            times = sorted({t for e in dynamic for t in e.t}) or [t_first, t_last]
            rows = []
            for t in times:
                pq = compose(chain, t)
                if pq is not None:
                    rows.append((t, *pq[0], *pq[1]))
            if not rows:
                raise BagError(f"--tf {a.tf}: the links of the chain never overlap in time")
            if len(rows) == 1:
                rows.append((rows[0][0] + max(t_last - t_first, 1.0), *rows[0][1:]))
            write_csv(out / "pose.csv", ["t_s", "px", "py", "pz", "qx", "qy", "qz", "qw"], rows)
            mapping += f"""
# /tf, /tf_static: {base} -> {sensor}, {len(chain)} links ({len(dynamic)} moving), {len(rows)} rows
[files.pose]
path = "pose.csv"
time = {{ column = "t_s", unit = "s" }}
position = {{ columns = ["px", "py", "pz"], unit = "m" }}
orientation = {{ type = "quaternion", order = "xyzw", columns = ["qx", "qy", "qz", "qw"] }}
"""
    (out / "mapping.toml").write_text(mapping, encoding="utf-8")
    for n in notes:
        sys.stderr.write(f"bag_to_csv: note: {n}\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bag", required=True, help="ROS 2 bag directory (or .db3 / .mcap file)")
    ap.add_argument("--out", required=True, help="directory for the CSV files and mapping.toml")
    ap.add_argument("--wrench", required=True, help="geometry_msgs/msg/WrenchStamped topic")
    ap.add_argument("--imu", help="sensor_msgs/msg/Imu topic")
    ap.add_argument("--joints", help="sensor_msgs/msg/JointState topic")
    ap.add_argument("--joint-names", help="the 6 joint names A1..A6, comma-separated")
    ap.add_argument("--tf", help="BASE:SENSOR frames of the pose, from /tf and /tf_static")
    a = ap.parse_args()
    try:
        convert(a)
    except BagError as e:
        sys.stderr.write(f"bag_to_csv: {a.bag}: {e}\n")
        sys.exit(2)
    except Exception as e:  # a bag rosbags cannot read: say which and why
        sys.stderr.write(f"bag_to_csv: {a.bag}: cannot read the bag: {type(e).__name__}: {e}\n")
        sys.exit(2)


if __name__ == "__main__":
    main()
