#!/usr/bin/env bash
# Reproduces every benchmark table and plot of BENCHMARKS.md in one command:
#
#   scripts/bench.sh [--build-dir DIR] [--out DIR] [--jobs N] [--no-install] [--no-build] [--copy-plots]
#                    [--only lod|fidelity|split|tile|roofer]
#
# 0. installs the Debian packages it needs (scripts/install-deps.sh
#    --with-bench-tools: the build dependencies, meshoptimizer, gnuplot)
#    unless --no-install;
# 1. configures + builds a Release build with -DCITYLOD_BUILD_BENCH=ON in
#    build-bench/ (or --build-dir; --no-build reuses it as is);
# 2. runs lod_bench, fidelity_bench, split_bench, tile_bench and the side-by-side
#    comparison with 3DBAG's roofer (scripts/roofer-compare.sh: roofer and
#    `citylod tile` on the Delft LAS + footprints, roofer_bench per building),
#    each output kept under bench-results/<date>/ (or --out); --only runs one;
# 3. plots e2 against triangle count per fidelity input (gnuplot, PNG);
# 4. writes bench-results/<date>/summary.md: date, commit, `uname -a`, CPU
#    model, load average, wall time of each program and all the tables.
# --copy-plots also copies the PNGs to docs/bench/ (the committed copies that
# BENCHMARKS.md shows).
#
# Needs ../shared/data (the real inputs) beside the checkout. Exit status: 0
# when every program succeeded, 1 otherwise (the others still run).
set -uo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"

build_dir="build-bench"
out_dir=""
jobs="$(nproc 2>/dev/null || echo 2)"
do_build=1
do_install=1
copy_plots=0
only=""
usage() { sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) build_dir="${2:?--build-dir needs a value}"; shift 2 ;;
    --out) out_dir="${2:?--out needs a value}"; shift 2 ;;
    --jobs|-j) jobs="${2:?--jobs needs a value}"; shift 2 ;;
    --no-build) do_build=0; shift ;;
    --no-install) do_install=0; shift ;;
    --copy-plots) copy_plots=1; shift ;;
    --only) only="${2:?--only needs a value}"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "bench.sh: unknown argument $1" >&2; usage >&2; exit 2 ;;
  esac
done

if [ "$do_install" = 1 ]; then
  scripts/install-deps.sh --with-bench-tools || { echo "bench.sh: installing the dependencies failed" >&2; exit 1; }
fi

day="$(date +%Y-%m-%d)"
[ -n "$out_dir" ] || out_dir="bench-results/$day"
data="$(cd "$here/.." && pwd)/shared/data"
if [ ! -d "$data" ]; then
  echo "bench.sh: $data is missing: the benchmarks run on the real inputs of ../shared/data" >&2
  exit 1
fi
mkdir -p "$out_dir"
out_dir="$(cd "$out_dir" && pwd)"
log="$out_dir/bench.log"
: > "$log"
say() { echo "bench.sh: $*" | tee -a "$log" >&2; }

load_start="$(cut -d' ' -f1-3 /proc/loadavg)"
started="$(date -Iseconds)"

# 1. Build -------------------------------------------------------------------
if [ "$do_build" = 1 ]; then
  say "configuring $build_dir (Release, CITYLOD_BUILD_BENCH=ON)"
  cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release -DCITYLOD_BUILD_BENCH=ON >>"$log" 2>&1 ||
    { say "configure failed (see $log)"; exit 1; }
  targets=(citylod lod_bench split_bench fidelity_bench roofer_bench)
  if grep -q 'add_executable(tile_bench' bench/CMakeLists.txt 2>/dev/null; then targets+=(tile_bench); fi
  for t in "${targets[@]}"; do
    say "building $t"
    cmake --build "$build_dir" --target "$t" -j "$jobs" >>"$log" 2>&1 || say "build of $t failed (see $log)"
  done
fi
citylod_exe="$(cd "$build_dir" && pwd)/app/citylod"
bench_bin="$(cd "$build_dir" && pwd)/bench"

# 2. Run ---------------------------------------------------------------------
failed=()
declare -A wall
run() {  # run NAME OUTPUT.md COMMAND... : stdout -> OUTPUT.md, stderr -> NAME.log
  local name="$1" md="$2"; shift 2
  if [ ! -x "$1" ]; then
    say "$name: $1 not built, skipped"
    failed+=("$name (not built)")
    return
  fi
  say "running $name: $*"
  local t0 t1
  t0="$(date +%s.%N)"
  "$@" >"$out_dir/$md" 2>"$out_dir/$name.log"
  local rc=$?
  t1="$(date +%s.%N)"
  wall[$name]="$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }')"
  if [ $rc -ne 0 ]; then
    say "$name exited with status $rc (see $out_dir/$name.log)"
    failed+=("$name (status $rc)")
  fi
}

want() { [ -z "$only" ] || [ "$only" = "$1" ]; }
want lod && run lod_bench lod_bench.md "$bench_bin/lod_bench"
want fidelity && run fidelity_bench fidelity.md "$bench_bin/fidelity_bench" --out "$out_dir/fidelity"
want split && run split_bench split_bench.md "$bench_bin/split_bench" --memory-limit 256M
if want tile; then
  if [ -x "$bench_bin/tile_bench" ]; then
    run tile_bench tile_bench.md "$bench_bin/tile_bench" --citylod "$citylod_exe" --out "$out_dir/tile"
  else
    say "tile_bench not built in $build_dir: skipped"
  fi
fi
want roofer && run roofer_compare roofer.txt "$here/scripts/roofer-compare.sh" --citylod "$citylod_exe" \
  --bench "$bench_bin/roofer_bench" --out "$out_dir/roofer"

# 3. Plots -------------------------------------------------------------------
plots=()
if command -v gnuplot >/dev/null; then
  for csv in "$out_dir"/fidelity/*.csv; do
    [ -e "$csv" ] || continue
    name="$(basename "$csv" .csv)"
    png="$out_dir/fidelity/$name.png"
    if gnuplot -e "csv='$csv'; png='$png'; name='$name'" bench/plot_fidelity.gp >>"$log" 2>&1; then
      plots+=("$png")
    else
      say "gnuplot failed on $csv"
      failed+=("plot $name")
    fi
  done
else
  say "gnuplot not installed (apt-get install gnuplot-nox): no plots"
fi
if [ "$copy_plots" = 1 ] && [ ${#plots[@]} -gt 0 ]; then
  mkdir -p docs/bench
  for png in "${plots[@]}"; do cp "$png" "docs/bench/fidelity_$(basename "$png")"; done
  say "copied ${#plots[@]} plots to docs/bench/"
fi

# 4. Summary -----------------------------------------------------------------
load_end="$(cut -d' ' -f1-3 /proc/loadavg)"
commit="$(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
dirty="$(git status --porcelain --untracked-files=no 2>/dev/null | awk '{ print $2 }' | tr '\n' ' ')"
summary="$out_dir/summary.md"
{
  echo "# citylod benchmark run, $day"
  echo
  echo "- command: \`scripts/bench.sh\` (build dir \`$build_dir\`, Release)"
  echo "- started: $started, finished: $(date -Iseconds)"
  echo "- commit: $commit${dirty:+ (uncommitted changes in: $dirty)}"
  echo "- machine: \`$(uname -a)\`"
  echo "- CPU: $(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -1), $(nproc) cores; memory $(free -g | awk '/^Mem:/ { print $2 }') GiB"
  echo "- compiler: $(c++ --version 2>/dev/null | head -1)"
  echo "- load average (1/5/15 min) at start: $load_start; at end: $load_end"
  echo "- wall time per program (s): $(for k in lod_bench fidelity_bench split_bench tile_bench roofer_compare; do [ -n "${wall[$k]:-}" ] && printf '%s %s; ' "$k" "${wall[$k]}"; done)"
  if [ ${#failed[@]} -gt 0 ]; then echo "- **FAILED**: ${failed[*]}"; fi
  section() {  # section TITLE FILE [pre]: FILE's markdown, or plain text fenced when "pre"
    [ -s "$out_dir/$2" ] || return 0
    echo
    echo "## $1"
    echo
    if [ "${3:-}" = pre ]; then echo '```'; cat "$out_dir/$2"; echo '```'; else cat "$out_dir/$2"; fi
  }
  section "LOD engine on real buildings (lod_bench)" lod_bench.md
  section "Fidelity against size vs QEM (fidelity_bench)" fidelity.md
  if [ ${#plots[@]} -gt 0 ]; then
    echo
    for png in "${plots[@]}"; do echo "![$(basename "$png" .png)](fidelity/$(basename "$png"))"; done
  fi
  section "Splitting (split_bench --memory-limit 256M)" split_bench.md pre
  section "City run scaling (tile_bench)" tile_bench.md
  section "citylod vs roofer, side by side (scripts/roofer-compare.sh)" roofer.txt pre
} >"$summary"
say "summary: $summary"
[ ${#failed[@]} -eq 0 ]
