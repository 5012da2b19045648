#!/usr/bin/env bash
# Installs everything locaid needs to build, test and run, from Debian 12
# packages only. Used by the README commands, .ci/run and deploy/Containerfile.
#
#   deploy/install-deps.sh            # build + test dependencies
#   deploy/install-deps.sh --build    # build dependencies only (container build stage)
#   deploy/install-deps.sh --runtime  # only the shared libraries the binaries need
#   deploy/install-deps.sh --fuzz     # build + test dependencies and clang/libFuzzer (fuzz/)
set -euo pipefail

build_pkgs=(
  build-essential cmake pkg-config ninja-build
  libopencv-dev
  libeigen3-dev libgeographiclib-dev
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc
  libgtest-dev libgmock-dev libbenchmark-dev
  libyaml-cpp-dev nlohmann-json3-dev libcli11-dev prometheus-cpp-dev
  libgps-dev libzstd-dev zlib1g-dev libboost-dev
  python3 python3-matplotlib python3-grpcio python3-protobuf python3-grpc-tools
)
runtime_pkgs=(
  libopencv-core406 libopencv-imgproc406 libopencv-imgcodecs406
  libopencv-features2d406 libopencv-calib3d406 libopencv-video406
  libgeographiclib23 libgrpc++1.51 libprotobuf32 libyaml-cpp0.7
  libprometheus-cpp-pull1.0 libprometheus-cpp-core1.0 libgps28 libzstd1 zlib1g
)

fuzz_pkgs=(clang libclang-rt-14-dev)  # optional: libFuzzer + sanitizer runtimes
test_pkgs=(prometheus gpsd gpsd-clients python3-gps)  # promtool (metrics test); gpsd + gpsfake (NMEA test)

pkgs=("${build_pkgs[@]}" "${test_pkgs[@]}")
[[ "${1:-}" == "--build" ]] && pkgs=("${build_pkgs[@]}")
[[ "${1:-}" == "--runtime" ]] && pkgs=("${runtime_pkgs[@]}")
[[ "${1:-}" == "--fuzz" ]] && pkgs+=("${fuzz_pkgs[@]}")

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
