#!/usr/bin/env bash
# Delay the Foxglove bridge adds: a synthetic session played in real time
# (10 Hz) on a real locaid-server, locaid-foxglove in front of it, N Foxglove
# WebSocket clients (@foxglove/ws-protocol, bench/foxglove/ws_delay.mjs) on
# loopback. Two delays:
# - added by the bridge (the target): from the gRPC pose reaching the bridge
#   to each of its WebSocket messages handed to a client's socket, every
#   channel and client, as the bridge reports it when it stops (10 us bins);
# - seen by a client: per /locaid/update message, receipt at the Node client
#   minus the server's hand-over to its gRPC subscribers
#   (PoseUpdate.published_unix_ns), so it also holds the gRPC hop and the
#   Node client's own wake-up and decoding.
# Also the bridge's CPU time per pose. --bridge-fifo runs the bridge with
# SCHED_FIFO priority 10 (chrt; needs root or CAP_SYS_NICE), which shows how
# much of the delay is waiting for a CPU the server and clients also want.
#
#   bench/foxglove/bridge_latency.sh [--clients 10] [--poses 300] [--bridge-fifo] [--build build]
set -euo pipefail
clients=10 poses=300 build=build bridge_prefix=()
while (($#)); do
  case "$1" in
    --clients) clients=$2; shift 2 ;;
    --poses) poses=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --bridge-fifo) bridge_prefix=(chrt -f 10); shift ;;
    *) echo "bridge_latency.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
here=$(cd "$(dirname "$0")" && pwd)
bash "$here/../../tests/record/js/setup.sh" "$here/../../tests/foxglove/js" >/dev/null
bin=$(cd "$build/bin" && pwd)
work=$(mktemp -d /tmp/locaid_bridge_bench.XXXXXX)
pids=()
cleanup() { kill "${pids[@]}" 2>/dev/null || true; wait 2>/dev/null || true; rm -rf "$work"; }
trap cleanup EXIT
"$bin/locaid-server" --listen 127.0.0.1:0 --port-file "$work/port" --work-dir "$work/w" >"$work/server.log" 2>&1 &
pids+=($!)
for _ in $(seq 100); do [[ -s "$work/port" ]] && break; sleep 0.1; done
server="127.0.0.1:$(cat "$work/port")"
ws_port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
"${bridge_prefix[@]}" "$bin/locaid-foxglove" --server "$server" --listen "127.0.0.1:$ws_port" >"$work/bridge.log" 2>&1 &
bridge_pid=$!
pids+=($bridge_pid)
sleep 0.5
for i in $(seq "$clients"); do
  node "$here/ws_delay.mjs" --url "ws://127.0.0.1:$ws_port" --count "$poses" --timeout-s 120 >"$work/client$i.json" &
  pids+=($!)
done
sleep 1
cpu0=$(awk '{print $14 + $15}' /proc/$bridge_pid/stat)
"$bin/locaid" --server "$server" session start --synthetic 3 --frames $((poses + 20)) --rate 1 >/dev/null
for i in $(seq "$clients"); do
  while [[ ! -s "$work/client$i.json" ]]; do sleep 0.2; done
done
cpu1=$(awk '{print $14 + $15}' /proc/$bridge_pid/stat)
kill -TERM "$bridge_pid"
wait "$bridge_pid" || true
bridge_delay=$(grep -o 'delay from gRPC pose to socket [^)]*' "$work/bridge.log" || echo "bridge delay: not reported")
echo "bridge: $bridge_delay (all channels, $clients clients)"
python3 - "$work" "$clients" "$poses" "$cpu0" "$cpu1" "$(getconf CLK_TCK)" <<'PY'
import json, sys, statistics
work, n, poses, cpu0, cpu1, tck = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), *map(int, sys.argv[4:])
d = sorted(x for i in range(1, n + 1) for x in json.load(open(f"{work}/client{i}.json"))["delays_ms"])
p = lambda q: d[min(len(d) - 1, int(q * len(d)))]
print(f"clients: {n} clients, {len(d)} /locaid/update messages, server hand-over to client receipt: p50 {p(0.5):.3f} ms, p99 {p(0.99):.3f} ms, max {d[-1]:.3f} ms")
print(f"bridge CPU {1000 * (cpu1 - cpu0) / tck / poses:.3f} ms per pose (all channels, {n} clients)")
PY
