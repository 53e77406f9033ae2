#!/usr/bin/env bash
# Runs every libFuzzer harness of tests/fuzz for SECONDS each (default 60) and
# prints one line per harness: executions, corpus, findings.
#
#   scripts/fuzz.sh [SECONDS] [HARNESS...]      e.g. scripts/fuzz.sh 600, scripts/fuzz.sh 5 fuzz_las
#
# The fuzz build (clang-14, libFuzzer + ASan) is configured in $FUZZ_BUILD
# (default build-fuzz) when missing and built. Seeds are taken at run time
# from ../shared/data (files cut to 64 KiB) and, for glb and the work-dir
# records, from a `citylod tile` run of examples/delft_small with the normal
# build ($CITYLOD, default build/app/citylod); nothing is copied into the repo.
# Corpora grow in $FUZZ_BUILD/fuzz-corpus/, crashes go to $FUZZ_BUILD/fuzz-artifacts/.
# FUZZ_SEED=N fixes libFuzzer's seed (scripts/test.sh: CI runs the same
# mutations each time). Exit status: 1 when any harness found something.
set -euo pipefail
cd "$(dirname "$0")/.."
SECS=${1:-60}
shift || true
B=${FUZZ_BUILD:-build-fuzz}
DATA=${CITYLOD_SHARED_DATA:-$(cd .. && pwd)/shared/data}
CITYLOD=${CITYLOD:-build/app/citylod}
ALL=(fuzz_las fuzz_laz fuzz_ply fuzz_obj fuzz_off fuzz_xyz fuzz_geojson fuzz_glb fuzz_workdir fuzz_tileset)
HARNESSES=("$@")
[ ${#HARNESSES[@]} -eq 0 ] && HARNESSES=("${ALL[@]}")

if [ ! -f "$B/build.ninja" ]; then
  cmake -S . -B "$B" -G Ninja -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCITYLOD_FUZZ=ON -DCITYLOD_BUILD_TESTS=OFF >/dev/null
fi
if [ -e /tmp/citylod-build.lock ]; then
  flock /tmp/citylod-build.lock cmake --build "$B" -j2 --target fuzzers >/dev/null
else
  cmake --build "$B" -j2 --target fuzzers >/dev/null
fi

CORPUS=$B/fuzz-corpus
ARTIFACTS=$B/fuzz-artifacts
mkdir -p "$CORPUS" "$ARTIFACTS"
seed() {  # seed HARNESS FILE...: the first 64 KiB of each file
  local h=$1
  shift
  mkdir -p "$CORPUS/$h"
  local f
  for f in "$@"; do
    [ -f "$f" ] && head -c 65536 "$f" >"$CORPUS/$h/seed-$(basename "$f")"
  done
  return 0
}
if [ -d "$DATA" ]; then
  seed fuzz_las $(find "$DATA" -name '*.las')
  seed fuzz_laz $(find "$DATA" -name '*.laz')
  seed fuzz_ply $(find "$DATA" -name '*.ply')
  seed fuzz_obj $(find "$DATA" -name '*.obj' | sort | head -12)
  seed fuzz_off $(find "$DATA" -name '*.off')
  seed fuzz_xyz $(find "$DATA" -name '*.csv' -o -name '*.xyz' -o -name '*.pts')
  seed fuzz_geojson $(find "$DATA" -name '*.geojson')
else
  echo "fuzz.sh: $DATA not found: harnesses start from an empty corpus" >&2
fi
# glb and work-dir records: from a tile run of the bundled example
SEEDRUN=$B/fuzz-seed-run
if [ -x "$CITYLOD" ] && [ ! -f "$SEEDRUN/run_report.json" ]; then
  "$CITYLOD" -q tile examples/delft_small/delft_small.las --crs EPSG:28992 \
    --footprints examples/delft_small/footprints.geojson --out "$SEEDRUN" >/dev/null 2>&1 || true
fi
if [ -f "$SEEDRUN/run_report.json" ]; then
  seed fuzz_glb $(find "$SEEDRUN/tileset" -name '*.glb' | sort | head -8)
  mkdir -p "$CORPUS/fuzz_workdir"
  # the first byte chooses the record: 0 manifest, 1 report, 2 overrides, 3 run report
  { printf '\000'; head -c 65536 "$SEEDRUN/work/manifest.json"; } >"$CORPUS/fuzz_workdir/seed-manifest"
  r=$(find "$SEEDRUN/work/lod" -name report.json | sort | head -1)
  { printf '\001'; head -c 65536 "$r"; } >"$CORPUS/fuzz_workdir/seed-report"
  printf '\002{"buildings": {"fp-1": {"set": {"planes.epsilon": "0.2"}, "select": [0, 3]}}}' \
    >"$CORPUS/fuzz_workdir/seed-overrides"
  { printf '\003'; head -c 65536 "$SEEDRUN/run_report.json"; } >"$CORPUS/fuzz_workdir/seed-run-report"
  seed fuzz_tileset "$SEEDRUN/tileset/tileset.json"
fi
# tileset.json: NUL-separated files tileset.json, a.json, b.json, sub/c.json (see fuzz_tileset.cpp)
mkdir -p "$CORPUS/fuzz_tileset"
printf '%s\000%s\000%s\000%s' \
  '{"asset":{"version":"1.1"},"geometricError":64,"root":{"transform":[1,0,0,0,0,1,0,0,0,0,1,0,10,20,30,1],"geometricError":32,"refine":"REPLACE","content":{"uri":"t.glb"},"children":[{"geometricError":0,"contents":[{"uri":"a.json"},{"uri":"x/../u.glb?v=1"}]},{"geometricError":0,"content":{"url":"sub/c.json"}}]}}' \
  '{"asset":{"version":"1.0"},"root":{"geometricError":4,"content":{"uri":"b.json"},"children":[{"content":{"uri":"a1.glb"}}]}}' \
  '{"root":{"transform":[2,0,0,0,0,2,0,0,0,0,2,0,0,0,0,1],"content":{"uri":"b1.glb"}}}' \
  '{"root":{"content":{"uri":"../c0.glb"},"children":[{"content":{"uri":"c1.glb"}}]}}' \
  >"$CORPUS/fuzz_tileset/seed-external"

status=0
for h in "${HARNESSES[@]}"; do
  log=$ARTIFACTS/$h.log
  set +e
  "$B/tests/fuzz/$h" "$CORPUS/$h" -max_total_time="$SECS" -rss_limit_mb=2048 -timeout=20 \
    ${FUZZ_SEED:+-seed="$FUZZ_SEED"} \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$ARTIFACTS/$h-" >"$log" 2>&1
  rc=$?
  set -e
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo '?')
  units=$(find "$CORPUS/$h" -type f | wc -l)
  findings=$(grep -c -E '^==[0-9]+==ERROR|FINDING|ERROR: libFuzzer' "$log" || true)
  printf '%-14s %4ss  executions %-10s corpus %-6s findings %s%s\n' "$h" "$SECS" "$execs" \
    "$units" "$findings" "$([ $rc -ne 0 ] && echo "  (exit $rc, see $log)")"
  [ $rc -ne 0 ] && status=1
done
exit $status
