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
# Then the container image test (deploy/test-image.sh) with whichever engine
# the machine has, said before it runs: LOCAID_IMAGE_TEST=auto (default: with
# podman when it is on PATH, else with docker when a Docker engine answers
# `docker info`, else skipped with a message), 1 (always; podman unless
# LOCAID_CONTAINER_ENGINE=docker; test-image.sh installs podman), 0 (never).
# It adds about 10-25 minutes on 2 cores; a fresh Debian 12 machine has
# neither engine, so there it is skipped unless LOCAID_IMAGE_TEST=1.
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
  1) bash deploy/test-image.sh --engine "${LOCAID_CONTAINER_ENGINE:-podman}" ;;
  auto)
    if command -v podman >/dev/null 2>&1; then
      echo "test.sh: container image test with podman"
      bash deploy/test-image.sh --engine podman
    elif command -v docker >/dev/null 2>&1 && docker info >/dev/null 2>&1; then
      echo "test.sh: container image test with docker (podman is not installed)"
      bash deploy/test-image.sh --engine docker
    else
      echo "test.sh: container image test skipped: neither podman nor a running Docker engine" \
           "(LOCAID_IMAGE_TEST=1 makes deploy/test-image.sh install podman and run)"
    fi ;;
  *) echo "test.sh: LOCAID_IMAGE_TEST must be auto, 0 or 1, got '${LOCAID_IMAGE_TEST}'" >&2; exit 2 ;;
esac
