#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine:
#   ./run.sh demo   install what is missing, build, run the demo into out/
#   ./run.sh test   install what is missing, build, run the whole test suite
#   ./run.sh build  install what is missing and build only
#   ./run.sh bench  build, then run the benchmarks (arguments go to isk_bench)
#   ./run.sh benchmarks  build, run the whole suite, write bench/BENCHMARKS.md
#                   (arguments go to bench/run_benchmarks.py)
#   ./run.sh fuzz [SECONDS] [libFuzzer args]  build the fuzzer with Clang
#                   into build-fuzz/ and fuzz the importer (default 60 s)
#   ./run.sh sanitize  AddressSanitizer + UndefinedBehaviorSanitizer build in
#                   build-asan/, then the whole test suite through CTest
#   ./run.sh valgrind  memcheck on a short subset of isk_tests (the normal
#                   build): CPU references, import, one OpenCL frame
set -euo pipefail
cd "$(dirname "$0")"

PACKAGES=(build-essential cmake pkg-config
  ocl-icd-opencl-dev opencl-c-headers opencl-clhpp-headers pocl-opencl-icd clinfo
  libeigen3-dev libopenmesh-dev libassimp-dev libgtest-dev libbenchmark-dev
  libstb-dev libcli11-dev nlohmann-json3-dev libcgal-dev python3
  pybind11-dev python3-dev python3-numpy python3-pytest blender)
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

# build [TARGET...]: configure, then build the targets named (default: all).
build() {
  install_missing
  # PoCL reports no device at all when it cannot create its kernel cache.
  export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$PWD/.pocl-cache}
  mkdir -p "$POCL_CACHE_DIR"
  cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release >&2
  if [ $# -gt 0 ]; then
    cmake --build "$BUILD_DIR" -j "$JOBS" --target "$@" >&2
  else
    cmake --build "$BUILD_DIR" -j "$JOBS" >&2
  fi
}

# libFuzzer over import -> rig -> skinning (fuzz/README.md). Seeds: the
# shared assets up to 1 MB, read at run time; the corpus grows in
# build-fuzz/corpus, crashes land in build-fuzz/findings.
fuzz() {
  local seconds=${1:-60}
  shift || true
  PACKAGES+=(clang libclang-rt-14-dev)
  install_missing
  local dir=${ISK_FUZZ_BUILD_DIR:-build-fuzz}
  cmake -S . -B "$dir" -DCMAKE_CXX_COMPILER=clang++ \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
    -DISK_BUILD_FUZZERS=ON -DISK_BUILD_TESTS=OFF -DISK_BUILD_SAMPLES=OFF \
    -DISK_BUILD_BENCHMARKS=OFF >&2
  cmake --build "$dir" -j "$JOBS" --target isk_import_fuzzer >&2
  local data=${ISK_DATA_DIR:-../shared/data}
  mkdir -p "$dir/corpus" "$dir/seeds" "$dir/findings"
  if [ -d "$data" ]; then
    find "$data" -maxdepth 1 -type f -size -1024k ! -name '*.md' \
      -exec cp -f {} "$dir/seeds/" \;
  else
    echo "== fuzz: no data folder at $data: starting from an empty corpus" >&2
  fi
  echo "== fuzz: $seconds s, corpus $dir/corpus, seeds from $data" >&2
  # Leaks inside Assimp (failed imports) are known and not ours: suppressed.
  export LSAN_OPTIONS=suppressions=$PWD/fuzz/lsan.supp:print_suppressions=0
  # One job at a time in a child process that is restarted after a finding,
  # so that a crash or a hang inside Assimp does not end the run; every
  # finding is then triaged (fuzz/triage.sh): the run fails for ours only.
  "$dir/fuzz/isk_import_fuzzer" -fork=1 -ignore_crashes=1 \
    -ignore_timeouts=1 -ignore_ooms=1 -max_total_time="$seconds" \
    -dict=fuzz/isk.dict -timeout=30 -rss_limit_mb=4096 \
    -artifact_prefix="$dir/findings/" -print_final_stats=1 "$@" \
    "$dir/corpus" "$dir/seeds" 2>"$dir/fuzz.log" || true
  if ! grep -q "^INFO: exiting" "$dir/fuzz.log"; then
    tail -n 20 "$dir/fuzz.log" >&2
    echo "== fuzz: the fuzzer did not run to its end (see $dir/fuzz.log)" >&2
    return 1
  fi
  grep -E '^#[0-9]+|^INFO: .*(files found|seed corpus)|^stat::' "$dir/fuzz.log" |
    tail -n 4 >&2
  echo "== fuzz: triage of this run's findings ($dir/findings)" >&2
  fuzz/triage.sh "$dir/fuzz/isk_import_fuzzer" "$dir/findings"
}

# Sanitizer and valgrind runs: suppressions name third-party code only
# (PoCL, its LLVM, the OpenCL loader, Assimp, glibc's loader), see
# tests/sanitizers/.
SANITIZERS=$PWD/tests/sanitizers
SANITIZE_ASSETS=RiggedSimple.dae,anim_test.x,animation_with_skeleton.fbx\
,quad_skin.glb,fox-animations.glb,dragon-animations.glb,RobotExpressive.glb

sanitize() {
  install_missing
  export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$PWD/.pocl-cache}
  mkdir -p "$POCL_CACHE_DIR"
  local dir=${ISK_SANITIZE_BUILD_DIR:-build-asan}
  # -O1 -g1: quicker to build than Release, fast enough to run, with line
  # numbers in reports. _GLIBCXX_ASSERTIONS: bounds checks in the standard
  # containers; no NDEBUG, so Eigen's index asserts are on too.
  cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -D_GLIBCXX_ASSERTIONS" \
    -DISK_SANITIZE=address,undefined -DISK_BUILD_BENCHMARKS=OFF >&2
  cmake --build "$dir" -j "$JOBS" >&2
  # intercept_tls_get_addr=0: up to GCC 13 the runtime's __tls_get_addr
  # interceptor takes a dynamic TLS block (PoCL's, LLVM's) that happens to
  # sit 16 bytes into a page for a pre-2.25 glibc header and reads a bogus
  # range from it, and LeakSanitizer's tracer dies on it at exit ("Tracer
  # caught signal 11", google/sanitizers#1322) after a test has passed.
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:halt_on_error=1:intercept_tls_get_addr=0}
  export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$SANITIZERS/lsan.supp:print_suppressions=0}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
  # The asset tests on one asset of each format and of each trait that
  # takes its own path (a clip-less rig, 100 joints, 21 meshes of rigid
  # pieces): under ASan the CPU references of the dense characters were most
  # of CI's time (docs/reliability.md). ISK_TEST_ASSETS= (empty) runs all.
  export ISK_TEST_ASSETS=${ISK_TEST_ASSETS-$SANITIZE_ASSETS}
  (cd "$dir" && ctest --output-on-failure -j "$JOBS")
}

# memcheck is ~30x slower than a native run and PoCL compiles its kernels
# again under it (its cache entries from native runs do not match): a short
# subset that still reaches every layer -- CPU references, import and export,
# LBS/DQS kernels, the tracking kernels stage by stage on the procedural rigs,
# implicit frames of two characters sharing a context, error paths. About 5
# CPU-minutes with a cold PoCL cache, 30 s warm: a manual check, not in CI.
VALGRIND_TESTS='Hrbf.*:Reparameterization.*:OneRings.*:SelfIntersection.*'\
':SkinWeights.*:Skeleton.*:Mesh.*:Animation.*:Pose.*:VertexNormals.*'\
':ProceduralRigs.*:ImportErrors.*:ImportGltf.*:ExportTest.*:MeshMetricsTest.*'\
':ThetaController.*:SurfaceTrackingOptions.*:Skinning.DualQuaternion*'\
':Skinning.SingleRigidMotionIsExact:Skinning.ValidateReportsBadInputs'\
':Skinning.BindPoseReproducesInputOnProceduralRigs'\
':ImplicitSkinner.CharactersShareOneContext:ImplicitSkinner.BadInputIsAClearError'\
':ClSurfaceTracking.StagesMatchTheReferenceOnProceduralRigs'

valgrind_run() {
  PACKAGES+=(valgrind)
  build
  export ISK_CACHE_DIR=${ISK_CACHE_DIR:-$PWD/$BUILD_DIR/isk-cache}
  valgrind --tool=memcheck --error-exitcode=1 --leak-check=full \
    --errors-for-leak-kinds=definite,possible --num-callers=40 \
    --suppressions="$SANITIZERS/valgrind.supp" --gen-suppressions=all \
    "$BUILD_DIR/tests/isk_tests" --gtest_filter="${ISK_VALGRIND_FILTER:-$VALGRIND_TESTS}"
}

case "${1:-}" in
  demo)
    # The demo and the library only: not the tests and benchmarks.
    build isk-demo
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
    build isk_bench
    shift
    "$BUILD_DIR/bench/isk_bench" "$@"
    ;;
  benchmarks)
    build isk_bench
    shift
    python3 bench/run_benchmarks.py --bench "$BUILD_DIR/bench/isk_bench" "$@"
    ;;
  fuzz)
    shift
    fuzz "$@"
    ;;
  sanitize)
    sanitize
    ;;
  valgrind)
    valgrind_run
    ;;
  *)
    echo "usage: $0 demo|test|build|bench|benchmarks|fuzz|sanitize|valgrind [args]" >&2
    exit 2
    ;;
esac
