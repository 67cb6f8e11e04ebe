// Implicit skinning per frame (Vaillant et al. 2013, surface tracking of
// section 5) against DQS on the same device and against the single-thread
// CPU reference, on the shared assets and on CesiumMan subdivided to about
// 40k and 150k vertices (the paper's Table 1 has a 31,750-vertex hand and
// the 172,974-vertex Armadillo).
//
// Implicit/<model>/opencl: a frame = pose from the clip -> ImplicitSkinner::
// run (upload, DQS, projection and relaxation rounds, smoothing, normals) ->
// read back positions and normals. Counters give the per-stage times
// (OpenCL profiling events; readback is host wall time) averaged over
// iterations, and the vertices stopped at a contact (and at a crease, and
// lost) per frame, counted with the timer paused.
// Implicit/<model>/dqs: the same frame with isk::ClSkinning (DQS, normals
// recomputed, reads) on the same device, so that implicit / DQS is a ratio
// measured in one process.
// Implicit/<model>/reference: isk::CpuImplicitSkinner (1 thread).
//
// The fields (union at every joint, the library's default) are built once
// per model, outside the timing; PoCL compiles a kernel at its first launch,
// so one frame runs before the timed loop. Frames are independent (tracking
// starts from the skinned pose every frame), so the timed frames step through
// the clip by the golden ratio: the few frames of a large model's run are
// spread over the whole clip, and the three backends see the same sequence.
//
//   isk_bench --benchmark_filter='^Implicit/'
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "bench_support.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/implicit_skinner.hpp"

namespace isk::bench {
namespace {

// Minimum time per benchmark: the whole family takes about 2 minutes on 2 CPU
// cores (CesiumMan-x64: 13 to 20 frames per backend).
constexpr double kMinTimeS = 2.0;

// The clip frame of the i-th timed frame.
int64_t spreadFrame(const Rig& rig, int64_t i) {
  const double golden = 0.6180339887498949;
  const double x = static_cast<double>(i) * golden;
  return static_cast<int64_t>((x - std::floor(x)) * clipFrameCount(rig));
}

std::shared_ptr<const ImplicitFields> implicitFieldsOf(const Model& model) {
  static std::map<std::string, std::shared_ptr<const ImplicitFields>> cache;
  auto& slot = cache[model.name];
  if (!slot)
    slot = std::make_shared<const ImplicitFields>(
        buildImplicitFields(rigOf(model), {}));
  return slot;
}

struct StageSums {
  double upload = 0, skinning = 0, projection = 0, relaxation = 0,
         smoothing = 0, normals = 0, readback = 0;
  void add(const ImplicitStageTimes& t) {
    upload += t.upload_ms;
    skinning += t.skinning_ms;
    projection += t.tracking.projection_ms;
    relaxation += t.tracking.relaxation_ms;
    smoothing += t.tracking.smoothing_ms;
    normals += t.tracking.normals_ms;
    readback += t.readback_ms;
  }
};

struct CountSums {
  double contact = 0, crease = 0, lost = 0;
  int tracked = 0;
  void add(const TrackingCounts& c, int vertices) {
    contact += c.contact;
    crease += c.crease;
    lost += c.lost;
    tracked = vertices - c.untracked;
  }
};

void setCounters(benchmark::State& state, const Rig& rig, int64_t frames,
                 const StageSums& t, const CountSums& c) {
  const double n = static_cast<double>(std::max<int64_t>(frames, 1));
  state.counters["vertices"] = rig.mesh.vertexCount();
  state.counters["tracked"] = c.tracked;
  state.counters["contact"] = c.contact / n;
  state.counters["crease"] = c.crease / n;
  state.counters["lost"] = c.lost / n;
  state.counters["upload_ms"] = t.upload / n;
  state.counters["skinning_ms"] = t.skinning / n;
  state.counters["projection_ms"] = t.projection / n;
  state.counters["relaxation_ms"] = t.relaxation / n;
  state.counters["smoothing_ms"] = t.smoothing / n;
  state.counters["normals_ms"] = t.normals / n;
  state.counters["readback_ms"] = t.readback / n;
  state.counters["fps"] = benchmark::Counter(static_cast<double>(frames),
                                             benchmark::Counter::kIsRate);
}

void implicitOpenCl(benchmark::State& state, const Model& model) {
  const Rig& rig = rigOf(model);
  ImplicitSkinner skinner(context(), rig, implicitFieldsOf(model));
  Matrix3Xf positions, normals;
  std::vector<TrackState> states;
  skinner.run(poseAt(rig, 0));  // PoCL compiles at the first launch
  StageSums times;
  CountSums counts;
  int64_t frame = 0;
  for (auto _ : state) {
    skinner.run(poseAt(rig, spreadFrame(rig, frame++)));
    skinner.readPositions(positions);
    skinner.readNormals(normals);
    benchmark::DoNotOptimize(positions.data());
    benchmark::DoNotOptimize(normals.data());
    times.add(skinner.lastTimes());
    state.PauseTiming();
    skinner.tracking().readStates(states);
    counts.add(countStates(states), skinner.vertexCount());
    state.ResumeTiming();
  }
  setCounters(state, rig, frame, times, counts);
  state.SetLabel(context()->info().describe());
}

void dqsOpenCl(benchmark::State& state, const Model& model) {
  const Rig& rig = rigOf(model);
  ClSkinning skinning(context(), rig.mesh, rig.weights,
                      rig.skeleton.jointCount());
  Matrix3Xf positions, normals;
  skinning.run(SkinningMethod::kDualQuaternion, poseAt(rig, 0), true);
  StageSums times;
  int64_t frame = 0;
  for (auto _ : state) {
    skinning.run(SkinningMethod::kDualQuaternion,
                 poseAt(rig, spreadFrame(rig, frame++)), true);
    skinning.readPositions(positions);
    skinning.readNormals(normals);
    benchmark::DoNotOptimize(positions.data());
    benchmark::DoNotOptimize(normals.data());
    const SkinningStageTimes& t = skinning.lastTimes();
    times.upload += t.upload_ms;
    times.skinning += t.skinning_ms;
    times.normals += t.normals_ms;
    times.readback += t.readback_ms;
  }
  setCounters(state, rig, frame, times, CountSums{});
  state.SetLabel(context()->info().describe());
}

void implicitReference(benchmark::State& state, const Model& model) {
  const Rig& rig = rigOf(model);
  CpuImplicitSkinner skinner(rig, implicitFieldsOf(model));
  StageSums times;
  CountSums counts;
  int64_t frame = 0;
  for (auto _ : state) {
    skinner.run(poseAt(rig, spreadFrame(rig, frame++)));
    benchmark::DoNotOptimize(skinner.positions().data());
    benchmark::DoNotOptimize(skinner.normals().data());
    times.add(skinner.lastTimes());
    counts.add(countStates(skinner.tracking().states()), skinner.vertexCount());
  }
  setCounters(state, rig, frame, times, counts);
  state.SetLabel("CPU reference, 1 thread");
}

}  // namespace

void registerImplicitBenchmarks() {
  for (const Model& model : models()) {
    if (!available(model)) continue;
    const std::string prefix = "Implicit/" + model.name + "/";
    benchmark::RegisterBenchmark((prefix + "opencl").c_str(), implicitOpenCl,
                                 model)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->MinTime(kMinTimeS);
    benchmark::RegisterBenchmark((prefix + "dqs").c_str(), dqsOpenCl, model)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->MinTime(kMinTimeS);
    benchmark::RegisterBenchmark((prefix + "reference").c_str(),
                                 implicitReference, model)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->MinTime(kMinTimeS);
  }
}

}  // namespace isk::bench
