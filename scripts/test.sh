#!/usr/bin/env bash
# Installs dependencies, checks the formatting (scripts/format.sh --check),
# builds Release with tests and warnings as errors, runs the whole test suite,
# then builds everything again with ASan+UBSan and runs the unit, CLI and
# real-data tests under the sanitizers, then runs every fuzzer briefly
# (scripts/fuzz.sh 10: libFuzzer + ASan, clang-14).
# Usage: scripts/test.sh [--no-install] [--no-sanitize] [--no-fuzz]
set -euo pipefail
cd "$(dirname "$0")/.."

install=1 sanitize=1 fuzz=1
for a in "$@"; do
  case "$a" in
    --no-install) install=0 ;;
    --no-sanitize) sanitize=0 ;;
    --no-fuzz) fuzz=0 ;;
    *) echo "usage: scripts/test.sh [--no-install] [--no-sanitize] [--no-fuzz]" >&2; exit 2 ;;
  esac
done

if ((install)); then
  scripts/install-deps.sh --with-test-tools
  # glTF validator, headless viewer test, CesiumJS (npm registry; tests skip without them)
  scripts/install-node-tools.sh || echo "test.sh: node tools not installed; the validator and viewer tests will skip" >&2
fi
jobs=$(nproc)

echo "== format check"
scripts/format.sh --check

echo "== Release build (warnings are errors) + full test suite"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DCITYLOD_BUILD_TESTS=ON -DCITYLOD_WERROR=ON
cmake --build build -j"$jobs"
ctest --test-dir build --output-on-failure -j"$jobs" --timeout 900

if ((sanitize)); then
  echo "== ASan+UBSan build; unit, CLI (the citylod binary under the sanitizers) and real-data tests"
  # Not -DCITYLOD_WERROR here: GCC 12 reports false -Wmaybe-uninitialized in libstdc++'s
  # <regex> under -fsanitize (the Release build above enforces warnings as errors).
  cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCITYLOD_BUILD_TESTS=ON -DCITYLOD_SANITIZE=ON \
    -DCITYLOD_WERROR=OFF
  cmake --build build-asan -j"$jobs"
  ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build-asan --output-on-failure -j"$jobs" --timeout 1800 -L '^(geo|io|lod|tiler|cli|lodreal)$'
fi
if ((fuzz)); then
  echo "== fuzzers of every reader (libFuzzer + ASan), 10 s each (RELIABILITY.md)"
  FUZZ_SEED=1 scripts/fuzz.sh 10
fi
echo "== all tests passed"
