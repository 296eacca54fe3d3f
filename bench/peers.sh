#!/usr/bin/env bash
# bench/peers.sh — the cache against its peers inside lumesh (issue 17): for each
# scene, `lumesh converge --methods cache,vpl,bdir,vpl-ism,bdir-ism,path-tracer`
# (METHODS overrides the list) against one reference,
# each method alone on the machine for the same times (from the scene loaded),
# and one table: relMSE and mean dE of each method at 1, 10 and 60 s (or the
# times asked), the VPLs instant radiosity made, and the imperfect shadow maps'
# share of the -ism methods' time. docs/peers.md has the
# methods, their bias and the measured tables.
#
# usage: bench/peers.sh [BUILD_DIR] [SECONDS] [REFERENCE_SECONDS] [SCENES...]
#   BUILD_DIR          where lumesh was built (default build/release)
#   SECONDS            length of each method's run (default 60); snapshots at 1, 10, 60
#                      and SECONDS, those not above it
#   REFERENCE_SECONDS  path-tracing time of a missing reference (default 600), model
#                      transport; kept in BUILD_DIR/bench-data as NAME-WxH-ref.exr and
#                      reused (bench/converge.sh and bench/indirect.sh make the same files)
#   SCENES             CornellBox-Original, CornellBox-Glossy, CornellBox-Water (640x480),
#                      veach-door (640x360, bench/scenes/veach-door.json); default: Original,
#                      Water and the door
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
seconds=${2:-60}
ref_seconds=${3:-600}
shift $(( $# < 3 ? $# : 3 ))
names=("$@")
[ ${#names[@]} -gt 0 ] || names=(CornellBox-Original CornellBox-Water veach-door)
lumesh=$build/lumesh
data=$build/bench-data
mkdir -p "$data"
[ -x "$lumesh" ] || { echo "no $lumesh: build first (cmake --build $build)"; exit 1; }
snaps=$(python3 -c "import sys; s=float(sys.argv[1]); print(','.join('%g' % t for t in sorted({t for t in (1, 10, 60) if t < s} | {s})))" "$seconds")

for name in "${names[@]}"; do
  case $name in
    veach-door) scene=bench/scenes/veach-door.json; w=640; h=360 ;;
    CornellBox-*) scene=../shared/scenes/cornell-box/$name.obj; w=640; h=480 ;;
    *) echo "unknown scene $name" >&2; exit 1 ;;
  esac
  ref=$data/$name-${w}x$h-ref.exr
  if [ ! -s "$ref" ]; then
    echo "reference for $name: ${ref_seconds} s of path tracing (kept in $ref)" >&2
    "$lumesh" reference "$scene" -o "$ref" --transport model --seconds "$ref_seconds" --width $w --height $h >&2
  fi
  out=$data/$name-peers
  "$lumesh" converge "$scene" --reference "$ref" --seconds "$seconds" --out "$out" --snapshots "$snaps" \
    --methods "${METHODS:-cache,vpl,bdir,vpl-ism,bdir-ism,path-tracer}" > "$out.log"
  python3 - "$name" "$out/convergence.json" <<'PY'
import json, sys
name, path = sys.argv[1], sys.argv[2]
j = json.load(open(path))
m = j["methods"]
order = [k for k in ("lumesh", "vpl", "bdir", "vpl-ism", "bdir-ism", "path-tracer") if k in m]
print("\n%s, %dx%d, %g s a method (reference %s; %s)" % (name, j["width"], j["height"], j["seconds"], j["reference"],
                                                        j["transport_note"]))
print("| time | " + " | ".join("%s relMSE / mean dE" % k for k in order) +
      " | VPLs made (vpl / bdir's candidates) | maps' share of vpl-ism / bdir-ism time |")
print("|---|" + "---|" * len(order) + "---|---|")
rows = {k: {r["target_seconds"]: r for r in m[k]} for k in order}
for t in sorted(rows[order[0]]):
    cells = []
    for k in order:
        r = rows[k].get(t)
        cells.append("%.3g / %.2f" % (r["error"]["relmse"], r["error"]["delta_e_mean"]) if r else "-")
    made = ["%d" % rows[k][t]["vpls"] if k in rows and t in rows[k] else "-" for k in ("vpl", "bdir")]
    share = ["%.0f%%" % (100.0 * rows[k][t]["ism_seconds"] / rows[k][t]["seconds"]) if k in rows and t in rows[k]
             else "-" for k in ("vpl-ism", "bdir-ism")]
    print("| %g s | %s | %s | %s |" % (t, " | ".join(cells), " / ".join(made), " / ".join(share)))
noise = m[order[0]][0]["error"].get("relmse_reference_noise", 0.0)
print("the reference's own noise: relMSE %.3g of every relMSE above" % noise)
PY
done
