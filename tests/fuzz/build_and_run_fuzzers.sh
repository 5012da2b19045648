#!/usr/bin/env bash
# CTest case FuzzTargets.BuildAndRunEach (tests/fuzz/CMakeLists.txt): builds
# every libFuzzer target of fuzz/ with clang in BUILD_DIR (its own folder
# under the CTest build tree, kept for the next run) and runs each for SECONDS
# on its seed corpus and committed regression inputs, with
# fuzz/run-fuzzers.sh. A build error, a missing target or a crash fails.
#
#   tests/fuzz/build_and_run_fuzzers.sh REPO BUILD_DIR SECONDS
#
# Without clang++ or its libFuzzer runtime (Debian: clang, libclang-rt-14-dev)
# it exits 77, which CTest reports as skipped, with the reason; when the
# environment variable CI is set (to anything but "", "0" or "false") it
# fails instead, so a CI run cannot pass with the fuzzers unbuilt.
# Env: LOCAID_FUZZ_CXX (default clang++), LOCAID_FUZZ_JOBS (default 2).
set -euo pipefail

repo=$1 build_dir=$2 seconds=$3
cxx=${LOCAID_FUZZ_CXX:-clang++}

unavailable() {
  local ci=${CI:-}
  if [[ -n $ci && $ci != 0 && $ci != false ]]; then
    echo "FAIL: $1 (CI is set: the fuzz targets must build; deploy/install-deps.sh installs clang and libclang-rt-14-dev)" >&2
    exit 1
  fi
  echo "SKIPPED: $1; install clang and libclang-rt-14-dev (deploy/install-deps.sh) to build and run the fuzz targets"
  exit 77
}

command -v "$cxx" >/dev/null 2>&1 || unavailable "$cxx not found"
# The libFuzzer and sanitizer runtimes ship separately from clang on Debian.
probe=$(mktemp -d "${TMPDIR:-/tmp}/locaid-fuzz-probe.XXXXXX")
trap 'rm -rf "$probe"' EXIT
printf 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }\n' \
  >"$probe/probe.cpp"
if ! "$cxx" -fsanitize=fuzzer,address,undefined "$probe/probe.cpp" -o "$probe/probe" 2>"$probe/err"; then
  unavailable "$cxx cannot link a libFuzzer program: $(head -n 2 "$probe/err" | tr '\n' ' ')"
fi
rm -rf "$probe"
trap - EXIT

echo "fuzz test: building the fuzz targets with $cxx in $build_dir, then ${seconds} s per target"
CXX=$cxx exec bash "$repo/fuzz/run-fuzzers.sh" -b "$build_dir" -t "$seconds" -j "${LOCAID_FUZZ_JOBS:-2}"
