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
// FieldBuild/<model>/cached-load: isk::buildImplicitFields with the field
// cache (isk/fields/field_cache.hpp) hitting: partition, samples + fits + grids
// read and validated from the cache file (written once before the loop into
// a temporary folder removed afterwards; in the OS page cache), composition
// and iso values; all threads. FieldBuild/<model>/threads:<n>
// (bench_fields.cpp) is the same build without the cache; the counter
// uncached_ms holds one uncached build measured in the same process, and
// speedup their ratio; read_ms, partition_ms and iso_ms split the cached
// load (the rest: composition and freeing the previous fields).
//
// Import/<asset>/<in-process|isolated>: isk::importRig of a shared asset
// (in the OS page cache) in the calling process, and in a child process
// with a time limit (ImportOptions::time_limit_seconds: fork, import,
// the rig sent back over a pipe). The isolated run's counters hold one
// in-process import measured in the same process (in_process_ms) and
// overhead_ms, the difference of the two medians of 5.
//
//   isk_bench
//   --benchmark_filter='^OperatorTable/|^ProgramBuild/|cached-load|^Import/'
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "bench_support.hpp"
#include "data_folder.hpp"
#include "isk/fields/composition_operator.hpp"
#include "isk/fields/field_cache.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/io/import.hpp"

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

void loadCachedFields(benchmark::State& state, const Model& model) {
  const Rig& rig = rigOf(model);
  std::random_device random;
  const fs::path folder =
      fs::temp_directory_path() /
      ("isk-bench-field-cache-" + std::to_string(::getpid()) + "-" +
       std::to_string(random()));
  ImplicitFieldsOptions options;
  options.cache = true;
  options.cache_folder = folder.string();
  // Uncached build (its time for the ratio), then the cache file.
  ImplicitFieldsOptions plain;
  const auto start = std::chrono::steady_clock::now();
  benchmark::DoNotOptimize(buildImplicitFields(rig, plain).iso_values.data());
  const double uncached_ms = std::chrono::duration<double, std::milli>(
                                 std::chrono::steady_clock::now() - start)
                                 .count();
  const ImplicitFields first = buildImplicitFields(rig, options);
  std::error_code ec;
  const double file_mib =
      fs::file_size(first.cache_file, ec) / (1024.0 * 1024.0);
  bool loaded = true;
  double total = 0, load = 0, iso = 0, partition = 0;
  int64_t n = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const ImplicitFields fields = buildImplicitFields(rig, options);
    total += std::chrono::duration<double, std::milli>(
                 std::chrono::steady_clock::now() - t0)
                 .count();
    ++n;
    load += fields.times.sampling_ms;  // the cache read, when loaded
    iso += fields.times.iso_ms;
    partition += fields.times.partition_ms;
    loaded = loaded && fields.cache_origin == FieldCacheOrigin::kLoaded;
    benchmark::DoNotOptimize(fields.iso_values.data());
  }
  fs::remove_all(folder, ec);
  if (!loaded) {
    state.SkipWithError("the field cache did not hit");
    return;
  }
  state.counters["uncached_ms"] = uncached_ms;
  state.counters["speedup"] = n > 0 ? uncached_ms / (total / n) : 0;
  state.counters["file_MiB"] = file_mib;
  if (n > 0) {
    state.counters["read_ms"] = load / n;
    state.counters["iso_ms"] = iso / n;
    state.counters["partition_ms"] = partition / n;
  }
  state.counters["fields"] = first.grids.fieldCount();
  state.SetLabel("from " + fieldCacheFileName(rig, options));
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

double medianImportMs(const std::string& path, const ImportOptions& options) {
  std::vector<double> ms;
  for (int i = 0; i < 5; ++i) {
    const auto start = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(importRig(path, options).mesh.positions.data());
    ms.push_back(std::chrono::duration<double, std::milli>(
                     std::chrono::steady_clock::now() - start)
                     .count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[2];
}

void importAsset(benchmark::State& state, Model model, bool isolated) {
  const std::string path = samples::dataFile(model.file);
  ImportOptions options;
  if (isolated) options.time_limit_seconds = 600;
  int vertices = 0;
  for (auto _ : state) {
    vertices = importRig(path, options).mesh.vertexCount();
  }
  state.counters["vertices"] = vertices;
  if (isolated) {
    const double in_process = medianImportMs(path, {});
    state.counters["in_process_ms"] = in_process;
    state.counters["overhead_ms"] = medianImportMs(path, options) - in_process;
  }
}

void registerPrecomputeBenchmarks() {
  for (const Model& model : models()) {
    if (model.file.empty() || model.subdivision_levels > 0 ||
        !available(model)) {
      continue;
    }
    for (const bool isolated : {false, true}) {
      registerGuarded(
          "Import/" + model.name + (isolated ? "/isolated" : "/in-process"),
          importAsset, model, isolated)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
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
  for (const Model& model : models()) {
    if (!available(model)) continue;
    registerGuarded(("FieldBuild/" + model.name + "/cached-load").c_str(),
                    loadCachedFields, model)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
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
