#!/usr/bin/env bash
# hil.sh --bin BUILD_DIR --out DIR CASE...
#
# Hardware-in-the-loop run of zerog-rt against the rig emulator (zerog-emu: KR 210 controller
# over RSI/UDP with servo lag, ATI NETCANOEM board on vcan0, STIM300 on a pty, all driven by the
# rig simulator). Needs a kernel with vcan (tests/vm/run_in_vm.sh provides one). For each CASE
# (tests/hil/cases/CASE.toml = the emulator's scenario; zerog-rt's configuration template is
# cases/zerog-rt.base.toml, extended or replaced by CASE.rt.toml if there is one) it starts the
# emulator, deploys the emulated payload's exact model with `zerog export`, runs zerog-rt with
# --enable-zero-g and checks the run with check_hil.py.
# A scenario with a `# plc = SCRIPT` line has no --enable-zero-g: SCRIPT (in tests/hil/, the
# cell PLC over Modbus) runs beside zerog-rt and enables zero-g itself. A template with
# @DDS_DOMAIN@ gets DDS telemetry: the independent Python subscriber (the repository's .venv)
# records every topic during the run and check_telemetry.py compares it with cycles.csv.
# Results per case in DIR/CASE/. Exit status: 0 if every case passed, 77 if none failed but some
# were inconclusive (the VM could not keep the rig in real time), else 1.
set -uo pipefail

here=$(cd "$(dirname "$0")" && pwd)
bin= out=
cases=()
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    -*) echo "hil.sh: unknown option $1" >&2; exit 2 ;;
    *) cases+=("$1"); shift ;;
  esac
done
[ -n "$bin" ] && [ -n "$out" ] && [ ${#cases[@]} -gt 0 ] || {
  echo "usage: hil.sh --bin BUILD_DIR --out DIR CASE..." >&2; exit 2; }
emu=$bin/host/emu/zerog-emu
rt=$bin/firmware/rt/zerog-rt
zerog=$bin/host/cli/zerog
for p in "$emu" "$rt" "$zerog"; do
  [ -x "$p" ] || { echo "hil.sh: $p not built" >&2; exit 2; }
done
ip link show vcan0 >/dev/null 2>&1 || { echo "hil.sh: no vcan0 (run inside tests/vm/run_in_vm.sh)" >&2; exit 2; }
# Warm the guest's page cache before the first, timed case: cold (binaries and libraries read
# over 9p, Python's numpy), zerog-rt's start-up took 1.4 s longer in the first case of each VM,
# which then met its fault at 3 s with fewer cycles in zero-g than the checks want.
cat "$emu" "$rt" "$zerog" >/dev/null
for p in "$emu" "$rt" "$zerog"; do "$p" --help >/dev/null 2>&1; done
/usr/bin/python3 -c 'import numpy' 2>/dev/null

# One run of case $1 into folder $2 (attempt $3); 0 if it ran and every check passed.
run_case() {
  local c=$1 w=$2 attempt=$3
  local scenario=$here/cases/$c.toml own=$here/cases/$c.rt.toml base=$here/cases/zerog-rt.base.toml
  [ -f "$scenario" ] || { echo "hil.sh: no case $c" >&2; return 1; }
  rm -rf "$w" && mkdir -p "$w/rec"
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
  [ -n "$duration" ] || { echo "hil.sh: $scenario lacks a '# duration_s = N' line" >&2; return 1; }
  echo "=== $c: ${duration} s (attempt $attempt) ==="
  local emu_start emu_pid rt_duration rt_status emu_status
  # The DDS subscriber first: Python and its imports can take seconds in the VM, and the
  # emulator's run is timed.
  local domain=$((150 + attempt)) dds= sub_pid=
  if grep -q '@DDS_DOMAIN@' "$template"; then
    dds=$here/../../.venv/bin/python
    "$dds" "$here/../telemetry/dds_subscriber.py" --domain $domain --interface lo \
      --peer 127.0.0.1 --no-multicast --duration $((${duration%.*} + 60)) --idle 3 \
      --out "$w/telemetry.jsonl" --ready "$w/telemetry.ready" 2>"$w/telemetry.err" &
    sub_pid=$!
    for _ in $(seq 1 300); do
      [ -f "$w/telemetry.ready" ] && break
      kill -0 $sub_pid 2>/dev/null || break
      sleep 0.1
    done
    [ -f "$w/telemetry.ready" ] || echo "hil.sh: $c: the DDS subscriber did not start" >&2
  fi
  # The payload's truth model and the rig first, and zerog export, before the emulator's clock
  # starts: in the VM the export alone takes about a second, which every scenario's event times
  # would otherwise have to leave for start-up.
  "$emu" --scenario "$scenario" --write-model "$w/truth-model.json" --write-rig "$w/rig.rig.toml" \
    --write-only >"$w/emu-write.out" 2>&1 \
    || { echo "hil.sh: $c: zerog-emu --write-only failed:" >&2; cat "$w/emu-write.out" >&2;
         kill $sub_pid 2>/dev/null; return 1; }
  "$zerog" export --model "$w/truth-model.json" --rig "$w/rig.rig.toml" --out "$w/model.zgm" -q \
    || { echo "hil.sh: $c: zerog export failed" >&2; kill $sub_pid 2>/dev/null; return 1; }
  sed -e "s|@MODEL@|$w/model.zgm|" -e "s|@RIG@|$w/rig.rig.toml|" -e "s|@IMU@|$w/imu-tty|" \
    -e "s|@DDS_DOMAIN@|$domain|" "$template" >"$w/zerog-rt.toml"
  emu_start=$(date +%s.%N)
  "$emu" --scenario "$scenario" --can vcan0 --imu-link "$w/imu-tty" \
    --robot-bind 127.0.0.1:49153 --rt-address 127.0.0.1:49152 --duration "$duration" \
    --truth-out "$w/truth.csv" --summary-out "$w/emu.json" >"$w/emu.out" 2>"$w/emu.err" &
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
  # zerog-rt stops 0.7 s before the emulator does, so the robot never goes silent on it: at an
  # absolute deadline from the emulator's start (SIGINT: it stops and writes its files), not
  # after a --duration counted from its own start, which its start-up (DDS, Modbus, the F/T
  # calibration read-out) would push past the emulator's end under the VM's emulation.
  "$rt" --config "$w/zerog-rt.toml" $enable --record "$w/rec" --duration "$duration" \
    --summary-out "$w/rt.json" >"$w/rt.out" 2>"$w/rt.err" &
  local rt_pid=$!
  # Start-up figures: zerog-rt started this long after the emulator (its first reply is in
  # truth.csv, on the emulator's clock).
  awk -v s="$emu_start" -v n="$(date +%s.%N)" 'BEGIN { printf "zerog_rt_started_s = %.3f\n", n - s }' \
    >"$w/start.txt"
  if [ -n "$plc" ]; then
    /usr/bin/python3 "$here/$plc" --port 1502 --out "$w/plc.json" >"$w/plc.out" 2>&1 &
    plc_pid=$!
  fi
  rt_duration=$(awk -v d="$duration" -v s="$emu_start" -v n="$(date +%s.%N)" \
    'BEGIN { t = d - (n - s) - 0.7; print (t > 0 ? t : 0) }')
  (sleep "$rt_duration" && kill -INT $rt_pid 2>/dev/null) &
  local stopper=$!
  wait $rt_pid
  rt_status=$?
  kill $stopper 2>/dev/null
  wait $stopper 2>/dev/null
  if [ -n "$plc_pid" ]; then wait $plc_pid; plc_status=$?; fi
  wait $emu_pid
  emu_status=$?
  if [ -n "$sub_pid" ]; then
    wait $sub_pid
    local crc
    crc=$(/usr/bin/python3 -c 'import sys, zlib; print(hex(zlib.crc32(open(sys.argv[1], "rb").read())))' "$w/model.zgm")
    "$dds" "$here/../telemetry/check_telemetry.py" --received "$w/telemetry.jsonl" \
      --cycles "$w/rec/cycles.csv" --expect-crc "$crc" --min-fraction 0.95 >"$w/telemetry.txt" 2>&1
    echo $? >"$w/telemetry.status"
  fi
  [ $plc_status -eq 0 ] || echo "hil.sh: $c: the PLC script exited $plc_status (see plc.json)" >&2
  if [ $rt_status -ne 0 ] || [ $emu_status -ne 0 ]; then
    echo "hil.sh: $c: zerog-rt exited $rt_status, zerog-emu $emu_status" >&2
    tail -n 5 "$w/rt.err" "$w/emu.err" >&2
    return 1
  fi
  /usr/bin/python3 "$here/check_hil.py" --case "$c" --dir "$w" --scenario "$scenario" \
    --rt-config "$w/zerog-rt.toml" --attempt "$attempt"
}

# A case that fails is run once more (its first run kept in CASE.attempt1/, the retry recorded in
# check.json): under qemu's software emulation the guest sometimes freezes for 30 ms or more,
# which a real cabinet PC does not, and a late reply then really jolts the emulated robot. A
# behaviour that is broken fails both times. A retry that fails while the emulated rig itself
# fell more than two cycles behind real time (check_hil.py, exit status 3) is inconclusive: the
# VM could not emulate the rig, which says nothing about zerog-rt. Then, if nothing failed, the
# exit status is 77 (ctest: skipped) and the inconclusive cases are listed.
status=0
inconclusive=()
for c in "${cases[@]}"; do
  if ! run_case "$c" "$out/$c" 1; then
    rm -rf "$out/$c.attempt1" && mv "$out/$c" "$out/$c.attempt1"
    run_case "$c" "$out/$c" 2
    case $? in
      0) ;;
      3) inconclusive+=("$c") ;;
      *) status=1 ;;
    esac
  fi
done
if [ $status -eq 0 ] && [ ${#inconclusive[@]} -gt 0 ]; then
  echo "hil.sh: inconclusive, the emulated rig could not keep real time in this VM:" \
    "${inconclusive[*]} (check.json: rig_worst_lag_s); the other cases passed" >&2
  exit 77
fi
exit $status
