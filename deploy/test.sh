#!/usr/bin/env bash
# README command 2: installs dependencies, builds everything with tests, and
# runs the whole test suite with CTest, then prints a summary: the counts and
# every skipped test by name with its reason (deploy/test-summary.py, from
# CTest's JUnit file build/ctest-junit.xml). Skips are for what this machine
# cannot offer: the shared KITTI data in ../shared/data/kitti, or root /
# CAP_SYS_ADMIN (the four full-disk tests mount a tmpfs). A missing tool fails
# its test when CI is set (.ci/run sets it); deploy/install-deps.sh installs
# them all.
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
status=0
(cd build && ctest --output-on-failure -j"$(nproc)" --timeout 900 --output-junit ctest-junit.xml) || status=$?
python3 deploy/test-summary.py build/ctest-junit.xml
if ((status != 0)); then
  echo "test.sh: CTest failed (exit $status)" >&2
  exit "$status"
fi

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
