// Offline field construction (section 4.1): partition, Poisson-disk sampling,
// HRBF fits, 32^3 baking and iso values, per model, on 1 thread and on every
// hardware thread. Counters give each stage's milliseconds, the number of
// fields and the baked fields' memory.
//
//   isk_bench --benchmark_filter='FieldBuild'
#include <benchmark/benchmark.h>

#include <algorithm>
#include <string>
#include <thread>

#include "bench_support.hpp"
#include "isk/implicit_fields.hpp"

namespace isk::bench {
namespace {

void buildFields(benchmark::State& state, const Model& model, int threads) {
  const Rig& rig = rigOf(model);
  ImplicitFieldsOptions options;
  options.threads = threads;
  ImplicitFieldsTimes sum;
  int64_t runs = 0;
  size_t bytes = 0;
  int fields = 0;
  for (auto _ : state) {
    const ImplicitFields built = buildImplicitFields(rig, options);
    benchmark::DoNotOptimize(built.iso_values.data());
    sum.partition_ms += built.times.partition_ms;
    sum.sampling_ms += built.times.sampling_ms;
    sum.fitting_ms += built.times.fitting_ms;
    sum.baking_ms += built.times.baking_ms;
    sum.iso_ms += built.times.iso_ms;
    bytes = built.grids.bytes();
    fields = built.grids.fieldCount();
    ++runs;
  }
  const double n = static_cast<double>(std::max<int64_t>(runs, 1));
  state.counters["vertices"] = rig.mesh.vertexCount();
  state.counters["joints"] = rig.skeleton.jointCount();
  state.counters["fields"] = fields;
  state.counters["field_MiB"] = bytes / (1024.0 * 1024.0);
  state.counters["partition_ms"] = sum.partition_ms / n;
  state.counters["sampling_ms"] = sum.sampling_ms / n;
  state.counters["fitting_ms"] = sum.fitting_ms / n;
  state.counters["baking_ms"] = sum.baking_ms / n;
  state.counters["iso_ms"] = sum.iso_ms / n;
  state.SetLabel(std::to_string(threads) + " thread(s)");
}

}  // namespace

void registerFieldBenchmarks() {
  const int all = static_cast<int>(
      std::max(1u, std::thread::hardware_concurrency()));
  for (const Model& model : models()) {
    if (!available(model) || model.subdivision_levels > 0) continue;
    for (int threads : {1, all}) {
      if (threads == all && all == 1) continue;
      benchmark::RegisterBenchmark(
          ("FieldBuild/" + model.name + "/threads:" + std::to_string(threads))
              .c_str(),
          buildFields, model, threads)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
}

}  // namespace isk::bench
