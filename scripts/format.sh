#!/usr/bin/env bash
# clang-format (14, .clang-format) over the C++ sources tracked by git.
#   scripts/format.sh           reformat in place
#   scripts/format.sh --check   list the files that differ; exit 1 if any (CI: scripts/test.sh)
set -euo pipefail
cd "$(dirname "$0")/.."

check=0
case "${1:-}" in
  --check) check=1 ;;
  "") ;;
  *) echo "usage: scripts/format.sh [--check]" >&2; exit 2 ;;
esac
cf=$(command -v clang-format-14 || command -v clang-format || true)
if [[ -z "$cf" ]]; then
  echo "format.sh: clang-format not found (apt-get install clang-format)" >&2
  exit 2
fi
mapfile -t files < <(git ls-files -- '*.cpp' '*.hpp' '*.h')
if ((check)); then
  bad=()
  for f in "${files[@]}"; do
    [[ -f "$f" ]] || continue
    "$cf" --dry-run --Werror "$f" > /dev/null 2>&1 || bad+=("$f")
  done
  if ((${#bad[@]})); then
    echo "format.sh: ${#bad[@]} of ${#files[@]} files differ from .clang-format (run scripts/format.sh):" >&2
    printf '  %s\n' "${bad[@]}" >&2
    exit 1
  fi
  echo "format.sh: ${#files[@]} files formatted"
else
  "$cf" -i "${files[@]}"
fi
