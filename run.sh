#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine:
#   ./run.sh demo   install what is missing, build, run the demo into out/
#   ./run.sh test   install what is missing, build, run the whole test suite
#   ./run.sh build  install what is missing and build only
#   ./run.sh bench  build, then run the benchmarks (arguments go to isk_bench)
#   ./run.sh benchmarks  build, run the whole suite, write BENCHMARKS.md
#                   (arguments go to bench/run_benchmarks.py)
set -euo pipefail
cd "$(dirname "$0")"

PACKAGES=(build-essential cmake pkg-config
  ocl-icd-opencl-dev opencl-c-headers opencl-clhpp-headers pocl-opencl-icd clinfo
  libeigen3-dev libopenmesh-dev libassimp-dev libgtest-dev libbenchmark-dev
  libstb-dev libcli11-dev nlohmann-json3-dev)
BUILD_DIR=${ISK_BUILD_DIR:-build}
JOBS=${ISK_JOBS:-$(nproc)}

install_missing() {
  local missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" ||
      missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "== installing: ${missing[*]}" >&2
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >&2
}

build() {
  install_missing
  # PoCL reports no device at all when it cannot create its kernel cache.
  export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$PWD/.pocl-cache}
  mkdir -p "$POCL_CACHE_DIR"
  cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release >&2
  cmake --build "$BUILD_DIR" -j "$JOBS" >&2
}

case "${1:-}" in
  demo)
    build
    shift
    "$BUILD_DIR/samples/demo/isk-demo" --out out "$@"
    ;;
  test)
    build
    (cd "$BUILD_DIR" && ctest --output-on-failure -j "$JOBS")
    ;;
  build)
    build
    ;;
  bench)
    build
    shift
    "$BUILD_DIR/bench/isk_bench" "$@"
    ;;
  benchmarks)
    build
    shift
    python3 bench/run_benchmarks.py --bench "$BUILD_DIR/bench/isk_bench" "$@"
    ;;
  *)
    echo "usage: $0 demo|test|build|bench|benchmarks [args]" >&2
    exit 2
    ;;
esac
