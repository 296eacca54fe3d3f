#!/usr/bin/env bash
# bench/bounces.sh — multiple bounces (issue 13's targets), on this machine:
#  1. against the full transport: `lumesh converge --bounces auto --vs-path-tracer`
#     at every snapshot (mean dE, relMSE, and the path tracer's at equal time),
#     with the bounce count auto chose and why;
#  2. what auto costs (the boxes): `lumesh render --bounces 1` and `--bounces auto`
#     until converged at the scene's JND, REPEATS times each, alternating (the
#     machine's load moves both alike), and the ratio of their medians.
#
# usage: bench/bounces.sh [BUILD_DIR] [SECONDS] [REFERENCE_SECONDS] [REPEATS] [SCENES...]
#   BUILD_DIR          where lumesh was built (default build/release)
#   SECONDS            length of each converge run (default 60)
#   REFERENCE_SECONDS  path-tracing time of a missing full-transport reference (default 600);
#                      kept in BUILD_DIR/bench-data as NAME-WxH-full.exr and reused
#   REPEATS            renders per bounce setting (default 3)
#   SCENES             any of CornellBox-Original CornellBox-Water veach-door (default
#                      CornellBox-Original veach-door); the boxes at 640x480, the door at
#                      640x360 (bench/scenes/veach-door.json)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
seconds=${2:-60}
ref_seconds=${3:-600}
repeats=${4:-3}
shift $(( $# < 4 ? $# : 4 ))
names=("$@")
[ ${#names[@]} -gt 0 ] || names=(CornellBox-Original veach-door)
lumesh=$build/lumesh
data=$build/bench-data
mkdir -p "$data"
[ -x "$lumesh" ] || { echo "no $lumesh: build first (cmake --build $build)"; exit 1; }

snaps=0.1,0.25,0.5,1,2,3,5,7,10,15,20,30,45,60,90,120
for name in "${names[@]}"; do
  if [ "$name" = veach-door ]; then
    scene=bench/scenes/veach-door.json; w=640; h=360
  else
    scene=../shared/scenes/cornell-box/$name.obj; w=640; h=480
  fi
  ref=$data/$name-${w}x$h-full.exr
  if [ ! -s "$ref" ]; then
    echo "full-transport reference for $name: ${ref_seconds} s of path tracing (kept in $ref)" >&2
    "$lumesh" reference "$scene" -o "$ref" --transport full --seconds "$ref_seconds" --width $w --height $h >&2
  fi
  out=$data/$name-bounces
  "$lumesh" converge "$scene" --reference "$ref" --transport full --seconds "$seconds" --out "$out" --snapshots "$snaps" \
    --vs-path-tracer --stats "$out/stats.json" > "$out.log"
  python3 - "$name" "$out/convergence.json" "$out/stats.json" <<'EOF'
import json, sys
name, path, stats = sys.argv[1], sys.argv[2], sys.argv[3]
j = json.load(open(path))
st = json.load(open(stats))
lm = j["methods"]["lumesh"]
pt = {r["target_seconds"]: r for r in j["methods"].get("path-tracer", [])}
print("\n%s against the full transport, %dx%d, %d s (%s)" % (name, j["width"], j["height"], j["seconds"], j["reference"]))
print(j["transport_note"])
print("| time | lumesh mean dE | lumesh relMSE | path tracer mean dE | path tracer relMSE | state |")
print("|---|---|---|---|---|---|")
for r in lm:
    p = pt.get(r["target_seconds"])
    print("| %g s (at %.2f) | %.3f | %.3g | %s | %s | %s |" % (
        r["target_seconds"], r["seconds"], r["error"]["delta_e_mean"], r["error"]["relmse"],
        "%.3f" % p["error"]["delta_e_mean"] if p else "-", "%.3g" % p["error"]["relmse"] if p else "-", r["state"]))
b = st["bounces"]
print("bounces at the end: %d (%s); each further bounce's largest dE where seen: %s; transport: %d vertices, "
      "%d hits, traced in %.1f ms, re-evaluated %d times in %.2f s" % (
          b["shown"], b["why"], ", ".join("%.2f" % x for x in b["delta_e"]), b["vertices"], b["hits"],
          1e3 * b["trace_seconds"], b["updates"], b["update_seconds"]))
EOF
  # What auto costs: time to convergence at the scene's JND, one bounce against auto
  # (the boxes: the door does not converge at its JND within minutes either way).
  if [ "$name" = veach-door ]; then continue; fi
  t1=(); ta=()
  for i in $(seq "$repeats"); do
    for b in 1 auto; do
      line=$("$lumesh" render "$scene" -o "$data/$name-bounces-$b.exr" --width $w --height $h --bounces $b \
             --stats "$data/$name-bounces-$b.json" 2>&1 | tail -1)
      s=$(python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); print("%.3f %s" % (j["seconds"], "converged" if j["converged"] else "not-converged"))' \
          "$data/$name-bounces-$b.json")
      if [ $b = 1 ]; then t1+=("$s"); else ta+=("$s"); fi
    done
  done
  python3 - "$name" "${t1[*]}" "${ta[*]}" <<'EOF'
import statistics, sys
name, one, auto = sys.argv[1], sys.argv[2].split(), sys.argv[3].split()
def parse(v): return [float(v[i]) for i in range(0, len(v), 2)], v[1::2]
t1, s1 = parse(one); ta, sa = parse(auto)
m1, ma = statistics.median(t1), statistics.median(ta)
print("%s, render until converged at the JND: one bounce %s s (median %.2f), auto %s s (median %.2f): auto/one %.2f%s" % (
    name, ", ".join("%.2f" % t for t in t1), m1, ", ".join("%.2f" % t for t in ta), ma, ma / m1,
    "" if all(s == "converged" for s in s1 + sa) else " (some runs did not converge)"))
EOF
done
