#!/usr/bin/env bash
# Installs the pinned Foxglove WebSocket client and protobufjs (package-lock.json)
# that client.mjs needs, once, with the same npm ci logic as the record tests.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
exec bash "$here/../../record/js/setup.sh" "$here"
