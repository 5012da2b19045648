#!/usr/bin/env bash
# Sanitizer builds of the test executables, each mode in its own build folder:
#   asan: AddressSanitizer + UndefinedBehaviorSanitizer, build-asan/: every
#         test executable defined under tests/ (or the ones named) is built,
#         then ctest runs every test registered there (the fuzz label aside:
#         the fuzzers have their own ASan+UBSan build).
#   tsan: ThreadSanitizer, build-tsan/: the server's test executables (those
#         defined in tests/server/, or the ones named), then ctest runs their
#         tests (the soak label aside: 100 clients under TSan take too long).
#
#   deploy/sanitize.sh                 # asan then tsan
#   deploy/sanitize.sh asan kitti_tests fusion_tests
#   deploy/sanitize.sh tsan
#   deploy/sanitize.sh --list          # the test executables found, then exit
#
# Test executables are the EXECUTABLE targets defined under tests/, read from
# CMake's file API after configuring (not guessed from folder names); a name
# that is not one fails. A named subset runs only the tests of those
# executables.
#
# asan verdict: any ASan/UBSan report fails the test that triggered it
# (halt_on_error, no UBSan recovery), so ctest's result is the verdict.
#
# tsan verdict and Debian's gRPC: libgrpc, libgrpc++, libgpr and absl from
# Debian (and GDAL, which cv::imdecode loads) are not built with TSan, so TSan
# sees neither their memory accesses nor their locks, and reports races on
# data that gRPC hands from one thread to another. A clean verdict needs a
# TSan-built gRPC, which Debian does not ship. No suppression file is used: a
# `race:` entry matches any frame of a stack, and the service's reactor
# callbacks run on gRPC threads, so it would hide races in our code too.
# Instead every process logs its reports (build-tsan/tsan-logs/, halt_on_error
# off, exitcode 0, so tests run to the end) and each report is classified by
# the first frame of each racing access or lock stack, skipping TSan's
# interceptors and libstdc++ headers:
#   project        a frame in this repository (or its generated proto code);
#   uninstrumented every such frame in gRPC/absl/GDAL or their headers.
# build-tsan/tsan-summary.txt lists each distinct report with those frames.
# tsan FAILs when a test fails or a project report exists; uninstrumented
# reports are counted, not fatal. A project report may still be a false
# positive (the hand-over went through gRPC's uninstrumented locks): read it.
#
# Options: -j JOBS (default 2), --list. Env: CXX to pick the compiler
# (default: CMake's choice), LOCAID_SANITIZE_CTEST_ARGS for extra ctest
# arguments (e.g. "-R Pose"), LOCAID_SANITIZE_CMAKE_ARGS for extra configure
# arguments (e.g. "-DLOCAID_SHARED_DATA=/data/kitti").
# Exit status: non-zero when a build or a test failed (or, tsan, a project
# report).
set -euo pipefail

repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
jobs=2
list_only=0
modes=()
targets=()
while (($#)); do
  case $1 in
    -j) jobs=$2; shift 2 ;;
    --list) list_only=1; shift ;;
    asan|tsan) modes+=("$1"); shift ;;
    -h|--help) sed -n '2,47p' "$0"; exit 0 ;;
    -*) echo "sanitize: unknown option $1" >&2; exit 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
((${#modes[@]})) || modes=(asan tsan)
((list_only)) && modes=("${modes[0]}")

# "<name> <folder>" for every EXECUTABLE target defined under tests/ (CMake
# file API reply of the last configure of build folder $1).
test_executables() {
  /usr/bin/python3 - "$1" <<'EOF'
import glob, json, os, sys
reply = os.path.join(sys.argv[1], ".cmake", "api", "v1", "reply")
index = json.load(open(sorted(glob.glob(os.path.join(reply, "index-*.json")))[-1]))
model = next(o for o in index["objects"] if o["kind"] == "codemodel")
config = json.load(open(os.path.join(reply, model["jsonFile"])))["configurations"][0]
dirs = config["directories"]
for t in config["targets"]:
    target = json.load(open(os.path.join(reply, t["jsonFile"])))
    folder = dirs[t["directoryIndex"]]["source"]
    if target["type"] == "EXECUTABLE" and (folder == "tests" or folder.startswith("tests/")):
        print(target["name"], folder)
EOF
}

# Numbers of the ctest tests of build folder $1 whose program is one of the
# executables named after it ("0,0,0,n,n,..." for ctest -I), or "none".
# ctest numbers -I in the list left by the other filters (-R, -E, -L, -LE),
# so the same filters ($ctest_filter) are applied here first.
tests_of() {
  local build=$1; shift
  (cd "$build" && ctest --show-only=json-v1 "${ctest_filter[@]}") | /usr/bin/python3 -c '
import json, os, sys
wanted = set(sys.argv[1:])
numbers = [str(i + 1) for i, t in enumerate(json.load(sys.stdin)["tests"])
           if t.get("command") and os.path.basename(t["command"][0]) in wanted]
print("0,0,0," + ",".join(numbers) if numbers else "none")' "$@"
}

# Classifies the TSan reports in the logs of folder $1 (see the header);
# writes $2 and prints its summary; exit 1 when a project report exists.
classify_tsan() {
  /usr/bin/python3 - "$1" "$2" "$repo" <<'EOF'
import collections, glob, os, re, sys
log_dir, out_path, repo = sys.argv[1], sys.argv[2], os.path.realpath(sys.argv[3])
# "    #3 ns::(anonymous namespace)::F(int) /path/f.cpp:12:5 (module+0x1f)"
frame_re = re.compile(r"^\s+#\d+ (.*) \((\S+?)\+0x[0-9a-f]+\)$")
# Stack titles that say where something was made, not who raced or locked.
context = re.compile(r"^  (Location is|Thread T\d+|Mutex M\d+ \(0x[0-9a-f]+\) created|Mutex M\d+ created|As if)")
def frame(line):
    m = frame_re.match(line)
    if not m:
        return None
    func, _, where = m.group(1).rpartition(" ")
    return func, where, m.group(2)
def skip(func, where, module):
    return ("libtsan" in module or "libstdc++" in module or where.startswith("/usr/include/c++/")
            or func.startswith(("__tsan", "__interceptor")))
def kind_of(func, where, module):
    # "<null>" (no debug line, as in Debian's libgrpc) is no path: a relative
    # one would resolve against the working folder, which is in the repo.
    path = where.split(":")[0]
    inside = os.path.isabs(path) and os.path.realpath(path).startswith(repo + "/")
    return "project" if inside else "uninstrumented"
def tops_of(block, use_context):
    tops, in_stack, decided = [], True, False
    for line in block.splitlines():
        if re.match(r"^  \S", line):  # a stack title
            in_stack, decided = use_context or not context.match(line), False
            continue
        f = frame(line)
        if in_stack and not decided and f and not skip(*f):
            tops.append((kind_of(*f),) + f)
            decided = True
    return tops
reports = collections.OrderedDict()
for log in sorted(glob.glob(os.path.join(log_dir, "*"))):
    text = open(log, errors="replace").read()
    for block in text.split("==================\n"):
        m = re.search(r"WARNING: ThreadSanitizer: (.*?) \(pid=(\d+)\)", block)
        if not m:
            continue
        what = m.group(1)
        body = block[m.end():]
        tops = tops_of(body, False) or tops_of(body, True)  # a thread leak has only context stacks
        kind = "project" if any(t[0] == "project" for t in tops) else "uninstrumented"
        key = (what, tuple(t[1:3] for t in tops))
        entry = reports.setdefault(key, {"kind": kind, "what": what, "tops": tops, "count": 0, "logs": set()})
        entry["count"] += 1
        entry["logs"].add(os.path.basename(log))
counts = collections.Counter()
with open(out_path, "w") as out:
    for r in reports.values():
        counts[r["kind"]] += 1
        out.write(f"[{r['kind']}] {r['what']} x{r['count']} ({len(r['logs'])} process(es))\n")
        for kind, func, where, module in r["tops"]:
            out.write(f"    {kind:14s} {func} {where} ({os.path.basename(module)})\n")
total = sum(r["count"] for r in reports.values())
print(f"sanitize[tsan]: {total} report(s), {len(reports)} distinct: {counts['project']} with a project frame "
      f"on top, {counts['uninstrumented']} inside uninstrumented gRPC/absl/GDAL (list: {out_path})")
for r in reports.values():
    if r["kind"] == "project":
        print(f"  [project] {r['what']} x{r['count']}: " +
              "; ".join(f"{func} {where}" for _, func, where, _ in r["tops"]))
sys.exit(1 if counts["project"] else 0)
EOF
}

run_mode() {
  local mode=$1; shift
  local build=$repo/build-$mode flags cxx_flags
  case $mode in
    asan)
      flags="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer -g"
      # detect_leaks: LeakSanitizer needs ptrace; set ASAN_OPTIONS=detect_leaks=1 where allowed.
      export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=0:halt_on_error=1:abort_on_error=1:detect_stack_use_after_return=1}
      export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
      ;;
    tsan)
      flags="-fsanitize=thread -fno-omit-frame-pointer -g"
      ;;
  esac
  cxx_flags=$flags
  echo "sanitize[$mode]: configuring $build ($flags)"
  mkdir -p "$build/.cmake/api/v1/query"
  touch "$build/.cmake/api/v1/query/codemodel-v2"
  # shellcheck disable=SC2086
  cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLOCAID_BUILD_TESTS=ON \
        -DLOCAID_BUILD_BENCH=OFF -DLOCAID_BUILD_FUZZ=OFF \
        -DCMAKE_CXX_FLAGS="$cxx_flags" -DCMAKE_EXE_LINKER_FLAGS="$flags" \
        ${LOCAID_SANITIZE_CMAKE_ARGS:-} >/dev/null || return 1

  local found=() names=() folder name t
  mapfile -t found < <(test_executables "$build")
  if ((list_only)); then printf '%s\n' "${found[@]}"; return 0; fi
  local want=("$@")
  if ((${#want[@]} == 0)); then
    for t in "${found[@]}"; do
      read -r name folder <<<"$t"
      if [[ $mode == asan || $folder == tests/server ]]; then want+=("$name"); fi
    done
  else
    for t in "${want[@]}"; do
      printf '%s\n' "${found[@]}" | grep -q "^$t " || {
        echo "sanitize[$mode]: $t is not a test executable; known: $(printf '%s\n' "${found[@]}" | cut -d' ' -f1 | tr '\n' ' ')" >&2
        return 1; }
    done
  fi
  ((${#want[@]})) || { echo "sanitize[$mode]: no test executable found" >&2; return 1; }
  echo "sanitize[$mode]: building ${want[*]}"
  local build_args=()
  for t in "${want[@]}"; do build_args+=(--target "$t"); done
  cmake --build "$build" -j"$jobs" "${build_args[@]}" || return 1

  # Which tests: all registered ones for a full asan run (they include the
  # Python contract suite and the JS clients, on these sanitized programs);
  # otherwise those of the executables built.
  local select=() exclude='fuzz'
  [[ $mode == tsan ]] && exclude='fuzz|soak'
  # *_NOT_BUILT: placeholders of test executables not built here.
  # shellcheck disable=SC2206
  local ctest_filter=(-E '_NOT_BUILT$' -LE "$exclude" ${LOCAID_SANITIZE_CTEST_ARGS:-})
  if [[ $mode == tsan || $# -gt 0 ]]; then
    local numbers
    numbers=$(tests_of "$build" "${want[@]}")
    [[ $numbers == none ]] && { echo "sanitize[$mode]: the executables registered no test" >&2; return 1; }
    select=(-I "$numbers")
  fi
  local status=0 logs=$build/tsan-logs
  if [[ $mode == tsan ]]; then
    rm -rf "$logs"; mkdir -p "$logs"
    export TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=0:exitcode=0:second_deadlock_stack=1:log_path=$logs/tsan}
  fi
  echo "sanitize[$mode]: ctest"
  ctest --test-dir "$build" -j"$jobs" --output-on-failure --timeout 900 "${ctest_filter[@]}" "${select[@]}" \
    || status=1
  if [[ $mode == tsan ]]; then
    classify_tsan "$logs" "$build/tsan-summary.txt" || status=1
  fi
  return $status
}

status=0
for mode in "${modes[@]}"; do
  if run_mode "$mode" "${targets[@]}"; then
    ((list_only)) || echo "sanitize[$mode]: PASS"
  else
    echo "sanitize[$mode]: FAIL"; status=1
  fi
done
exit $status
