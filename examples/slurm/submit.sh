#!/bin/bash
# Submits a whole citylod city run to Slurm:
#   1. split      one job (skip it with SPLIT=0 when DIR/work is already split)
#   2. lod        an array of N tasks (citylod.sbatch), after the split succeeded
#   3. assemble   one job, --dependency=afterok on the whole array
#
#   examples/slurm/submit.sh DIR N INPUT... --crs EPSG:28992 [--footprints F.geojson] [split options]
#
# Writes DIR/work and DIR/tileset, the same layout (and the same tileset bytes)
# as `citylod tile INPUT... --out DIR`. Environment: CITYLOD (binary, default
# `citylod` on PATH), CITYLOD_LOD_ARGS (extra lod options, e.g. "--set planes.epsilon=0.2"),
# CITYLOD_ASSEMBLE_ARGS (e.g. "--quantize"), WAIT=1 (block until the assemble
# job ended; exit with its status), SBATCH_ARGS (e.g. "--partition=batch --time=4:00:00").
# Prints the three job ids.
set -euo pipefail
DIR=${1:?usage: submit.sh DIR N INPUT... [split options]}
N=${2:?usage: submit.sh DIR N INPUT... [split options]}
shift 2
HERE=$(cd "$(dirname "$0")" && pwd)
CITYLOD=${CITYLOD:-$(command -v citylod || echo citylod)}
export CITYLOD
mkdir -p "$DIR/logs"
DIR=$(cd "$DIR" && pwd)
# shellcheck disable=SC2086
common=(--parsable --chdir="$DIR/logs" ${SBATCH_ARGS:-})

dep=()
split_job=none
if [[ "${SPLIT:-1}" != 0 ]]; then
  split_cmd=$(printf '%q ' "$CITYLOD" split "$@" --out "$DIR/work")
  split_job=$(sbatch "${common[@]}" --job-name=citylod-split --output=citylod-split-%j.log --wrap "$split_cmd")
  dep=(--dependency="afterok:$split_job")
fi
lod_job=$(sbatch "${common[@]}" "${dep[@]}" --array="0-$((N - 1))" "$HERE/citylod.sbatch" "$DIR")
asm_cmd="$(printf '%q ' "$CITYLOD" assemble "$DIR/work" --out "$DIR/tileset") ${CITYLOD_ASSEMBLE_ARGS:-}"
wait=()
if [[ "${WAIT:-0}" == 1 ]]; then wait=(--wait); fi
echo "split $split_job lod $lod_job"
asm_job=$(sbatch "${common[@]}" "${wait[@]}" --dependency="afterok:$lod_job" --kill-on-invalid-dep=yes \
  --job-name=citylod-assemble --output=citylod-assemble-%j.log --wrap "$asm_cmd")
echo "assemble $asm_job"
