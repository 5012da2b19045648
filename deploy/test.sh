#!/usr/bin/env bash
# README command 2: installs dependencies, builds everything with tests, and
# runs the whole test suite with CTest. Tests that need ../shared/data/kitti
# say so and skip when it is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/install-deps.sh
bash deploy/build.sh -DLOCAID_BUILD_TESTS=ON
cd build
ctest --output-on-failure -j"$(nproc)" --timeout 900
