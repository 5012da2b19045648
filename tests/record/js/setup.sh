#!/usr/bin/env bash
# Installs the pinned MCAP reader (package-lock.json) the record tests run.
#
#   setup.sh [DEST [SRC]]
#
# SRC (default: this folder) holds package.json, package-lock.json and the
# .mjs scripts; they are copied to DEST (default: SRC), and `npm ci` installs
# DEST/node_modules when it is missing or older than the lock. CTest passes a
# folder of the build tree as DEST, so two builds (or checkouts) testing at
# once never share a node_modules.
#
# Without node or npm: says so and exits 0 (the tests that run node skip),
# unless CI is set: then exits 1, so a CI run cannot pass with them unrun
# (deploy/install-deps.sh installs nodejs and npm when they are missing).
set -euo pipefail
src="$(cd "${2:-$(dirname "$0")}" && pwd)"
dest="${1:-$src}"

missing=()
for tool in node npm; do
  command -v "$tool" >/dev/null 2>&1 || missing+=("$tool")
done
if ((${#missing[@]} > 0)); then
  if [[ -n "${CI:-}" && "${CI}" != 0 && "${CI}" != false ]]; then
    echo "setup.sh: ${missing[*]} not installed and CI is set: the node tests cannot run" \
         "(deploy/install-deps.sh installs nodejs and npm)" >&2
    exit 1
  fi
  echo "setup.sh: ${missing[*]} not installed; the tests that run node will skip"
  exit 0
fi

mkdir -p "$dest"
dest="$(cd "$dest" && pwd)"
if [[ "$dest" != "$src" ]]; then
  for f in "$src"/package.json "$src"/package-lock.json "$src"/*.mjs; do
    cmp -s "$f" "$dest/$(basename "$f")" || cp "$f" "$dest/"
  done
fi
cd "$dest"
# npm writes node_modules/.package-lock.json on every install.
if [[ -f node_modules/.package-lock.json && ! package-lock.json -nt node_modules/.package-lock.json ]]; then
  exit 0
fi
# npm's download cache and its debug log go to a folder of this run's own
# (removed on exit), not ~/.npm: a test run leaves nothing outside its folders.
tmp="$(mktemp -d "${TMPDIR:-/tmp}/locaid_npm_XXXXXX")"
trap 'rm -rf "$tmp"' EXIT
if ! npm ci --no-audit --no-fund --no-update-notifier --cache "$tmp/cache" --logs-dir "$tmp/logs"; then
  tail -n 40 "$tmp"/logs/*.log >&2 2>/dev/null || true
  exit 1
fi
