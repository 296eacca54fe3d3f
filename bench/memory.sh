#!/usr/bin/env bash
# bench/memory.sh — peak resident memory (the kernel's "Maximum resident set
# size", from /usr/bin/time -v, which counts the Assimp reader's child process
# too: wait4's ru_maxrss is the larger of a process's own and its children's)
# of `lumesh info`, `lumesh render --samples 1` and `lumesh render --seconds T`
# at 640x480, one table row per scene (docs/memory.md).
#
# usage: bench/memory.sh [BUILD_DIR] [SECONDS] [SCENES...]
#   BUILD_DIR  where lumesh was built (default build/release)
#   SECONDS    refinement time of the last column (default 20)
#   SCENES     scene files (default bench/scenes/cornell-bunny-dragon.json and
#              ../shared/scenes/cornell-box/CornellBox-Water.obj)
# Extra `render` options (e.g. --sampler embree) go in LUMESH_RENDER_ARGS.
# `auto` keeps GL's costs per machine (docs/sampling.md): a `--seconds` run makes
# its calibration's GL context only where no earlier run showed GL cannot win
# here. LUMESH_CACHE_DIR= (empty) measures every run as a first run on a machine.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
seconds=${2:-20}
shift $(( $# < 2 ? $# : 2 ))
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] ||
  scenes=(bench/scenes/cornell-bunny-dragon.json ../shared/scenes/cornell-box/CornellBox-Water.obj)
lumesh=$build/lumesh
[ -x "$lumesh" ] || { echo "no $lumesh: build first (cmake --build $build)"; exit 1; }
[ -x /usr/bin/time ] || { echo "no /usr/bin/time (Debian: apt-get install time)"; exit 1; }
read -r -a extra <<< "${LUMESH_RENDER_ARGS:-}"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Peak RSS of one command in MB (10^6 bytes); the command's own output is kept
# in $tmp/log and shown when it fails.
peak_mb() {
  if ! /usr/bin/time -f '%M' -o "$tmp/rss" "$@" > "$tmp/log" 2>&1; then
    echo "failed: $*" >&2
    cat "$tmp/log" >&2
    exit 1
  fi
  awk '{ printf "%.0f", $1 * 1024 / 1e6 }' "$tmp/rss"
}

printf '| scene | triangles | info | render --samples 1 | render --seconds %s |\n' "$seconds"
printf '|---|---|---|---|---|\n'
for s in "${scenes[@]}"; do
  tris=$("$lumesh" info "$s" | awk '/^triangles/ { print $2 }')
  a=$(peak_mb "$lumesh" info "$s")
  b=$(peak_mb "$lumesh" render "$s" -o "$tmp/out.png" --width 640 --height 480 --samples 1 "${extra[@]}")
  c=$(peak_mb "$lumesh" render "$s" -o "$tmp/out.png" --width 640 --height 480 --seconds "$seconds" "${extra[@]}")
  printf '| %s | %s | %s MB | %s MB | %s MB |\n' "$(basename "$s")" "$tris" "$a" "$b" "$c"
done
