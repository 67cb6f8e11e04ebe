// Per-frame geometric skinning (LBS, DQS) on the OpenCL device against the
// single-thread CPU reference, on the shared assets and on CesiumMan
// subdivided to about 40k and 150k vertices.
//
// A frame = pose from the clip -> upload joint transforms -> skinning kernel
// -> normals kernel -> read back positions and normals. Counters give the
// per-stage device times (OpenCL profiling events) averaged over iterations.
//
//   isk_bench --benchmark_filter='CesiumMan'    (see bench/README.md)
#include <benchmark/benchmark.h>

#include <cstdio>
#include <map>
#include <memory>
#include <string>

#include "data_folder.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/cpu_skinning.hpp"
#include "isk/import.hpp"
#include "isk/pose.hpp"
#include "isk/procedural.hpp"
#include "isk/subdivide.hpp"

namespace {

struct Model {
  std::string name;
  std::string file;  // in the data folder, empty for procedural
  int subdivision_levels = 0;
};

const std::vector<Model>& models() {
  static const std::vector<Model> list = {
      {"builtin-arm", "", 0},
      {"RiggedSimple", "RiggedSimple.dae", 0},
      {"anim_test", "anim_test.x", 0},
      {"CesiumMan", "CesiumMan.glb", 0},
      {"animation_with_skeleton", "animation_with_skeleton.fbx", 0},
      {"RobotExpressive", "RobotExpressive.glb", 0},
      {"human-addon", "human-addon-animations.glb", 0},
      {"CesiumMan-x16", "CesiumMan.glb", 2},
      {"CesiumMan-x64", "CesiumMan.glb", 3},
  };
  return list;
}

const isk::Rig& rigOf(const Model& model) {
  static std::map<std::string, std::unique_ptr<isk::Rig>> cache;
  auto& slot = cache[model.name];
  if (!slot) {
    isk::Rig rig = model.file.empty()
                       ? isk::makeBuiltinRig("arm")
                       : isk::importRig(isk::samples::dataFile(model.file));
    slot = std::make_unique<isk::Rig>(
        isk::subdivideRig(rig, model.subdivision_levels));
  }
  return *slot;
}

// Skinning transforms of frame `frame` of the rig's first clip (30 fps).
isk::TransformList poseAt(const isk::Rig& rig, int64_t frame) {
  if (rig.clips.empty()) return isk::bindPoseSkinning(rig.skeleton);
  const isk::AnimationClip& clip = rig.clips.front();
  const int frames = std::max(1, static_cast<int>(clip.duration * 30.0) + 1);
  const double t = clip.start + (frame % frames) / 30.0;
  return isk::skinningTransforms(
      rig.skeleton,
      isk::globalTransforms(rig.skeleton, clip.sampleLocal(rig.skeleton, t)));
}

std::shared_ptr<isk::ClContext> context() {
  static std::shared_ptr<isk::ClContext> ctx = isk::ClContext::create("");
  return ctx;
}

void skinOpenCl(benchmark::State& state, const Model& model,
                isk::SkinningMethod method) {
  const isk::Rig& rig = rigOf(model);
  isk::ClSkinning skinning(context(), rig.mesh, rig.weights,
                           rig.skeleton.jointCount());
  isk::Matrix3Xf positions, normals;
  double upload = 0, skin = 0, normal = 0, readback = 0;
  int64_t frame = 0;
  for (auto _ : state) {
    skinning.run(method, poseAt(rig, frame++), true);
    skinning.readPositions(positions);
    skinning.readNormals(normals);
    benchmark::DoNotOptimize(positions.data());
    const isk::SkinningStageTimes& t = skinning.lastTimes();
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
  state.SetLabel(context()->info().describe());
}

void skinReference(benchmark::State& state, const Model& model,
                   isk::SkinningMethod method) {
  const isk::Rig& rig = rigOf(model);
  isk::CpuSkinning skinning(rig.mesh, rig.weights, rig.skeleton.jointCount());
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

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  const bool have_data = isk::samples::dataFolderPresent();
  if (!have_data) {
    std::fprintf(
        stderr,
        "data folder '%s' is absent (set ISK_DATA_DIR): only the builtin rig "
        "is benchmarked\n",
        isk::samples::dataFolder().c_str());
  }
  for (const Model& model : models()) {
    if (!model.file.empty() && !have_data) continue;
    for (auto method : {isk::SkinningMethod::kLinearBlend,
                        isk::SkinningMethod::kDualQuaternion}) {
      const std::string suffix =
          model.name + "/" + isk::skinningMethodName(method);
      benchmark::RegisterBenchmark(("Frame/opencl/" + suffix).c_str(),
                                   skinOpenCl, model, method)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
      benchmark::RegisterBenchmark(("Frame/reference/" + suffix).c_str(),
                                   skinReference, model, method)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
