#!/usr/bin/env bash
# hil.sh --bin BUILD_DIR --out DIR [--mode lockstep|realtime] [--bus local|vcan] [--seed N]
#        [--mutant NAME --expect-fail TEXT] [--ros2-mutant NAME --expect-fail TEXT]
#        [--zerog PATH] CASE...
#
# Hardware-in-the-loop run of zerog-rt against the rig emulator (zerog-emu: KR 210 controller
# over RSI/UDP with servo lag, ATI NETCANOEM board on a CAN bus, STIM300 on a pty, all driven by
# the rig simulator). For each CASE (tests/hil/cases/CASE.toml = the emulator's scenario;
# zerog-rt's configuration template is cases/zerog-rt.base.toml, extended or replaced by
# CASE.rt.toml if there is one) it starts the emulator, deploys the emulated payload's exact
# model with `zerog export`, runs zerog-rt with --enable-zero-g and checks the run with
# check_hil.py.
#
#   --mode lockstep (default): zerog-emu is zerog-rt's clock (proto/lockstep.md): the result
#       depends on the seed only, not on the host's load; the checks are exact.
#   --mode realtime: both on the wall clock, as on the cabinet PC; a timing benchmark (the
#       checks' tolerances are those of a real rig).
#   --bus local (default): the F/T board on the user-space CAN transport (a unix datagram
#       socket, [ft] transport = "local"); --bus vcan: on vcan0 (a kernel with vcan, e.g. in
#       tests/vm/run_in_vm.sh).
#   --seed N: the scenario's [payload] seed replaced by N (results in DIR/CASE-seedN/).
#   --mutant NAME: zerog-rt --test-mutant NAME (broken on purpose); with --expect-fail TEXT the
#       run passes only if every case fails a check whose line contains TEXT.
#   --zerog PATH: the host CLI that writes the deployed model (`zerog export`; default
#       BUILD_DIR/host/cli/zerog). The sanitizer stage of scripts/test.sh passes the CI tree's:
#       the programs under test there are zerog-rt and zerog-emu, not the host tool.
# A scenario with a `# plc = SCRIPT` line has no --enable-zero-g: SCRIPT (in tests/hil/, the
# cell PLC over Modbus) runs beside zerog-rt and enables zero-g itself. A template with
# @DDS_DOMAIN@ gets DDS telemetry: the independent Python subscriber (the repository's .venv)
# records every topic during the run and check_telemetry.py compares it with cycles.csv; beside
# it the ROS 2-side subscriber (types from rosbags' ROS 2 message definitions) records every rt/
# topic and check_ros2_telemetry.py compares it with cycles.csv too.
#   --ros2-mutant NAME: that subscriber's types broken on purpose (ros2_subscriber.py --mutant
#       type_name|member_order); with --expect-fail TEXT the run passes only if it is caught.
# Results per case in DIR/CASE/. Exit status 0 if every case passed, else 1. A failed check is a
# failure: there is no retry and no "inconclusive".
set -uo pipefail

here=$(cd "$(dirname "$0")" && pwd)
bin= out= mode=lockstep bus=local seed= mutant= expect_fail= zerog= ros2_mutant=
cases=()
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --mode) mode=$2; shift 2 ;;
    --bus) bus=$2; shift 2 ;;
    --seed) seed=$2; shift 2 ;;
    --mutant) mutant=$2; shift 2 ;;
    --ros2-mutant) ros2_mutant=$2; shift 2 ;;
    --expect-fail) expect_fail=$2; shift 2 ;;
    --zerog) zerog=$2; shift 2 ;;
    -*) echo "hil.sh: unknown option $1" >&2; exit 2 ;;
    *) cases+=("$1"); shift ;;
  esac
done
[ -n "$bin" ] && [ -n "$out" ] && [ ${#cases[@]} -gt 0 ] || {
  echo "usage: hil.sh --bin BUILD_DIR --out DIR [--mode lockstep|realtime] [--bus local|vcan]" \
    "[--seed N] [--mutant NAME --expect-fail TEXT] [--zerog PATH] CASE..." >&2; exit 2; }
case "$mode" in lockstep|realtime) ;; *) echo "hil.sh: --mode lockstep or realtime" >&2; exit 2 ;; esac
case "$bus" in local|vcan) ;; *) echo "hil.sh: --bus local or vcan" >&2; exit 2 ;; esac
[ -z "$expect_fail" ] || [ -n "$mutant$ros2_mutant" ] || {
  echo "hil.sh: --expect-fail needs --mutant or --ros2-mutant" >&2; exit 2; }
# One rule for paths (proto/paths.md): a path on the command line is relative to the current
# folder, a path inside a file is relative to that file's folder. The configuration written for
# zerog-rt below lives in the results folder, so the paths it names are made absolute here.
bin=$(realpath -m -- "$bin")
out=$(realpath -m -- "$out")
[ -z "$zerog" ] || zerog=$(realpath -m -- "$zerog")
emu=$bin/host/emu/zerog-emu
rt=$bin/firmware/rt/zerog-rt
zerog=${zerog:-$bin/host/cli/zerog}
for p in "$emu" "$rt" "$zerog"; do
  [ -x "$p" ] || { echo "hil.sh: $p not built" >&2; exit 2; }
done
if [ "$bus" = vcan ]; then
  ip link show vcan0 >/dev/null 2>&1 || {
    echo "hil.sh: --bus vcan needs vcan0 (run inside tests/vm/run_in_vm.sh)" >&2; exit 2; }
fi
# Warm the page cache before the first case (in the VM, binaries and libraries come over 9p).
cat "$emu" "$rt" "$zerog" >/dev/null
for p in "$emu" "$rt" "$zerog"; do "$p" --help >/dev/null 2>&1; done
/usr/bin/python3 -c 'import numpy' 2>/dev/null

# One run of case $1 into folder $2; 0 if it ran and every check passed.
run_case() {
  local c=$1 w=$2
  local source=$here/cases/$c.toml own=$here/cases/$c.rt.toml base=$here/cases/zerog-rt.base.toml
  [ -f "$source" ] || { echo "hil.sh: no case $c" >&2; return 1; }
  rm -rf "$w" && mkdir -p "$w/rec"
  # The scenario, with the seed of this run.
  local scenario=$w/scenario.toml
  if [ -n "$seed" ]; then
    grep -q '^seed = ' "$source" || { echo "hil.sh: $source has no 'seed = ' line" >&2; return 1; }
    sed "s/^seed = .*/seed = $seed/" "$source" >"$scenario"
  else
    cp "$source" "$scenario"
  fi
  # zerog-rt's configuration template: the shared one, the shared one and the case's tables, or
  # the case's own (cases/zerog-rt.base.toml says when which).
  local template=$w/zerog-rt.template.toml
  if [ ! -f "$own" ]; then
    cp "$base" "$template"
  elif [ "$(head -n 1 "$own")" = "# extends zerog-rt.base.toml" ]; then
    { cat "$base"; echo; cat "$own"; } >"$template"
  else
    cp "$own" "$template"
  fi
  local duration
  duration=$(sed -n 's/^# duration_s = \([0-9.]*\)$/\1/p' "$scenario")
  [ -n "$duration" ] || { echo "hil.sh: $source lacks a '# duration_s = N' line" >&2; return 1; }
  echo "=== $c: ${duration} s, $mode, F/T on $bus${seed:+, seed $seed}${mutant:+, MUTANT $mutant} ==="
  local emu_pid rt_status emu_status
  # Free ports for this run (RSI: zerog-rt's and the controller's; Modbus) and a DDS domain of
  # its own: runs of other build trees may be going on beside this one.
  local ports rt_port robot_port modbus_port
  ports=$(/usr/bin/python3 -c '
import socket
held = []
for kind in (socket.SOCK_DGRAM, socket.SOCK_DGRAM, socket.SOCK_STREAM):
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    held.append(s)
print(" ".join(str(s.getsockname()[1]) for s in held))')
  read -r rt_port robot_port modbus_port <<<"$ports"
  # The DDS subscriber first: Python and its imports take a while.
  local domain=$((220 + rt_port % 12)) dds= sub_pid= ros2_pid=  # 220..231: the telemetry tests use 10..219
  if grep -q '@DDS_DOMAIN@' "$template"; then
    dds=$here/../../.venv/bin/python
    "$dds" "$here/../telemetry/dds_subscriber.py" --domain $domain --interface lo \
      --peer 127.0.0.1 --no-multicast --duration $((${duration%.*} * 20 + 120)) --idle 3 \
      --out "$w/telemetry.jsonl" --ready "$w/telemetry.ready" 2>"$w/telemetry.err" &
    sub_pid=$!
    "$dds" "$here/../telemetry/ros2_subscriber.py" --domain $domain --interface lo \
      --peer 127.0.0.1 --no-multicast --duration $((${duration%.*} * 20 + 120)) --idle 3 \
      ${ros2_mutant:+--mutant "$ros2_mutant"} --out "$w/ros2.jsonl" --ready "$w/ros2.ready" \
      2>"$w/ros2.err" &
    ros2_pid=$!
    for _ in $(seq 1 300); do
      [ -f "$w/telemetry.ready" ] && [ -f "$w/ros2.ready" ] && break
      kill -0 $sub_pid 2>/dev/null && kill -0 $ros2_pid 2>/dev/null || break
      sleep 0.1
    done
    [ -f "$w/telemetry.ready" ] && [ -f "$w/ros2.ready" ] || {
      echo "hil.sh: $c: a DDS subscriber did not start:" >&2
      cat "$w/telemetry.err" "$w/ros2.err" >&2; kill $sub_pid $ros2_pid 2>/dev/null; return 1; }
    sub_pid="$sub_pid $ros2_pid"
  fi
  # The payload's truth model and the rig first, and zerog export, before the emulator's clock
  # starts.
  "$emu" --scenario "$scenario" --write-model "$w/truth-model.json" --write-rig "$w/rig.rig.toml" \
    --write-only >"$w/emu-write.out" 2>&1 \
    || { echo "hil.sh: $c: zerog-emu --write-only failed:" >&2; cat "$w/emu-write.out" >&2;
         kill $sub_pid 2>/dev/null; return 1; }
  "$zerog" export --model "$w/truth-model.json" --rig "$w/rig.rig.toml" --out "$w/model.zgm" -q \
    || { echo "hil.sh: $c: zerog export failed" >&2; kill $sub_pid 2>/dev/null; return 1; }
  # The sockets in a folder of their own under /tmp: a socket cannot be bound on every file
  # system (the VM's results folder is 9p) and its path is limited to 107 bytes.
  local sockets
  sockets=$(mktemp -d /tmp/zerog-hil.XXXXXX)
  local can_args=(--can vcan0) ft_bus=
  if [ "$bus" = local ]; then
    can_args=(--can-local "$sockets/can")
    ft_bus="transport = \"local\"\nlocal_path = \"$sockets/can\""
  fi
  sed -e "s|@MODEL@|$w/model.zgm|" -e "s|@RIG@|$w/rig.rig.toml|" -e "s|@IMU@|$w/imu-tty|" \
    -e "s|@DDS_DOMAIN@|$domain|" -e "s|^bind_port = 49152\$|bind_port = $rt_port|" \
    -e "s|^port = 49153\$|port = $robot_port|" -e "s|^port = 1502\$|port = $modbus_port|" \
    "$template" >"$w/zerog-rt.toml"
  if [ -n "$ft_bus" ]; then
    grep -q '^interface = "vcan0"$' "$w/zerog-rt.toml" \
      || { echo "hil.sh: $c: the template has no [ft] interface = \"vcan0\" line" >&2; return 1; }
    sed -i "s|^interface = \"vcan0\"\$|$ft_bus|" "$w/zerog-rt.toml"
  fi
  local step_args=() rt_step_args=()
  if [ "$mode" = lockstep ]; then
    step_args=(--lockstep "$sockets/lockstep")
    rt_step_args=(--lockstep "$sockets/lockstep")
    # A PLC script acts on the wall clock: emulated time must not outrun it.
    grep -q '^# plc = ' "$scenario" && step_args+=(--lockstep-paced)
  fi
  local emu_start
  emu_start=$(date +%s.%N)
  # A guard against a hung program only (lockstep runs take a few times the scenario's length
  # at most): never part of a result.
  local guard=$(( ${duration%.*} * 30 + 120 ))
  timeout -s INT -k 10 $guard "$emu" --scenario "$scenario" "${can_args[@]}" --imu-link "$w/imu-tty" \
    --robot-bind 127.0.0.1:$robot_port --rt-address 127.0.0.1:$rt_port --duration "$duration" \
    "${step_args[@]}" --truth-out "$w/truth.csv" --summary-out "$w/emu.json" \
    >"$w/emu.out" 2>"$w/emu.err" &
  emu_pid=$!
  for _ in $(seq 1 300); do
    grep -q "zerog-emu: ready" "$w/emu.out" 2>/dev/null && break
    kill -0 $emu_pid 2>/dev/null || break
    sleep 0.1
  done
  if ! grep -q "zerog-emu: ready" "$w/emu.out" 2>/dev/null; then
    echo "hil.sh: $c: the emulator did not come up:" >&2; cat "$w/emu.err" >&2
    kill $emu_pid $sub_pid 2>/dev/null; wait $emu_pid 2>/dev/null; return 1
  fi
  local plc enable=--enable-zero-g plc_pid= plc_status=0
  plc=$(sed -n 's/^# plc = \(.*\)$/\1/p' "$scenario")
  [ -z "$plc" ] || enable=
  local mutant_args=()
  [ -z "$mutant" ] || mutant_args=(--test-mutant "$mutant")
  local rt_pid stopper=
  if [ "$mode" = lockstep ]; then
    # zerog-rt stops when the emulator ends the run (the lockstep's `end`).
    timeout -s INT -k 10 $guard "$rt" --config "$w/zerog-rt.toml" $enable "${rt_step_args[@]}" \
      "${mutant_args[@]}" --record "$w/rec" --summary-out "$w/rt.json" >"$w/rt.out" 2>"$w/rt.err" &
    rt_pid=$!
  else
    # zerog-rt stops 0.7 s before the emulator does, so the robot never goes silent on it: at
    # an absolute deadline from the emulator's start (SIGINT: it stops and writes its files).
    "$rt" --config "$w/zerog-rt.toml" $enable "${mutant_args[@]}" --record "$w/rec" \
      --duration "$duration" --summary-out "$w/rt.json" >"$w/rt.out" 2>"$w/rt.err" &
    rt_pid=$!
    local rt_duration
    rt_duration=$(awk -v d="$duration" -v s="$emu_start" -v n="$(date +%s.%N)" \
      'BEGIN { t = d - (n - s) - 0.7; print (t > 0 ? t : 0) }')
    (sleep "$rt_duration" && kill -INT $rt_pid 2>/dev/null) &
    stopper=$!
  fi
  awk -v s="$emu_start" -v n="$(date +%s.%N)" 'BEGIN { printf "zerog_rt_started_s = %.3f\n", n - s }' \
    >"$w/start.txt"
  if [ -n "$plc" ]; then
    /usr/bin/python3 "$here/$plc" --port "$modbus_port" --out "$w/plc.json" >"$w/plc.out" 2>&1 &
    plc_pid=$!
  fi
  # Whichever side ends first: if it failed, the other is stopped at once (SIGINT, then SIGKILL
  # after 3 s) instead of waiting for a peer that will never come, and the failed side is named.
  local first first_status other other_name first_name
  wait -n -p first $rt_pid $emu_pid
  first_status=$?
  if [ "$first" = "$rt_pid" ]; then
    rt_status=$first_status other=$emu_pid first_name=zerog-rt other_name=zerog-emu
  else
    emu_status=$first_status other=$rt_pid first_name=zerog-emu other_name=zerog-rt
  fi
  if [ "$first_status" -ne 0 ]; then
    local err_file=$w/rt.err
    [ "$first_name" = zerog-emu ] && err_file=$w/emu.err
    echo "hil.sh: $c: $first_name exited $first_status: $(tail -n 1 "$err_file" 2>/dev/null)" >&2
    echo "hil.sh: $c: stopping $other_name" >&2
    kill -INT $other 2>/dev/null
    for _ in $(seq 1 30); do kill -0 $other 2>/dev/null || break; sleep 0.1; done
    kill -KILL $other 2>/dev/null
    [ -z "$plc_pid" ] || kill $plc_pid 2>/dev/null
    [ -z "$sub_pid" ] || kill $sub_pid 2>/dev/null
  fi
  local other_status=0
  wait $other || other_status=$?
  if [ "$other" = "$rt_pid" ]; then rt_status=$other_status; else emu_status=$other_status; fi
  if [ -n "$stopper" ]; then kill $stopper 2>/dev/null; wait $stopper 2>/dev/null; fi
  if [ -n "$plc_pid" ]; then wait $plc_pid; plc_status=$?; fi
  awk -v s="$emu_start" -v n="$(date +%s.%N)" 'BEGIN { printf "wall_s = %.3f\n", n - s }' \
    >>"$w/start.txt"
  rm -rf "$sockets"
  if [ -n "$sub_pid" ]; then
    wait $sub_pid
    local crc
    crc=$(/usr/bin/python3 -c 'import sys, zlib; print(hex(zlib.crc32(open(sys.argv[1], "rb").read())))' "$w/model.zgm")
    "$dds" "$here/../telemetry/check_telemetry.py" --received "$w/telemetry.jsonl" \
      --cycles "$w/rec/cycles.csv" --expect-crc "$crc" --min-fraction 0.95 >"$w/telemetry.txt" 2>&1
    echo $? >"$w/telemetry.status"
    "$dds" "$here/../telemetry/check_ros2_telemetry.py" --received "$w/ros2.jsonl" \
      --cycles "$w/rec/cycles.csv" --expect-crc "$crc" --min-fraction 0.95 >"$w/ros2.txt" 2>&1
    echo $? >"$w/ros2.status"
  fi
  [ $plc_status -eq 0 ] || echo "hil.sh: $c: the PLC script exited $plc_status (see plc.json)" >&2
  if [ $rt_status -ne 0 ] || [ $emu_status -ne 0 ]; then
    echo "hil.sh: $c: zerog-rt exited $rt_status, zerog-emu $emu_status" >&2
    tail -n 5 "$w/rt.err" "$w/emu.err" >&2
    return 1
  fi
  # The contact gate from this run's noise at rest (docs/zerog-rt.md, "Setting the contact
  # gate"): the drift cases float untouched; check_hil.py checks the replay.
  case "$c" in drift*)
    "$zerog" gate "$w/rec/cycles.csv" --config "$w/zerog-rt.toml" --json >"$w/gate.json" \
      2>"$w/gate.err" || echo "hil.sh: $c: zerog gate failed (see gate.err)" >&2 ;;
  esac
  # The servo model from this run's joints and corrections (docs/zerog-rt.md, "Identifying the
  # servo model"): check_hil.py compares it with the emulator's servo.
  case "$c" in servo_*|glide_elastic_fused|spin_elastic_fused)
    "$zerog" servo "$w/rec/cycles.csv" --config "$w/zerog-rt.toml" --json >"$w/servo.json" \
      2>"$w/servo.err" || echo "hil.sh: $c: zerog servo found no servo (see servo.json)" >&2 ;;
  esac
  /usr/bin/python3 "$here/check_hil.py" --case "$c" --dir "$w" --scenario "$scenario" \
    --rt-config "$w/zerog-rt.toml" \
    | tee "$w/check.txt"
  return "${PIPESTATUS[0]}"
}

status=0
for c in "${cases[@]}"; do
  w=$out/$c${seed:+-seed$seed}${mutant:+-$mutant}${ros2_mutant:+-ros2-$ros2_mutant}
  run_case "$c" "$w"
  st=$?
  if [ -n "$expect_fail" ]; then
    # A mutant must be caught: the case fails, and by the check named.
    if [ $st -eq 0 ]; then
      echo "hil.sh: $c: the mutant $mutant$ros2_mutant PASSED the checks: they cannot see what it breaks" >&2
      status=1
    elif ! grep -F -- "FAIL" "$w/check.txt" 2>/dev/null | grep -qF -- "$expect_fail"; then
      echo "hil.sh: $c: the mutant $mutant$ros2_mutant failed, but not the check '$expect_fail'" >&2
      status=1
    else
      echo "hil.sh: $c: mutant $mutant$ros2_mutant caught by '$expect_fail'"
    fi
  elif [ $st -ne 0 ]; then
    status=1
  fi
done
exit $status
