#!/usr/bin/env python3
"""zerog import --bag on ROS 2 bags this test writes itself (rosbags' Writer, sqlite3 and MCAP).

bag_import_test.py ZEROG WORKDIR, run with the project's venv python (rosbags and tomli-w from
scripts/install-deps.sh).

Round trip: a short `zerog sim` run is the source: its rows become geometry_msgs/WrenchStamped
(/ft, frame ft_sensor), sensor_msgs/Imu (/imu), sensor_msgs/JointState (/joint_states: the six
joints in another order, plus a gripper joint) and tf2_msgs/TFMessage (the pose split into a
moving base_link -> tool0 on /tf and the rig's fixed tool0 -> ft_sensor on /tf_static, so the
importer must compose the chain). Every imported column must equal the source's (to 1e-9
relative; quaternions up to sign), in both storage formats.

By name, the mounting from TF (issue 25, item 6), on two seeds: a 60-s run as a bag with no rig
and no pose, only the joints (scrambled, with a gripper joint), /tf_static (tool0 -> ft_sensor,
tool0 -> imu_link, some frame names with ROS 1's leading '/') and --robot. Once as the KR 210
with its 6 joints, once as a 7-joint arm (the KR 210 with A6 split into two joints about the same
axis, tests' own robot file): the imported pose must be the source's (1e-9 m), the rig's
mountings the ones in TF, and the fit of the 7-joint import the fit of the 6-joint import (1e-6),
both within the 6-joint case's tolerances of the truth (mass 0.5 %, centre of mass 5 mm). The
mutant (joints by position, the old rule) must fail the pose check. Refusals (a missing topic, a
wrong --tf frame, no rosbags, joints without names, unknown or ambiguous names, a mounting in
neither rig nor TF, rig and TF disagreeing) must say what is wrong and what to do.
"""

import csv
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

ZEROG, WORK = sys.argv[1], Path(sys.argv[2])
REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "host" / "io"))
import bag_to_csv  # noqa: E402  (its joint_columns, checked directly below)
T0 = 1_700_000_000  # ROS stamps: a zero stamp means "not set"
TS = get_typestore(Stores.ROS2_HUMBLE)
M = TS.types
failures = []


def check(ok, what):
    if not ok:
        failures.append(what)
        print("FAIL:", what, file=sys.stderr)


def run(args, expect_ok=True, env=None):
    r = subprocess.run([ZEROG] + args, capture_output=True, text=True,
                       env=dict(os.environ, **(env or {})))
    if expect_ok and r.returncode != 0:
        sys.exit(f"zerog {' '.join(args)} failed:\n{r.stdout}\n{r.stderr}")
    return r


def read_log(path):
    with open(path, encoding="utf-8") as f:
        rows = [line for line in f if not line.startswith("#")]
    return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(rows)]


def qmul(a, b):  # (x, y, z, w)
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def qconj(q):
    return (-q[0], -q[1], -q[2], q[3])


def qrot(q, v):
    return qmul(qmul(q, (*v, 0.0)), qconj(q))[:3]


def header(t, frame):
    sec = T0 + int(math.floor(t))
    nsec = int(round((t - math.floor(t)) * 1e9))
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return M["std_msgs/msg/Header"](stamp=M["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                    frame_id=frame)


def vec(x, y, z):
    return M["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)


def quat(q):
    return M["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])


# tool0 -> ft_sensor, fixed: a turn of 30 deg about z and an offset; the round trip's rig says
# the same (the import checks the rig against TF).
Q_TOOL_FT = (0.0, 0.0, math.sin(math.pi / 12), math.cos(math.pi / 12))
P_TOOL_FT = (0.01, -0.02, 0.06)
NAMES = ["joint_a3", "joint_a1", "gripper", "joint_a2", "joint_a6", "joint_a5", "joint_a4"]


def wrench_msg(r, frame):
    """The log row's wrench as geometry_msgs/WrenchStamped in `frame`."""
    return M["geometry_msgs/msg/WrenchStamped"](
        header=header(r["t_s"], frame),
        wrench=M["geometry_msgs/msg/Wrench"](force=vec(r["Fx_N"], r["Fy_N"], r["Fz_N"]),
                                             torque=vec(r["Mx_Nm"], r["My_Nm"], r["Mz_Nm"])))


def imu_msg(r, frame):
    """The log row's IMU columns as sensor_msgs/Imu in `frame` (no orientation)."""
    cov = np.zeros(9)
    return M["sensor_msgs/msg/Imu"](
        header=header(r["t_s"], frame), orientation=quat((0.0, 0.0, 0.0, 1.0)),
        orientation_covariance=cov,
        angular_velocity=vec(r["imu_wx_radps"], r["imu_wy_radps"], r["imu_wz_radps"]),
        angular_velocity_covariance=cov,
        linear_acceleration=vec(r["imu_fx_mps2"], r["imu_fy_mps2"], r["imu_fz_mps2"]),
        linear_acceleration_covariance=cov)


def write_bag(path, plugin, rows):
    with Writer(path, version=8, storage_plugin=plugin) as w:
        c_ft = w.add_connection("/ft", "geometry_msgs/msg/WrenchStamped", typestore=TS)
        c_imu = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=TS)
        c_js = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=TS)
        c_tf = w.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=TS)
        c_st = w.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=TS)

        def put(conn, t, msg):
            w.write(conn, int((T0 + t) * 1e9), TS.serialize_cdr(msg, conn.msgtype))

        static = M["geometry_msgs/msg/TransformStamped"](
            header=header(0.0, "tool0"), child_frame_id="ft_sensor",
            transform=M["geometry_msgs/msg/Transform"](translation=vec(*P_TOOL_FT),
                                                       rotation=quat(Q_TOOL_FT)))
        put(c_st, rows[0]["t_s"], M["tf2_msgs/msg/TFMessage"](transforms=[static]))
        for r in rows:
            t = r["t_s"]
            put(c_ft, t, wrench_msg(r, "ft_sensor"))
            put(c_imu, t, imu_msg(r, "ft_sensor"))
            q = {f"joint_a{k}": r[f"q{k}_rad"] for k in range(1, 7)}
            q["gripper"] = 0.01
            put(c_js, t, M["sensor_msgs/msg/JointState"](
                header=header(t, ""), name=NAMES, position=np.array([q[n] for n in NAMES]),
                velocity=np.zeros(0), effort=np.zeros(0)))
            # base_link -> tool0 = (base_link -> ft_sensor) * (tool0 -> ft_sensor)^-1
            q_bs = (r["qx"], r["qy"], r["qz"], r["qw"])
            q_bt = qmul(q_bs, qconj(Q_TOOL_FT))
            off = qrot(q_bt, P_TOOL_FT)
            p_bt = (r["px_m"] - off[0], r["py_m"] - off[1], r["pz_m"] - off[2])
            moving = M["geometry_msgs/msg/TransformStamped"](
                header=header(t, "base_link"), child_frame_id="tool0",
                transform=M["geometry_msgs/msg/Transform"](translation=vec(*p_bt),
                                                           rotation=quat(q_bt)))
            put(c_tf, t, M["tf2_msgs/msg/TFMessage"](transforms=[moving]))


def compare(source, imported, label):
    check(len(imported) == len(source),
          f"{label}: {len(imported)} rows imported, {len(source)} in the source")
    worst = worst_t = 0.0
    for a, b in zip(source, imported):
        for k in ["q1_rad", "q2_rad", "q3_rad", "q4_rad", "q5_rad", "q6_rad", "px_m", "py_m",
                  "pz_m", "imu_fx_mps2", "imu_fy_mps2", "imu_fz_mps2", "imu_wx_radps",
                  "imu_wy_radps", "imu_wz_radps", "Fx_N", "Fy_N", "Fz_N", "Mx_Nm", "My_Nm",
                  "Mz_Nm"]:
            worst = max(worst, abs(a[k] - b[k]) / (1.0 + abs(a[k])))
        s = 1.0 if a["qw"] * b["qw"] + a["qx"] * b["qx"] + a["qy"] * b["qy"] + a["qz"] * b[
            "qz"] > 0 else -1.0
        for k in ["qw", "qx", "qy", "qz"]:
            worst = max(worst, abs(a[k] - s * b[k]))
        # Times since 1970 in a double resolve 2.4e-7 s: compare them to 1 us.
        worst_t = max(worst_t, abs((b["t_s"] - T0) - a["t_s"]))
    check(worst < 1e-8, f"{label}: largest relative difference {worst:g} (want < 1e-8)")
    check(worst_t < 1e-6, f"{label}: times differ by up to {worst_t:g} s (want < 1e-6 s)")
    print(f"{label}: {len(imported)} rows, largest relative difference {worst:.2e}, "
          f"time {worst_t:.2e} s")


# The KR 210 with A6 split into two joints about the same axis (A6 = q6 + q7): a 7-joint arm
# whose flange moves as the KR 210's (rows 1-5 as calib/robots/kr210_r2700.robot.toml).
SPLIT_ROBOT = """format = "zerog-robot"
version = 1
[robot]
name = "KR 210 R2700, A6 split in two (test)"
convention = "dh"
ros_flange = "tool0"
[[robot.joint]]
ros_name = "joint_a1"
a_m = 0.350
alpha_deg = -90
d_m = 0.675
sign = -1
[[robot.joint]]
ros_name = "joint_a2"
a_m = 1.150
alpha_deg = 0
d_m = 0.0
[[robot.joint]]
ros_name = "joint_a3"
a_m = -0.041
alpha_deg = -90
d_m = 0.0
theta_offset_deg = -90
[[robot.joint]]
ros_name = "joint_a4"
a_m = 0.0
alpha_deg = 90
d_m = 1.200
sign = -1
[[robot.joint]]
ros_name = "joint_a5"
a_m = 0.0
alpha_deg = -90
d_m = 0.0
[[robot.joint]]
ros_name = "joint_a6"
a_m = 0.0
alpha_deg = 0
d_m = 0.215
sign = -1
theta_offset_deg = 180
[[robot.joint]]
ros_name = "joint_a7"
a_m = 0.0
alpha_deg = 0
d_m = 0.0
sign = -1
"""


def write_joint_bag(path, rows, names, joints_of, with_tf=True):
    """Wrench, IMU (frame imu_link), JointState (`names`, values joints_of(row) by name) and,
    if `with_tf`, /tf_static tool0 -> ft_sensor and tool0 -> imu_link (the sim rig's mounting:
    60 mm along the flange's z, the IMU at the sensor); no pose. Some frame names carry ROS 1's
    leading '/'."""
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        c_ft = w.add_connection("/ft", "geometry_msgs/msg/WrenchStamped", typestore=TS)
        c_imu = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=TS)
        c_js = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=TS)
        c_st = w.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=TS)

        def put(conn, t, msg):
            w.write(conn, int((T0 + t) * 1e9), TS.serialize_cdr(msg, conn.msgtype))

        def fixed(parent, child):
            return M["geometry_msgs/msg/TransformStamped"](
                header=header(0.0, parent), child_frame_id=child,
                transform=M["geometry_msgs/msg/Transform"](
                    translation=vec(0.0, 0.0, 0.06), rotation=quat((0.0, 0.0, 0.0, 1.0))))
        if with_tf:
            put(c_st, rows[0]["t_s"], M["tf2_msgs/msg/TFMessage"](
                transforms=[fixed("/tool0", "ft_sensor"), fixed("tool0", "/imu_link")]))
        for r in rows:
            t = r["t_s"]
            put(c_ft, t, wrench_msg(r, "/ft_sensor"))
            put(c_imu, t, imu_msg(r, "imu_link"))
            q = joints_of(r)
            put(c_js, t, M["sensor_msgs/msg/JointState"](
                header=header(t, ""), name=names, position=np.array([q[n] for n in names]),
                velocity=np.zeros(0), effort=np.zeros(0)))


def fresh(path):
    if path.exists():
        for f in path.iterdir():
            f.unlink()
        path.rmdir()
    return path


def pose_error(source, imported):
    """Largest position difference (m) and quaternion difference (up to sign) per row."""
    dp = dq = 0.0
    for a, b in zip(source, imported):
        dp = max(dp, math.dist([a["px_m"], a["py_m"], a["pz_m"]], [b["px_m"], b["py_m"], b["pz_m"]]))
        dot = sum(a[k] * b[k] for k in ("qw", "qx", "qy", "qz"))
        dq = max(dq, min(sum((a[k] - b[k]) ** 2 for k in ("qw", "qx", "qy", "qz")),
                         sum((a[k] + b[k]) ** 2 for k in ("qw", "qx", "qy", "qz"))) ** 0.5)
        del dot
    return dp, dq


def fitted(model_path):
    import json
    p = json.loads(Path(model_path).read_text(encoding="utf-8"))["parameters"]["gravity"]
    return p["mass"]["value"], [p[k]["value"] for k in ("cx", "cy", "cz")]


def rig_of(path):
    import tomllib
    with open(path, "rb") as f:
        return tomllib.load(f)


def by_name(seed, kr210):
    """The 6-joint and the 7-joint bag of one seed's 60-s run: imported by name with the
    mounting from /tf_static, fitted; returns the failures' count before and after."""
    work = WORK / f"by_name_{seed}"
    work.mkdir(parents=True, exist_ok=True)
    src = work / "run.csv"
    run(["sim", "--kind", "random", "--points", "8", "--seed", str(seed), "--duration-limit",
         "60", "--out", str(src), "-q"])
    rows = read_log(src)
    truth = fitted(work / "run.truth.json")
    split = work / "kr210_split_a6.robot.toml"
    split.write_text(SPLIT_ROBOT, encoding="utf-8")

    def six(r):
        q = {f"joint_a{k}": r[f"q{k}_rad"] for k in range(1, 7)}
        q["gripper_finger_joint"] = 0.02
        return q

    def seven(r):
        q = six(r)
        q["joint_a7"] = 0.4 * math.sin(0.7 * r["t_s"])  # the split: A6 = joint_a6 + joint_a7
        q["joint_a6"] = r["q6_rad"] - q["joint_a7"]
        return q

    names6 = ["joint_a3", "joint_a1", "gripper_finger_joint", "joint_a2", "joint_a6",
              "joint_a5", "joint_a4"]
    names7 = ["joint_a5", "gripper_finger_joint", "joint_a1", "joint_a7", "joint_a3",
              "joint_a2", "joint_a6", "joint_a4"]
    fits = {}
    for label, names, joints_of, robot in (("6 joints", names6, six, kr210),
                                           ("7 joints", names7, seven, str(split))):
        bag = fresh(work / f"bag_{len(names) - 1}")
        write_joint_bag(bag, rows, names, joints_of)
        out = work / f"imported_{len(names) - 1}.csv"
        r = run(["import", "--bag", str(bag), "--wrench", "/ft", "--imu", "/imu", "--joints",
                 "/joint_states", "--robot", robot, "--out", str(out)])
        imported = read_log(out)
        dp, dq = pose_error(rows, imported)
        check(len(imported) == len(rows), f"seed {seed}, {label}: {len(imported)} rows of "
              f"{len(rows)}")
        # The log holds 9 significant digits: 1e-7 is its resolution over a 2.5-m arm.
        check(dp < 1e-7 and dq < 1e-7, f"seed {seed}, {label}: the pose from the joints is off "
              f"the source's by {dp:.2e} m, {dq:.2e} (quaternion)")
        rig = rig_of(out.with_suffix(".rig.toml"))
        check(math.dist(rig["flange_sensor"]["p_m"], [0.0, 0.0, 0.06]) < 1e-12
              and math.dist(rig["sensor_imu"]["p_m"], [0.0, 0.0, 0.0]) < 1e-12,
              f"seed {seed}, {label}: the rig's mountings are not TF's: {rig}")
        check(len(rig["robot"]["joint"]) == len(names) - 1,
              f"seed {seed}, {label}: the rig's robot has {len(rig['robot']['joint'])} joints")
        fit = work / f"fit_{len(names) - 1}.json"
        run(["fit", str(out), "--out", str(fit), "-q"])
        fits[label] = fitted(fit)
        mass, com = fits[label]
        dm = abs(mass - truth[0]) / truth[0]
        dc = math.dist(com, truth[1])
        print(f"seed {seed}, {label}: pose within {max(dp, dq):.1e}; mass {mass:.4f} kg "
              f"(truth {truth[0]:.4f}, {100 * dm:.3f} %), centre of mass {1000 * dc:.2f} mm off")
        check(dm < 0.005 and dc < 0.005, f"seed {seed}, {label}: the fit is outside the "
              f"6-joint case's tolerances (mass {100 * dm:.3f} %, centre {1000 * dc:.2f} mm)")
        if label == "6 joints":
            # The mutant: the old rule (the first six of the message, by position) must fail
            # the pose check above.
            script = (REPO / "host" / "io" / "bag_to_csv.py").read_text(encoding="utf-8")
            rule = "    names, how = joint_columns(robot, given, list(joints[0][1].name), a.joints)"
            check(rule in script, "the mutant's line is not in bag_to_csv.py")
            mutant = work / "bag_to_csv_positional.py"
            mutant.write_text(script.replace(rule, rule.replace(
                "joint_columns(robot, given, list(joints[0][1].name), a.joints)",
                "list(joints[0][1].name)[:6], 'position'")), encoding="utf-8")
            out_m = work / "imported_mutant.csv"
            run(["import", "--bag", str(bag), "--wrench", "/ft", "--imu", "/imu", "--joints",
                 "/joint_states", "--robot", robot, "--out", str(out_m)],
                env={"ZEROG_BAG_SCRIPT": str(mutant)})
            mp, _ = pose_error(rows, read_log(out_m))
            check(mp > 0.01, f"seed {seed}: the positional mutant's pose is within {mp:.2e} m")
            print(f"seed {seed}: the positional mutant puts the sensor up to {mp:.2f} m off")
    (m6, c6), (m7, c7) = fits["6 joints"], fits["7 joints"]
    check(abs(m7 - m6) < 1e-6 * m6 and math.dist(c6, c7) < 1e-6,
          f"seed {seed}: the 7-joint fit ({m7}, {c7}) is not the 6-joint fit ({m6}, {c6})")
    return work


def refusals_by_name(work, kr210):
    bag = str(work / "bag_6")
    base = ["import", "--bag", bag, "--wrench", "/ft", "--imu", "/imu", "--joints",
            "/joint_states", "--dry-run"]
    r = run(base, False)
    check(r.returncode != 0 and "never takes joints by position" in r.stderr
          and "--robot FILE" in r.stderr, f"joints without a robot or names: {r.stderr.strip()}")
    r = run(base + ["--robot", kr210, "--joint-names",
                    "joint_a1,joint_a2,joint_a3,joint_a4,joint_a5,joint_x"], False)
    check(r.returncode != 0 and "does not name the joints ['joint_x']" in r.stderr,
          f"an unknown --joint-names name: {r.stderr.strip()}")
    r = run(base + ["--robot", kr210, "--joint-names", "joint_a1,joint_a2"], False)
    check(r.returncode != 0 and "gives 2 names; the robot 'KR 210 R2700' has 6 joints" in r.stderr,
          f"--joint-names too short: {r.stderr.strip()}")
    iiwa = str(REPO / "calib" / "robots" / "lbr_iiwa14_r820.robot.toml")
    r = run(base + ["--robot", iiwa], False)
    check(r.returncode != 0 and "robot joint 7 (joint_a7 or A7): none of" in r.stderr
          and "--joint-names" in r.stderr, f"a robot joint not in the message: {r.stderr.strip()}")
    r = run(base + ["--robot", kr210, "--flange", "flange"], False)
    check(r.returncode != 0 and "no chain from the flange frame 'flange'" in r.stderr
          and "--flange FRAME" in r.stderr, f"a wrong --flange: {r.stderr.strip()}")
    wrong = work / "wrong.rig.toml"
    text = (work / "run.rig.toml").read_text(encoding="utf-8")
    wrong.write_text(text.replace("p_m = [0.0, 0.0, 0.06]", "p_m = [0.0, 0.0, 0.08]"),
                     encoding="utf-8")
    r = run(base + ["--robot", kr210, "--rig", str(wrong)], False)
    check(r.returncode != 0 and "disagree" in r.stderr and "[flange_sensor]" in r.stderr,
          f"rig and TF disagreeing: {r.stderr.strip()}")
    # No TF at all: the mounting must come from a rig, and the message says so.
    notf = fresh(work / "bag_no_tf")
    write_joint_bag(notf, read_log(work / "run.csv")[:50],
                    ["joint_a1", "joint_a2", "joint_a3", "joint_a4", "joint_a5", "joint_a6"],
                    lambda r: {f"joint_a{k}": r[f"q{k}_rad"] for k in range(1, 7)}, False)
    r = run(["import", "--bag", str(notf), "--wrench", "/ft", "--joints", "/joint_states",
             "--robot", kr210, "--dry-run"], False)
    check(r.returncode != 0 and "neither in the rig nor in the bag's TF" in r.stderr
          and "--rig" in r.stderr, f"no mounting anywhere: {r.stderr.strip()}")
    r = run(["import", "--bag", str(notf), "--wrench", "/ft", "--joints", "/joint_states",
             "--robot", kr210, "--rig", str(work / "run.rig.toml"), "--dry-run"], False)
    check(r.returncode == 0, f"no TF but a rig: {r.stderr.strip()}")
    # The name rule itself: a suffix (lbr_fri_ros2_stack's lbr_A1) is found, two are ambiguous.
    robot = {"name": "arm", "joint": [{"name": "A1", "column": 2}, {"name": "A2", "column": 1}]}
    cols, _ = bag_to_csv.joint_columns(robot, [], ["lbr_A2", "tool_changer", "lbr_A1"], "/js")
    check(cols == ["lbr_A2", "lbr_A1"], f"suffix names and the column keys: {cols}")
    try:
        bag_to_csv.joint_columns(robot, [], ["left_A1", "right_A1", "lbr_A2"], "/js")
        check(False, "two joints ending in A1 were not refused")
    except bag_to_csv.BagError as e:
        check("['left_A1', 'right_A1'] all match" in str(e), f"ambiguous names: {e}")


def main():
    WORK.mkdir(parents=True, exist_ok=True)
    src = WORK / "run.csv"
    run(["sim", "--kind", "random", "--points", "3", "--seed", "5", "--duration-limit", "6",
         "--out", str(src), "-q"])
    rows = read_log(src)
    assert len(rows) > 400, len(rows)
    rig = str(WORK / "roundtrip.rig.toml")
    text = (WORK / "run.rig.toml").read_text(encoding="utf-8")
    old = text[text.index("[flange_sensor]"):text.index("[sensor_imu]")]
    Path(rig).write_text(text.replace(old, f"""[flange_sensor]
p_m = {list(P_TOOL_FT)}
q_wxyz = {[Q_TOOL_FT[3], *Q_TOOL_FT[:3]]}

"""), encoding="utf-8")
    common = ["--wrench", "/ft", "--imu", "/imu", "--joints", "/joint_states", "--joint-names",
              ",".join(f"joint_a{k}" for k in range(1, 7)), "--tf", "base_link:ft_sensor",
              "--rig", rig]
    for plugin, name in ((StoragePlugin.SQLITE3, "sqlite3"), (StoragePlugin.MCAP, "mcap")):
        bag = WORK / f"bag_{name}"
        if bag.exists():
            for f in bag.iterdir():
                f.unlink()
            bag.rmdir()
        write_bag(bag, plugin, rows)
        out = WORK / f"imported_{name}.csv"
        r = run(["import", "--bag", str(bag), "--out", str(out)] + common)
        compare(rows, read_log(out), name)
        check(out.with_suffix(".rig.toml").exists(), f"{name}: no rig beside the log")

    # The imported 6-s log goes on through fit, compare and diagnose (blocks chosen for it).
    imported = str(WORK / "imported_mcap.csv")
    fit = str(WORK / "fit.json")
    run(["fit", imported, "--out", fit, "-q"])
    run(["compare", imported, "-m", fit, "-q"])
    r = run(["diagnose", imported, "-m", fit, "--no-discover", "-q"])
    check("held-out split: blocks of 0.75 s (8 blocks" in r.stdout,
          f"diagnose of the imported bag: {r.stdout[:300]}")

    bag = str(WORK / "bag_mcap")
    # Refusals name what is wrong and what would work.
    r = run(["import", "--bag", bag, "--wrench", "/force", "--rig", rig, "--dry-run"], False)
    check(r.returncode != 0 and "topic /force is not in the bag" in r.stderr
          and "/ft (geometry_msgs/msg/WrenchStamped)" in r.stderr,
          f"missing topic: {r.stderr.strip()}")
    r = run(["import", "--bag", bag, "--wrench", "/ft", "--tf", "base_link:tool0", "--rig", rig,
             "--dry-run"], False)
    check(r.returncode != 0 and "give --tf base_link:ft_sensor" in r.stderr,
          f"wrong --tf frame: {r.stderr.strip()}")
    r = run(["import", "--bag", bag, "--wrench", "/imu", "--rig", rig, "--dry-run"], False)
    check(r.returncode != 0 and "holds sensor_msgs/msg/Imu" in r.stderr,
          f"wrong message type: {r.stderr.strip()}")
    r = run(["import", "--bag", bag, "--wrench", "/ft", "--rig", rig, "--dry-run"], False,
            env={"ZEROG_PYTHON": "/usr/bin/python3"})
    check(r.returncode != 0 and "scripts/install-deps.sh" in r.stderr and "rosbags" in r.stderr,
          f"no rosbags: {r.stderr.strip()}")
    r = run(["import", "--bag", bag, "--wrench", "/ft", "--rig", rig, "--dry-run"], False,
            env={"ZEROG_PYTHON": str(WORK / "no-such-python")})
    check(r.returncode != 0 and "scripts/install-deps.sh" in r.stderr,
          f"no venv: {r.stderr.strip()}")

    kr210 = str(REPO / "calib" / "robots" / "kr210_r2700.robot.toml")
    work = None
    for seed in (5, 11):
        work = by_name(seed, kr210)
    refusals_by_name(work, kr210)
    if failures:
        sys.exit(f"{len(failures)} failures")
    print("bag_import_test: ok")


main()
