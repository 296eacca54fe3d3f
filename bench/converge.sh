#!/usr/bin/env bash
# bench/converge.sh — the renderer's targets, measured with `lumesh converge`
# (640x480, the sampler `auto` picks, this machine), as a table:
#   first image (full geometry, coarse light) after the scene is loaded;
#   mean dE against the model-transport reference at 1 s and 10 s, and the time
#   it first reaches dE <= 1;
#   relMSE of the previewer and of the Embree path tracer at equal time (1 s, 10 s).
# Multi-mesh and --single-mesh are both run. A frame from cached samples (the
# viewer's, one sample a pixel) is timed by bench/bench_frame.
#
# usage: bench/converge.sh [BUILD_DIR] [SECONDS] [REFERENCE_SECONDS]
#   BUILD_DIR          where lumesh was built (default build/release)
#   SECONDS            length of each convergence run (default 10)
#   REFERENCE_SECONDS  path-tracing time of a missing reference (default 300); references
#                      are kept in BUILD_DIR/bench-data and reused
# Scenes come from ../shared/scenes beside the checkout (CornellBox-Water, -Original).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
seconds=${2:-10}
ref_seconds=${3:-300}
lumesh=$build/lumesh
data=$build/bench-data
scenes=../shared/scenes/cornell-box
mkdir -p "$data"
[ -x "$lumesh" ] || { echo "no $lumesh: build first (cmake --build $build)"; exit 1; }

rows=()
for name in CornellBox-Water CornellBox-Original; do
  ref=$data/$name-ref.exr
  if [ ! -s "$ref" ]; then
    echo "reference for $name: ${ref_seconds} s of path tracing (kept in $ref)" >&2
    "$lumesh" reference "$scenes/$name.obj" -o "$ref" --seconds "$ref_seconds" --width 640 --height 480 >&2
  fi
  for mode in multi single; do
    out=$data/$name-$mode
    flags=()
    [ "$mode" = single ] && flags=(--single-mesh)
    [ "$mode" = multi ] && flags=(--vs-path-tracer)
    "$lumesh" converge "$scenes/$name.obj" --reference "$ref" --seconds "$seconds" --out "$out" \
      --snapshots 0.1,0.2,0.5,1,2,3,5,7,10,20,50 "${flags[@]}" > "$out.log"
    rows+=("$name" "$mode" "$out/convergence.json")
  done
done

python3 - "${rows[@]}" <<'EOF'
import json, sys
args = sys.argv[1:]
print("| scene | cache | first image | dE@1s | dE@10s | dE<=1 at | converged | relMSE@1s (path tracer) | relMSE@10s (path tracer) | light+indirect samples at the end |")
print("|---|---|---|---|---|---|---|---|---|---|")
for i in range(0, len(args), 3):
    name, mode, path = args[i], args[i + 1], args[i + 2]
    j = json.load(open(path))
    lm = j["methods"].get("lumesh") or j["methods"].get("lumesh-single-mesh")
    pt = j["methods"].get("path-tracer", [])
    def at(rows, t, key):
        best = None
        for r in rows:
            if r["target_seconds"] <= t + 1e-9:
                best = r
        return best["error"][key] if best else float("nan")
    reach = next((r["seconds"] for r in lm if r["error"]["delta_e_mean"] <= 1.0), None)
    last = lm[-1]["samples"]
    light = sum(v for k, v in last.items() if k.startswith("light"))
    rel = lambda t: "%.2e (%s)" % (at(lm, t, "relmse"), "%.2e" % at(pt, t, "relmse") if pt else "-")
    conv = j["converged_seconds"]
    print("| %s | %s | %.3f s | %.3f | %.3f | %s | %s | %s | %s | %d + %d |" % (
        name, mode, j["first_image_seconds"], at(lm, 1, "delta_e_mean"), at(lm, 10, "delta_e_mean"),
        "%.2f s" % reach if reach is not None else "not reached", "%.2f s" % conv if conv is not None else "no",
        rel(1), rel(10), light, last["indirect"]))
EOF
