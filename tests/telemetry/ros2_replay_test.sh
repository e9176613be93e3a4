#!/bin/sh
# ctest `telemetry_ros2_python` and its mutants (label dds): zerog-telemetry-replay publishes
# generated records through the real TelemetryChannel on loopback and writes them as the
# recorder's cycles.csv; ros2_subscriber.py (types built from rosbags' ROS 2 message definitions,
# not from zerog's IDL) records every rt/ topic; check_ros2_telemetry.py compares field by field.
#   ros2_replay_test.sh REPLAY PYTHON OUT_DIR DOMAIN [MUTANT EXPECTED_TEXT]
# With MUTANT the subscriber's types are broken on purpose (ros2_subscriber.py --mutant): the
# check must fail, with a line containing EXPECTED_TEXT.
set -eu
replay=$1 python=$2 out=$3 domain=$4 mutant=${5:-} expected=${6:-}
here=$(dirname "$0")
mkdir -p "$out"
rm -f "$out/ready" "$out/received.jsonl" "$out/cycles.csv" "$out/check.txt"
net="--interface lo --peer 127.0.0.1 --no-multicast"
"$python" "$here/ros2_subscriber.py" --domain "$domain" $net --duration 60 --idle 2 \
  --out "$out/received.jsonl" --ready "$out/ready" ${mutant:+--mutant "$mutant"} &
sub=$!
i=0
while [ ! -f "$out/ready" ]; do
  i=$((i + 1))
  if [ $i -gt 300 ] || ! kill -0 $sub 2>/dev/null; then
    echo "ros2_replay_test: the ROS 2 subscriber did not start" >&2
    kill $sub 2>/dev/null || true
    exit 1
  fi
  sleep 0.1
done
"$replay" --domain "$domain" $net --generate 500 --period-s 0.004 --write-csv "$out/cycles.csv" \
  --wait-subscribers 1 --wait-s 20 --linger-s 0.5
wait $sub
status=0
"$python" "$here/check_ros2_telemetry.py" --received "$out/received.jsonl" \
  --cycles "$out/cycles.csv" --expect-crc 0x12345678 --min-fraction 0.95 >"$out/check.txt" 2>&1 \
  || status=$?
cat "$out/check.txt"
if [ -z "$mutant" ]; then exit $status; fi
if [ $status -eq 0 ]; then
  echo "ros2_replay_test: the mutant $mutant PASSED the check: it cannot see what it breaks" >&2
  exit 1
fi
if ! grep "FAIL" "$out/check.txt" | grep -qF -- "$expected"; then
  echo "ros2_replay_test: the mutant $mutant failed, but not with '$expected'" >&2
  exit 1
fi
echo "ros2_replay_test: mutant $mutant caught: '$expected'"
