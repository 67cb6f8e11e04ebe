// Shared pieces of the benchmark suite: the models benchmarked, their rigs
// (cached), poses from their clips, the procedural rigs of the scaling
// series with their bend pose, and one OpenCL context per device.
//
// Benchmark names (bench/run_benchmarks.py parses them; Google Benchmark
// appends its own /min_time:..., /iterations:..., /real_time parts):
//   an OpenCL benchmark names its device as "<backend>:<d>", d the index in
//   isk::listClDevices() (ClContext::create("d") selects it); its label is
//   the device's "platform / name". The JSON context carries every device as
//   isk_device_<d> ("platform / name") and isk_device_<d>_type (gpu, cpu or
//   other).
#pragma once

#include <benchmark/benchmark.h>

#include <exception>
#include <memory>
#include <string>
#include <vector>

#include "isk/cl/runtime.hpp"
#include "isk/core/types.hpp"
#include "isk/rig/rig.hpp"

namespace isk::bench {

struct Model {
  std::string name;
  std::string file;  // in the data folder, empty for procedural
  int subdivision_levels = 0;
};

// The builtin arm, every shared asset, CesiumMan subdivided 1-to-4 twice
// and three times (about 38k and 152k vertices) and human-addon once and
// twice (about 31k and 125k vertices).
const std::vector<Model>& models();
// Whether the model can run (asset models need the data folder).
bool available(const Model& model);
const Rig& rigOf(const Model& model);
// Frames of the rig's first clip at 30 fps (1 without a clip).
int clipFrameCount(const Rig& rig);
// Skinning transforms of frame `frame` (modulo clipFrameCount) of the rig's
// first clip.
TransformList poseAt(const Rig& rig, int64_t frame);

// The OpenCL devices benchmarked: every device of listClDevices().
const std::vector<ClDeviceInfo>& devices();
// A context on device `device` (index in devices()), created once.
std::shared_ptr<ClContext> context(int device);
// "<backend>:<device>", the name part of an OpenCL benchmark.
std::string onDevice(const std::string& backend, int device);

// A procedural cylinder of the scaling series: `bones` bones of length 3
// and radius 1 along +x, about `vertices` vertices with nearly square
// triangles (cached).
const Rig& scalingRig(int vertices, int bones);
// Every inner joint of a chain bent about z by an angle between 30 and 50
// degrees that changes with `frame`, alternately up and down (a zigzag that
// never folds the chain onto itself): skinning transforms.
TransformList zigzagPose(const Rig& rig, int64_t frame);

// The i-th of a sequence of numbers spread over [0, 1) (golden ratio).
double spread(int64_t i);

// benchmark::RegisterBenchmark(name, fn, args...) with fn(state, args...)
// run inside a try block: an exception (a kernel that fails to build on one
// device, a model that fails to load) skips that benchmark with its message
// instead of ending the whole suite.
template <class Fn, class... Args>
benchmark::internal::Benchmark* registerGuarded(const std::string& name, Fn fn,
                                                Args... args) {
  return benchmark::RegisterBenchmark(name.c_str(),
                                      [fn, args...](benchmark::State& state) {
                                        try {
                                          fn(state, args...);
                                        } catch (const std::exception& e) {
                                          state.SkipWithError(e.what());
                                        }
                                      });
}

void registerSkinningBenchmarks();
void registerFieldBenchmarks();
void registerImplicitBenchmarks();
void registerPrecomputeBenchmarks();

}  // namespace isk::bench
