#!/usr/bin/env bash
# Fails when a C++ file differs from the root .clang-format (clang-format 14, Debian 12's) or a
# JavaScript file from the root .prettierrc.json (prettier, pinned in web-viewer/package.json).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh >/dev/null
mapfile -t files < <(git ls-files '*.cpp' '*.h')
if [ "${#files[@]}" -gt 0 ]; then
    clang-format-14 --dry-run -Werror "${files[@]}"
fi
echo "check-format: ${#files[@]} C++ files formatted"
# prettier comes with the web viewer's npm packages, as locked (npm ci when missing or stale)
if [ ! -f web-viewer/node_modules/.package-lock.json ] ||
    [ web-viewer/package-lock.json -nt web-viewer/node_modules/.package-lock.json ]; then
    (cd web-viewer && npm ci --no-audit --no-fund >/dev/null)
fi
mapfile -t js < <(git ls-files '*.js' '*.mjs')
if [ "${#js[@]}" -gt 0 ]; then
    web-viewer/node_modules/.bin/prettier --check --log-level warn "${js[@]}"
fi
echo "check-format: ${#js[@]} JavaScript files formatted"
