#!/usr/bin/env bash
# bench/indirect.sh — the indirect issue's table: interiors lit through an opening
# against the Cornell boxes, the cache and the Embree path tracer at equal time
# (lumesh converge --vs-path-tracer, the sampler `auto` picks), against each
# scene's model-transport reference:
#   mean dE / relMSE at each snapshot, the path tracer's beside them, and the
#   99th-percentile dE and mean radiance (red) at the end; under each cache row,
#   the cache's own estimate of its mean dE and of the share of pixels above the
#   JND (cache_estimate) against the same measured, and its final state; where more
#   than 1% of the pixels lie in leaves not tested yet, their share [untested]: the
#   estimate is a guess there.
#
# usage: bench/indirect.sh [BUILD_DIR] [SECONDS] [REFERENCE_SECONDS] [SCALE]
#   BUILD_DIR          where lumesh was built (default build/release)
#   SECONDS            length of each run (default 60)
#   REFERENCE_SECONDS  path-tracing time of a missing reference (default 600); kept in
#                      BUILD_DIR/bench-data and reused
#   SCALE              image size as a multiple of each camera's (default 1: the door at
#                      320x180, the window room 320x240; the boxes are always 256x256)
# Scenes: bench/scenes/veach-door.json and window-room.json, and CornellBox-Original,
# -Glossy, -Water from ../shared/scenes beside the checkout.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
seconds=${2:-60}
ref_seconds=${3:-600}
scale=${4:-1}
lumesh=$build/lumesh
data=$build/bench-data
mkdir -p "$data"
[ -x "$lumesh" ] || { echo "no $lumesh: build first (cmake --build $build)"; exit 1; }

snaps=$(python3 -c "import sys; t=float(sys.argv[1]); print(','.join(str(s) for s in (1,2,5,10,30,60,120) if s < t) + ',' + sys.argv[1])" "$seconds")
rows=()
run() { # name scene width height
  local name=$1 scene=$2 w=$3 h=$4 ref=$data/$1-${3}x${4}-ref.exr out=$data/$1-${3}x${4}-indirect
  if [ ! -s "$ref" ]; then
    echo "reference for $name: ${ref_seconds} s of path tracing (kept in $ref)" >&2
    "$lumesh" reference "$scene" -o "$ref" --transport model --seconds "$ref_seconds" --width "$w" --height "$h" >&2
  fi
  echo "$name: ${seconds} s, cache and path tracer" >&2
  "$lumesh" converge "$scene" --reference "$ref" --seconds "$seconds" --out "$out" --snapshots "$snaps" \
    --vs-path-tracer > "$out.log"
  rows+=("$name" "$out/convergence.json")
}
run veach-door bench/scenes/veach-door.json $((320 * scale)) $((180 * scale))
run window-room bench/scenes/window-room.json $((320 * scale)) $((240 * scale))
for box in CornellBox-Original CornellBox-Glossy CornellBox-Water; do
  run "$box" "../shared/scenes/cornell-box/$box.obj" 256 256
done

python3 - "$snaps" "${rows[@]}" <<'PY'
import json, sys
snaps = [float(s) for s in sys.argv[1].split(",")]
args = sys.argv[2:]
head = " | ".join("%g s" % s for s in snaps)
print("| scene | method | " + head + " | p99 dE at the end | converged |")
print("|---|---|" + "---|" * len(snaps) + "---|---|")
for i in range(0, len(args), 2):
    name, j = args[i], json.load(open(args[i + 1]))
    for method, rows in j["methods"].items():
        def at(t):
            best = None
            for r in rows:
                if r["target_seconds"] <= t + 1e-9:
                    best = r
            return "%.2f / %.2g" % (best["error"]["delta_e_mean"], best["error"]["relmse"]) if best else "-"
        conv = j.get("converged_seconds") if method.startswith("lumesh") else None
        print("| %s | %s | %s | %.1f | %s |" % (name, method, " | ".join(at(s) for s in snaps),
              rows[-1]["error"]["delta_e_p99"], "%.1f s" % conv if conv else "-"))
        if method.startswith("lumesh"):
            # The cache's own estimate (cache_estimate) beside the error measured.
            def est(t):
                best = None
                for r in rows:
                    if r["target_seconds"] <= t + 1e-9:
                        best = r
                if not best or "estimated_error" not in best:
                    return "-"
                e = best["estimated_error"]
                guess = " [%.0f%% untested]" % (100 * e["fraction_untested"]) if e.get("fraction_untested", 0) > 0.01 else ""
                return "%.2f (%.0f%%)%s vs %.2f (%.0f%%)" % (
                    e["delta_e_mean"], 100 * e["fraction_above_jnd"], guess,
                    best["error"]["delta_e_mean"], 100 * best["error"]["delta_e_above_jnd"])
            print("| %s | estimated vs measured dE (above JND) | %s | | %s |" % (
                name, " | ".join(est(s) for s in snaps), rows[-1]["state"]))
PY
