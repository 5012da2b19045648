#!/usr/bin/env bash
# Time from a fix's arrival off the gpsd socket to its use by the filter, on a
# live session fed the way a car feeds it: a synthetic drive's NMEA played by
# gpsfake through a real gpsd, frames and IMU pushed by locaid-push in real
# time (paced on the receiver's clock, 0.2 s ahead of its fixes). Prints the
# session's GetStats figures (median and max over the last 256 fixes).
#
#   bench/sensors/gpsd_latency.sh [--seconds 120] [--gps-hz 1] [--width 640 --height 192] [--build build]
set -euo pipefail
seconds=120 gps_hz=1 width=640 height=192 build=build
while (($#)); do
  case "$1" in
    --seconds) seconds=$2; shift 2 ;;
    --gps-hz) gps_hz=$2; shift 2 ;;
    --width) width=$2; shift 2 ;;
    --height) height=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    *) echo "gpsd_latency.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
command -v gpsfake >/dev/null || { echo "gpsd_latency.sh: gpsfake missing (deploy/install-deps.sh)" >&2; exit 1; }
bin=$(cd "$build/bin" && pwd)
work=$(mktemp -d /tmp/locaid_gpsd_bench.XXXXXX)
cleanup() { kill "${server_pid:-}" "${fake_pid:-}" 2>/dev/null || true; wait 2>/dev/null || true; rm -rf "$work"; }
trap cleanup EXIT
frames=$((seconds * 10))
"$bin/locaid-synth" -q --out "$work/d" --frames "$frames" --width "$width" --height "$height" --seed 11
drive=$(ls -d "$work"/d/*_sync)
printf 'base: open-sky\ngps: {rate_hz: %s}\nseed: 1\n' "$gps_hz" > "$work/s.yaml"
"$bin/locaid-nmea" --drive "$drive" --scenario "$work/s.yaml" --start-utc 2026-01-01T00:00:00Z --out "$work/f.nmea" 2>/dev/null
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
"$bin/locaid-server" --listen 127.0.0.1:0 --port-file "$work/port" --work-dir "$work/w" >"$work/server.log" 2>&1 &
server_pid=$!
for _ in $(seq 100); do [[ -s "$work/port" ]] && break; sleep 0.1; done
# Three sentences per epoch, paced per sentence.
cycle=$(python3 -c "print(1.0 / ($gps_hz * 3))")
gpsfake -1 -q -c "$cycle" -P "$port" "$work/f.nmea" >"$work/gpsfake.log" 2>&1 &
fake_pid=$!
"$bin/locaid-push" --server "127.0.0.1:$(cat "$work/port")" --drive "$drive" --gps gpsd \
  --gpsd "127.0.0.1:$port" --start-utc 2026-01-01T00:00:00Z >"$work/push.out" 2>"$work/push.log"
id=$(head -1 "$work/push.out")
kill "$fake_pid" 2>/dev/null || true
tail -1 "$work/push.log"
PYTHONPATH="$(cd "$build" && pwd)/python" /usr/bin/python3 - "$(cat "$work/port")" "$id" <<'PY'
import sys, grpc
from locaid.v1 import localization_pb2 as pb, localization_pb2_grpc as rpc
stub = rpc.LocalizationStub(grpc.insecure_channel("127.0.0.1:" + sys.argv[1]))
s = stub.GetStats(pb.GetStatsRequest(session_id=sys.argv[2]))
print(f"fixes in {s.gps_fixes_in}, late {s.gps_fixes_late}, frames {s.frames_processed}, "
      f"frame latency mean {s.latency_mean_ms:.1f} ms")
print(f"fix arrival -> filter: median {s.gpsd.fix_latency_median_ms:.3f} ms, max {s.gpsd.fix_latency_max_ms:.3f} ms")
PY
