#!/usr/bin/env bash
# Installs the pinned Foxglove WebSocket client and protobufjs (package-lock.json)
# that client.mjs and crowd.mjs need, with the record tests' setup logic:
#   setup.sh [DEST]   DEST: where the scripts and node_modules go (default: this folder)
# Fails without node/npm when CI is set (see tests/record/js/setup.sh).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
exec "${BASH:-bash}" "$here/../../record/js/setup.sh" "${1:-$here}" "$here"
