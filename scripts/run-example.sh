#!/usr/bin/env bash
# Installs the dependencies, builds citylod (Release) and runs the main job on
# the bundled example scene (examples/delft_small: AHN3 LiDAR of Delft, CC0,
# EPSG:28992 + NAP heights) with one `citylod tile`: split into buildings ->
# LOD-Tree per building -> 3D Tiles. The tileset lands in out/example/tileset; look at it with
#   build/app/citylod serve out/example/tileset      (CesiumJS viewer, offline)
# Usage: scripts/run-example.sh [--no-install]
set -euo pipefail
cd "$(dirname "$0")/.."

if [[ "${1:-}" != "--no-install" ]]; then
  scripts/install-deps.sh
  scripts/install-node-tools.sh || echo "run-example: CesiumJS not installed; 'citylod serve' needs it" >&2
fi
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DCITYLOD_BUILD_TESTS=OFF
cmake --build build -j"$(nproc)" --target citylod

citylod=build/app/citylod
scene=examples/delft_small/delft_small.las
out=out/example
mkdir -p "$out"

"$citylod" info "$scene"
"$citylod" tile "$scene" --crs EPSG:28992 \
  --footprints examples/delft_small/footprints.geojson --threads "$(nproc)" --out "$out"

echo
echo "Done. 3D Tiles tileset:          $out/tileset/tileset.json"
echo "Per-building LOD models:         $out/work/lod/<id>/model_*.obj (any mesh viewer)"
echo "Run report:                      $out/run_report.json"
echo "View it in a browser (offline):  $citylod serve $out/tileset"
