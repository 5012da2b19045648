#!/usr/bin/env bash
# README command 1: installs dependencies, builds, and runs the demo:
#   render a synthetic drive -> start locaid-server on 127.0.0.1 -> start a
#   session with the tunnel-30s GPS scenario -> subscribe with the CLI and
#   record (CSV, GeoJSON, MCAP; live view through locaid-foxglove) -> inject an extra live GPS outage -> score the recording against
#   the drive's ground truth -> metrics summary + PNG plots in out/demo/.
# Options (environment): DEMO_FRAMES (default 900 = 90 s), DEMO_SEED (7),
# DEMO_RATE (playback speed, x real time; default 3).
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/install-deps.sh
bash deploy/build.sh

frames=${DEMO_FRAMES:-900}
seed=${DEMO_SEED:-7}
rate=${DEMO_RATE:-3}
out=$PWD/out/demo
bin=$PWD/build/bin
rm -rf "$out"
mkdir -p "$out"
step() { printf '\n== %s\n' "$*"; }

step "1/7 render a synthetic drive ($frames frames, seed $seed)"
"$bin/locaid-synth" --out "$out/drive" --frames "$frames" --seed "$seed"
drive=$(ls -d "$out"/drive/*_sync)

step "2/7 start locaid-server on 127.0.0.1 (log: $out/server.log)"
"$bin/locaid-server" --listen 127.0.0.1:0 --port-file "$out/port" --work-dir "$out/work" \
  >"$out/server.log" 2>&1 &
server_pid=$!
trap 'kill "$server_pid" 2>/dev/null || true' EXIT
for _ in $(seq 100); do [[ -s "$out/port" ]] && break; sleep 0.1; done
[[ -s "$out/port" ]] || { echo "server did not start:"; cat "$out/server.log"; exit 1; }
addr="127.0.0.1:$(cat "$out/port")"
cli=("$bin/locaid" --server "$addr")
"${cli[@]}" health
# The live view: Foxglove / Lichtblick -> Foxglove WebSocket -> ws://127.0.0.1:8765
# (layout: deploy/foxglove/locaid-layout.json). DEMO_FOXGLOVE_PORT changes the port.
"$bin/locaid-foxglove" --server "$addr" --listen "127.0.0.1:${DEMO_FOXGLOVE_PORT:-8765}" \
  >"$out/foxglove.log" 2>&1 &
fox_pid=$!
trap 'kill "$server_pid" "$fox_pid" 2>/dev/null || true' EXIT
echo "live view: ws://127.0.0.1:${DEMO_FOXGLOVE_PORT:-8765} (locaid-foxglove, log: $out/foxglove.log)"

step "3/7 start a session on the drive, scenario tunnel-30s, ${rate}x real time"
session=$("${cli[@]}" session start --kitti "$drive" --scenario tunnel-30s --rate "$rate")
echo "session: $session"

step "4/7 subscribe and record (CSV + GeoJSON + MCAP), inject a live outage at 70 s for 8 s (the tunnel is at 30-60 s)"
"${cli[@]}" subscribe "$session" --from-start --format csv --out "$out/poses.csv" --progress &
sub_pid=$!
"${cli[@]}" subscribe "$session" --from-start --format geojson --out "$out/poses.geojson" &
geo_pid=$!
"${cli[@]}" subscribe "$session" --from-start --format mcap --out "$out/poses.mcap" &
mcap_pid=$!
"${cli[@]}" outage window "$session" --start 70 --duration 8
wait "$sub_pid" "$geo_pid" "$mcap_pid"

step "5/7 session stats"
"${cli[@]}" stats "$session" | tee "$out/stats.txt"

step "6/7 score the recording against the drive's OXTS ground truth"
"$bin/locaid-score" --drive "$drive" --poses "$out/poses.csv" --scenario tunnel-30s \
  --out-csv "$out/plot.csv" --json >"$out/metrics.json"
"$bin/locaid-score" --drive "$drive" --poses "$out/poses.csv" --scenario tunnel-30s
/usr/bin/python3 clients/plot_outage.py "$out/plot.csv" --out "$out/report"

step "7/7 stop the Foxglove bridge and the server with SIGTERM"
kill -TERM "$fox_pid"
wait "$fox_pid" && echo "locaid-foxglove exited cleanly" || { echo "locaid-foxglove exit code $?"; exit 1; }
kill -TERM "$server_pid"
wait "$server_pid" && echo "server exited cleanly" || { echo "server exit code $?"; exit 1; }
trap - EXIT

printf '\nDemo output in %s:\n' "$out"
ls -1 "$out" | sed 's/^/  /'
