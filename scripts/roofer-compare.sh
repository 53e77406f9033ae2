#!/usr/bin/env bash
# citylod vs 3DBAG's roofer, side by side on the same LAS + footprints, same
# machine, runs alternating (these machines are noisy):
#
#   scripts/roofer-compare.sh [--citylod EXE] [--bench EXE] [--las FILE] [--footprints GPKG]
#                             [--crs EPSG:nnnn] [--rounds N] [--threads N] [--out DIR]
#
# Defaults: the shared Delft tile (../shared/data/delft/ahn3_cropped_2.las with
# bgt_pand.gpkg, EPSG:28992), 3 rounds, 2 threads, build-bench/ binaries,
# output in bench-results/<date>/roofer/. Each round runs roofer
# (../shared/tools/roofer/run-roofer.sh --lod12 --lod13 --lod22, id gml_id) and
# `citylod tile` (the same GeoPackage, --footprints-id gml_id), and records both
# wall times. Then roofer_bench compares the last
# round's models building by building (RMSE of the points to the model, roof
# height RMSE, triangles, validity, time per building) and prints the summary.
# Prints roofer_bench's whole output, then one line per round with the wall
# times (and each round's median LOD time per building). Needs roofer's runtime libraries (run-roofer.sh installs those).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
data="$(cd "$here/.." && pwd)/shared/data"
roofer="$(cd "$here/.." && pwd)/shared/tools/roofer/run-roofer.sh"
citylod="$here/build-bench/app/citylod"
[ -x "$citylod" ] || citylod="$here/build/app/citylod"
bench="$here/build-bench/bench/roofer_bench"
las="$data/delft/ahn3_cropped_2.las"
gpkg="$data/delft/bgt_pand.gpkg"
crs="EPSG:28992"
rounds=3
threads=2
out="$here/bench-results/$(date +%Y-%m-%d)/roofer"
while [ $# -gt 0 ]; do
  case "$1" in
    --citylod) citylod="$2"; shift 2 ;;
    --bench) bench="$2"; shift 2 ;;
    --las) las="$2"; shift 2 ;;
    --footprints) gpkg="$2"; shift 2 ;;
    --crs) crs="$2"; shift 2 ;;
    --rounds) rounds="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    -h|--help) sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "roofer-compare.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
for f in "$citylod" "$bench" "$roofer"; do
  [ -x "$f" ] || { echo "roofer-compare.sh: $f is missing or not executable" >&2; exit 1; }
done
mkdir -p "$out"

secs() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", b - a }'; }
times=()
for ((r = 1; r <= rounds; r++)); do
  rm -rf "$out/roofer-out" "$out/citylod"
  t0=$(date +%s.%N)
  "$roofer" --lod12 --lod13 --lod22 --srs "$crs" --id-attribute gml_id -j "$threads" "$las" "$gpkg" \
    "$out/roofer-out" >"$out/roofer.log" 2>&1
  t1=$(date +%s.%N)
  "$citylod" tile "$las" --crs "$crs" --footprints "$gpkg" --footprints-id gml_id --threads "$threads" --out "$out/citylod" \
    >"$out/citylod.log" 2>&1
  t2=$(date +%s.%N)
  # this round's per-building LOD times (the machines are noisy: one line per round)
  jsonl="$(ls "$out"/roofer-out/*.city.jsonl | head -1)"
  lodt="$("$bench" "$out/citylod/work" "$jsonl" | sed -n 's/^LOD time per building, median: //p')"
  times+=("round $r: roofer $(secs "$t0" "$t1") s wall, citylod tile $(secs "$t1" "$t2") s wall; per building $lodt")
done
"$bench" "$out/citylod/work" "$jsonl" --csv "$out/per_building.csv"
echo
echo "same machine, alternating runs, $threads threads, $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg):"
for t in "${times[@]}"; do echo "  $t"; done
