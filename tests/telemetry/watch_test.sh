#!/bin/sh
# ctest `telemetry_watch` (label dds): `zerog watch` against zerog-telemetry-replay on loopback:
# it must print the model identity, health with the final fault, lines of measured vs
# predicted, and write the wrench samples it got (--csv) with the replay's values.
#   watch_test.sh ZEROG REPLAY OUT_DIR DOMAIN
set -eu
zerog=$1 replay=$2 out=$3 domain=$4
mkdir -p "$out"
rm -f "$out/watch.txt" "$out/watch.csv" "$out/cycles.csv"
net="--interface lo --peer 127.0.0.1"
"$zerog" watch --domain "$domain" $net --every 100 --duration 8 --csv "$out/watch.csv" \
  > "$out/watch.txt" &
w=$!
"$replay" --domain "$domain" $net --no-multicast --generate 400 --period-s 0.004 \
  --write-csv "$out/cycles.csv" --wait-subscribers 1 --wait-s 6 --linger-s 1
wait $w
cat "$out/watch.txt"
fail() { echo "watch_test: FAIL: $*" >&2; exit 1; }
grep -q '^model: rig replay-rig (KR 210 R2700), effects bias,gravity,linear_inertia,rotational_inertia, network no, file replay.zgm crc32 12345678$' "$out/watch.txt" || fail "no model identity line"
grep -q '^health: cycle 400 state fault fault contact_over_limit' "$out/watch.txt" || fail "no final health line (cycle 400, fault)"
grep -q '^cycle 200 t 0.796 s zero_g | F meas ' "$out/watch.txt" || fail "no line for cycle 200"
lines=$(grep -c '^cycle ' "$out/watch.txt")
[ "$lines" -ge 3 ] || fail "only $lines cycle lines (every 100 of 400 cycles)"
# The CSV: same values as the replay's cycles.csv (joined on cycle, same columns).
rows=$(($(wc -l < "$out/watch.csv") - 1))
[ "$rows" -ge 380 ] || fail "watch.csv has $rows rows of 400"
awk -F, 'NR == FNR { if (FNR == 1) { for (i = 1; i <= NF; ++i) col[$i] = i } else want[$1] = $0; next }
         FNR == 1 { for (i = 1; i <= NF; ++i) name[i] = $i; next }
         { split(want[$1], w, ","); for (i = 2; i <= NF; ++i) { if (!(name[i] in col)) continue;
             a = $i + 0; b = w[col[name[i]]] + 0; d = a - b; if (d < 0) d = -d;
             if (d > 1e-12 * (1 + (a < 0 ? -a : a))) { print "cycle " $1 " " name[i] ": " a " vs " b; bad = 1; exit 1 } } }
         END { exit bad }' "$out/cycles.csv" "$out/watch.csv" || fail "watch.csv differs from cycles.csv"
echo "watch_test: OK ($lines lines, $rows csv rows)"
