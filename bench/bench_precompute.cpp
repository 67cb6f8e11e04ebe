// Start-up costs: operator tables and OpenCL program builds.
//
// OperatorTable/<blend|bulge>/bake: baking one 128^3 table on every hardware
// thread (bakeOperatorTable). OperatorTable/<blend|bulge>/cached-load: the
// same table read back and validated from the on-disk cache
// (loadOperatorTable, file written once before the loop into a temporary
// folder that is removed afterwards; the file is in the OS page cache, as on
// any start after the first).
//
// ProgramBuild/<kernel>/<mode>:<d>: building one embedded kernel file
// (fields, tracking, skinning, normals) on OpenCL device d with the options
// the library uses there (clCreateProgramWithSource + clBuildProgram; PoCL
// compiles each kernel's work-group function later, at its first launch:
// Implicit/'s first_frame_ms holds that):
//   cold        a fresh ClContext and a define unique to the iteration, so
//               that the driver's own disk cache (POCL_CACHE_DIR) misses;
//   warm        a fresh ClContext and the same options every time (built
//               once before the loop): the driver's disk cache hits;
//   in-process  ClContext::program on a context that built it already (the
//               library's per-context cache).
// Each cold iteration leaves one entry in POCL_CACHE_DIR.
//
//   isk_bench --benchmark_filter='^OperatorTable/|^ProgramBuild/'
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <random>
#include <string>
#include <thread>

#include "bench_support.hpp"
#include "isk/composition_operator.hpp"

namespace isk::bench {
namespace {

namespace fs = std::filesystem;

void bakeTable(benchmark::State& state, CompositionOperator op) {
  size_t bytes = 0;
  for (auto _ : state) {
    const OperatorTable table = bakeOperatorTable(op);
    benchmark::DoNotOptimize(table.nodes.data());
    bytes = table.bytes();
  }
  state.counters["table_MiB"] = bytes / (1024.0 * 1024.0);
  state.SetLabel(
      "128^3, " +
      std::to_string(std::max(1u, std::thread::hardware_concurrency())) +
      " thread(s)");
}

void loadTable(benchmark::State& state, CompositionOperator op) {
  std::random_device random;
  const fs::path folder =
      fs::temp_directory_path() /
      ("isk-bench-operator-cache-" + std::to_string(::getpid()) + "-" +
       std::to_string(random()));
  const fs::path path = folder / operatorTableCacheFileName(op, 128);
  std::string error;
  if (!saveOperatorTable(bakeOperatorTable(op), path.string(), &error)) {
    state.SkipWithError(("cannot write the cache: " + error).c_str());
    fs::remove_all(folder);
    return;
  }
  size_t bytes = 0;
  bool ok = true;
  for (auto _ : state) {
    OperatorTable table;
    ok = loadOperatorTable(path.string(), op, 128, &table, &error) && ok;
    benchmark::DoNotOptimize(table.nodes.data());
    bytes = table.bytes();
  }
  fs::remove_all(folder);
  if (!ok) state.SkipWithError(("cache load failed: " + error).c_str());
  state.counters["table_MiB"] = bytes / (1024.0 * 1024.0);
  state.SetLabel("128^3, from " + operatorTableCacheFileName(op, 128));
}

// The extra build options the library uses for `kernel` on `device`.
std::string libraryOptions(const std::string& kernel,
                           const ClDeviceInfo& device) {
  if (kernel == "fields" || kernel == "tracking")
    return device.is_gpu ? "-DISK_FIELDS_IMAGE=1" : "-DISK_FIELDS_IMAGE=0";
  return "";
}

enum class BuildMode { kCold, kWarm, kInProcess };

void buildProgram(benchmark::State& state, const std::string& kernel,
                  int device, BuildMode mode) {
  const ClDeviceInfo& info = devices()[device];
  const std::string options = libraryOptions(kernel, info);
  // A token no earlier run used: pid, time and a random number.
  std::random_device random;
  const std::string run_token =
      std::to_string(::getpid()) + "_" +
      std::to_string(std::chrono::system_clock::now().time_since_epoch() /
                     std::chrono::microseconds(1)) +
      "_" + std::to_string(random());
  const std::string warm_options = options + " -DISK_BENCH_WARM=1";
  std::shared_ptr<ClContext> kept;
  if (mode == BuildMode::kWarm) {
    ClContext::create(std::to_string(device))->program(kernel, warm_options);
  } else if (mode == BuildMode::kInProcess) {
    kept = ClContext::create(std::to_string(device));
    kept->program(kernel, options);
  }
  int64_t i = 0;
  for (auto _ : state) {
    std::shared_ptr<ClContext> ctx = kept;
    std::string build_options = options;
    if (mode == BuildMode::kCold)
      build_options +=
          " -DISK_BENCH_COLD=" + run_token + "_" + std::to_string(i++);
    else if (mode == BuildMode::kWarm)
      build_options = warm_options;
    if (!ctx) {
      state.PauseTiming();
      ctx = ClContext::create(std::to_string(device));
      state.ResumeTiming();
    }
    benchmark::DoNotOptimize(ctx->program(kernel, build_options)());
    if (mode != BuildMode::kInProcess) {
      state.PauseTiming();
      ctx.reset();
      state.ResumeTiming();
    }
  }
  state.SetLabel(info.describe());
}

}  // namespace

void registerPrecomputeBenchmarks() {
  for (const CompositionOperator op :
       {CompositionOperator::kBlend, CompositionOperator::kBulge}) {
    const std::string prefix =
        std::string("OperatorTable/") + compositionOperatorName(op) + "/";
    registerGuarded((prefix + "bake").c_str(), bakeTable, op)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(3);
    registerGuarded((prefix + "cached-load").c_str(), loadTable, op)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(10);
  }
  for (const std::string& kernel : embeddedKernelNames()) {
    for (const ClDeviceInfo& device : devices()) {
      const std::string prefix = "ProgramBuild/" + kernel + "/";
      registerGuarded((prefix + onDevice("cold", device.index)).c_str(),
                      buildProgram, kernel, device.index, BuildMode::kCold)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime()
          ->Iterations(2);
      registerGuarded((prefix + onDevice("warm", device.index)).c_str(),
                      buildProgram, kernel, device.index, BuildMode::kWarm)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime()
          ->Iterations(3);
      registerGuarded((prefix + onDevice("in-process", device.index)).c_str(),
                      buildProgram, kernel, device.index, BuildMode::kInProcess)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime()
          ->MinTime(0.1);
    }
  }
}

}  // namespace isk::bench
