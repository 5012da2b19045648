#!/usr/bin/env bash
# Sanitizer builds of the test suites, each in its own build folder:
#   asan: AddressSanitizer + UndefinedBehaviorSanitizer, every test executable
#         (or the ones named), build-asan/, then ctest.
#   tsan: ThreadSanitizer, the server tests (threads, hub, gRPC streams),
#         build-tsan/, then ctest.
#
#   deploy/sanitize.sh                 # asan then tsan
#   deploy/sanitize.sh asan kitti_tests
#   deploy/sanitize.sh tsan            # server_tests (skipped if it does not exist yet)
#
# Any sanitizer report fails the test that triggered it (halt_on_error, no
# UBSan recovery), so ctest's result is the verdict. Options: -j JOBS (default
# 2), env CXX to pick the compiler (default: CMake's choice), env
# LOCAID_SANITIZE_CTEST_ARGS for extra ctest arguments (e.g. "-R Pose").
# Exit status: non-zero when a build or a test failed.
set -euo pipefail

repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
jobs=2
modes=()
targets=()
while (($#)); do
  case $1 in
    -j) jobs=$2; shift 2 ;;
    asan|tsan) modes+=("$1"); shift ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    -*) echo "sanitize: unknown option $1" >&2; exit 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
((${#modes[@]})) || modes=(asan tsan)

# Test executables that exist in this checkout (tests/<module>/CMakeLists.txt).
all_test_targets() {
  local d
  for d in "$repo"/tests/*/; do
    [[ -f $d/CMakeLists.txt ]] && echo "$(basename "$d")_tests"
  done
  return 0
}

run_mode() {
  local mode=$1; shift
  local build=$repo/build-$mode flags opts
  case $mode in
    asan)
      flags="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer -g"
      # detect_leaks: LeakSanitizer needs ptrace; set ASAN_OPTIONS=detect_leaks=1 where allowed.
      export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=0:halt_on_error=1:abort_on_error=1:detect_stack_use_after_return=1}
      export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
      ;;
    tsan)
      flags="-fsanitize=thread -fno-omit-frame-pointer -g"
      opts="halt_on_error=1:second_deadlock_stack=1"
      [[ -f $repo/deploy/tsan.supp ]] && opts+=":suppressions=$repo/deploy/tsan.supp"
      export TSAN_OPTIONS=${TSAN_OPTIONS:-$opts}
      ;;
  esac
  local want=("$@")
  if ((${#want[@]} == 0)); then
    if [[ $mode == tsan ]]; then want=(server_tests); else mapfile -t want < <(all_test_targets); fi
  fi
  echo "sanitize[$mode]: configuring $build ($flags)"
  cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLOCAID_BUILD_TESTS=ON \
        -DLOCAID_BUILD_BENCH=OFF -DLOCAID_BUILD_FUZZ=OFF \
        -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="$flags" >/dev/null || return 1
  local present=() t
  for t in "${want[@]}"; do
    if [[ -f $repo/tests/${t%_tests}/CMakeLists.txt ]]; then present+=("$t")
    else echo "sanitize[$mode]: no target $t in this checkout: skipped"; fi
  done
  if ((${#present[@]} == 0)); then echo "sanitize[$mode]: nothing to run"; return 0; fi
  echo "sanitize[$mode]: building ${present[*]}"
  local build_args=()
  for t in "${present[@]}"; do build_args+=(--target "$t"); done
  cmake --build "$build" -j"$jobs" "${build_args[@]}" || return 1
  # Only executables built here registered their tests (gtest_discover_tests).
  echo "sanitize[$mode]: ctest"
  # shellcheck disable=SC2086
  # Test programs (locaid-eval ...) that some tests spawn are not built here;
  # those tests skip. *_NOT_BUILT are placeholders of unbuilt test executables.
  ctest --test-dir "$build" -j"$jobs" --output-on-failure --timeout 900 -E '_NOT_BUILT$' \
        ${LOCAID_SANITIZE_CTEST_ARGS:-} || return 1
}

status=0
for mode in "${modes[@]}"; do
  if run_mode "$mode" "${targets[@]}"; then echo "sanitize[$mode]: PASS"
  else echo "sanitize[$mode]: FAIL"; status=1; fi
done
exit $status
