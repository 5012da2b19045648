#!/usr/bin/env bash
# Reading a ROS 2 bag is not the bottleneck: locaid-replay --bag on a bag of a
# drive against --drive on the same folder, frames/s of each (median of N
# alternating runs). The bag is written by the reference writer
# (tests/rosbag/js/kitti_to_bag.mjs, the official @mcap/core and
# @foxglove/rosmsg2-serialization) with PNG CompressedImage by default.
#
#   bench/rosbag/bag_vs_drive.sh [--runs N] [--images png|raw|jpeg] [--bin-dir DIR] [DRIVE]
#
# DRIVE defaults to the shared real excerpt. Needs node and npm (the writer's
# packages are installed into the scratch folder, removed at the end).
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
runs=5 images=png bin="$root/build/bin"
drive="$root/../shared/data/kitti/raw/2011_09_26/2011_09_26_drive_unknown_extract"
while (($#)); do
  case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --images) images="$2"; shift 2 ;;
    --bin-dir) bin="$2"; shift 2 ;;
    -h|--help) sed -n 2,11p "$0"; exit 0 ;;
    -*) echo "bag_vs_drive: unknown option $1" >&2; exit 2 ;;
    *) drive="$1"; shift ;;
  esac
done
[[ -d "$drive" ]] || { echo "bag_vs_drive: no drive folder $drive" >&2; exit 1; }
[[ -x "$bin/locaid-replay" ]] || { echo "bag_vs_drive: no $bin/locaid-replay (build first)" >&2; exit 1; }

work="$(mktemp -d "${TMPDIR:-/tmp}/locaid_bag_bench_XXXXXX")"
trap 'rm -rf "$work"' EXIT
bash "$root/tests/record/js/setup.sh" "$work/js" "$root/tests/rosbag/js" >/dev/null
node "$work/js/kitti_to_bag.mjs" --drive "$drive" --out "$work/drive.mcap" --images "$images" >/dev/null
echo "bag: $(du -h "$work/drive.mcap" | cut -f1) ($images images)"

fps() {  # frames/s of one locaid-replay run
  "$bin/locaid-replay" "$@" --json 2>/dev/null | python3 -c 'import json,sys; print(json.load(sys.stdin)["frames_per_s"])'
}
drive_fps=() bag_fps=()
for ((i = 1; i <= runs; i++)); do
  drive_fps+=("$(fps --drive "$drive")")
  bag_fps+=("$(fps --bag "$work/drive.mcap")")
  echo "run $i: drive ${drive_fps[-1]} frames/s, bag ${bag_fps[-1]} frames/s"
done
python3 - "${drive_fps[*]}" "${bag_fps[*]}" <<'PY'
import statistics, sys
d = [float(x) for x in sys.argv[1].split()]
b = [float(x) for x in sys.argv[2].split()]
md, mb = statistics.median(d), statistics.median(b)
print(f"median frames/s: drive {md:.2f}, bag {mb:.2f}; bag/drive {mb / md:.2f}")
PY
