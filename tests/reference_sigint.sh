#!/usr/bin/env bash
# Ctrl-C during `lumesh reference`: it stops, still writes an image made of
# complete samples, and exits 0 saying it was interrupted.
# usage: reference_sigint.sh LUMESH OUTDIR
set -u
lumesh=$1
out=$2/sigint.exr
rm -f "$out"
"$lumesh" reference -o "$out" --seconds 120 --width 48 --height 32 > "$2/sigint.log" 2>&1 &
pid=$!
sleep 5  # past start-up (dynamic linking, scene load, BVH) even under ASan
kill -INT "$pid"
start=$(date +%s)
wait "$pid"
rc=$?
took=$(( $(date +%s) - start ))
cat "$2/sigint.log"
[ "$rc" -eq 0 ] || { echo "exit code $rc, expected 0"; exit 1; }
[ "$took" -le 20 ] || { echo "took ${took}s to stop"; exit 1; }
grep -q "(interrupted)" "$2/sigint.log" || { echo "no '(interrupted)' in the output"; exit 1; }
[ -s "$out" ] || { echo "no image written"; exit 1; }
ls "$2" | grep -q "sigint.exr.tmp" && { echo "a temporary file was left behind"; exit 1; }
exit 0
