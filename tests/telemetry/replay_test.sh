#!/bin/sh
# ctest `telemetry_dds_python` (label dds): zerog-telemetry-replay publishes generated records
# through the real TelemetryChannel on loopback (unicast, no multicast) and writes them as the
# recorder's cycles.csv; the independent Python subscriber (hand-declared types, PyPI's
# cyclonedds) records every topic; check_telemetry.py compares the two.
#   replay_test.sh REPLAY PYTHON OUT_DIR DOMAIN
set -eu
replay=$1 python=$2 out=$3 domain=$4
here=$(dirname "$0")
mkdir -p "$out"
rm -f "$out/ready" "$out/received.jsonl" "$out/cycles.csv"
net="--interface lo --peer 127.0.0.1 --no-multicast"
"$python" "$here/dds_subscriber.py" --domain "$domain" $net --duration 60 --idle 2 \
  --out "$out/received.jsonl" --ready "$out/ready" &
sub=$!
i=0
while [ ! -f "$out/ready" ]; do
  i=$((i + 1))
  if [ $i -gt 300 ] || ! kill -0 $sub 2>/dev/null; then
    echo "replay_test: the Python subscriber did not start" >&2
    kill $sub 2>/dev/null || true
    exit 1
  fi
  sleep 0.1
done
"$replay" --domain "$domain" $net --generate 500 --period-s 0.004 --write-csv "$out/cycles.csv" \
  --wait-subscribers 1 --wait-s 20 --linger-s 0.5
wait $sub
"$python" "$here/check_telemetry.py" --received "$out/received.jsonl" \
  --cycles "$out/cycles.csv" --expect-crc 0x12345678 --min-fraction 0.95
