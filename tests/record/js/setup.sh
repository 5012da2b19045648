#!/usr/bin/env bash
# Installs the pinned MCAP reader (package-lock.json) the record tests run,
# once: does nothing when node_modules is already up to date with the lock.
# Without npm it says so and succeeds; the tests then skip.
#   setup.sh [DIR]   DIR: another folder with a package-lock.json (default: this one)
set -euo pipefail
cd "${1:-$(dirname "$0")}"
if ! command -v npm >/dev/null 2>&1; then
  echo "setup.sh: npm not installed; the tests that run node will skip"
  exit 0
fi
# npm writes node_modules/.package-lock.json on every install.
if [[ -f node_modules/.package-lock.json && ! package-lock.json -nt node_modules/.package-lock.json ]]; then
  exit 0
fi
npm ci --no-audit --no-fund
