#!/usr/bin/env bash
# Installs everything locaid needs to build, test and run, from Debian 12
# packages only. Used by the README commands, .ci/run and deploy/Containerfile.
#
#   deploy/install-deps.sh            # build + test dependencies (everything a test runs)
#   deploy/install-deps.sh --build    # build dependencies only (container build stage)
#   deploy/install-deps.sh --runtime  # only the shared libraries the binaries need
#   deploy/install-deps.sh --fuzz     # the same as no option (kept: clang/libFuzzer are
#                                     # test dependencies now, for the fuzz targets' test)
#
# Node.js and npm (the Foxglove client and the official MCAP reader tests):
# Debian's nodejs and npm are installed only when `node` or `npm` is missing,
# so a newer Node.js already on the machine (CI images carry Node.js 20) is
# kept. A test that needs a tool this script installs fails when CI is set
# and the tool is missing (tests/needs_tool.hpp, tests/record/js/setup.sh).
set -euo pipefail

build_pkgs=(
  build-essential cmake pkg-config ninja-build ccache
  libopencv-dev
  libeigen3-dev libgeographiclib-dev
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc
  libgtest-dev libgmock-dev libbenchmark-dev
  libyaml-cpp-dev nlohmann-json3-dev libcli11-dev prometheus-cpp-dev
  libgps-dev libzstd-dev liblz4-dev zlib1g-dev libboost-dev
  libgstreamer1.0-dev libgstreamer-plugins-base1.0-dev   # cameras through GStreamer (sensors/gst_camera)
  cyclonedds-dev                  # locaid-ros2: ROS 2 topics over Eclipse Cyclone DDS (ros2/)
  python3 python3-matplotlib python3-grpcio python3-protobuf python3-grpc-tools
)
runtime_pkgs=(
  libopencv-core406 libopencv-imgproc406 libopencv-imgcodecs406
  libopencv-features2d406 libopencv-calib3d406 libopencv-video406
  libgeographiclib23 libgrpc++1.51 libprotobuf32 libyaml-cpp0.7
  libprometheus-cpp-pull1.0 libprometheus-cpp-core1.0 libgps28 libzstd1 liblz4-1 zlib1g
  libgstreamer1.0-0 libgstreamer-plugins-base1.0-0
  gstreamer1.0-plugins-base gstreamer1.0-plugins-good   # cameras: v4l2src, jpegdec, videoconvert, appsink
  libddsc0debian                  # locaid-ros2 (Cyclone DDS)
)

test_pkgs=(
  prometheus                      # promtool (metrics test)
  gpsd gpsd-clients python3-gps   # gpsd + gpsfake (NMEA and gpsd tests)
  gstreamer1.0-plugins-base gstreamer1.0-plugins-good  # videotestsrc, multifilesrc, pngdec, v4l2src (camera tests)
  openssl                         # self-signed certificates (TLS tests)
  clang libclang-rt-14-dev        # libFuzzer + sanitizer runtimes (fuzz/ targets and their test)
  podman runc debootstrap         # the container image test (deploy/test-image.sh), on every test run
  podman-compose golang-github-containernetworking-plugin-dnsname  # its deploy/compose.yaml step (dnsname: service names on podman's CNI networks)
  slurm-wlm munge                 # a real single-node Slurm for the locaid-sweep tests (tests/sweep)
  libfastrtps-dev fastddsgen      # the Fast DDS peer of the locaid-ros2 tests (tests/ros2), types from ROS 2 IDL
)
node_pkgs=()  # Debian's Node.js only where none is installed (see above)
command -v node >/dev/null 2>&1 || node_pkgs+=(nodejs)
command -v npm >/dev/null 2>&1 || node_pkgs+=(npm)

case "${1:-}" in
  "" | --fuzz) pkgs=("${build_pkgs[@]}" "${test_pkgs[@]}" "${node_pkgs[@]}") ;;
  --build) pkgs=("${build_pkgs[@]}") ;;
  --runtime) pkgs=("${runtime_pkgs[@]}") ;;
  *) echo "install-deps: unknown option '$1' (--build, --runtime, --fuzz or none)" >&2; exit 2 ;;
esac

missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]} == 0)); then
  echo "install-deps: all ${#pkgs[@]} packages present"
  exit 0
fi
if [[ $(id -u) -ne 0 ]]; then
  echo "install-deps: missing packages (run as root to install): ${missing[*]}" >&2
  exit 1
fi
echo "install-deps: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"
