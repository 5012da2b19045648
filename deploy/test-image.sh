#!/usr/bin/env bash
# Builds the locaid container image with podman or docker and proves it works:
# start the server from the image, check health, start a session, stream
# poses with the CLI, start a session from a ROS 2 bag mounted into the
# container, run a small sweep with the image's locaid-sweep, stop with
# SIGTERM and check the clean exit; then bring deploy/compose.yaml up with
# podman-compose (docker compose with --engine docker) against the image on
# ports --port+1 and +2, check that the recorder wrote the demo session's poses
# into its volume and that the ROS 2 adapter's poses reach a Fast DDS
# subscriber on the host (build/bin/locaid-fastdds-probe), and bring it down
# leaving nothing of the project.
#
#   deploy/test-image.sh [--tag IMAGE] [--base IMAGE] [--no-cache] [--skip-build]
#                        [--run auto|podman|chroot] [--port N] [--keep]
#                        [--engine podman|docker] [--bag-drive DIR]
#
# The bag: the tests' reference writer (tests/rosbag/js/kitti_to_bag.mjs on
# Node.js, the official MCAP libraries) writes the first 80 frames of a KITTI
# raw drive as a ROS 2 bag on the host; the drive is --bag-drive DIR (env
# LOCAID_BAG_DRIVE; default the real excerpt in ../shared/data/kitti). Without
# that drive the bag step is skipped and the summary says so; with CI set it
# fails instead.
#
# Run as root on Debian 12. --engine (env LOCAID_CONTAINER_ENGINE; default
# podman) picks the tool: podman (installed with runc and debootstrap if
# missing) or docker (a running Docker engine: `docker info` must answer;
# debootstrap is installed if a base image has to be made).
# Paths it can take, printed as it goes:
#   base  : --base IMAGE | local localhost/debian:12 | registry debian:12 |
#           debootstrap of the apt mirror in /etc/apt/sources.list* (imported
#           as localhost/debian:12) when no registry is reachable
#   build : podman build --isolation chroot (works without a container runtime)
#           | docker build
#   run   : podman run (default runtime) | podman run --runtime runc with
#           lowered rlimits (hosts without CAP_SYS_RESOURCE / hybrid cgroups) |
#           chroot into a podman-mounted container filesystem as uid 10001 |
#           docker run
# Everything generated lives in $LOCAID_DEPLOY_DIR (default /var/tmp/locaid-deploy).
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/.." && pwd)
STATE=${LOCAID_DEPLOY_DIR:-/var/tmp/locaid-deploy}
TAG=localhost/locaid:test
BASE=""
NO_CACHE=()
SKIP_BUILD=0
RUN_MODE=auto
PORT=50751
KEEP=0
MAX_IMAGE_MB=400
ENGINE=${LOCAID_CONTAINER_ENGINE:-podman}
BAG_DRIVE=${LOCAID_BAG_DRIVE:-$ROOT/../shared/data/kitti/raw/2011_09_26/2011_09_26_drive_unknown_extract}
while (($#)); do
  case "$1" in
    --tag) TAG=$2; shift 2 ;;
    --base) BASE=$2; shift 2 ;;
    --no-cache) NO_CACHE=(--no-cache); shift ;;
    --skip-build) SKIP_BUILD=1; shift ;;
    --run) RUN_MODE=$2; shift 2 ;;
    --port) PORT=$2; shift 2 ;;
    --keep) KEEP=1; shift ;;
    --engine) ENGINE=$2; shift 2 ;;
    --bag-drive) BAG_DRIVE=$2; shift 2 ;;
    -h | --help) sed -n '2,36p' "$0"; exit 0 ;;
    *) echo "test-image: unknown argument '$1'" >&2; exit 2 ;;
  esac
done

say() { echo "test-image: $*"; }
fail() { echo "test-image: FAIL: $*" >&2; exit 1; }
summary=()
note() { summary+=("$*"); say "$*"; }

[[ $ENGINE == podman || $ENGINE == docker ]] || { echo "test-image: --engine must be podman or docker, got '$ENGINE'" >&2; exit 2; }
[[ $ENGINE == docker && $RUN_MODE == chroot ]] && { echo "test-image: --run chroot needs --engine podman" >&2; exit 2; }
[[ $(id -u) -eq 0 ]] || fail "run as root ($ENGINE build/mount and chroot need it)"
mkdir -p "$STATE"

# The few commands whose spelling differs between the two engines.
image_exists() { if [[ $ENGINE == podman ]]; then podman image exists "$1"; else docker image inspect "$1" >/dev/null 2>&1; fi; }
# Untagged images the Containerfile labelled: an earlier build's stages, or
# the image a rebuild took the tag from.
leftovers() {
  for label in io.locaid.stage org.opencontainers.image.title=locaid; do
    "$ENGINE" images -q --no-trunc --filter dangling=true --filter "label=$label"
  done | sort -u
}
# Copies an image's filesystem into a fresh folder; prints the folder.
image_files() {
  local dir cid
  dir=$(mktemp -d "$STATE/files.XXXXXX")
  cid=$(docker create "$1") && docker export "$cid" | tar -C "$dir" -x && docker rm "$cid" >/dev/null
  echo "$dir"
}

# ------------------------------------------------------------ tools ----
need=()
if [[ $ENGINE == podman ]]; then
  command -v podman >/dev/null || need+=(podman)
  command -v runc >/dev/null || need+=(runc)
  # deploy/compose.yaml (step 8): podman-compose, and on podman's CNI network
  # backend (Debian 12's) the dnsname plugin, without which the services of
  # a compose project cannot resolve each other's names.
  command -v podman-compose >/dev/null || need+=(podman-compose)
  [[ -x /usr/lib/cni/dnsname ]] || need+=(golang-github-containernetworking-plugin-dnsname)
else
  command -v docker >/dev/null || fail "--engine docker: no docker command"
  docker info >/dev/null 2>&1 || fail "--engine docker: the Docker engine does not answer (docker info); start dockerd"
fi
command -v debootstrap >/dev/null || need+=(debootstrap)
if ((${#need[@]})); then
  say "installing ${need[*]} with apt-get"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi
if [[ $ENGINE == podman ]]; then
  note "podman $(podman --version | awk '{print $3}'), storage $(podman info --format '{{.Store.GraphDriverName}}')"
else
  note "docker engine $(docker version --format '{{.Server.Version}}'), storage $(docker info --format '{{.Driver}}')"
  docker compose version >/dev/null 2>&1 || fail "--engine docker: no 'docker compose' (the Compose plugin) for deploy/compose.yaml"
fi

# ------------------------------------------------------------- base ----
apt_mirror() {  # first Debian (non-security) URI of the host's apt sources
  local f uri
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list /etc/apt/sources.list.d/*.sources; do
    [[ -f $f ]] || continue
    uri=$(grep -hoE '(^deb|^URIs:)[[:space:]]+(\[[^]]*\][[:space:]]+)?https?://[^[:space:]]+' "$f" |
      grep -oE 'https?://[^[:space:]]+' | grep -v security | grep -i debian | head -n1 || true)
    [[ -n $uri ]] && { echo "${uri%/}"; return; }
  done
  echo "http://deb.debian.org/debian"
}

if [[ -n $BASE ]]; then
  note "base: $BASE (given)"
elif image_exists localhost/debian:12; then
  BASE=localhost/debian:12
  note "base: localhost/debian:12 (already imported)"
elif timeout 90 "$ENGINE" pull -q docker.io/library/debian:12 >/dev/null 2>&1; then
  BASE=docker.io/library/debian:12
  note "base: docker.io/library/debian:12 (pulled from the registry)"
else
  mirror=$(apt_mirror)
  rootfs="$STATE/rootfs-bookworm"
  say "no registry reachable: debootstrap bookworm from $mirror into $rootfs"
  rm -rf "$rootfs"
  debootstrap --variant=minbase bookworm "$rootfs" "$mirror" >"$STATE/debootstrap.log" 2>&1 ||
    fail "debootstrap failed, see $STATE/debootstrap.log"
  rm -rf "$rootfs"/var/cache/apt/archives/*.deb "$rootfs"/var/lib/apt/lists/*
  sec="${mirror%/debian}/debian-security"
  printf 'deb %s bookworm main\ndeb %s bookworm-updates main\ndeb %s bookworm-security main\n' \
    "$mirror" "$mirror" "$sec" >"$rootfs/etc/apt/sources.list"
  tar -C "$rootfs" -c . | "$ENGINE" import - localhost/debian:12 >/dev/null
  BASE=localhost/debian:12
  note "base: localhost/debian:12 made with debootstrap from $mirror (no registry reachable)"
fi

# -------------------------------------------------------------- bag ----
# A ROS 2 bag for the bag session, written before anything runs so a missing
# writer fails early. The folder is mounted read-only at /data/bags.
BAG_DIR="$STATE/bags"
rm -rf "$BAG_DIR"
bag=""
if [[ -d $BAG_DRIVE ]]; then
  command -v node >/dev/null && command -v npm >/dev/null ||
    fail "node and npm are needed to write the test bag (deploy/install-deps.sh installs them)"
  bash "$ROOT/tests/record/js/setup.sh" "$STATE/js" "$ROOT/tests/rosbag/js" >"$STATE/js-setup.log" 2>&1 ||
    { cat "$STATE/js-setup.log" >&2; fail "npm ci of the bag writer (tests/rosbag/js)"; }
  mkdir -p "$BAG_DIR"
  node "$STATE/js/kitti_to_bag.mjs" --drive "$BAG_DRIVE" --out "$BAG_DIR/drive.mcap" --max-frames 80 \
    >"$STATE/bag-writer.log" 2>&1 || { cat "$STATE/bag-writer.log" >&2; fail "kitti_to_bag.mjs"; }
  chmod -R a+rX "$BAG_DIR"
  bag=/data/bags/drive.mcap
  note "bag: $(du -k "$BAG_DIR/drive.mcap" | cut -f1) kB ROS 2 bag of 80 frames of $BAG_DRIVE (kitti_to_bag.mjs), mounted at /data/bags"
elif [[ -n ${CI:-} && ${CI} != 0 && ${CI} != false ]]; then
  fail "no KITTI drive at $BAG_DRIVE to write the test bag from, and CI is set (--bag-drive DIR)"
else
  note "bag session: SKIPPED, no KITTI drive at $BAG_DRIVE to write a bag from (--bag-drive DIR)"
fi

# ------------------------------------------------------------ build ----
if ((SKIP_BUILD == 0)); then
  # Package cache for the build's apt runs: a private copy (hard links when
  # possible) of the host's, so builds start warm but never take the host's
  # apt lock or change its cache.
  cache_dir="$STATE/apt-archives"
  mkdir -p "$cache_dir/partial"
  if compgen -G '/var/cache/apt/archives/*.deb' >/dev/null; then
    cp -al -n /var/cache/apt/archives/*.deb "$cache_dir/" 2>/dev/null ||
      cp -n /var/cache/apt/archives/*.deb "$cache_dir/"
  fi
  cache=(-v "$cache_dir:/var/cache/apt/archives")
  # The host's compiler cache (deploy/build.sh fills it): the build stage
  # compiles what the host build already compiled from the cache.
  ccache_dir=""
  if command -v ccache >/dev/null && ccache_dir=$(ccache -k cache_dir 2>/dev/null) && [[ -d $ccache_dir ]]; then
    cache+=(-v "$ccache_dir:/ccache")
  fi
  if [[ $ENGINE == podman ]]; then
    how=(podman build --isolation chroot --format docker "${cache[@]}")
    say "building $TAG (${how[*]:0:4}, base $BASE, apt cache $cache_dir: $(ls "$cache_dir" | grep -c '\.deb$') packages)"
  else
    how=(docker build)  # no bind mounts while building: apt downloads afresh
    say "building $TAG (docker build, base $BASE)"
  fi
  # With the image the tag names now: it is left untagged when this build differs.
  earlier="$(leftovers) $("$ENGINE" images -q --no-trunc "$TAG" 2>/dev/null || true)"
  t0=$(date +%s)
  "${how[@]}" "${NO_CACHE[@]}" --build-arg BASE_IMAGE="$BASE" --build-arg BUILD_JOBS="$(nproc)" \
    -f "$ROOT/deploy/Containerfile" -t "$TAG" "$ROOT" >"$STATE/build.log" 2>&1 ||
    { tail -n 40 "$STATE/build.log" >&2; fail "$ENGINE build failed, full log $STATE/build.log"; }
  t1=$(date +%s)
  hits=$(grep -E '^ *(Hits|Misses):' "$STATE/build.log" | tr -s ' ' | tr '\n' ' ' || true)
  note "build: ${how[*]:0:3} ${NO_CACHE[*]} took $((t1 - t0)) s on $(nproc) cores (log $STATE/build.log)${ccache_dir:+; ccache $ccache_dir: ${hits:-no compile step ran}}"
  # Earlier builds leave their stages and the image this tag named untagged
  # (about 3 GB a build); they go, unless this build took them as its cache
  # (the log names every step's image), which the next build then reuses.
  removed=0
  for id in $earlier; do
    short=${id#sha256:}
    grep -q -- "${short:0:11}" "$STATE/build.log" && continue  # this build's cache or result
    "$ENGINE" rmi "$id" >/dev/null 2>&1 && removed=$((removed + 1))
  done
  note "build: removed $removed untagged images of earlier builds (labelled by the Containerfile)"
fi
image_exists "$TAG" || fail "image $TAG does not exist"

# ----------------------------------------------------- image checks ----
size=$("$ENGINE" image inspect --format '{{.Size}}' "$TAG")
size_mb=$((size / 1000000))
((size_mb <= MAX_IMAGE_MB)) || fail "image is $size_mb MB > $MAX_IMAGE_MB MB"
note "image size: $size_mb MB (limit $MAX_IMAGE_MB MB)"
user=$("$ENGINE" image inspect --format '{{.Config.User}}' "$TAG")
[[ -n $user && ${user%%:*} != 0 && ${user%%:*} != root ]] || fail "image runs as root (User='$user')"
ports=$("$ENGINE" image inspect --format '{{range $p, $v := .Config.ExposedPorts}}{{$p}} {{end}}' "$TAG")
[[ $ports == *50051/tcp* ]] || fail "port 50051 not exposed (ExposedPorts: $ports)"
hc=$("$ENGINE" image inspect --format '{{if .Config.Healthcheck}}{{join .Config.Healthcheck.Test " "}}{{end}}' "$TAG" 2>/dev/null || true)
[[ $hc == *health* ]] || fail "no HEALTHCHECK using 'locaid health' (got '$hc')"
if [[ $ENGINE == podman ]]; then mnt=$(podman image mount "$TAG"); else mnt=$(image_files "$TAG"); fi
bad=$(ls "$mnt"/usr/bin/{gcc,g++,cc,c++,cmake,ld} 2>/dev/null || true)
[[ -z $bad ]] || fail "toolchain in the runtime image: $bad"
devpk=$(awk '/^Package: /{p=$2} /^Status: install ok installed/{print p}' "$mnt/var/lib/dpkg/status" |
  grep -E -- '-dev$|^libgtk|^libqt|^libgl1-mesa-dri$|^libllvm' || true)
[[ -z $devpk ]] || fail "unwanted packages in the runtime image: $devpk"
npk=$(grep -c '^Status: install ok installed' "$mnt/var/lib/dpkg/status")
if [[ $ENGINE == podman ]]; then podman image unmount "$TAG" >/dev/null; else rm -rf "$mnt"; fi
note "image config: user $user, exposes $ports, healthcheck '$hc'; $npk packages, no compiler/-dev/GUI toolkit/Mesa"

# -------------------------------------------------------------- run ----
NAME=locaid-test-$$
WORK=/var/lib/locaid
mode=""
rt=()
if [[ $ENGINE == docker ]]; then
  out=$(timeout 60 docker run --rm --no-healthcheck "$TAG" true 2>&1) || fail "docker run refused: ${out//$'\n'/ }"
  mode=docker
elif [[ $RUN_MODE == auto || $RUN_MODE == podman ]]; then
  if out=$(timeout 60 podman run --rm --no-healthcheck "$TAG" true 2>&1); then
    mode=podman
  else
    say "podman run (default runtime) refused: ${out//$'\n'/ }"
    rt=(--runtime runc --ulimit "nofile=$(ulimit -n):$(ulimit -n)" --ulimit nproc=4096:4096)
    if out=$(timeout 60 podman "${rt[@]:0:2}" run --rm --no-healthcheck "${rt[@]:2}" "$TAG" true 2>&1); then
      mode=podman-runc
    else
      say "podman run --runtime runc refused: ${out//$'\n'/ }"
      [[ $RUN_MODE == podman ]] && fail "no way to run containers here"
    fi
  fi
fi
[[ -z $mode ]] && mode=chroot

cleanup() {
  set +e
  if [[ $mode == chroot ]]; then
    [[ -n ${srv_pid:-} ]] && kill -TERM "$srv_pid" 2>/dev/null
    [[ -n ${cmnt:-} ]] && { umount "$cmnt/proc" "$cmnt/dev" 2>/dev/null; }
  fi
  if ((KEEP == 0)); then "$ENGINE" rm -f "$NAME" >/dev/null 2>&1; fi
  [[ -n ${probe_pid:-} ]] && kill "$probe_pid" 2>/dev/null
  [[ -n ${proj:-} ]] && ((KEEP == 0)) && compose_down >/dev/null 2>&1
}
trap cleanup EXIT

if [[ $mode == chroot ]]; then
  note "run: chroot into the image's filesystem (podman create + podman mount), server as uid 10001 on 127.0.0.1:$PORT: podman cannot run containers here"
  if (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null; then fail "port $PORT is in use (--port N)"; fi
  podman create --name "$NAME" "$TAG" >/dev/null
  cmnt=$(podman mount "$NAME")
  mount --bind /dev "$cmnt/dev"
  mount -t proc proc "$cmnt/proc"
  [[ -n $bag ]] && { mkdir -p "$cmnt/data/bags" && cp "$BAG_DIR/drive.mcap" "$cmnt/data/bags/"; }
  envs=(env -i HOME=$WORK PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
    LOCAID_LISTEN=127.0.0.1:$PORT LOCAID_WORK_DIR=$WORK)
  chroot --userspec=10001:10001 "$cmnt" "${envs[@]}" /usr/local/bin/locaid-entrypoint demo \
    >"$STATE/server.log" 2>&1 &
  srv_pid=$!
  in_image() { chroot --userspec=10001:10001 "$cmnt" "${envs[@]}" "$@"; }
  outside() { in_image "$@"; }  # same network namespace as the host
else
  note "run: $ENGINE run ($mode${rt:+: ${rt[*]}}), port 127.0.0.1:$PORT -> 50051"
  # (Without systemd, podman logs that it cannot add health-check timers;
  # `podman healthcheck run` below still runs the check.)
  mounts=()
  [[ -n $bag ]] && mounts=(-v "$BAG_DIR:/data/bags:ro")
  "$ENGINE" "${rt[@]:0:2}" run -d --name "$NAME" "${rt[@]:2}" "${mounts[@]}" -p "127.0.0.1:$PORT:50051" "$TAG" \
    >/dev/null 2>"$STATE/run.err" || { cat "$STATE/run.err" >&2; fail "$ENGINE run -d"; }
  in_image() { "$ENGINE" exec "$NAME" "$@"; }
  # A second container on the host network talks to the published port.
  outside() { "$ENGINE" "${rt[@]:0:2}" run --rm --no-healthcheck "${rt[@]:2}" --network host "$TAG" "$@"; }
fi
cli=(locaid --server 127.0.0.1:50051)
[[ $mode == chroot ]] && cli=(locaid --server 127.0.0.1:$PORT)

# The server's output so far (on failure): the chroot run writes it to a
# file; a container's is in podman (the file would be an older run's).
server_log_now() {
  if [[ $mode == chroot ]]; then
    cat "$STATE/server.log" 2>/dev/null
  else
    echo "container $NAME: $("$ENGINE" inspect --format '{{.State.Status}} exit={{.State.ExitCode}}' "$NAME" 2>&1)"
    "$ENGINE" logs "$NAME" 2>&1 | tail -n 40
  fi
}

# 1. health
t0=$(date +%s)
until h=$(in_image "${cli[@]}" health 2>&1) && [[ $h == SERVING ]]; do
  (($(date +%s) - t0 < 60)) || { server_log_now; fail "not SERVING after 60 s: $h"; }
  sleep 1
done
note "health: SERVING after $(($(date +%s) - t0)) s (locaid health)"
if [[ $mode != chroot ]]; then
  h=$(outside locaid --server "127.0.0.1:$PORT" health) || fail "published port: $h"
  if [[ $ENGINE == podman ]]; then
    hc_out=$(podman healthcheck run "$NAME" 2>/dev/null) && hc_rc=0 || hc_rc=$?
    ((hc_rc == 0)) || fail "podman healthcheck run: rc=$hc_rc $hc_out"
    hs=$(podman inspect --format '{{.State.Health.Status}}' "$NAME" 2>/dev/null || true)
    note "published port 127.0.0.1:$PORT from the host network: $h; podman healthcheck run: exit 0, status $hs"
  else  # the engine runs the image's HEALTHCHECK on its own schedule
    t1=$(date +%s)
    until hs=$(docker inspect --format '{{.State.Health.Status}}' "$NAME") && [[ $hs == healthy ]]; do
      (($(date +%s) - t1 < 120)) || fail "docker health status '$hs' after 120 s"
      sleep 2
    done
    note "published port 127.0.0.1:$PORT from the host network: $h; docker health status: $hs"
  fi
fi

# 2. the default demo session (renders a synthetic drive first)
t0=$(date +%s)
until demo=$(in_image cat "$WORK/demo-session-id" 2>/dev/null) && [[ -n $demo ]]; do
  (($(date +%s) - t0 < 300)) || fail "no demo session after 300 s"
  sleep 2
done
note "demo session: $demo (ready $(($(date +%s) - t0)) s after SERVING)"
drive=$(in_image "${cli[@]}" session get "$demo" | grep -oE 'source=[^ ]+' | head -n1)
drive=${drive#source=}
drive=${drive#kitti:}
say "demo drive: $drive"

# 3. start a session of our own on the same drive, as fast as possible
sid=$(in_image "${cli[@]}" session start --kitti "$drive" --rate 0 --scenario open-sky) ||
  fail "session start: $sid"
sid=${sid%%[[:space:]]*}
note "session start --kitti $drive --rate 0: $sid"

# 4. stream poses (print) and record them (TUM) with the CLI
poses=$(in_image "${cli[@]}" subscribe "$sid" --from-start --max 20 --stream-timeout-s 120) ||
  fail "subscribe: $poses"
n=$(grep -c '^seq=' <<<"$poses" || true)
((n == 20)) || { echo "$poses" >&2; fail "expected 20 poses, got $n"; }
note "subscribe --from-start --max 20: $n poses; last: $(tail -n1 <<<"$poses")"
in_image "${cli[@]}" subscribe "$demo" --from-start --max 30 --format tum --out "$WORK/demo.tum" \
  --stream-timeout-s 120 >/dev/null || fail "subscribe --format tum"
ntum=$(in_image cat "$WORK/demo.tum" | grep -cvE '^#|^$' || true)
((ntum == 30)) || fail "expected 30 TUM lines in $WORK/demo.tum, got $ntum"
note "recorded $ntum TUM poses of the demo session into $WORK/demo.tum"
if [[ $mode != chroot ]]; then
  rp=$(outside locaid --server "127.0.0.1:$PORT" subscribe "$sid" --from-start --max 5 | grep -c '^seq=' || true)
  ((rp == 5)) || fail "streaming through the published port gave $rp poses"
  note "streamed $rp poses through the published port from another container"
fi
stats=$(in_image "${cli[@]}" stats "$sid" | grep -E '^(frames_processed|poses_published|fps) ' | tr '\n' ' ')
note "stats $sid: $stats"
in_image "${cli[@]}" session stop "$sid" >/dev/null || fail "session stop"

# 5. a session from the ROS 2 bag on the container's disk, played as fast as possible
if [[ -n $bag ]]; then
  bid=$(in_image "${cli[@]}" session start --bag "$bag" --rate 0 --scenario open-sky 2>&1) ||
    fail "session start --bag $bag: $bid"
  bid=${bid%%[[:space:]]*}
  bposes=$(in_image "${cli[@]}" subscribe "$bid" --from-start --max 40 --stream-timeout-s 120) ||
    fail "subscribe to the bag session: $bposes"
  nb=$(grep -c '^seq=' <<<"$bposes" || true)
  ((nb == 40)) || { echo "$bposes" >&2; fail "bag session: expected 40 poses, got $nb"; }
  bget=$(in_image "${cli[@]}" session get "$bid")
  grep -q "bag" <<<"$bget" || fail "bag session $bid does not report its bag source: $bget"
  note "session start --bag $bag --rate 0: $bid, $nb poses streamed; last: $(tail -n1 <<<"$bposes")"
fi
# 5b. a live session on cameras the server reads through GStreamer inside
#     the image: multifilesrc plays the demo drive's images at 10 Hz in place
#     of two cameras, calibrated by camera_info files made on the host from
#     the drive's calibration (clients/kitti_camera_info.py --rectified)
calib=$(in_image cat "$(dirname "$drive")/calib_cam_to_cam.txt") || fail "reading the demo drive's calibration"
mkdir -p "$STATE/cams" && printf '%s\n' "$calib" >"$STATE/cams/calib_cam_to_cam.txt"
python3 "$ROOT/clients/kitti_camera_info.py" --rectified "$STATE/cams/calib_cam_to_cam.txt" "$STATE/cams" >/dev/null ||
  fail "kitti_camera_info.py on the demo drive's calibration"
for side in left right; do
  in_image sh -c 'printf "%s" "$1" >"$2"' sh "$(cat "$STATE/cams/$side.yaml")" "$WORK/$side.yaml" ||
    fail "writing $side.yaml into the image"
done
play() { echo "multifilesrc location=$drive/$1/data/%010d.png index=0 caps=image/png,framerate=10/1 ! pngdec"; }
cid=$(in_image "${cli[@]}" session start --live --camera-left "$(play image_00)" --camera-right "$(play image_01)" \
  --camera-info-left "$WORK/left.yaml" --camera-info-right "$WORK/right.yaml" 2>&1) ||
  fail "session start --live with GStreamer cameras: $cid"
cid=${cid%%[[:space:]]*}
cposes=$(in_image "${cli[@]}" subscribe "$cid" --from-start --max 30 --stream-timeout-s 120) ||
  fail "subscribe to the camera session: $cposes"
ntrack=$(grep -c 'vo_health=TRACKING' <<<"$cposes" || true)
((ntrack >= 25)) || { echo "$cposes" >&2; fail "camera session: $ntrack of 30 poses tracked (expected >= 25)"; }
cstats=$(in_image "${cli[@]}" stats "$cid" | grep -E '^camera ' || true)
[[ -n $cstats ]] || fail "camera session $cid: no camera line in its stats"
in_image "${cli[@]}" session stop "$cid" >/dev/null || fail "session stop $cid"
note "session start --live (two multifilesrc pipelines, camera_info from the drive's calib): $cid, $ntrack of 30 poses tracked; $cstats"
in_image "${cli[@]}" session list | sed 's/^/test-image:   /'

# 6. a small sweep inside the image (what a Kubernetes sweep task runs): the
#    demo drive, one scenario, two seeds, with the image's locaid-sweep and
#    locaid-replay
in_image sh -c "printf 'recordings:\n  - path: %s\nscenarios: [open-sky]\nseeds: [1, 2]\n' '$drive' >$WORK/sweep.yaml" ||
  fail "writing a sweep manifest in the image"
sw=$(in_image locaid-sweep run "$WORK/sweep.yaml" --out "$WORK/sweep" --jobs 1 2>&1) ||
  { echo "$sw" | tail -n 20 >&2; fail "locaid-sweep run in the image"; }
st=$(in_image locaid-sweep status "$WORK/sweep" 2>&1) || { echo "$st" >&2; fail "locaid-sweep status: not all done"; }
rows=$(in_image cat "$WORK/sweep/results.csv" | grep -c ',done,' || true)
((rows == 2)) || fail "sweep in the image: expected 2 done rows in results.csv, got $rows"
note "locaid-sweep in the image: 2 runs of the demo drive done, results.csv written"

# 7. SIGTERM and clean exit
t0=$(date +%s%N)
if [[ $mode == chroot ]]; then
  kill -TERM "$srv_pid"
  rc=0; wait "$srv_pid" || rc=$?
  srv_pid=""
  log=$(cat "$STATE/server.log")
else
  "$ENGINE" stop -t 30 "$NAME" >/dev/null
  rc=$("$ENGINE" inspect --format '{{.State.ExitCode}}' "$NAME")
  log=$("$ENGINE" logs "$NAME" 2>&1)
  printf '%s\n' "$log" >"$STATE/server.log"
fi
ms=$((($(date +%s%N) - t0) / 1000000))
((rc == 0)) || { echo "$log" | tail -n 20 >&2; fail "server exit code $rc after SIGTERM"; }
grep -q 'locaid-server: stopped' <<<"$log" || fail "no 'locaid-server: stopped' in the log"
note "SIGTERM: exit code 0 after $ms ms; log ends: $(tail -n1 <<<"$log")"

# 8. deploy/compose.yaml as a user brings it up (podman-compose; docker
#    compose with --engine docker) against this image, under a project name
#    of its own and on free loopback ports: the server plays its demo session,
#    the recorder finds it by the service name `server` and writes its poses
#    into the `records` volume, the Foxglove bridge follows it, and the ROS 2
#    adapter's nav_msgs/Odometry reaches a Fast DDS subscriber on the host
#    (build/bin/locaid-fastdds-probe, or $LOCAID_FASTDDS_PROBE: bound to the
#    project network's gateway, the adapter's container its unicast peer, a
#    domain id of the test's own). Then down -v, and the project's
#    containers, network and volumes must be gone.
proj=""
compose_down() {  # brings the project down and removes what it made
  local net=${proj}_default br=""
  [[ $ENGINE == podman ]] && br=$(podman network inspect --format '{{.NetworkInterface}}' "$net" 2>/dev/null || true)
  compose down -v -t 20 || return 1
  # podman-compose 1.0.3 leaves the project's network (docker compose removes it)
  if [[ $ENGINE == podman ]] && podman network exists "$net"; then podman network rm "$net" >/dev/null || return 1; fi
  # the dnsname plugin leaves its INPUT rule for the bridge's DNS port behind
  if [[ -n $br ]] && ! ip link show "$br" >/dev/null 2>&1 &&
    iptables -C INPUT -i "$br" -p udp -m udp --dport 53 -j ACCEPT 2>/dev/null; then
    iptables -D INPUT -i "$br" -p udp -m udp --dport 53 -j ACCEPT
  fi
}
if [[ $mode == chroot ]]; then
  [[ -n ${CI:-} && ${CI} != 0 && ${CI} != false ]] && fail "compose: podman cannot run containers here, and CI is set"
  note "compose: SKIPPED, podman cannot run containers here (chroot path)"
else
  proj=locaid-test-$$
  cport=$((PORT + 1)) fport=$((PORT + 2))
  cdomain=$((100 + $$ % 120))
  probe=${LOCAID_FASTDDS_PROBE:-$ROOT/build/bin/locaid-fastdds-probe}
  if [[ ! -x $probe ]]; then
    [[ -n ${CI:-} && ${CI} != 0 && ${CI} != false ]] &&
      fail "compose: no Fast DDS probe at $probe (built with the tests when Fast DDS and fastddsgen are installed), and CI is set"
    note "compose: the Fast DDS check is SKIPPED: no $probe (build with -DLOCAID_BUILD_TESTS=ON, Fast DDS and fastddsgen)"
    probe=""
  fi
  if [[ $ENGINE == podman ]]; then
    ccmd=(podman-compose)
    [[ $mode == podman-runc ]] && ccmd+=(--podman-args "--runtime runc")
    ccmd+=(-p "$proj" -f "$ROOT/deploy/compose.yaml")
    cversion="podman-compose $(podman-compose version 2>/dev/null | awk '/podman-compose/ {print $NF; exit}')"
  else
    ccmd=(docker compose -p "$proj" -f "$ROOT/deploy/compose.yaml")
    cversion="docker compose $(docker compose version --short)"
  fi
  # The compose file's own defaults, but for the image and the host ports.
  compose() {
    env -u KITTI_DIR -u LOCAID_DEMO_DRIVE -u LOCAID_DEMO_FRAMES -u LOCAID_DEMO_SCENARIO \
      LOCAID_IMAGE="$TAG" LOCAID_PORT="$cport" LOCAID_FOXGLOVE_PORT="$fport" ROS_DOMAIN_ID="$cdomain" "${ccmd[@]}" "$@"
  }
  cid_of() {  # the project's container of a service (both tools set these labels)
    "$ENGINE" ps -a -q --filter "label=com.docker.compose.project=$proj" \
      --filter "label=com.docker.compose.service=$1" | head -n1
  }
  cstate() { "$ENGINE" inspect --format '{{.State.Status}} exit={{.State.ExitCode}}' "$1" 2>&1; }
  clog() { "$ENGINE" logs "$1" 2>&1 | tail -n 30; }
  for p in "$cport" "$fport"; do
    if (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then fail "compose: port $p is in use (--port N moves it)"; fi
  done
  tc0=$(date +%s)
  # podman-compose exits 0 even when a container does not start: the
  # containers' states below are the check.
  compose up -d --no-build >"$STATE/compose-up.log" 2>&1 ||
    { tail -n 30 "$STATE/compose-up.log" >&2; fail "compose up -d (log $STATE/compose-up.log)"; }
  csrv=$(cid_of server) crec=$(cid_of recorder) cfox=$(cid_of foxglove) cros=$(cid_of ros2)
  for c in "server:$csrv" "recorder:$crec" "foxglove:$cfox" "ros2:$cros"; do
    [[ -n ${c#*:} ]] || { tail -n 30 "$STATE/compose-up.log" >&2; fail "compose: no container for service ${c%%:*}"; }
  done
  if [[ $ENGINE == podman ]]; then
    dns=$(podman network inspect --format '{{.DNSEnabled}}' "${proj}_default")
    [[ $dns == true ]] || fail "compose: network ${proj}_default resolves no names (dns_enabled=$dns; dnsname plugin missing?)"
  fi
  # A Fast DDS subscriber on the host (a ROS 2 node on the default rmw), from
  # before the demo session: the adapter's poses must reach it.
  if [[ -n $probe ]]; then
    if [[ $ENGINE == podman ]]; then
      gw=$(podman network inspect --format '{{range .Subnets}}{{.Gateway}}{{end}}' "${proj}_default")
    else
      gw=$(docker network inspect --format '{{range .IPAM.Config}}{{.Gateway}}{{end}}' "${proj}_default")
    fi
    rip=$("$ENGINE" inspect --format '{{range .NetworkSettings.Networks}}{{.IPAddress}}{{end}}' "$cros")
    [[ -n $gw && -n $rip ]] || fail "compose: no gateway ('$gw') or ros2 container address ('$rip') on ${proj}_default"
    "$probe" --domain "$cdomain" --address "$gw" --peer "$rip" --count 20 --timeout-s 300 \
      >"$STATE/compose-probe.json" 2>"$STATE/compose-probe.log" &
    probe_pid=$!
  fi
  tc1=$(date +%s)
  until h=$("$ENGINE" exec "$csrv" locaid --server 127.0.0.1:50051 health 2>&1) && [[ $h == SERVING ]]; do
    (($(date +%s) - tc1 < 60)) || {
      grep -iE 'error' "$STATE/compose-up.log" | tail -n 10 >&2
      echo "server: $(cstate "$csrv")" >&2; clog "$csrv" >&2; fail "compose: server not SERVING after 60 s: $h"
    }
    sleep 1
  done
  h=$(outside locaid --server "127.0.0.1:$cport" health) || fail "compose: published port 127.0.0.1:$cport: $h"
  note "compose: $cversion up -d: 4 containers in $((tc1 - tc0)) s, network ${proj}_default${dns:+ (dns_enabled=$dns)}; server SERVING after $(($(date +%s) - tc1)) s, $h through 127.0.0.1:$cport"
  tc1=$(date +%s)
  until cdemo=$("$ENGINE" exec "$csrv" cat /var/lib/locaid/demo-session-id 2>/dev/null) && [[ -n $cdemo ]]; do
    (($(date +%s) - tc1 < 300)) || { clog "$csrv" >&2; fail "compose: no demo session after 300 s"; }
    sleep 2
  done
  cdemo_s=$(($(date +%s) - tc1))
  # The recorder exits when the demo session's input ends (20 s at real time).
  until [[ $(cstate "$crec") == exited* ]]; do
    (($(date +%s) - tc1 < 300)) || { clog "$crec" >&2; fail "compose: recorder still $(cstate "$crec") after 300 s"; }
    sleep 2
  done
  rstate=$(cstate "$crec")
  [[ $rstate == "exited exit=0" ]] || { clog "$crec" >&2; fail "compose: recorder $rstate"; }
  rlog=$("$ENGINE" logs "$crec" 2>&1)
  grep -q "recording session $cdemo " <<<"$rlog" || { echo "$rlog" | tail -n 20 >&2; fail "compose: the recorder did not record the demo session $cdemo"; }
  crec_s=$(($(date +%s) - tc1))
  sget=$("$ENGINE" exec "$csrv" locaid --server 127.0.0.1:50051 session get "$cdemo")
  frames=$(grep -oE 'frames=[0-9]+/[0-9]+' <<<"$sget" | head -n1)
  frames=${frames##*/}
  [[ -n $frames ]] || fail "compose: session get $cdemo: $sget"
  # The recording, read from the volume on the host.
  vdir=$("$ENGINE" volume inspect --format '{{.Mountpoint}}' "${proj}_records") || fail "compose: no volume ${proj}_records"
  tum=$(ls "$vdir/$cdemo"-*.tum 2>/dev/null | head -n1)
  [[ -n $tum ]] || { ls -l "$vdir" >&2; fail "compose: no $cdemo-*.tum in the records volume"; }
  owner=$(stat -c %u:%g "$tum")
  # The server's own record of the session, to compare line by line.
  out=$("$ENGINE" exec "$csrv" locaid --server 127.0.0.1:50051 subscribe "$cdemo" --from-start --format tum \
    --out /tmp/compose-check.tum --stream-timeout-s 60 2>&1) || fail "compose: subscribe $cdemo in the server: $out"
  "$ENGINE" exec "$csrv" cat /tmp/compose-check.tum >"$STATE/compose-server.tum"
  cp "$tum" "$STATE/compose-recorder.tum"
  day=$(grep -oE '/[0-9]{4}_[0-9]{2}_[0-9]{2}/' <<<"$sget" | head -n1 | tr -d /)
  check=$(python3 - "$STATE/compose-recorder.tum" "$STATE/compose-server.tum" "$frames" "$day" <<'PY'
import datetime, math, statistics, sys
rec, srv, frames, day = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
def rows(path):
    return [l.split() for l in open(path) if l.strip() and not l.startswith("#")]
r, s = rows(rec), rows(srv)
def bad(msg): print(msg); sys.exit(1)
if len(r) != frames: bad(f"{len(r)} poses in the recording, the session has {frames} frames")
if r != s: bad(f"the recording ({len(r)} poses) differs from the server's stream of the session ({len(s)})")
if any(len(x) != 8 for x in r): bad("a line without 8 fields")
v = [[float(f) for f in x] for x in r]
t = [x[0] for x in v]
steps = [b - a for a, b in zip(t, t[1:])]
if min(steps) <= 0: bad("timestamps not strictly increasing")
med = statistics.median(steps)
if not 0.09 <= med <= 0.11: bad(f"median step {med:.4f} s, not the drive's 10 Hz")
if max(steps) > 0.5: bad(f"a gap of {max(steps):.3f} s")
if day:
    d0 = datetime.datetime.strptime(day, "%Y_%m_%d").replace(tzinfo=datetime.timezone.utc).timestamp()
    if not (d0 <= t[0] and t[-1] < d0 + 86400): bad(f"stamps {t[0]}..{t[-1]} not on the drive's day {day} (UTC)")
if any(abs(math.hypot(*x[4:8]) - 1) > 1e-3 for x in v): bad("a quaternion that is not unit")
dist = math.dist(v[0][1:4], v[-1][1:4])
if dist < 10: bad(f"the vehicle moved {dist:.1f} m in the recording")
print(f"{len(r)} poses, stamps {t[0]:.1f} .. {t[-1]:.1f} ({datetime.datetime.fromtimestamp(t[0], datetime.timezone.utc):%Y-%m-%dT%H:%M:%SZ}, {t[-1]-t[0]:.1f} s, median step {med:.3f} s), {dist:.0f} m from first to last pose, identical to the server's stream")
PY
  ) || fail "compose: recording $tum: $check"
  note "compose: demo session $cdemo ready $cdemo_s s after SERVING; recorder exited 0 after $crec_s s and wrote $(basename "$tum") (owner $owner) into volume ${proj}_records: $check"
  flog=$("$ENGINE" logs "$cfox" 2>&1)
  grep -q "following session $cdemo" <<<"$flog" || { echo "$flog" | tail -n 20 >&2; fail "compose: the Foxglove bridge did not follow $cdemo"; }
  [[ $(cstate "$cfox") == running* ]] || fail "compose: foxglove $(cstate "$cfox")"
  note "compose: the foxglove container follows $cdemo (resolved server:50051)"
  # The ROS 2 adapter: a DDS participant (deploy/cyclonedds.xml: multicast
  # off, the host as its only peer, so nothing leaves the machine) following
  # the same session.
  olog=$("$ENGINE" logs "$cros" 2>&1)
  grep -q "following session $cdemo" <<<"$olog" || { echo "$olog" | tail -n 20 >&2; fail "compose: the ROS 2 adapter did not follow $cdemo"; }
  [[ $(cstate "$cros") == running* ]] || { echo "$olog" | tail -n 20 >&2; fail "compose: ros2 $(cstate "$cros")"; }
  note "compose: the ros2 container follows $cdemo: $(grep -m1 'DDS domain' <<<"$olog" || true)"
  if [[ -n $probe ]]; then
    wait "$probe_pid" || { cat "$STATE/compose-probe.log" >&2; head -c 400 "$STATE/compose-probe.json" >&2
      echo "$olog" | tail -n 10 >&2; fail "compose: the Fast DDS probe on $gw (peer $rip, domain $cdomain) got no 20 poses"; }
    probe_pid=""
    check=$(python3 - "$STATE/compose-probe.json" "$STATE/compose-server.tum" <<'PY'
import bisect, json, sys
probe = json.load(open(sys.argv[1]))
stream = sorted(float(l.split()[0]) for l in open(sys.argv[2]) if l.strip() and not l.startswith("#"))
def bad(msg): print(msg); sys.exit(1)
s = probe["samples"]
if probe["writers_matched"] < 1: bad("no writer matched")
for m in s:
    if (m["frame_id"], m["child_frame_id"]) != ("map", "base_link"):
        bad(f"frames {m['frame_id']} -> {m['child_frame_id']}, not map -> base_link")
    t = m["stamp_ns"] / 1e9
    i = bisect.bisect_left(stream, t - 1e-3)
    if i == len(stream) or abs(stream[i] - t) > 1e-3: bad(f"a pose at {t:.3f} s that the server's stream has not")
t = [m["stamp_ns"] for m in s]
if any(b <= a for a, b in zip(t, t[1:])): bad("stamps not strictly increasing")
print(f"{probe['received']} nav_msgs/Odometry map -> base_link, {t[0] / 1e9:.1f} .. {t[-1] / 1e9:.1f} s, each a pose of the server's stream")
PY
    ) || fail "compose: the Fast DDS probe's poses: $check"
    note "compose: a Fast DDS subscriber on the host ($gw, domain $cdomain, peer: the ros2 container $rip) received $check"
  fi
  if ((KEEP == 1)); then
    note "compose: --keep, project $proj left up (LOCAID_IMAGE=$TAG ${ccmd[*]} down -v)"
    proj=""
  else
    tc1=$(date +%s)
    compose_down >"$STATE/compose-down.log" 2>&1 || { tail -n 20 "$STATE/compose-down.log" >&2; fail "compose down -v"; }
    left=$("$ENGINE" ps -a -q --filter "label=com.docker.compose.project=$proj")
    [[ -z $left ]] || fail "compose: containers left after down: $left"
    left=$("$ENGINE" volume ls -q | grep -E "^${proj}_" || true)
    [[ -z $left ]] || fail "compose: volumes left after down: $left"
    left=$("$ENGINE" network ls --format '{{.Name}}' | grep -E "^${proj}_" || true)
    [[ -z $left ]] || fail "compose: networks left after down: $left"
    note "compose: down -v in $(($(date +%s) - tc1)) s; no container, volume or network of $proj left; whole compose step $(($(date +%s) - tc0)) s"
    proj=""
  fi
fi

echo
echo "test-image: PASS ($mode)"
for s in "${summary[@]}"; do echo "  - $s"; done
