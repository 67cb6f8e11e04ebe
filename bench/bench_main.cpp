// The benchmark suite's entry point: registers every family, then runs what
// --benchmark_filter selects.
#include <benchmark/benchmark.h>

#include <cstdio>

#include "bench_support.hpp"
#include "data_folder.hpp"

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (!isk::samples::dataFolderPresent()) {
    std::fprintf(
        stderr,
        "data folder '%s' is absent (set ISK_DATA_DIR): only the builtin rig "
        "is benchmarked\n",
        isk::samples::dataFolder().c_str());
  }
  isk::bench::registerSkinningBenchmarks();
  isk::bench::registerFieldBenchmarks();
  isk::bench::registerImplicitBenchmarks();
  isk::bench::registerPrecomputeBenchmarks();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
