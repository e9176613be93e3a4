#!/bin/sh
# ctest `telemetry_dds_python` and `telemetry_ros2_python` (+ its mutants; label dds):
# zerog-telemetry-replay publishes generated records through the real TelemetryChannel on
# loopback (unicast, no multicast) and writes them as the recorder's cycles.csv; an independent
# Python subscriber (PyPI's cyclonedds) records every topic and a checker compares the two.
#   replay_test.sh REPLAY PYTHON OUT_DIR DOMAIN [ros2 [MUTANT EXPECTED_TEXT]]
# Without `ros2`: the zerog/ topics, dds_subscriber.py (hand-declared types), check_telemetry.py.
# With `ros2`: the rt/ topics, ros2_subscriber.py (types built from rosbags' ROS 2 message
# definitions, not from zerog's IDL), check_ros2_telemetry.py. With MUTANT the subscriber's types
# are broken on purpose (ros2_subscriber.py --mutant): the check must fail, with a line
# containing EXPECTED_TEXT.
set -eu
replay=$1 python=$2 out=$3 domain=$4 flavour=${5:-} mutant=${6:-} expected=${7:-}
here=$(dirname "$0")
if [ "$flavour" = ros2 ]; then
  subscriber=ros2_subscriber.py checker=check_ros2_telemetry.py
else
  subscriber=dds_subscriber.py checker=check_telemetry.py
fi
mkdir -p "$out"
rm -f "$out/ready" "$out/received.jsonl" "$out/cycles.csv" "$out/check.txt"
net="--interface lo --peer 127.0.0.1 --no-multicast"
"$python" "$here/$subscriber" --domain "$domain" $net --duration 60 --idle 2 \
  --out "$out/received.jsonl" --ready "$out/ready" ${mutant:+--mutant "$mutant"} &
sub=$!
i=0
while [ ! -f "$out/ready" ]; do
  i=$((i + 1))
  if [ $i -gt 300 ] || ! kill -0 $sub 2>/dev/null; then
    echo "replay_test: the Python subscriber ($subscriber) did not start" >&2
    kill $sub 2>/dev/null || true
    exit 1
  fi
  sleep 0.1
done
"$replay" --domain "$domain" $net --generate 500 --period-s 0.004 --write-csv "$out/cycles.csv" \
  --wait-subscribers 1 --wait-s 20 --linger-s 0.5
wait $sub
status=0
"$python" "$here/$checker" --received "$out/received.jsonl" \
  --cycles "$out/cycles.csv" --expect-crc 0x12345678 --min-fraction 0.95 >"$out/check.txt" 2>&1 \
  || status=$?
cat "$out/check.txt"
if [ -z "$mutant" ]; then exit $status; fi
if [ $status -eq 0 ]; then
  echo "replay_test: the mutant $mutant PASSED the check: it cannot see what it breaks" >&2
  exit 1
fi
if ! grep "FAIL" "$out/check.txt" | grep -qF -- "$expected"; then
  echo "replay_test: the mutant $mutant failed, but not with '$expected'" >&2
  exit 1
fi
echo "replay_test: mutant $mutant caught: '$expected'"
