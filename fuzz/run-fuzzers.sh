#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/, clang) and runs each for a bounded time
# on a seed corpus made at run time from the real KITTI excerpts in
# ../shared/data/kitti, the repository's scenarios/ and deploy/server.yaml and
# small built-in seeds (copied into a temporary folder, never into the repo),
# plus the committed regression inputs in fuzz/corpus/<target>/ (earlier
# findings, run first). Prints one summary line per target and exits non-zero
# when the build fails, a target is missing or any target found a crash (the
# reproducer is kept under BUILD_DIR/fuzz-artifacts/).
#
#   fuzz/run-fuzzers.sh                     # all targets, 60 s each
#   fuzz/run-fuzzers.sh -t 20 oxts pose_file
#   fuzz/run-fuzzers.sh --no-build -t 300   # reuse an existing build
#
# Options: -t SECONDS per target (default 60, env LOCAID_FUZZ_SECONDS),
#          -b BUILD_DIR (default <repo>/build-fuzz), -j JOBS for the build,
#          --no-build, --keep-corpus (print and keep the temp corpus folder).
# Env: LOCAID_SHARED_DATA (default <repo>/../shared/data/kitti), CXX (clang++).
set -euo pipefail

repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=${LOCAID_FUZZ_SECONDS:-60}
build_dir=$repo/build-fuzz
jobs=2
do_build=1
keep_corpus=0
targets=()
while (($#)); do
  case $1 in
    -t) seconds=$2; shift 2 ;;
    -b) build_dir=$2; shift 2 ;;
    -j) jobs=$2; shift 2 ;;
    --no-build) do_build=0; shift ;;
    --keep-corpus) keep_corpus=1; shift ;;
    -h|--help) sed -n '2,18p' "$0"; exit 0 ;;
    -*) echo "run-fuzzers: unknown option $1" >&2; exit 2 ;;
    *) targets+=("${1#fuzz_}"); shift ;;
  esac
done
data=${LOCAID_SHARED_DATA:-$repo/../shared/data/kitti}
all_targets=(oxts timestamps pose_file calib_cam_to_cam calib_rigid calib_odometry
             scenario_yaml server_config frame_decode push_requests bag_reader
             ros2_sample ros2_graph camera_info_yaml sweep_manifest)
((${#targets[@]})) || targets=("${all_targets[@]}")

if ((do_build)); then
  cxx=${CXX:-clang++}
  command -v "$cxx" >/dev/null || {
    echo "run-fuzzers: $cxx not found (deploy/install-deps.sh --fuzz installs clang)" >&2; exit 2; }
  mkdir -p "$build_dir"
  build_log=$build_dir/fuzz-build.log
  build_targets=()
  for t in "${targets[@]}"; do build_targets+=(--target "fuzz_$t"); done
  if ! { cmake -S "$repo" -B "$build_dir" -DCMAKE_CXX_COMPILER="$cxx" -DLOCAID_BUILD_FUZZ=ON \
           -DLOCAID_BUILD_TESTS=OFF -DLOCAID_BUILD_BENCH=OFF &&
         cmake --build "$build_dir" -j"$jobs" "${build_targets[@]}"; } >"$build_log" 2>&1; then
    echo "run-fuzzers: build failed (full log: $build_log):" >&2
    grep -E -A3 'error|Error' "$build_log" | head -n 40 >&2
    exit 1
  fi
fi

work=$(mktemp -d "${TMPDIR:-/tmp}/locaid-fuzz.XXXXXX")
if ((keep_corpus)); then echo "run-fuzzers: corpus kept in $work"; else trap 'rm -rf "$work"' EXIT; fi
artifacts=$build_dir/fuzz-artifacts
mkdir -p "$artifacts"

# ---- seed corpora (real files; small slices of the long ones) ---------------
have_data=1
[[ -d $data ]] || { have_data=0; echo "run-fuzzers: $data absent: starting from built-in seeds only" >&2; }
raw_date=$data/raw/2011_09_26
odo=$data/odometry
seed() {  # seed <target> <name>  (content on stdin)
  mkdir -p "$work/$1"; cat >"$work/$1/$2"
}
copy_seed() {  # copy_seed <target> <file> [lines]
  [[ -f $2 ]] || return 0
  local name; name=$(echo "$2" | sed "s|^$data/||; s|/|_|g")
  if [[ -n ${3:-} ]]; then head -n "$3" "$2" | seed "$1" "$name"; else seed "$1" "$name" <"$2"; fi
}
make_seeds() {
  local t=$1 f i
  mkdir -p "$work/$t"
  case $t in
    oxts)
      if ((have_data)); then
        i=0
        for f in "$raw_date"/*/oxts/data/*.txt; do  # every 20th record
          if ((i++ % 20 == 0)); then copy_seed oxts "$f"; fi
        done
      fi
      printf '49 8.4 110 0 0 0 0 0 0 0 0 0 0 9.81 0 0 9.81 0 0 0 0 0 0 1 0.1 4 10 5 5 5\n' | seed oxts builtin ;;
    timestamps)
      if ((have_data)); then
        for f in "$raw_date"/*/image_0*/timestamps.txt "$raw_date"/*/oxts/timestamps.txt; do
          copy_seed timestamps "$f" 20
          [[ -f $f ]] || continue
          head -n 1 "$f" | tr -d '\n' | seed timestamps "$(basename "$(dirname "$f")")_line"
        done
        copy_seed timestamps "$odo/sequences/00/times.txt" 20
      fi
      printf '2011-09-26 14:05:35.500923136\n' | seed timestamps builtin ;;
    pose_file)
      if ((have_data)); then
        for f in "$odo"/poses/*.txt "$odo"/reference_results/*.txt; do copy_seed pose_file "$f" 10; done
        # TUM seed: odometry times + translations of poses/00 (identity rotation).
        if [[ -f $odo/sequences/00/times.txt && -f $odo/poses/00.txt ]]; then
          paste -d ' ' <(head -n 10 "$odo/sequences/00/times.txt") <(head -n 10 "$odo/poses/00.txt") |
            awk '{print $1, $5, $9, $13, 0, 0, 0, 1}' | seed pose_file tum_from_00
        fi
      fi
      printf '# t tx ty tz qx qy qz qw\n0 0 0 0 0 0 0 1\n0.1 1 2 3 0 0 0.7071 0.7071\n' | seed pose_file builtin_tum ;;
    calib_cam_to_cam) ((have_data)) && copy_seed "$t" "$raw_date/calib_cam_to_cam.txt" ;;
    calib_rigid)
      if ((have_data)); then
        copy_seed "$t" "$raw_date/calib_velo_to_cam.txt"; copy_seed "$t" "$raw_date/calib_imu_to_velo.txt"
      fi ;;
    calib_odometry) ((have_data)) && copy_seed "$t" "$odo/sequences/00/calib.txt" ;;
    scenario_yaml)
      for f in "$repo"/scenarios/*.yaml; do [[ -f $f ]] && seed "$t" "$(basename "$f")" <"$f"; done
      printf 'name: s\nbase: open-sky\ngps: {rate_hz: 1, sigma_h_m: 3, sigma_v_m: 5, bias_sigma_m: 0.3, bias_tau_s: 60, jump_probability: 0.02, jump_size_m: 15, jump_duration_s: 0}\nimu: {grade: mems, accel_bias_sigma_mps2: 0.05, gyro_bias_sigma_radps: 0.002, accel_noise_mps2_sqrt_hz: 0.01, gyro_noise_radps_sqrt_hz: 0.0005}\noutages: [{start_s: 20, duration_s: 10}, {start_s: 60, end_s: 75}, {centered: true, duration_s: 5}]\nseed: 7\n' | seed "$t" builtin
      printf 'base: urban-canyon\noutages:\n  - start_s: 1\n    duration_s: 2\n' | seed "$t" builtin_block
      printf 'base: intermittent\ngps: {antenna_body_m: [1.2, 0.9, 0.0], rate_hz: 5}\n' | seed "$t" builtin_antenna ;;
    server_config)
      [[ -f $repo/deploy/server.yaml ]] && seed "$t" server.yaml <"$repo/deploy/server.yaml"
      printf 'listen: 127.0.0.1:0\nqueue_size: 8\nmax_queue_size: 16\nkeepalive_time_s: 5\nkeepalive_timeout_s: 2\n' | seed "$t" builtin
      printf 'listen: 0.0.0.0:50051\nlisten_unix: /tmp/locaid.sock\nmetrics_listen: 127.0.0.1:9464\nmax_ended_sessions: 100\nended_session_ttl_s: 3600\nmax_concurrent_renders: 2\nmax_synthetic_frames: 2000\nsynthetic_default_frames: 100\n' | seed "$t" builtin_sessions
      printf 'max_sessions: 32\nbehind_threshold_s: 0.1\nmax_cpu_cores: 1.8\nsession_cpu_cores_prior: 0.5\n' | seed "$t" builtin_realtime ;;
    frame_decode)
      # First byte selects mode/size (see fuzz_frame_decode.cpp).
      if ((have_data)); then
        local frames=("$raw_date"/*/image_00/data/*.png)
        if [[ -f ${frames[0]} ]]; then { printf '\x03'; cat "${frames[0]}"; } | seed "$t" kitti_frame; fi
      fi
      /usr/bin/python3 - "$work/$t/small_png" <<'EOF'
import struct, sys, zlib
w, h = 64, 48
rows = b"".join(b"\x00" + bytes((x * 4 + y * 2) % 256 for x in range(w)) for y in range(h))
def chunk(kind, body):
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
       + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
open(sys.argv[1], "wb").write(b"\x01" + png)
EOF
      printf '\x00\x80' | seed "$t" raw_1x1 ;;
    push_requests)
      # PushRequest streams written from text format by protoc (fuzz/make_push_seeds.py).
      /usr/bin/python3 "$repo/fuzz/make_push_seeds.py" "$work/$t" "$repo" ;;
    bag_reader)
      # Small MCAP files as rosbag2 writes them (fuzz/make_bag_seeds.py).
      /usr/bin/python3 "$repo/fuzz/make_bag_seeds.py" "$work/$t" ;;
    ros2_sample) /usr/bin/python3 "$repo/fuzz/make_ros2_seeds.py" sample "$work/$t" ;;
    ros2_graph) /usr/bin/python3 "$repo/fuzz/make_ros2_seeds.py" graph "$work/$t" ;;
    camera_info_yaml)
      printf 'image_width: 16\nimage_height: 12\ncamera_name: left\ncamera_matrix: {rows: 3, cols: 3, data: [10, 0, 8, 0, 10, 6, 0, 0, 1]}\ndistortion_model: plumb_bob\ndistortion_coefficients: {rows: 1, cols: 5, data: [-0.3, 0.1, 0.001, 0, 0]}\nrectification_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}\nprojection_matrix: {rows: 3, cols: 4, data: [10, 0, 8, 0, 0, 10, 6, 0, 0, 0, 1, 0]}\n' | seed "$t" small
      printf 'image_width: 1392\nimage_height: 512\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [984.2, 0, 690, 0, 980.8, 233.2, 0, 0, 1]\ndistortion_model: rational_polynomial\ndistortion_coefficients: {rows: 1, cols: 8, data: [-0.37, 0.2, 0.001, 0.0013, -0.07, 0, 0, 0]}\nrectification_matrix: {rows: 3, cols: 3, data: [1, 0.01, 0, -0.01, 1, 0, 0, 0, 1]}\nprojection_matrix: {rows: 3, cols: 4, data: [721.5, 0, 609.6, -387.6, 0, 721.5, 172.9, 0, 0, 0, 1, 0]}\n' | seed "$t" kitti_like ;;
    sweep_manifest)
      printf 'recordings:\n  - path: drive_sync\n  - path: drive.mcap\n    bag_topics: outage.yaml\nscenarios: [open-sky, tunnel-30s, outage.yaml]\nseeds: {from: 1, to: 3}\nimu: [on, off]\nreplay_args: ["--vehicle-constraints", "off"]\nsmooth: true\n' | seed "$t" builtin
      printf 'recordings: [{path: "*.mcap"}]\nscenarios: [urban-canyon]\nseeds: [1, 2, 3]\n' | seed "$t" builtin_glob ;;
  esac
  return 0
}

# ---- run ------------------------------------------------------------------
status=0
printf '%-18s %10s %8s %8s %7s %8s  %s\n' target execs exec/s cov ft corpus result
for t in "${targets[@]}"; do
  bin=$build_dir/bin/fuzz_$t
  if [[ ! -x $bin ]]; then
    printf '%-18s %s\n' "$t" "FAILED: $bin not built"; status=1; continue
  fi
  make_seeds "$t"
  dict=$repo/fuzz/dicts/$t.dict
  dict_arg=(); [[ -f $dict ]] && dict_arg=(-dict="$dict")
  # Committed regression inputs: a second corpus folder (read, never written).
  regress=(); [[ -d $repo/fuzz/corpus/$t ]] && regress=("$repo/fuzz/corpus/$t")
  log=$work/$t.log
  rm -f "$artifacts/$t-"*
  set +e
  # ASan's leak checker needs ptrace, unavailable in some containers: off.
  ASAN_OPTIONS=detect_leaks=0:${ASAN_OPTIONS:-} UBSAN_OPTIONS=print_stacktrace=1:${UBSAN_OPTIONS:-} \
    "$bin" "$work/$t" "${regress[@]}" "${dict_arg[@]}" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
      -print_final_stats=1 -artifact_prefix="$artifacts/$t-" >"$log" 2>&1
  rc=$?
  set -e
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -n 1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -n 1 | cut -d' ' -f2)
  ft=$(grep -o 'ft: [0-9]*' "$log" | tail -n 1 | cut -d' ' -f2)
  corp=$(grep -o 'corp: [0-9]*' "$log" | tail -n 1 | cut -d' ' -f2)
  found=$(find "$artifacts" -maxdepth 1 -name "$t-*" | wc -l)
  if ((rc == 0 && found == 0)); then
    result="ok, 0 crashes"
  else
    status=1
    result="FAILED rc=$rc, $found artifact(s): $(find "$artifacts" -maxdepth 1 -name "$t-*" | tr '\n' ' ')"
    cp "$log" "$artifacts/$t.log"
  fi
  printf '%-18s %10s %8s %8s %7s %8s  %s\n' "$t" "${execs:-?}" "${rate:-?}" "${cov:-?}" "${ft:-?}" \
    "${corp:-?}" "$result"
  if ((rc != 0)); then grep -a -m 5 -E 'ERROR|runtime error|contract violated|SUMMARY' "$log" | sed 's/^/    /'; fi
done
exit $status
