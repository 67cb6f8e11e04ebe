#include "test_support.hpp"

#include <map>
#include <mutex>
#include <random>

#include "data_folder.hpp"
#include "isk/import.hpp"
#include "isk/procedural.hpp"

namespace isk::test {

const std::vector<std::string>& assetNames() {
  static const std::vector<std::string> names = {
      "RiggedSimple.dae",    "anim_test.x",
      "CesiumMan.glb",       "human-addon-animations.glb",
      "RobotExpressive.glb", "animation_with_skeleton.fbx",
      "quad_skin.glb"};
  return names;
}

const Rig& loadAsset(const std::string& file) {
  static std::mutex mutex;
  static std::map<std::string, Rig> cache;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = cache.find(file);
  if (it == cache.end())
    it = cache.emplace(file, importRig(samples::dataFile(file))).first;
  return it->second;
}

const Rig& rigNamed(const std::string& name) {
  static std::mutex mutex;
  static std::map<std::string, Rig> builtins;
  for (const std::string& builtin : builtinRigNames()) {
    if (builtin != name) continue;
    std::lock_guard<std::mutex> lock(mutex);
    auto it = builtins.find(name);
    if (it == builtins.end())
      it = builtins.emplace(name, makeBuiltinRig(name)).first;
    return it->second;
  }
  return loadAsset(name);
}

const ImplicitFields& implicitFieldsOf(const std::string& name) {
  const Rig& rig = rigNamed(name);
  static std::mutex mutex;
  static std::map<std::string, ImplicitFields> cache;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = cache.find(name);
  if (it == cache.end())
    it = cache.emplace(name, buildImplicitFields(rig)).first;
  return it->second;
}

bool haveAssets() { return samples::dataFolderPresent(); }

std::string missingAssetsMessage(const std::string& what) {
  return "data folder '" + samples::dataFolder() +
         "' is absent (set ISK_DATA_DIR): skipped " + what +
         "; the procedural-rig tests check the same properties";
}

std::shared_ptr<ClContext> sharedContext() {
  static std::shared_ptr<ClContext> context = ClContext::create("");
  return context;
}

RowMismatch largestRowDistance(const Matrix3Xf& a, const Matrix3Xf& b) {
  RowMismatch result;
  if (a.rows() != b.rows()) {
    result.distance = std::numeric_limits<float>::infinity();
    return result;
  }
  for (int r = 0; r < a.rows(); ++r) {
    const float d = (a.row(r) - b.row(r)).norm();
    if (!(d <= result.distance)) {  // NaN counts as the worst
      result.distance =
          std::isnan(d) ? std::numeric_limits<float>::infinity() : d;
      result.row = r;
    }
  }
  return result;
}

ScopedTempDir::ScopedTempDir() {
  std::random_device random;
  path_ =
      std::filesystem::temp_directory_path() /
      ("isk_test_" + std::to_string(random()) + "_" + std::to_string(random()));
  std::filesystem::create_directories(path_);
}

ScopedTempDir::~ScopedTempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

}  // namespace isk::test
