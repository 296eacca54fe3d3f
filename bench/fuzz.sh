#!/usr/bin/env bash
# bench/fuzz.sh — the libFuzzer harnesses (tests/fuzz) against lumesh's loaders,
# under ASan and UBSan, each for a given time; prints a table of executions per
# second, coverage and findings (docs/robustness.md).
#
# usage: bench/fuzz.sh [SECONDS] [BUILD_DIR] [TARGETS...]
#   SECONDS    time for each target (default 60; the issue's runs: 1800)
#   BUILD_DIR  the clang fuzzing build, configured and built here when missing
#              (default build/fuzz)
#   TARGETS    among json xml obj ply gltf exr png (default: all); JOBS (default 2) run at a time
#
# Corpora grow in BUILD_DIR/fuzz-corpus/TARGET (kept between runs); seeds are
# tests/badinput, the built-in scene, tests/fuzz/seeds and a few small shared
# scenes. A crash, leak, hang (-timeout=30 s; the reader's child gets 5 s of CPU) or
# sanitizer report is written to
# BUILD_DIR/fuzz-findings/TARGET-*: reproduce it with
#   LUMESH_FUZZ_EXT=EXT BUILD_DIR/tests/fuzz/fuzz_HARNESS FILE
# and add it to tests/badinput with its fix.
# Needs clang and libFuzzer: apt-get install clang libclang-rt-14-dev.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
build=${2:-build/fuzz}
shift $(( $# < 2 ? $# : 2 ))
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(json xml obj ply gltf exr png)
command -v clang >/dev/null || { echo "clang is missing: apt-get install clang libclang-rt-14-dev"; exit 1; }

if [ ! -x "$build/tests/fuzz/fuzz_mesh" ]; then
  echo "building the fuzzing tree in $build (clang, ASan, UBSan, libFuzzer)" >&2
  CC=clang CXX=clang++ cmake -S . -B "$build" -DLUMESH_FUZZ=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DBUILD_TESTING=OFF >/dev/null
  cmake --build "$build" -j2 --target fuzz_scene_json fuzz_scene_xml fuzz_mesh fuzz_image >/dev/null
fi

shared=../shared/scenes
harness_of() { case $1 in json) echo fuzz_scene_json ;; xml) echo fuzz_scene_xml ;; obj|ply|gltf) echo fuzz_mesh ;; *) echo fuzz_image ;; esac; }
seed_dir() { # the seeds of target $1, in a fresh directory
  local t=$1 d=$build/fuzz-seeds/$1
  rm -rf "$d"; mkdir -p "$d"
  case $t in
    json) cp tests/badinput/json-*.json data/cornell-box.json "$d"/ ;;
    xml) cp tests/badinput/mitsuba-*.xml tests/fuzz/seeds/*.xml "$d"/
         [ -f "$shared"/veach-door/scene.xml ] && cp "$shared"/veach-door/scene.xml "$d"/veach-door.xml ;;
    obj) cp tests/badinput/*.obj data/cornell-box.obj data/cornell-box.mtl "$d"/
         for f in "$shared"/cornell-box/CornellBox-Original.{obj,mtl}; do [ -f "$f" ] && cp "$f" "$d"/; done ;;
    ply) cp tests/badinput/*.ply "$d"/ ;;
    *) for f in tests/fuzz/seeds/*."$t"; do [ -f "$f" ] && cp "$f" "$d"/; done ;;
  esac
  if [ "$t" = gltf ]; then # glTF seeds: the model tests' file and the shared scenes' small ones
    find "$shared" -name '*.gltf' -size -64k -exec cp {} "$d"/ \; 2>/dev/null || true
    cp tests/fuzz/seeds/*.gltf "$d"/ 2>/dev/null || true
  fi
  echo "$d"
}

run_one() { # target -> one line of the table
  local t=$1 h; h=$(harness_of "$t")
  local corpus=$build/fuzz-corpus/$t findings=$build/fuzz-findings log=$build/fuzz-logs/$t.log
  mkdir -p "$corpus" "$findings" "$build/fuzz-logs"
  local seeds; seeds=$(seed_dir "$t")
  LUMESH_FUZZ_EXT=$t ASAN_OPTIONS=detect_leaks=1 LUMESH_READER_CPU_SECONDS=5 \
    LSAN_OPTIONS=suppressions=$PWD/tests/lsan.supp \
    "$build/tests/fuzz/$h" "$corpus" "$seeds" -max_total_time="$seconds" -timeout=30 -rss_limit_mb=4096 \
      -max_len=65536 -fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 \
      -artifact_prefix="$findings/$t-" >"$log" 2>&1 || true
  # Fork mode: a finding is saved and the run goes on for the whole time.
  local runs execs cov ft corp found
  runs=$(grep -o '^#[0-9]*' "$log" | tail -1 | tr -d '#' || true)
  execs=$(grep -o 'exec/s:\? [0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || true)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || true)
  ft=$(grep -o 'ft: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || true)
  corp=$(find "$corpus" -type f | wc -l)
  found=$(find "$findings" -name "$t-*" -type f | wc -l)
  printf '| %s | %s | %s | %s | %s | %s | %s | %s | %s |\n' "$t" "$h" "$seconds" "${runs:-?}" "${execs:-?}" \
    "${cov:-?}" "${ft:-?}" "$corp" "$found"
}

jobs=${JOBS:-2}
echo "fuzzing ${targets[*]} for $seconds s each ($jobs at a time), logs in $build/fuzz-logs" >&2
echo "| target | harness | seconds | executions | exec/s | coverage (edges) | features | corpus files | findings |"
echo "|---|---|---|---|---|---|---|---|---|"
i=0
for t in "${targets[@]}"; do
  run_one "$t" > "$build/fuzz-row-$t.txt" &
  i=$((i + 1))
  if (( i % jobs == 0 )); then wait; fi
done
wait
for t in "${targets[@]}"; do cat "$build/fuzz-row-$t.txt"; rm -f "$build/fuzz-row-$t.txt"; done
