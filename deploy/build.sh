#!/usr/bin/env bash
# Configures and builds locaid into build/ (every program lands in build/bin/).
#   deploy/build.sh [extra cmake -D options]
# With ccache installed (deploy/install-deps.sh installs it) compiles go
# through it, with paths relative to the repository (CCACHE_BASEDIR), so the
# container image's build stage (deploy/test-image.sh mounts this cache) and
# other clones reuse the objects. ccache keys an object on the locale
# variables too, so compiles run with the same fixed locale here and in the
# image (deploy/Containerfile: keep the two launchers alike). The cache is
# ccache's own (`ccache -k cache_dir`; max_size, 5 GB by default, bounds it).
set -euo pipefail
cd "$(dirname "$0")/.."
launcher=()
if command -v ccache >/dev/null 2>&1; then
  launcher=("-DCMAKE_CXX_COMPILER_LAUNCHER=env;-u;LC_CTYPE;-u;LC_MESSAGES;LANG=C.UTF-8;LC_ALL=C.UTF-8;CCACHE_BASEDIR=$PWD;ccache")
fi
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" "$@" >/dev/null
cmake --build build -j"$(nproc)"
