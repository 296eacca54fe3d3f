#!/usr/bin/env bash
# Ctrl-C during `lumesh converge`: it stops, still writes complete CSV, JSON and
# plot of what was measured (marked interrupted), exits 0, leaves no temporary file.
# usage: converge_sigint.sh LUMESH OUTDIR
set -u
lumesh=$1
dir=$2/converge-sigint
rm -rf "$dir"
mkdir -p "$dir"
"$lumesh" reference -o "$dir/ref.exr" --spp 16 --width 40 --height 40 > /dev/null || exit 1
"$lumesh" converge --reference "$dir/ref.exr" --seconds 120 --snapshots 0.1,0.2,0.5,1,2,3,60 \
  --out "$dir/run" --vs-path-tracer > "$dir/log" 2>&1 &
pid=$!
sleep 6  # past start-up and several snapshots, even under ASan
kill -INT "$pid"
start=$(date +%s)
wait "$pid"
rc=$?
took=$(( $(date +%s) - start ))
cat "$dir/log"
[ "$rc" -eq 0 ] || { echo "exit code $rc, expected 0"; exit 1; }
[ "$took" -le 20 ] || { echo "took ${took}s to stop"; exit 1; }
grep -q "(interrupted" "$dir/log" || { echo "no '(interrupted' in the output"; exit 1; }
csv="$dir/run/convergence.csv"
[ -s "$csv" ] || { echo "no convergence.csv"; exit 1; }
rows=$(($(wc -l < "$csv") - 1))
# 8 snapshot times per method (the list and 120): the interruption, 6 s in, leaves some out.
[ "$rows" -ge 1 ] && [ "$rows" -lt 16 ] || { echo "$rows rows after an interruption"; exit 1; }
fields=$(head -1 "$csv" | tr -cd , | wc -c)
while IFS= read -r line; do
  [ "$(printf '%s' "$line" | tr -cd , | wc -c)" -eq "$fields" ] || { echo "incomplete row: $line"; exit 1; }
done < "$csv"
grep -q '"interrupted":[[:space:]]*true' "$dir/run/convergence.json" || { echo "JSON does not say interrupted"; exit 1; }
[ -s "$dir/run/convergence.png" ] || { echo "no plot"; exit 1; }
ls "$dir/run" | grep -q '\.tmp$' && { echo "a temporary file was left behind"; exit 1; }
echo "ok: $rows rows written after Ctrl-C"
exit 0
