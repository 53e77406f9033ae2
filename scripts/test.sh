#!/usr/bin/env bash
# Installs dependencies, builds Release with tests, runs the whole test suite,
# then builds the unit tests with ASan+UBSan and runs them.
# Usage: scripts/test.sh [--no-install] [--no-sanitize]
set -euo pipefail
cd "$(dirname "$0")/.."

install=1 sanitize=1
for a in "$@"; do
  case "$a" in
    --no-install) install=0 ;;
    --no-sanitize) sanitize=0 ;;
    *) echo "usage: scripts/test.sh [--no-install] [--no-sanitize]" >&2; exit 2 ;;
  esac
done

if ((install)); then
  scripts/install-deps.sh --with-test-tools
  # glTF validator, headless viewer test, CesiumJS (npm registry; tests skip without them)
  scripts/install-node-tools.sh || echo "test.sh: node tools not installed; the validator and viewer tests will skip" >&2
fi
jobs=$(nproc)

echo "== Release build + full test suite"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DCITYLOD_BUILD_TESTS=ON
cmake --build build -j"$jobs"
ctest --test-dir build --output-on-failure -j"$jobs" --timeout 900

if ((sanitize)); then
  echo "== ASan+UBSan build of the unit tests"
  cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCITYLOD_BUILD_TESTS=ON -DCITYLOD_SANITIZE=ON
  cmake --build build-asan -j"$jobs" --target citylod_geo_tests citylod_io_tests citylod_lod_tests citylod_tiler_tests
  ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build-asan --output-on-failure -j"$jobs" --timeout 1800 -L '^(geo|io|lod|tiler)$'
fi
echo "== all tests passed"
