#!/usr/bin/env bash
# README command 2: installs dependencies, builds everything with tests, runs
# the whole test suite with CTest, then builds and tests the container image,
# and prints a summary: the CTest counts, every skipped test by name with its
# reason (deploy/test-summary.py, from CTest's JUnit file
# build/ctest-junit.xml), the image test's result and how long each phase
# took. Skips are for what this machine cannot offer: the shared KITTI data in
# ../shared/data/kitti, or root / CAP_SYS_ADMIN (the four full-disk tests
# mount a tmpfs). A missing tool fails its test when CI is set (.ci/run sets
# it); deploy/install-deps.sh installs them all, podman included.
#
# The image test (deploy/test-image.sh: build the image with podman, run the
# server from it, a synthetic session and a ROS 2 bag session inside it) runs
# on every run. Only LOCAID_IMAGE_TEST=0 skips it, and the summary says so.
# LOCAID_CONTAINER_ENGINE=docker uses a running Docker engine instead.
set -euo pipefail
cd "$(dirname "$0")/.."
image_test=${LOCAID_IMAGE_TEST:-1}
[[ $image_test == 0 || $image_test == 1 ]] ||
  { echo "test.sh: LOCAID_IMAGE_TEST must be 0 or 1, got '$image_test'" >&2; exit 2; }

phases=()
phase() {  # phase NAME COMMAND...: runs it, records its wall time, keeps its status
  local name=$1 t0 rc=0
  shift
  t0=$(date +%s)
  echo "test.sh: phase '$name' started $(date -u +%H:%M:%S) UTC"
  "$@" || rc=$?
  phases+=("$(printf '%-8s %5d s  %s' "$name" $(($(date +%s) - t0)) "$([[ $rc == 0 ]] && echo ok || echo "FAILED (exit $rc)")")")
  return "$rc"
}
summary() {
  echo
  echo "test.sh: phases (wall time on $(nproc) cores)"
  for p in "${phases[@]}"; do echo "  $p"; done
  if [[ $image_test == 0 ]]; then
    echo "  image       -    container image test SKIPPED (LOCAID_IMAGE_TEST=0)"
  fi
}
trap summary EXIT

phase install bash deploy/install-deps.sh
phase build bash deploy/build.sh -DLOCAID_BUILD_TESTS=ON
status=0
phase tests bash -c 'cd build && ctest --output-on-failure -j"$(nproc)" --timeout 900 --output-junit ctest-junit.xml' ||
  status=$?
python3 deploy/test-summary.py build/ctest-junit.xml
((status == 0)) || echo "test.sh: CTest failed (exit $status); the image is tested all the same" >&2
image_status=0
if [[ $image_test == 1 ]]; then
  phase image bash deploy/test-image.sh --engine "${LOCAID_CONTAINER_ENGINE:-podman}" || image_status=$?
fi
((status == 0)) || exit "$status"
exit "$image_status"
