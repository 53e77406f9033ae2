#!/usr/bin/env bash
# Installs the node-based test tools (Khronos gltf-validator, playwright-core)
# and CesiumJS (for examples/viewer and `citylod serve`) into tests/node/node_modules
# from the committed package-lock.json. Idempotent: does nothing when
# node_modules already matches the lock file. Needs node >= 18 and npm; the
# browser test uses Debian's chromium (/usr/bin/chromium), not a downloaded one.
# Usage: scripts/install-node-tools.sh [--force]
set -euo pipefail
cd "$(dirname "$0")/../tests/node"

force=0
for a in "$@"; do
  case "$a" in
    --force) force=1 ;;
    *) echo "usage: scripts/install-node-tools.sh [--force]" >&2; exit 2 ;;
  esac
done

if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  echo "install-node-tools: node and npm are needed (Debian: apt-get install nodejs npm)" >&2
  exit 1
fi

# npm ci records the lock it installed in node_modules/.package-lock.json.
stamp=node_modules/.citylod-lock.sha256
want=$(sha256sum package-lock.json | cut -d' ' -f1)
if ((force == 0)) && [[ -f $stamp && "$(cat "$stamp")" == "$want" ]] &&
   [[ -d node_modules/gltf-validator && -d node_modules/playwright-core && -f node_modules/cesium/Build/Cesium/Cesium.js &&
   -f node_modules/three/build/three.module.js && -d node_modules/3d-tiles-renderer ]]; then
  echo "install-node-tools: tests/node/node_modules is up to date"
  exit 0
fi

# Playwright must not download browsers: we drive /usr/bin/chromium.
export PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1
npm ci --no-audit --no-fund --loglevel=error
echo "$want" > "$stamp"
echo "install-node-tools: installed $(ls node_modules | wc -l) packages in tests/node/node_modules"
