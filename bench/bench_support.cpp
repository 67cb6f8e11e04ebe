#include "bench_support.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <mutex>

#include "data_folder.hpp"
#include "isk/io/import.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/procedural.hpp"
#include "isk/tools/subdivide.hpp"

namespace isk::bench {

const std::vector<Model>& models() {
  static const std::vector<Model> list = {
      {"builtin-arm", "", 0},
      {"RiggedSimple", "RiggedSimple.dae", 0},
      {"anim_test", "anim_test.x", 0},
      {"CesiumMan", "CesiumMan.glb", 0},
      {"animation_with_skeleton", "animation_with_skeleton.fbx", 0},
      {"RobotExpressive", "RobotExpressive.glb", 0},
      {"human-addon", "human-addon-animations.glb", 0},
      {"fox", "fox-animations.glb", 0},
      {"horse", "horse-animations.glb", 0},
      {"dragon", "dragon-animations.glb", 0},
      {"CesiumMan-x16", "CesiumMan.glb", 2},
      {"CesiumMan-x64", "CesiumMan.glb", 3},
      {"human-addon-x4", "human-addon-animations.glb", 1},
      {"human-addon-x16", "human-addon-animations.glb", 2},
  };
  return list;
}

const Rig& rigOf(const Model& model) {
  static std::map<std::string, std::unique_ptr<Rig>> cache;
  auto& slot = cache[model.name];
  if (!slot) {
    Rig rig = model.file.empty() ? makeBuiltinRig("arm")
                                 : importRig(samples::dataFile(model.file));
    slot = std::make_unique<Rig>(subdivideRig(rig, model.subdivision_levels));
  }
  return *slot;
}

int clipFrameCount(const Rig& rig) {
  if (rig.clips.empty()) return 1;
  return std::max(1, static_cast<int>(rig.clips.front().duration * 30.0) + 1);
}

TransformList poseAt(const Rig& rig, int64_t frame) {
  if (rig.clips.empty()) return bindPoseSkinning(rig.skeleton);
  const AnimationClip& clip = rig.clips.front();
  const double t = clip.start + (frame % clipFrameCount(rig)) / 30.0;
  return skinningTransforms(
      rig.skeleton,
      globalTransforms(rig.skeleton, clip.sampleLocal(rig.skeleton, t)));
}

const std::vector<ClDeviceInfo>& devices() {
  static const std::vector<ClDeviceInfo> list = [] {
    const std::vector<ClDeviceInfo> found = listClDevices();
    for (const ClDeviceInfo& d : found) {
      const std::string key = "isk_device_" + std::to_string(d.index);
      benchmark::AddCustomContext(key, d.describe());
      benchmark::AddCustomContext(key + "_type", d.is_gpu   ? "gpu"
                                                 : d.is_cpu ? "cpu"
                                                            : "other");
    }
    return found;
  }();
  return list;
}

std::shared_ptr<ClContext> context(int device) {
  static std::mutex mutex;
  static std::map<int, std::shared_ptr<ClContext>> contexts;
  std::lock_guard<std::mutex> lock(mutex);
  auto& slot = contexts[device];
  if (!slot) slot = ClContext::create(std::to_string(device));
  return slot;
}

std::string onDevice(const std::string& backend, int device) {
  return backend + ":" + std::to_string(device);
}

const Rig& scalingRig(int vertices, int bones) {
  static std::map<std::pair<int, int>, std::unique_ptr<Rig>> cache;
  auto& slot = cache[{vertices, bones}];
  if (!slot) {
    CylinderRigOptions options;
    options.bones = bones;
    options.radius = 1.f;
    options.length = 3.f * bones;
    // Ring spacing = segment spacing (length / rings = 2 pi radius /
    // segments) with rings * segments = vertices, then rings lowered for
    // the two caps (segments / 8 rings of `segments` vertices each).
    const double two_pi = 6.283185307179586;
    options.segments = std::max(8, static_cast<int>(std::lround(std::sqrt(
                                       vertices * two_pi / options.length))));
    const int cap_vertices = 2 * (options.segments / 8) * options.segments;
    options.rings = std::max(2, (vertices - cap_vertices) / options.segments);
    slot = std::make_unique<Rig>(makeCylinderRig(options));
  }
  return *slot;
}

double spread(int64_t i) {
  const double x = static_cast<double>(i) * 0.6180339887498949;
  return x - std::floor(x);
}

TransformList zigzagPose(const Rig& rig, int64_t frame) {
  const Skeleton& skeleton = rig.skeleton;
  const float degrees = 30.f + 20.f * static_cast<float>(spread(frame));
  const float angle = degrees * 3.14159265358979f / 180.f;
  TransformList locals;
  locals.reserve(skeleton.joints.size());
  for (int j = 0; j < skeleton.jointCount(); ++j) {
    Eigen::Affine3f local = skeleton.joints[j].rest_local;
    // Joint 0 is the root (moving it is rigid); the tip carries no weight.
    if (j > 0 && skeleton.joints[j].is_skin_joint) {
      const float sign = (j % 2) ? 1.f : -1.f;
      local.rotate(Eigen::AngleAxisf(sign * angle, Eigen::Vector3f::UnitZ()));
    }
    locals.push_back(local);
  }
  return skinningTransforms(skeleton, globalTransforms(skeleton, locals));
}

bool available(const Model& model) {
  return model.file.empty() || samples::dataFolderPresent();
}

}  // namespace isk::bench
