#!/usr/bin/env python3
"""The MCAP round trip of a HIL run (ctest hil_mcap_roundtrip; proto/ros2_bags.md).

  mcap_roundtrip.py --zerog ZEROG --run DIR

DIR is a hil.sh case folder (rec/ = zerog-rt's --record, model.zgm). It runs
`zerog export-mcap DIR/rec -o DIR/run.mcap --model DIR/model.zgm`, then checks that
 1. PyPI's `mcap` reader opens the file: ROS 2 profile, every channel with a ros2msg schema,
    the rig and the model attached byte for byte, the zerog metadata;
 2. `rosbags` (AnyReader) opens it and deserialises every message; each topic has one message
    per cycle of cycles.csv (/tf_static once, the diagnostics on every state change);
 3. `zerog import --bag DIR/run.mcap --wrench /zerog/wrench --imu /zerog/imu
    --tf base_link:ft_sensor --rig DIR/rec/run.rig.toml` gives the recorder's run.csv: every
    row of run.csv, every column, as the same text (the last digit); the imported log's other
    rows are exactly the cycles the recorder leaves out of run.csv (proto/log_format.md: stale
    IPOC, before the first F/T and IMU sample), and any column import adds is one it forms
    (imu_dw*: ω̇).
Then the same with a mutant exporter (--mutant: the wrench written as Fy, Fx, Fz) must fail 3.
Prints what it measured; exit 0 if all holds.
"""
import argparse
import csv
import os
import subprocess
import sys
from pathlib import Path

from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

FLAG_IPOC_STALE = 1 << 5  # loop::kIpocStale: the recorder logs no row for such a cycle


def fail(msg):
    print(f"mcap_roundtrip: FAIL: {msg}")
    return 1


def read_log(path):
    with open(path) as fh:
        lines = [l.rstrip("\n") for l in fh if not l.startswith("#") and l.strip()]
    header = lines[0].split(",")
    return header, [l.split(",") for l in lines[1:]]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--zerog", required=True)
    ap.add_argument("--run", required=True)
    ap.add_argument("--mutant", action="store_true",
                    help="export with the wrench's Fx and Fy swapped: the round trip must fail")
    a = ap.parse_args()
    run = Path(a.run)
    rec = run / "rec"
    mcap_path = run / ("run-mutant.mcap" if a.mutant else "run.mcap")
    env = dict(os.environ)
    if a.mutant:
        env["ZEROG_MCAP_TEST_MUTANT"] = "swap_fx_fy"
    cmd = [a.zerog, "export-mcap", str(rec), "-o", str(mcap_path), "--force",
           "--model", str(run / "model.zgm")]
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    print(p.stdout.strip() + p.stderr.strip())
    if p.returncode != 0:
        return fail(f"zerog export-mcap exited {p.returncode}")
    size = mcap_path.stat().st_size
    again = subprocess.run(cmd[:-3] + cmd[-2:], capture_output=True, text=True, env=env)
    if again.returncode == 0 or "exists already" not in again.stderr:
        return fail(f"export-mcap over an existing file without --force: exit {again.returncode}, "
                    f"{again.stderr.strip()!r}")

    # 1. PyPI's mcap reader.
    with open(mcap_path, "rb") as fh:
        reader = make_reader(fh)
        header = reader.get_header()
        summary = reader.get_summary()
        attachments = {x.name: x.data for x in reader.iter_attachments()}
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    if header.profile != "ros2":
        return fail(f"MCAP profile {header.profile!r}, not ros2")
    schemas = {s.id: s for s in summary.schemas.values()}
    for ch in summary.channels.values():
        s = schemas[ch.schema_id]
        if s.encoding != "ros2msg" or ch.message_encoding != "cdr":
            return fail(f"channel {ch.topic}: schema {s.encoding}, messages {ch.message_encoding}")
    if attachments.get("run.rig.toml") != (rec / "run.rig.toml").read_bytes():
        return fail("the rig attachment is not run.rig.toml byte for byte")
    if attachments.get("model.zgm") != (run / "model.zgm").read_bytes():
        return fail("the model attachment is not model.zgm byte for byte")
    if "zerog" not in metadata:
        return fail("no zerog metadata record")
    n_messages = summary.statistics.message_count
    print(f"mcap_roundtrip: mcap reader: {size} bytes, {len(summary.channels)} channels, "
          f"{n_messages} messages, attachments {sorted(attachments)}, metadata "
          f"{metadata['zerog']['cycles']} cycles")

    # 2. rosbags deserialises every message.
    with open(rec / "cycles.csv", newline="") as fh:
        cycles = list(csv.DictReader(fh))
    counts = {}
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with AnyReader([mcap_path], default_typestore=ts) as r:
        for conn, _, raw in r.messages():
            r.deserialize(raw, conn.msgtype)
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
    if sum(counts.values()) != n_messages:
        return fail(f"rosbags read {sum(counts.values())} messages, the summary says {n_messages}")
    for topic, n in counts.items():
        want = (1 if topic == "/tf_static" else
                None if topic.endswith("diagnostics") else
                sum(c["temp_measured"] == "1" for c in cycles) if topic.endswith("temperature")
                else len(cycles))
        if want is not None and n != want:
            return fail(f"{topic}: {n} messages, expected {want}")
    print(f"mcap_roundtrip: rosbags: every message deserialised: " +
          ", ".join(f"{t} {n}" for t, n in sorted(counts.items())))

    # 3. zerog import --bag gives the recorder's log.
    imported = run / ("imported-mutant.csv" if a.mutant else "imported.csv")
    cmd = [a.zerog, "import", "--bag", str(mcap_path), "--wrench", "/zerog/wrench", "--imu",
           "/zerog/imu", "--tf", "base_link:ft_sensor", "--rig", str(rec / "run.rig.toml"),
           "--out", str(imported)]
    h_rec, rows_rec = read_log(rec / "run.csv")
    if "temp_C" in h_rec:
        cmd += ["--temperature", "/zerog/temperature"]
    if "q1_rad" in h_rec:
        cmd += ["--joints", "/zerog/joint_states", "--joint-names",
                "joint_a1,joint_a2,joint_a3,joint_a4,joint_a5,joint_a6"]
    p = subprocess.run(cmd, capture_output=True, text=True)
    print("\n".join("    " + l for l in (p.stdout + p.stderr).strip().splitlines()[-6:]))
    if p.returncode != 0:
        return fail(f"zerog import --bag exited {p.returncode}")
    h_imp, rows_imp = read_log(imported)
    missing = [c for c in h_rec if c not in h_imp]
    if missing:
        return fail(f"the imported log lacks columns {missing}")
    added = [c for c in h_imp if c not in h_rec]
    if any(not c.startswith("imu_dw") for c in added):
        return fail(f"the imported log has columns run.csv lacks: {added}")
    col = {c: h_imp.index(c) for c in h_rec}
    imp_by_t = {}
    for row in rows_imp:
        imp_by_t[row[col["t_s"]]] = row
    diffs = []
    for i, row in enumerate(rows_rec):
        t = row[0] if h_rec[0] == "t_s" else row[h_rec.index("t_s")]
        other = imp_by_t.get(t)
        if other is None:
            diffs.append(f"run.csv row {i + 1} (t_s {t}): not in the imported log")
            continue
        for j, c in enumerate(h_rec):
            if row[j] != other[col[c]]:
                diffs.append(f"run.csv row {i + 1} (t_s {t}) {c}: recorder {row[j]}, "
                             f"imported {other[col[c]]}")
    # The imported rows run.csv has not: the cycles the recorder leaves out (proto/log_format.md).
    log_t = {row[h_rec.index("t_s")] for row in rows_rec}
    extra = [t for t in imp_by_t if t not in log_t]
    seen_ft = seen_imu = False
    skipped = set()
    temperature = "temp_C" in h_rec
    for c in cycles:  # the recorder's rules (firmware/rt/src/recorder.cpp, Recorder::add)
        seen_ft = seen_ft or int(c["ft_samples"]) > 0
        seen_imu = seen_imu or int(c["imu_samples"]) > 0
        if (int(c["flags"]) & FLAG_IPOC_STALE or not (seen_ft and seen_imu)
                or (temperature and c["temp_measured"] != "1")):
            skipped.add(repr(float(c["t_s"])) if "e" not in c["t_s"] else c["t_s"])
            skipped.add(c["t_s"])
    unexplained = [t for t in extra if t not in skipped]
    if unexplained:
        diffs.append(f"{len(unexplained)} imported rows are no cycle the recorder skipped: "
                     f"t_s {unexplained[:5]}")
    print(f"mcap_roundtrip: zerog import --bag: {len(rows_imp)} rows; run.csv's {len(rows_rec)} "
          f"rows x {len(h_rec)} columns compared as text: {len(diffs)} differences; "
          f"{len(extra)} more rows, all cycles the recorder left out of run.csv; added columns "
          f"{added}")
    if diffs:
        for d in diffs[:10]:
            print(f"mcap_roundtrip: FAIL: {d}")
        return 1
    print("mcap_roundtrip: OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
