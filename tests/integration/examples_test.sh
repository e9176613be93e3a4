#!/usr/bin/env bash
# examples_test.sh SOURCE_DIR BUILD_DIR WORK_DIR
#
# Every example the repository ships goes through the command it is meant for, as the README and
# the examples' own comments tell a user to run it: from the repository's root, with the paths
# as written there (issue 26). What each must give is checked, not only the exit status.
#   calib/import_example/      zerog import --mapping …, then zerog fit of the log
#   calib/import_example/kr210.rig.toml   zerog decode-rsi --rig (the rig names its robot)
#   calib/static_table/        zerog import --mapping …, zerog fit --effects bias,gravity
#   calib/poses/…attitudes.csv zerog design --attitudes
#   calib/robots/*.robot.toml  the KR 210 through the example rig above; the LBR iiwa through a
#                              rig naming it (robot_file) and zerog import of a 7-joint recording
#   firmware/rt/zerog-rt.sample.toml   zerog-rt --check-config beside a model and rig
# The HIL cases (tests/hil/cases) run in the hil_* tests, the demo in demo_first_command.
set -uo pipefail
src=$1 bin=$2 work=$3
zerog=$bin/host/cli/zerog rt=$bin/firmware/rt/zerog-rt
rm -rf "$work" && mkdir -p "$work"
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
# run NAME CMD...: runs CMD from the repository's root; output in $work/NAME.out.
run() {
  local name=$1; shift
  local status=0
  (cd "$src" && "$@") >"$work/$name.out" 2>&1 || status=$?
  if [ $status -ne 0 ]; then
    fail "$name: '$*' exited $status:"; tail -n 5 "$work/$name.out"; return 1
  fi
}
json() { /usr/bin/python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print($2)" "$1"; }

echo "== calib/import_example: import"
# 0.2 s of a KR 210 turning A1 with 100 kg (make_example.py): an example of merging three
# recordings, not a calibration run (too short and too still to identify a payload).
if run import_example "$zerog" import --mapping calib/import_example/mapping.toml \
     --out "$work/example/run.csv"; then
  grep -q '^rows out: 181 of 200 master rows' "$work/import_example.out" \
    || fail "import_example: not the 181 merged rows the example gives: $(grep '^rows out' "$work/import_example.out")"
  grep -q '^\[robot\]' "$work/example/run.rig.toml" \
    || fail "import_example: the log's rig does not carry the example's robot"
  # The payload hangs below the sensor: Fz is its weight, 100 kg x g (+- the 2 N wiggle).
  /usr/bin/python3 - "$work/example/run.csv" <<'PY' || fail "import_example: Fz is not 100 kg x g"
import csv, sys
rows = [r for r in csv.reader(l for l in open(sys.argv[1]) if not l.startswith("#"))]
fz = [float(r[rows[0].index("Fz_N")]) for r in rows[1:]]
mean = sum(fz) / len(fz)
print(f"import_example: mean Fz {mean:.2f} N over {len(fz)} rows")
sys.exit(abs(mean - 100.0 * 9.80665) > 2.5)
PY
fi

echo "== calib/import_example/kr210.rig.toml: decode-rsi --rig"
if run decode_rsi "$zerog" decode-rsi tests/data/rsi_capture/emulator_kr210.txt \
     --rig calib/import_example/kr210.rig.toml --out "$work/rsi/robot.csv"; then
  # The capture is the emulator's KR 210: the joints through the rig's robot give RIst's pose.
  /usr/bin/python3 - "$work/rsi/robot.csv" <<'PY' || fail "decode_rsi: no pose check against the rig's robot"
import csv, sys
rows = [r for r in csv.reader(l for l in open(sys.argv[1]) if not l.startswith("#"))]
k = rows[0].index("pose_check_m")
worst = max(float(r[k]) for r in rows[1:])
print(f"decode_rsi: {len(rows) - 1} messages, RIst within {worst:.2g} m of the joints' pose")
sys.exit(not worst < 1e-4)
PY
fi

echo "== calib/static_table: import, fit bias and gravity"
if run static_table "$zerog" import --mapping calib/static_table/mapping.toml \
     --out "$work/static/static.csv" \
   && run static_fit "$zerog" fit "$work/static/static.csv" --effects bias,gravity -q \
        --out "$work/static/fit.json"; then
  mass=$(json "$work/static/fit.json" 'd["parameters"]["gravity"]["mass"]["value"]')
  # The table holds zerog sim's default 100 kg payload (calib/static_table/README.md).
  /usr/bin/python3 -c "import sys; sys.exit(abs(float(sys.argv[1]) - 100.0) > 1.0)" "$mass" \
    || fail "static_fit: mass $mass kg, not within 1 kg of the table's 100 kg"
  echo "static_table: fitted mass $mass kg"
fi

echo "== calib/poses: design --attitudes"
if run poses "$zerog" design --attitudes calib/poses/001_appendix_c_attitudes.csv \
     --out "$work/poses/design.csv"; then
  rows=$(grep -cv '^#' "$work/poses/design.csv")
  [ "$rows" -eq 16 ] || fail "poses: $rows lines in the design (15 attitudes and a header expected)"
fi

echo "== calib/robots/lbr_iiwa14_r820.robot.toml: a 7-joint recording imported through it"
mkdir -p "$work/iiwa"
/usr/bin/python3 - "$work/iiwa" <<'PY'
import math, sys
d = sys.argv[1]
with open(f"{d}/arm.csv", "w") as f:
    f.write("t,Fx,Fy,Fz,Mx,My,Mz,A1,A2,A3,A4,A5,A6,A7\n")
    for i in range(2500):  # 10 s at 4 ms, every joint moving
        t = i * 0.004
        q = [0.6 * math.sin(0.5 * t + k) for k in range(7)]
        f.write(",".join(f"{v:.9g}" for v in [t, 1.0, -2.0, -110.0, 0.1, 0.2, 0.0] + q) + "\n")
PY
cat >"$work/iiwa/cell.rig.toml" <<EOF
format = "zerog-rig"
version = 1
name = "iiwa-example"
robot_file = "$src/calib/robots/lbr_iiwa14_r820.robot.toml"
sample_period_s = 0.004
ft_rate_hz = 250.0
imu_rate_hz = 250.0
[flange_sensor]
p_m = [0.0, 0.0, 0.03]
q_wxyz = [1.0, 0.0, 0.0, 0.0]
[sensor_imu]
p_m = [0.0, 0.0, 0.0]
q_wxyz = [1.0, 0.0, 0.0, 0.0]
EOF
cat >"$work/iiwa/mapping.toml" <<'EOF'
format = "zerog-import"
version = 1
rig_file = "cell.rig.toml"
kinematics = "robot"
[files.arm]
path = "arm.csv"
time = { column = "t", unit = "s" }
force = { columns = ["Fx", "Fy", "Fz"], unit = "N" }
torque = { columns = ["Mx", "My", "Mz"], unit = "N*m" }
joints = { columns = ["A1", "A2", "A3", "A4", "A5", "A6", "A7"], unit = "rad" }
EOF
if run iiwa "$zerog" import --mapping "$work/iiwa/mapping.toml" --out "$work/iiwa/run.csv"; then
  grep -q 'LBR iiwa' "$work/iiwa/run.rig.toml" \
    || fail "iiwa: the imported rig does not name the iiwa from the robot file"
  [ "$(grep -c '^\[\[robot.joint\]\]' "$work/iiwa/run.rig.toml")" -eq 7 ] \
    || fail "iiwa: the imported rig does not carry the robot file's seven joints"
fi

echo "== firmware/rt/zerog-rt.sample.toml: zerog-rt --check-config beside a model and its rig"
cab=$work/cabinet
mkdir -p "$cab"
cp "$src/firmware/rt/zerog-rt.sample.toml" "$cab/zerog-rt.toml"
if run cab_sim "$zerog" sim --kind random --points 12 --seed 3 --out "$cab/run.csv" -q \
   && run cab_fit "$zerog" fit "$cab/run.csv" -q --out "$cab/fit.json" \
   && cp "$cab/run.rig.toml" "$cab/rig.rig.toml" \
   && run cab_export "$zerog" export --model "$cab/fit.json" --rig "$cab/rig.rig.toml" \
        --out "$cab/deploy.zgm" -q; then
  # The sample's paths (deploy.zgm, rig.rig.toml) are relative to its own folder: check it from
  # another folder.
  if run sample_config "$rt" --config "$cab/zerog-rt.toml" --check-config; then
    echo "sample configuration: $(tail -n 1 "$work/sample_config.out")"
  fi
fi

if [ $failures -ne 0 ]; then echo "examples_test: $failures failure(s)"; exit 1; fi
echo "examples_test: every shipped example passed through its command"
