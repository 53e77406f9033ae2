#!/usr/bin/env bash
# Idempotent installer of citylod's build and test dependencies (Debian 12 packages only).
# Usage: scripts/install-deps.sh [--with-test-tools | --with-bench-tools]
#   --with-test-tools  also installs what the test suite needs beyond the build
#                      (nodejs/npm, chromium, gdal-bin, gnuplot, slurm-wlm, munge,
#                      val3dity's runtime libraries, python3-numpy,
#                      postgresql-15-postgis-3 for the PostGIS footprint test, which
#                      runs when CITYLOD_TEST_PG names a server).
#   --with-bench-tools also installs what scripts/bench.sh needs (gnuplot, gdal-bin for ogr2ogr).
set -euo pipefail

build_pkgs=(
  build-essential cmake ninja-build pkg-config
  libcgal-dev libeigen3-dev libpcl-dev libgeographiclib-dev
  libproj-dev proj-data proj-bin libtinygltf-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libmeshoptimizer-dev libomp-dev
  libgdal-dev
)
# clang-14 + libclang-rt-14-dev: the libFuzzer harnesses (scripts/fuzz.sh)
# libgeos-c1v5 ... libgmp10: the runtime of the prebuilt val3dity in ../shared/tools
# (the CityJSON tests validate with it); python3-numpy: ../shared/tools/scale/replicate.py
test_pkgs=(clang-format clang-14 libclang-rt-14-dev chromium gdal-bin gnuplot-nox slurm-wlm munge postgresql-15-postgis-3
  libgeos-c1v5 libboost-filesystem1.74.0 libmpfr6 libgmp10 python3-numpy)
# Node.js/npm: use the machine's own if present (Debian's npm conflicts with a
# nodejs installed from elsewhere); otherwise Debian's.
if ! command -v npm >/dev/null 2>&1; then test_pkgs+=(nodejs npm); fi

want=("${build_pkgs[@]}")
if [[ "${1:-}" == "--with-test-tools" ]]; then
  want+=("${test_pkgs[@]}")
elif [[ "${1:-}" == "--with-bench-tools" ]]; then
  want+=(gnuplot-nox gdal-bin)
fi

missing=()
for p in "${want[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]} == 0)); then
  echo "install-deps: all ${#want[@]} packages already installed"
  exit 0
fi

SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
