#!/usr/bin/env bash
# Byte-identical output of two citylod binaries: runs `citylod tile` of OLD and
# of NEW on the bundled example (examples/delft_small, as scripts/run-example.sh
# runs it) into two temporary directories and compares every file of the
# outputs -- the tileset, buildings.city.jsonl, the work directory,
# run_report.json -- byte for byte. What legitimately differs between two runs
# of the SAME binary is normalised first, and only that: the values of the JSON
# keys in VOLATILE_KEYS (timings and peak memory in run_report.json and the
# work directory's lod/*/report.json) and the run's own directory in the
# strings of JSON files. A file that differs otherwise is listed; exit 1.
#
# Usage: scripts/same-output.sh OLD NEW [--threads N] [--args 'OPTIONS'] [--thread-counts] [--keep]
#   --threads N       threads of both runs (default 2)
#   --args 'OPTIONS'  more options of both `tile` runs, e.g. '--compression none --quantize'
#   --thread-counts   also NEW --threads 1 against NEW --threads 2 (the `threads`
#                     run_report.json records normalised too)
#   --keep            keep the temporary directories (printed)
# Exit: 0 same, 1 some file differs, 2 usage or a run failed.
set -euo pipefail
cd "$(dirname "$0")/.."

usage() {
  echo "usage: scripts/same-output.sh OLD NEW [--threads N] [--args 'OPTIONS'] [--thread-counts] [--keep]" >&2
  exit 2
}
(($# >= 2)) || usage
old=$(realpath "$1")
new=$(realpath "$2")
shift 2
threads=2 thread_counts=0 keep=0 args=()
while (($#)); do
  case "$1" in
    --threads) threads=${2:?}; shift ;;
    --args) read -r -a args <<< "${2:?}"; shift ;;
    --thread-counts) thread_counts=1 ;;
    --keep) keep=1 ;;
    *) usage ;;
  esac
  shift
done
for exe in "$old" "$new"; do
  [[ -x "$exe" ]] || { echo "same-output: $exe is not an executable" >&2; exit 2; }
done

# Keys whose values are measurements of a run, not its output (found by running
# one binary twice; nothing else differs): run_report.json's stage `seconds`,
# `seconds_total` and `peak_rss_bytes` (self, children); each
# work/lod/<id>/report.json's `timings_s` (per step). Their paths (the input
# chunk's absolute path) are the run's directory, normalised as such.
VOLATILE_KEYS=seconds,seconds_total,timings_s,peak_rss_bytes

tmp=$(mktemp -d "${TMPDIR:-/tmp}/same-output.XXXXXX")
((keep)) || trap 'rm -rf "$tmp"' EXIT

run() {  # EXE DIR THREADS
  mkdir -p "$2"
  if ! "$1" tile examples/delft_small/delft_small.las --crs EPSG:28992 \
    --footprints examples/delft_small/footprints.geojson --threads "$3" --out "$2/out" "${args[@]}" \
    > "$2/log" 2>&1; then
    echo "same-output: $1 tile failed (log: $2/log)" >&2
    tail -5 "$2/log" >&2
    exit 2
  fi
}

# compare A B [KEYS]: every file of A/out and B/out; prints the ones that differ
# (KEYS: normalised too).
compare() {
  python3 - "$1/out" "$2/out" "$VOLATILE_KEYS${3:+,$3}" <<'EOF'
import json, os, sys

a_root, b_root, keys = sys.argv[1], sys.argv[2], set(sys.argv[3].split(","))

def files(root):
    out = set()
    for d, _, names in os.walk(root):
        for n in names:
            out.add(os.path.relpath(os.path.join(d, n), root))
    return out

def normalise(v, root):
    """The JSON value with the volatile keys' values and the run's directory
    replaced by placeholders."""
    if isinstance(v, dict):
        return {k: "<volatile>" if k in keys else normalise(x, root) for k, x in v.items()}
    if isinstance(v, list):
        return [normalise(x, root) for x in v]
    if isinstance(v, str):
        return v.replace(os.path.dirname(root), "<run>")
    return v

def as_json(name, data, root):
    """The normalised JSON of a .json file or of each line of a .jsonl one."""
    try:
        text = data.decode("utf-8")
        lines = text.splitlines() if name.endswith(".jsonl") else [text]
        return [normalise(json.loads(l), root) for l in lines]
    except (UnicodeDecodeError, ValueError):
        return None

fa, fb = files(a_root), files(b_root)
bad = 0
for f in sorted(fa - fb):
    print(f"only in {a_root}: {f}"); bad += 1
for f in sorted(fb - fa):
    print(f"only in {b_root}: {f}"); bad += 1
normalised = 0
for f in sorted(fa & fb):
    da = open(os.path.join(a_root, f), "rb").read()
    db = open(os.path.join(b_root, f), "rb").read()
    if da == db:
        continue
    if f.endswith((".json", ".jsonl")):
        ja, jb = as_json(f, da, a_root), as_json(f, db, b_root)
        if ja is not None and ja == jb:
            normalised += 1
            continue
    print(f"differs: {f}"); bad += 1
print(f"{len(fa | fb)} files: {len(fa | fb) - bad} same"
      f" ({normalised} after normalising {','.join(sorted(keys))} and the run directory)"
      f", {bad} differ")
sys.exit(1 if bad else 0)
EOF
}

status=0
echo "same-output: OLD $old --threads $threads ${args[*]}"
run "$old" "$tmp/old" "$threads"
echo "same-output: NEW $new --threads $threads ${args[*]}"
run "$new" "$tmp/new" "$threads"
echo "same-output: OLD vs NEW"
compare "$tmp/old" "$tmp/new" || status=1
if ((thread_counts)); then
  other=$((threads == 1 ? 2 : 1))
  echo "same-output: NEW --threads $other"
  run "$new" "$tmp/new-$other" "$other"
  echo "same-output: NEW --threads $threads vs --threads $other"
  compare "$tmp/new" "$tmp/new-$other" threads || status=1  # run_report.json records --threads
fi
((keep)) && echo "same-output: kept $tmp"
if ((status)); then echo "same-output: DIFFERENT"; else echo "same-output: identical"; fi
exit $status
