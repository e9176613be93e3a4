#!/usr/bin/env python3
"""zerog import --bag on ROS 2 bags this test writes itself (rosbags' Writer, sqlite3 and MCAP).

bag_import_test.py ZEROG WORKDIR, run with the project's venv python (rosbags from
scripts/install-deps.sh). A short `zerog sim` run is the source: its rows become
geometry_msgs/WrenchStamped (/ft, frame ft_sensor), sensor_msgs/Imu (/imu), sensor_msgs/JointState
(/joint_states: the six joints under other names, in another order, plus a gripper joint) and
tf2_msgs/TFMessage (the pose split into a moving base_link -> tool0 on /tf and a fixed
tool0 -> ft_sensor on /tf_static, so the importer must compose the chain). Every imported column
must equal the source's (to 1e-9 relative; quaternions up to sign), in both storage formats; the
refusals (a missing topic, a wrong --tf frame, no rosbags) must say what is wrong and what to do.
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


# tool0 -> ft_sensor, fixed: a turn of 30 deg about z and a 60 mm offset.
Q_TOOL_FT = (0.0, 0.0, math.sin(math.pi / 12), math.cos(math.pi / 12))
P_TOOL_FT = (0.01, -0.02, 0.06)
NAMES = ["joint_a3", "joint_a1", "gripper", "joint_a2", "joint_a6", "joint_a5", "joint_a4"]


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
        cov = np.zeros(9)
        for r in rows:
            t = r["t_s"]
            put(c_ft, t, M["geometry_msgs/msg/WrenchStamped"](
                header=header(t, "ft_sensor"),
                wrench=M["geometry_msgs/msg/Wrench"](force=vec(r["Fx_N"], r["Fy_N"], r["Fz_N"]),
                                                     torque=vec(r["Mx_Nm"], r["My_Nm"],
                                                                r["Mz_Nm"]))))
            put(c_imu, t, M["sensor_msgs/msg/Imu"](
                header=header(t, "ft_sensor"), orientation=quat((0.0, 0.0, 0.0, 1.0)),
                orientation_covariance=cov,
                angular_velocity=vec(r["imu_wx_radps"], r["imu_wy_radps"], r["imu_wz_radps"]),
                angular_velocity_covariance=cov,
                linear_acceleration=vec(r["imu_fx_mps2"], r["imu_fy_mps2"], r["imu_fz_mps2"]),
                linear_acceleration_covariance=cov))
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


def main():
    WORK.mkdir(parents=True, exist_ok=True)
    src = WORK / "run.csv"
    run(["sim", "--kind", "random", "--points", "3", "--seed", "5", "--duration-limit", "6",
         "--out", str(src), "-q"])
    rows = read_log(src)
    assert len(rows) > 400, len(rows)
    rig = str(WORK / "run.rig.toml")
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
    if failures:
        sys.exit(f"{len(failures)} failures")
    print("bag_import_test: ok")


main()
