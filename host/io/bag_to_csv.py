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
  --joints  sensor_msgs/msg/JointState       position of the robot's joints, by name (the robot's
                                             ros_name or name, or --joint-names) -> joints.csv
  --tf BASE:SENSOR  tf2_msgs/msg/TFMessage   on /tf and /tf_static: the chain from BASE to SENSOR,
                                             composed (dynamic links interpolated: linear and
                                             slerp) -> pose.csv (quaternion x, y, z, w as ROS)
The rig goes into the mapping as its [rig] table: the user's --rig (if any) with what the bag
says filled in or checked against it: the sensor on the flange (TF from the robot's flange frame,
--flange or the robot file's ros_flange, to the wrench's frame), the IMU in the sensor (TF from
the wrench's frame to the IMU's), the robot (--robot), the native rates (from the stamps).
Times are the messages' header.stamp (s); a zero stamp falls back to the bag's receive time.
Frame names are compared without a leading '/' (ROS 1's tf_prefix habit).

Exit status: 0 written; 2 the bag or a topic cannot be used (message on stderr); 3 rosbags is
missing.
"""

import argparse
import bisect
import math
import statistics
import sys
import tomllib
from pathlib import Path

try:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    import tomli_w
except ImportError as missing:  # pragma: no cover - exercised by zerog's error path
    sys.stderr.write(
        f"bag_to_csv: the Python package '{missing.name}' is missing from this interpreter "
        f"({sys.executable}); run scripts/install-deps.sh (it installs rosbags and tomli-w "
        "into the project's .venv)\n")
    sys.exit(3)

WRENCH = "geometry_msgs/msg/WrenchStamped"
IMU = "sensor_msgs/msg/Imu"
JOINTS = "sensor_msgs/msg/JointState"
TEMPERATURE = "sensor_msgs/msg/Temperature"
TF = "tf2_msgs/msg/TFMessage"


class BagError(Exception):
    pass


def stamp_s(msg, receive_ns):
    """The stamp in s: the double nearest to the stamp's nanoseconds (Python's int / int is
    correctly rounded), so a stamp written from a time t (to the nanosecond) reads back as the
    double nearest that decimal time, not one a product of two roundings lands on."""
    st = msg.header.stamp
    if st.sec == 0 and st.nanosec == 0:
        return receive_ns / 1_000_000_000
    return (st.sec * 1_000_000_000 + st.nanosec) / 1_000_000_000


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


    def constant(self):
        """True for a /tf_static link, or a /tf link whose samples all agree (1e-9)."""
        if self.static or len(self.t) == 1:
            return True
        return all(max(abs(a - b) for a, b in zip(p + q, self.p[0] + self.q[0])) < 1e-9
                   for p, q in zip(self.p, self.q))


def frame(name):
    """A TF frame name as compared here: without ROS 1's leading '/'."""
    return name.lstrip("/")


class TfTree:
    """Every parent -> child link of /tf and /tf_static in the bag."""

    def __init__(self, reader):
        self.edges, self.parent = {}, {}
        for topic, static in (("/tf", False), ("/tf_static", True)):
            conns = [c for c in reader.connections if c.topic == topic]
            if not conns:
                continue  # (no connections would read every message of the bag)
            for c in conns:
                if c.msgtype != TF:
                    raise BagError(f"topic {topic} holds {c.msgtype}, not {TF}")
            for conn, t_ns, raw in reader.messages(connections=conns):
                for ts in reader.deserialize(raw, conn.msgtype).transforms:
                    p_name, c_name = frame(ts.header.frame_id), frame(ts.child_frame_id)
                    if self.parent.get(c_name, p_name) != p_name:
                        raise BagError(f"frame {c_name} has two parents: {self.parent[c_name]} "
                                       f"and {p_name}")
                    self.parent[c_name] = p_name
                    tr, ro = ts.transform.translation, ts.transform.rotation
                    self.edges.setdefault((p_name, c_name), Edge()).add(
                        stamp_s(ts, t_ns), (tr.x, tr.y, tr.z), (ro.x, ro.y, ro.z, ro.w), static)
        for e in self.edges.values():
            e.finish()

    def frames(self):
        return sorted(set(self.parent) | set(self.parent.values()))

    def has(self, name):
        return name in self.parent or name in self.parent.values()

    def up(self, name):
        """The frames from `name` up to the root, `name` first."""
        path = [name]
        while path[-1] in self.parent:
            path.append(self.parent[path[-1]])
            if len(path) > 64:
                raise BagError("the transform tree in /tf, /tf_static has a cycle")
        return path

    def chain(self, base, sensor, what):
        """The links from `base` down to `sensor`, base first; an error names the frames."""
        if not self.edges:
            raise BagError(f"{what}: the bag has no /tf or /tf_static messages")
        path = self.up(sensor)
        if base not in path:
            raise BagError(f"{what}: no transform chain from {base} to {sensor} (from {sensor} "
                           f"up it reaches {' -> '.join(path)}); frames in the bag: "
                           f"{', '.join(self.frames())}")
        chain = [self.edges[(path[k + 1], path[k])] for k in range(path.index(base))]
        chain.reverse()
        return chain

    def fixed(self, a, b, what):
        """The pose of frame b in frame a from links that do not move (p, q xyzw), or None if
        either frame is not in the tree. A moving link between them is an error."""
        if not self.has(a) or not self.has(b):
            return None
        up_a, up_b = self.up(a), self.up(b)
        common = next((f for f in up_a if f in up_b), None)
        if common is None:
            raise BagError(f"{what}: frames {a} and {b} are in two separate TF trees")
        legs = []
        for leaf in (a, b):
            chain = self.chain(common, leaf, what)
            for e in chain:
                if not e.constant():
                    raise BagError(f"{what}: the transform from {a} to {b} moves (a link on "
                                   "/tf changes): a mounting must be fixed")
            legs.append(compose(chain, None))
        (pa, qa), (pb, qb) = legs
        qa_inv = (-qa[0], -qa[1], -qa[2], qa[3])
        d = qrot(qa_inv, tuple(y - x for x, y in zip(pa, pb)))
        return d, qmul(qa_inv, qb)


def compose(chain, t):
    """The links composed at time t (None: each link's first sample, for constant links)."""
    p, q = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)
    for e in chain:
        pq = (e.p[0], e.q[0]) if t is None else e.at(t)
        if pq is None:
            return None
        ep, eq = pq
        r = qrot(q, ep)
        p = (p[0] + r[0], p[1] + r[1], p[2] + r[2])
        q = qmul(q, eq)
    return p, q


# --- the rig ---------------------------------------------------------------------------------
def load_toml(path, what):
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except OSError as e:
        raise BagError(f"{what} {path}: {e.strerror}") from e
    except tomllib.TOMLDecodeError as e:
        raise BagError(f"{what} {path}: {e}") from e


def robot_of(a, rig, rig_dir):
    """The robot as (its [robot] table, where it came from), or (None, why not)."""
    if a.robot:
        if "robot_file" in rig or isinstance(rig.get("robot"), dict):
            raise BagError(f"--robot {a.robot} and the rig's robot: give one of them")
        path = Path(a.robot).resolve()
        return load_toml(path, "--robot").get("robot"), str(path)
    if "robot_file" in rig:
        path = (rig_dir / rig["robot_file"]).resolve()
        rig["robot_file"] = str(path)
        return load_toml(path, "the rig's robot_file").get("robot"), str(path)
    if isinstance(rig.get("robot"), dict):
        return rig["robot"], "the rig's [robot] table"
    return None, "no robot: give --robot FILE (calib/robots/) or a rig with robot_file"


def joint_columns(robot, names_given, message_names, topic):
    """The message's joint names in the order of the recording's joint columns (the robot
    file's `column` keys; A1 first without them), and how each was found."""
    if robot is None:
        if not names_given:
            raise BagError(f"{topic}: which joints are which? The message names "
                           f"{list(message_names)}; give the robot (--robot FILE or a rig with "
                           "robot_file, whose joints' ros_name or name the import looks for) "
                           "or --joint-names A1,A2,... (zerog never takes joints by position)")
        return names_given, "--joint-names"
    rows = robot.get("joint", [])
    if names_given:
        if len(names_given) != len(rows):
            raise BagError(f"--joint-names gives {len(names_given)} names; the robot "
                           f"{robot.get('name', '')!r} has {len(rows)} joints")
        by_row = names_given
        how = "--joint-names"
    else:
        by_row = []
        for i, row in enumerate(rows):
            wanted = [n for n in (row.get("ros_name"), row.get("name")) if n]
            if not wanted:
                raise BagError(f"the robot's joint {i + 1} has no name or ros_name: give "
                               "--joint-names")
            hit = next(([m] for n in wanted for m in message_names if m == n), None)
            if hit is None:
                hit = sorted({m for n in wanted for m in message_names if m.endswith(n)})
            if len(hit) != 1:
                say = ("none of" if not hit else f"{hit} all match")
                raise BagError(f"{topic}: robot joint {i + 1} ({' or '.join(wanted)}): {say} "
                               f"the message's names {list(message_names)}; give "
                               "--joint-names in the robot's joint order")
            by_row.append(hit[0])
        how = "the robot's joint names"
    if len(set(by_row)) != len(by_row):
        raise BagError(f"{topic}: a joint is named twice: {by_row}")
    columns = [None] * len(by_row)
    for i, row in enumerate(rows):
        columns[row.get("column", i + 1) - 1] = by_row[i]
    return columns, how


def same_transform(a, b):
    """Rig transforms {p_m, q_wxyz} within 1 mm and 0.1 degree."""
    dp = math.dist(a["p_m"], b["p_m"])
    dot = abs(sum(x * y for x, y in zip(a["q_wxyz"], b["q_wxyz"])))
    return dp < 1e-3 and 2.0 * math.acos(min(1.0, dot)) < math.radians(0.1)


def rig_transform(pq):
    p, q = pq
    return {"p_m": [float(v) for v in p], "q_wxyz": [float(q[3]), float(q[0]), float(q[1]),
                                                      float(q[2])]}


def mounting(rig, key, from_tf, what, missing_hint, notes):
    """Fills rig[key] from TF, or checks the rig's against TF; an error if neither has it."""
    if from_tf is None:
        if key not in rig:
            raise BagError(f"{what} ([{key}]) is neither in the rig nor in the bag's TF: "
                           f"{missing_hint}")
        return
    tf = rig_transform(from_tf)
    if key in rig and not same_transform(rig[key], tf):
        raise BagError(f"{what}: the rig's [{key}] (p_m {rig[key]['p_m']}, q_wxyz "
                       f"{rig[key]['q_wxyz']}) and the bag's TF (p_m {tf['p_m']}, q_wxyz "
                       f"{tf['q_wxyz']}) disagree (more than 1 mm or 0.1 deg): correct one")
    if key not in rig:
        rig[key] = tf
        notes.append(f"[{key}] from the bag's TF: p_m {[round(v, 6) for v in tf['p_m']]}, "
                     f"q_wxyz {[round(v, 6) for v in tf['q_wxyz']]}")


def rate_hz(times):
    if len(times) < 2:
        return 0.0
    return 1.0 / statistics.median(b - a for a, b in zip(times, times[1:]))


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
    rig, rig_dir = {}, Path.cwd()
    if a.rig:
        rig = load_toml(a.rig, "--rig")
        rig_dir = Path(a.rig).resolve().parent
        rig.pop("format", None)
        rig.pop("version", None)
    robot, robot_from = robot_of(a, rig, rig_dir)
    if a.robot:
        rig["robot_file"] = robot_from
    with AnyReader([Path(a.bag)], default_typestore=typestore) as reader:
        tree = None

        def tf():
            nonlocal tree
            if tree is None:
                tree = TfTree(reader)
            return tree

        wrench = read_topic(reader, a.wrench, WRENCH)
        wrench_frame = frame(frame_of(wrench, a.wrench))
        rows = [(stamp_s(m, t), m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
                 m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z) for t, m in wrench]
        rows = strictly_increasing(rows, a.wrench)
        write_csv(out / "wrench.csv", ["t_s", "fx", "fy", "fz", "tx", "ty", "tz"], rows)
        t_first, t_last = rows[0][0], rows[-1][0]
        rig.setdefault("name", f"bag {Path(a.bag).name}")
        rig.setdefault("ft_rate_hz", rate_hz([r[0] for r in rows]))
        mapping = MAPPING_HEAD.format(bag=a.bag)
        mapping += f"""
# {a.wrench}: {len(rows)} messages, frame '{wrench_frame}'
[files.wrench]
path = "wrench.csv"
time = {{ column = "t_s", unit = "s" }}
force = {{ columns = ["fx", "fy", "fz"], unit = "N" }}
torque = {{ columns = ["tx", "ty", "tz"], unit = "N*m" }}
"""
        imu_frame = wrench_frame
        if a.imu:
            imu = read_topic(reader, a.imu, IMU)
            imu_frame = frame(frame_of(imu, a.imu))
            rows = [(stamp_s(m, t), m.linear_acceleration.x, m.linear_acceleration.y,
                     m.linear_acceleration.z, m.angular_velocity.x, m.angular_velocity.y,
                     m.angular_velocity.z) for t, m in imu]
            rows = strictly_increasing(rows, a.imu)
            write_csv(out / "imu.csv", ["t_s", "ax", "ay", "az", "wx", "wy", "wz"], rows)
            rig.setdefault("imu_rate_hz", rate_hz([r[0] for r in rows]))
            mapping += f"""
# {a.imu}: {len(rows)} messages, frame '{imu_frame}'
[files.imu]
path = "imu.csv"
time = {{ column = "t_s", unit = "s" }}
specific_force = {{ columns = ["ax", "ay", "az"], unit = "m/s^2" }}
angular_rate = {{ columns = ["wx", "wy", "wz"], unit = "rad/s" }}
"""
        if a.temperature:
            temp = read_topic(reader, a.temperature, TEMPERATURE)
            rows = strictly_increasing([(stamp_s(m, t), m.temperature) for t, m in temp],
                                       a.temperature)
            write_csv(out / "temperature.csv", ["t_s", "temp_C"], rows)
            mapping += f"""
# {a.temperature}: {len(rows)} messages (°C)
[files.temperature]
path = "temperature.csv"
time = {{ column = "t_s", unit = "s" }}
temperature = {{ column = "temp_C", unit = "C" }}
"""
        if a.joints:
            joints = read_topic(reader, a.joints, JOINTS)
            given = [n.strip() for n in a.joint_names.split(",")] if a.joint_names else []
            if any(not n for n in given):
                raise BagError(f"--joint-names '{a.joint_names}' has an empty name")
            names, how = joint_columns(robot, given, list(joints[0][1].name), a.joints)
            rows = []
            for k, (t, m) in enumerate(joints):
                index = {n: i for i, n in enumerate(m.name)}
                missing = [n for n in names if n not in index]
                if missing:
                    raise BagError(f"{a.joints}: message {k + 1} does not name the joints "
                                   f"{missing} (it names {list(m.name)})")
                if len(m.position) != len(m.name):
                    raise BagError(f"{a.joints}: message {k + 1} has {len(m.name)} names but "
                                   f"{len(m.position)} positions")
                rows.append((stamp_s(m, t), *(m.position[index[n]] for n in names)))
            rows = strictly_increasing(rows, a.joints)
            columns = [f"q{i + 1}" for i in range(len(names))]
            write_csv(out / "joints.csv", ["t_s"] + columns, rows)
            others = [n for n in joints[0][1].name if n not in names]
            mapping += f"""
# {a.joints}: {len(rows)} messages; joint columns 1..{len(names)} = {names} (by {how}); not
# taken: {others}
[files.joints]
path = "joints.csv"
time = {{ column = "t_s", unit = "s" }}
joints = {{ columns = {columns!r}, unit = "rad" }}
""".replace("'", '"')
        if a.tf:
            base, _, sensor = a.tf.partition(":")
            base, sensor = frame(base), frame(sensor)
            if not base or not sensor:
                raise BagError(f"--tf wants BASE:SENSOR (two frame names), not '{a.tf}'")
            if wrench_frame == base:
                raise BagError(f"the wrench is in the base frame '{base}' already: zerog import "
                               "reads wrenches in the sensor frame (record the sensor's own "
                               "frame)")
            if wrench_frame and wrench_frame != sensor:
                raise BagError(f"--tf {a.tf}: the wrench is measured in frame "
                               f"'{wrench_frame}', not '{sensor}': give --tf "
                               f"{base}:{wrench_frame} (the pose is of the wrench's frame)")
            chain = tf().chain(base, sensor, f"--tf {a.tf}")
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
        # The mountings: what TF says fills the rig or is checked against it.
        flange = frame(a.flange or (robot or {}).get("ros_flange") or "tool0")
        has_tf = bool(tf().edges)
        mounting(rig, "flange_sensor",
                 tf().fixed(flange, wrench_frame, "the sensor on the flange") if has_tf else None,
                 "the sensor's mounting on the flange",
                 f"the bag's TF has no chain from the flange frame '{flange}' to the wrench's "
                 f"frame '{wrench_frame}' (frames: {', '.join(tf().frames()) or 'none'}); give "
                 "--flange FRAME (the TF frame of the robot's flange) or a rig (--rig) with "
                 "[flange_sensor]", notes)
        imu_tf = None
        if imu_frame == wrench_frame:
            if "sensor_imu" not in rig:
                imu_tf = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        elif has_tf:
            imu_tf = tf().fixed(wrench_frame, imu_frame, "the IMU in the sensor")
        mounting(rig, "sensor_imu", imu_tf, "the IMU's mounting in the sensor frame",
                 f"the IMU is in frame '{imu_frame}', the wrench in '{wrench_frame}', and no TF "
                 "links them; publish that transform on /tf_static or give a rig (--rig) with "
                 "[sensor_imu]", notes)
    mapping += "\n# The rig: --rig (if given) with what the bag says (proto/ros2_bags.md)\n"
    mapping += tomli_w.dumps({"rig": rig})
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
    ap.add_argument("--temperature", help="sensor_msgs/msg/Temperature topic (°C): temp_C")
    ap.add_argument("--joint-names", help="the robot's joints in its order, comma-separated")
    ap.add_argument("--tf", help="BASE:SENSOR frames of the pose, from /tf and /tf_static")
    ap.add_argument("--rig", help="the rig file: what the bag does not say")
    ap.add_argument("--robot", help="robot file (calib/robots/), if the rig names none")
    ap.add_argument("--flange", help="TF frame of the robot's flange (default: the robot "
                    "file's ros_flange, else tool0)")
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
