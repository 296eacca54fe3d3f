#!/usr/bin/env bash
# bench/converge.sh — the renderer against the path tracer on the Cornell boxes
# (issue 14's targets), measured with `lumesh converge --vs-path-tracer` at
# 640x480 with the sampler `auto` picks, on this machine. For each scene, one
# table: at every snapshot, relMSE and mean dE of the previewer and of the Embree
# path tracer at equal time (both counted from the scene loaded), the ratio of
# their relMSE (path tracer / lumesh: above 1 lumesh is ahead), the JND the cache
# refined to and its state, the path samples a pixel of the residual that corrects
# it once the cache has finished, and the ratio net of the reference's own noise
# (its stderr channels: relMSE less that noise estimates relMSE against the truth);
# then the first image (time after the scene is loaded,
# its mean dE) and when the cache converged at its JND.
#
# usage: bench/converge.sh [BUILD_DIR] [SECONDS] [REFERENCE_SECONDS] [SCENES...]
#   BUILD_DIR          where lumesh was built (default build/release)
#   SECONDS            length of each run (default 120)
#   REFERENCE_SECONDS  path-tracing time of a missing reference (default 600); references
#                      are kept in BUILD_DIR/bench-data and reused. A reference's own noise
#                      is in every relMSE measured against it (about 1e-5 for Original
#                      at 300 s): late snapshots need a long reference.
#   SCENES             names in ../shared/scenes/cornell-box (default CornellBox-Original
#                      CornellBox-Glossy CornellBox-Water)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
seconds=${2:-120}
ref_seconds=${3:-600}
shift $(( $# < 3 ? $# : 3 ))
names=("$@")
[ ${#names[@]} -gt 0 ] || names=(CornellBox-Original CornellBox-Glossy CornellBox-Water)
lumesh=$build/lumesh
data=$build/bench-data
scenes=../shared/scenes/cornell-box
mkdir -p "$data"
[ -x "$lumesh" ] || { echo "no $lumesh: build first (cmake --build $build)"; exit 1; }

snaps=0.1,0.25,0.5,1,2,3,5,7,10,15,20,30,45,60,90,120
for name in "${names[@]}"; do
  ref=$data/$name-640x480-ref.exr
  if [ ! -s "$ref" ]; then
    echo "reference for $name: ${ref_seconds} s of path tracing (kept in $ref)" >&2
    "$lumesh" reference "$scenes/$name.obj" -o "$ref" --transport model --seconds "$ref_seconds" \
      --width 640 --height 480 >&2
  fi
  out=$data/$name-converge
  "$lumesh" converge "$scenes/$name.obj" --reference "$ref" --seconds "$seconds" --out "$out" \
    --snapshots "$snaps" --vs-path-tracer > "$out.log"
  first=$("$lumesh" compare "$out/first-image.exr" "$ref" --json)
  python3 - "$name" "$out/convergence.json" "$first" <<'EOF'
import json, sys
name, path, first = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
j = json.load(open(path))
lm = j["methods"]["lumesh"]
pt = {r["target_seconds"]: r for r in j["methods"].get("path-tracer", [])}
print("\n%s, 640x480, %d s (reference %s)" % (name, j["seconds"], j["reference"]))
print("| time | lumesh relMSE | path tracer relMSE | ratio | net ratio | lumesh mean dE | path tracer mean dE | JND | state | residual spp | its estimate / net relMSE |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
def net(e):
    return e["relmse"] - e.get("relmse_reference_noise", 0.0)
for r in lm:
    p = pt.get(r["target_seconds"])
    e = r["error"]
    pe = p["error"] if p else None
    ratio = "%.2f" % (pe["relmse"] / e["relmse"]) if pe and e["relmse"] > 0 else "-"
    net_ratio = "%.2f" % (net(pe) / net(e)) if pe and net(e) > 0 else "-"
    res = r.get("residual")
    est = "%.3g / %.3g" % (res["estimated_relmse"], net(e)) if res and "estimated_relmse" in res else "-"
    est_err = r.get("estimated_error") # null in the first snapshot: no estimate yet
    print("| %g s (at %.2f) | %.3g | %s | %s | %s | %.3f | %s | %s | %s | %s | %s |" % (
        r["target_seconds"], r["seconds"], e["relmse"], "%.3g" % pe["relmse"] if pe else "-", ratio, net_ratio,
        e["delta_e_mean"], "%.3f" % pe["delta_e_mean"] if pe else "-", "%g" % est_err["jnd"] if est_err else "-", r["state"],
        "%d..%d" % (res["spp_min"], res["spp_max"]) if res else "-", est))
noise = lm[0]["error"].get("relmse_reference_noise", 0.0) if lm else 0.0
print("the reference's own noise: relMSE %.3g of every number above (net ratio: both relMSEs less it)" % noise)
conv = j.get("converged_seconds")
print("first image after %.3f s: mean dE %.2f, relMSE %.3g; converged at its JND at %s" % (
    j["first_image_seconds"], first["delta_e_mean"], first["relmse"], "%.2f s" % conv if conv is not None else "never"))
ph, lp = j.get("first_image_phases"), j.get("load_phases")
if ph and lp:
    fmt = lambda v: "%.3f" % v if v is not None else "-"
    print("  its phases (s after the load): session %s, renderer %s, first snapshot %s; before the clock: reference read "
          "%s s, scene loaded %s s after the start" % (fmt(ph["session"]), fmt(ph["renderer"]), fmt(ph["first_snapshot"]),
                                                       fmt(lp["reference"]), fmt(lp["scene"])))
EOF
done
