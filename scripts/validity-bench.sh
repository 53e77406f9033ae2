#!/usr/bin/env bash
# Validity as val3dity measures it, position invariance and monotone chains
# (issue 26), on real data, for one or two citylod binaries side by side:
#
#   scripts/validity-bench.sh [--citylod EXE] [--before EXE] [--c3d PREFIX] [--out DIR]
#
# Scenes: the shared Delft tile (LAS + bgt_pand.gpkg), the tile copied 4 x 4
# (../shared/tools/scale/replicate.py: copies 300 m apart), the photogrammetry
# mesh city, and with --c3d PREFIX the City3D scene PREFIX.las + PREFIX.gpkg
# (../shared/tools/city3d_scene/make_scene.py, gml_id). For each binary and
# scene: `citylod tile --threads 2`, then val3dity 2.6.0 on buildings.city.jsonl
# at its default tolerances (scripts/val3dity-summary.py), the kept chains that
# get worse when zooming in (scripts/chain_monotone.py, 5 cm) and, on the
# replica, the buildings whose 16 copies get the same models
# (scripts/invariance.py). Needs python3 with numpy (replicate.py: Debian's
# /usr/bin/python3 + python3-numpy) and val3dity's runtime libraries.
set -euo pipefail
cd "$(dirname "$0")/.."
citylod=build/app/citylod before="" c3d="" out=/tmp/citylod-validity-bench
while (($#)); do
  case "$1" in
    --citylod) citylod="$2"; shift 2 ;;
    --before) before="$2"; shift 2 ;;
    --c3d) c3d="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    *) echo "validity-bench.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
shared=../shared
val3dity=$shared/tools/val3dity/run-val3dity.sh
py=python3
[[ -x /usr/bin/python3 ]] && py=/usr/bin/python3
mkdir -p "$out"
ogr2ogr -f GeoJSON "$out/fp.geojson" $shared/data/delft/bgt_pand.gpkg
[[ -f "$out/rep4.las" ]] || $py $shared/tools/scale/replicate.py $shared/data/delft/ahn3_cropped_2.las \
  "$out/fp.geojson" 4 4 "$out/rep4" >/dev/null
wkt="$(cat $shared/data/mesh_city/crs_local.wkt)"

run() {  # label exe scene-name args...
  local label="$1" exe="$2" name="$3"; shift 3
  local d="$out/$label-$name"
  rm -rf "$d"
  local t0 t1
  t0=$(date +%s.%N)
  "$exe" tile "$@" --threads 2 --out "$d" -q >"$d.log" 2>&1 || { echo "$label $name: citylod failed (see $d.log)"; return; }
  t1=$(date +%s.%N)
  "$val3dity" "$d/buildings.city.jsonl" --report "$d.val3dity.json" >/dev/null 2>&1 || true
  printf '%-7s %-8s %6.1f s | %s | %s' "$label" "$name" "$(awk -v a="$t0" -v b="$t1" 'BEGIN{print b-a}')" \
    "$($py scripts/val3dity-summary.py "$d.val3dity.json")" "$($py scripts/chain_monotone.py "$d" | cut -d';' -f1)"
  if [[ "$name" == replica ]]; then
    printf ' | %s' "$($py scripts/invariance.py "$d/work" | tail -1)"
  fi
  echo
}

for label in after before; do
  exe="$citylod"
  [[ $label == before ]] && exe="$before"
  [[ -z "$exe" ]] && continue
  run $label "$exe" delft $shared/data/delft/ahn3_cropped_2.las --crs EPSG:28992 \
    --footprints $shared/data/delft/bgt_pand.gpkg
  run $label "$exe" replica "$out/rep4.las" --crs EPSG:28992 --footprints "$out/rep4.geojson"
  run $label "$exe" mesh $shared/data/mesh_city/scene.ply --crs "$wkt" \
    --footprints $shared/data/mesh_city/footprints_bgt_local.geojson
  if [[ -n "$c3d" ]]; then
    run $label "$exe" city3d "$c3d.las" --crs EPSG:28992 --footprints "$c3d.gpkg" --footprints-id gml_id
  fi
done
echo "machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), $(date -u +%Y-%m-%dT%H:%MZ)"
