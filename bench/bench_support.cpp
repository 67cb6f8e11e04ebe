#include "bench_support.hpp"

#include <map>

#include "data_folder.hpp"
#include "isk/import.hpp"
#include "isk/pose.hpp"
#include "isk/procedural.hpp"
#include "isk/subdivide.hpp"

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
      {"CesiumMan-x16", "CesiumMan.glb", 2},
      {"CesiumMan-x64", "CesiumMan.glb", 3},
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

std::shared_ptr<ClContext> context() {
  static std::shared_ptr<ClContext> ctx = ClContext::create("");
  return ctx;
}

bool available(const Model& model) {
  return model.file.empty() || samples::dataFolderPresent();
}

}  // namespace isk::bench
