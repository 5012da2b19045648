#!/bin/bash
# Entrypoint of the locaid container image (deploy/Containerfile).
#
#   locaid-entrypoint demo [server flags]   (default) serve + one demo session
#   locaid-entrypoint server [server flags] serve only; clients start sessions
#   locaid-entrypoint health                exit 0 when the server is SERVING
#   locaid-entrypoint <program> [args]      run anything else (e.g. locaid ...)
#
# The server always becomes the container's main process (exec), so SIGTERM
# from `docker/podman stop` or Kubernetes reaches it directly and its exit
# code is the container's. The demo session is started by a background helper
# once the health service answers.
#
# Environment (defaults in brackets):
#   LOCAID_CONFIG        server YAML [/etc/locaid/server.yaml, if present]
#   LOCAID_LISTEN        listen address, overrides the YAML [0.0.0.0:50051]
#   LOCAID_WORK_DIR      writable scratch (rendered drives) [/var/lib/locaid]:
#                        the demo drive goes here, and when the variable is
#                        set the server's too (--work-dir, which overrides the
#                        YAML's work_dir; unset, the YAML's work_dir holds)
#   LOCAID_TOKEN_FILE    bearer token file, passed to server and demo client
#   LOCAID_METRICS_LISTEN  host:port of the Prometheus /metrics endpoint
#                        (--metrics-listen), e.g. 0.0.0.0:9464 [off]
#   LOCAID_MAX_CPU_CORES admit real-time sessions by their measured CPU, up to
#                        this many cores (--max-cpu-cores), e.g. 1.8 for a
#                        2-CPU limit [off: max_sessions only]
#   LOCAID_DEMO_DRIVE    KITTI raw drive folder to play instead of rendering a
#                        synthetic one, e.g. /data/kitti/2011_09_26/2011_09_26_drive_0001_sync
#   LOCAID_DEMO_FRAMES [200]  LOCAID_DEMO_SEED [7]  (synthetic demo drive)
#   LOCAID_DEMO_SCENARIO [open-sky]  LOCAID_DEMO_RATE [1] (1 = real time)
#   LOCAID_DEMO_SCENARIO_FILE  scenario YAML for the demo session (overrides
#                        LOCAID_DEMO_SCENARIO), e.g. /etc/locaid/scenario.yaml
set -euo pipefail

listen="${LOCAID_LISTEN:-0.0.0.0:50051}"
port="${listen##*:}"
work="${LOCAID_WORK_DIR:-/var/lib/locaid}"
config="${LOCAID_CONFIG:-/etc/locaid/server.yaml}"

log() { echo "locaid-entrypoint: $*" >&2; }

client() {  # locaid CLI against the local server
  local args=(--server "127.0.0.1:${port}")
  if [[ -n "${LOCAID_TOKEN_FILE:-}" ]]; then args+=(--token "$(head -n1 "$LOCAID_TOKEN_FILE")"); fi
  locaid "${args[@]}" "$@"
}

server_args() {
  local args=(--listen "$listen")
  if [[ -f "$config" ]]; then args+=(--config "$config"); fi
  if [[ -n "${LOCAID_WORK_DIR:-}" ]]; then args+=(--work-dir "$LOCAID_WORK_DIR"); fi
  if [[ -n "${LOCAID_TOKEN_FILE:-}" ]]; then args+=(--token-file "$LOCAID_TOKEN_FILE"); fi
  if [[ -n "${LOCAID_METRICS_LISTEN:-}" ]]; then args+=(--metrics-listen "$LOCAID_METRICS_LISTEN"); fi
  if [[ -n "${LOCAID_MAX_CPU_CORES:-}" ]]; then args+=(--max-cpu-cores "$LOCAID_MAX_CPU_CORES"); fi
  printf '%s\0' "${args[@]}"
}

start_demo() {  # runs in the background while the server starts
  local drive="${LOCAID_DEMO_DRIVE:-}"
  if [[ -z "$drive" ]]; then
    local frames="${LOCAID_DEMO_FRAMES:-200}" seed="${LOCAID_DEMO_SEED:-7}"
    local date_dir="$work/demo-seed${seed}-f${frames}/2024_05_17"
    drive="$date_dir/2024_05_17_drive_0001_sync"
    if [[ ! -f "$drive/.complete" ]]; then
      log "rendering synthetic demo drive (seed $seed, $frames frames) into $date_dir"
      rm -rf "$date_dir"
      locaid-synth --out "$date_dir" --date 2024_05_17 --drive 1 --frames "$frames" --seed "$seed" -q || return 1
      touch "$drive/.complete"
    fi
  fi
  local ok=0
  for _ in $(seq 1 120); do
    if client health >/dev/null 2>&1; then ok=1; break; fi
    sleep 0.5
  done
  if ((ok == 0)); then log "server did not become healthy in 60 s; no demo session"; return 1; fi
  local id scenario=(--scenario "${LOCAID_DEMO_SCENARIO:-open-sky}")
  if [[ -n "${LOCAID_DEMO_SCENARIO_FILE:-}" ]]; then scenario=(--scenario-file "$LOCAID_DEMO_SCENARIO_FILE"); fi
  id=$(client session start --kitti "$drive" "${scenario[@]}" --rate "${LOCAID_DEMO_RATE:-1}") || return 1
  id="${id%%[[:space:]]*}"
  echo "$id" >"$work/demo-session-id"
  log "demo session $id started on $drive (id also in $work/demo-session-id)"
}

mode="${1:-demo}"
case "$mode" in
  demo | server)
    shift || true
    mkdir -p "$work"
    mapfile -d '' sargs < <(server_args)
    if [[ "$mode" == demo ]]; then
      rm -f "$work/demo-session-id"
      (start_demo || log "demo session failed (the server keeps running)") &
    fi
    log "exec locaid-server ${sargs[*]} $*"
    exec locaid-server "${sargs[@]}" "$@"
    ;;
  health)
    client health
    ;;
  *)
    exec "$@"
    ;;
esac
