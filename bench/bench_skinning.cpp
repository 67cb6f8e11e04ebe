// Per-frame geometric skinning (LBS, DQS) on every OpenCL device against the
// single-thread CPU reference, on the shared assets and on CesiumMan and
// human-addon subdivided.
//
//   Frame/opencl:<d>/<model>/<lbs|dqs>, Frame/reference/<model>/<lbs|dqs>
//
// A frame = pose from the clip -> upload joint transforms -> skinning kernel
// -> normals kernel -> read back positions and normals. Counters give the
// per-stage device times (OpenCL profiling events) averaged over iterations.
//
//   isk_bench --benchmark_filter='^Frame/'    (docs/performance.md)
#include <benchmark/benchmark.h>

#include <string>

#include "bench_support.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/skinning/cpu_skinning.hpp"

namespace isk::bench {
namespace {

void skinOpenCl(benchmark::State& state, const Model& model, int device,
                SkinningMethod method) {
  const Rig& rig = rigOf(model);
  ClSkinning skinning(context(device), rig.mesh, rig.weights,
                      rig.skeleton.jointCount());
  Matrix3Xf positions, normals;
  // PoCL compiles a kernel at its first launch: keep that out of the loop.
  skinning.run(method, poseAt(rig, 0), true);
  double upload = 0, skin = 0, normal = 0, readback = 0;
  int64_t frame = 0;
  for (auto _ : state) {
    skinning.run(method, poseAt(rig, frame++), true);
    skinning.readPositions(positions);
    skinning.readNormals(normals);
    benchmark::DoNotOptimize(positions.data());
    const SkinningStageTimes& t = skinning.lastTimes();
    upload += t.upload_ms;
    skin += t.skinning_ms;
    normal += t.normals_ms;
    readback += t.readback_ms;
  }
  const double n = static_cast<double>(std::max<int64_t>(frame, 1));
  state.counters["vertices"] = rig.mesh.vertexCount();
  state.counters["upload_ms"] = upload / n;
  state.counters["skinning_ms"] = skin / n;
  state.counters["normals_ms"] = normal / n;
  state.counters["readback_ms"] = readback / n;
  state.counters["fps"] = benchmark::Counter(static_cast<double>(frame),
                                             benchmark::Counter::kIsRate);
  state.SetLabel(devices()[device].describe());
}

void skinReference(benchmark::State& state, const Model& model,
                   SkinningMethod method) {
  const Rig& rig = rigOf(model);
  CpuSkinning skinning(rig.mesh, rig.weights, rig.skeleton.jointCount());
  int64_t frame = 0;
  for (auto _ : state) {
    skinning.run(method, poseAt(rig, frame++), true);
    benchmark::DoNotOptimize(skinning.normals().data());
  }
  state.counters["vertices"] = rig.mesh.vertexCount();
  state.counters["fps"] = benchmark::Counter(static_cast<double>(frame),
                                             benchmark::Counter::kIsRate);
  state.SetLabel("CPU reference, 1 thread");
}

}  // namespace

void registerSkinningBenchmarks() {
  for (const Model& model : models()) {
    if (!available(model)) continue;
    for (auto method :
         {SkinningMethod::kLinearBlend, SkinningMethod::kDualQuaternion}) {
      const std::string suffix = model.name + "/" + skinningMethodName(method);
      for (const ClDeviceInfo& device : devices())
        registerGuarded(
            ("Frame/" + onDevice("opencl", device.index) + "/" + suffix)
                .c_str(),
            skinOpenCl, model, device.index, method)
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime();
      registerGuarded(("Frame/reference/" + suffix).c_str(), skinReference,
                      model, method)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
}

}  // namespace isk::bench
