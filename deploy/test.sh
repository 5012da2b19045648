#!/usr/bin/env bash
# README command 2: installs dependencies, builds everything with tests, and
# runs the whole test suite with CTest. Tests that need ../shared/data/kitti
# say so and skip when it is absent.
#
# Then the container image test (deploy/test-image.sh) when podman is
# installed: LOCAID_IMAGE_TEST=auto (default: run it if `podman` is on PATH),
# 1 (always; test-image.sh installs podman), 0 (never). It adds about 10-25
# minutes on 2 cores; a fresh Debian 12 machine has no podman, so there it is
# skipped with a message unless LOCAID_IMAGE_TEST=1.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/install-deps.sh
bash deploy/build.sh -DLOCAID_BUILD_TESTS=ON
(cd build && ctest --output-on-failure -j"$(nproc)" --timeout 900)

case "${LOCAID_IMAGE_TEST:-auto}" in
  0) echo "test.sh: container image test skipped (LOCAID_IMAGE_TEST=0)" ;;
  1) bash deploy/test-image.sh ;;
  auto)
    if command -v podman >/dev/null 2>&1; then
      bash deploy/test-image.sh
    else
      echo "test.sh: container image test skipped: podman is not installed" \
           "(LOCAID_IMAGE_TEST=1 makes deploy/test-image.sh install it and run)"
    fi ;;
  *) echo "test.sh: LOCAID_IMAGE_TEST must be auto, 0 or 1, got '${LOCAID_IMAGE_TEST}'" >&2; exit 2 ;;
esac
