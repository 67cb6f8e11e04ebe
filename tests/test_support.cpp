#include "test_support.hpp"

// stb_image decodes the pictures of the sample tests: compiled once, here.
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#define STBI_ONLY_PNG
#include <stb/stb_image.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <random>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "data_folder.hpp"
#include "isk/io/import.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/procedural.hpp"

namespace isk::test {

const std::vector<std::string>& allAssetNames() {
  static const std::vector<std::string> names = {
      "RiggedSimple.dae",     "anim_test.x",
      "CesiumMan.glb",        "human-addon-animations.glb",
      "RobotExpressive.glb",  "animation_with_skeleton.fbx",
      "quad_skin.glb",        "fox-animations.glb",
      "horse-animations.glb", "dragon-animations.glb",
      "human-female.glb"};
  return names;
}

std::vector<std::string> assetSelection(const char* list) {
  if (list == nullptr || *list == '\0') return allAssetNames();
  std::vector<std::string> chosen;
  std::stringstream stream(list);
  for (std::string name; std::getline(stream, name, ',');) {
    if (name.empty()) continue;
    const std::vector<std::string>& all = allAssetNames();
    if (std::find(all.begin(), all.end(), name) == all.end()) {
      std::string known;
      for (const std::string& asset : all) known += " " + asset;
      throw std::invalid_argument(
          std::string(kAssetSelectionVariable) + " names '" + name +
          "', which is not a test asset; they are:" + known);
    }
    chosen.push_back(name);
  }
  return chosen;
}

std::vector<std::string> assetNames() {
  const std::vector<std::string> chosen =
      assetSelection(std::getenv(kAssetSelectionVariable));
  std::vector<std::string> names;
  for (const std::string& name : allAssetNames()) {
    if (std::find(chosen.begin(), chosen.end(), name) != chosen.end())
      names.push_back(name);
    else
      std::cout << "[ left out ] " << name << ": not in "
                << kAssetSelectionVariable << "\n";
  }
  return names;
}

std::vector<std::string> assetNamesExcept(
    const std::vector<LeftOutAsset>& left_out) {
  std::vector<std::string> names;
  for (const std::string& name : assetNames()) {
    bool kept = true;
    for (const LeftOutAsset& out : left_out)
      if (out.name == name) {
        std::cout << "[ left out ] " << name << ": " << out.reason << "\n";
        kept = false;
      }
    if (kept) names.push_back(name);
  }
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

RigWithFields withDefaultFields(Rig rig) {
  RigWithFields out;
  out.rig = std::move(rig);
  out.fields = std::make_shared<const ImplicitFields>(
      buildImplicitFields(out.rig, ImplicitFieldsOptions()));
  return out;
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

Matrix3Xf positionsOf(const std::vector<Eigen::Vector3f>& points) {
  Matrix3Xf positions(static_cast<int>(points.size()), 3);
  for (size_t v = 0; v < points.size(); ++v)
    positions.row(v) = points[v].transpose();
  return positions;
}

TriangleMatrix trianglesOf(const std::vector<Eigen::Vector3i>& corners) {
  TriangleMatrix triangles(static_cast<int>(corners.size()), 3);
  for (size_t f = 0; f < corners.size(); ++f)
    triangles.row(f) = corners[f].transpose();
  return triangles;
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

std::string shellQuote(const std::string& arg) {
  std::string quoted = "'";
  for (char c : arg) {
    if (c == '\'') {
      quoted += "'\\''";
    } else {
      quoted += c;
    }
  }
  return quoted + "'";
}

RunOutput runProgram(const std::string& program,
                     const std::vector<std::string>& args,
                     const std::string& environment) {
  std::string command = environment + shellQuote(program);
  for (const std::string& arg : args) command += " " + shellQuote(arg);
  command += " 2>&1";
  RunOutput result;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) {
    ADD_FAILURE() << "popen failed: " << command;
    return result;
  }
  char buffer[4096];
  size_t n;
  while ((n = fread(buffer, 1, sizeof(buffer), pipe)) > 0) {
    result.output.append(buffer, n);
  }
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

std::string describeRun(const std::string& name,
                        const std::vector<std::string>& args,
                        const RunOutput& run) {
  std::string text = name;
  for (const std::string& arg : args) text += " " + arg;
  return text + "\nexit " + std::to_string(run.exit_code) + ", output:\n" +
         run.output;
}

ScopedEnv::ScopedEnv(const char* name, const char* value) : name_(name) {
  if (const char* old = std::getenv(name)) old_ = old;
  if (value) {
    ::setenv(name, value, 1);
  } else {
    ::unsetenv(name);
  }
}

ScopedEnv::~ScopedEnv() {
  if (old_) {
    ::setenv(name_.c_str(), old_->c_str(), 1);
  } else {
    ::unsetenv(name_.c_str());
  }
}

std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string colladaTriangle(const std::string& indices) {
  return R"(<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries>
    <geometry id="tri-mesh" name="tri">
      <mesh>
        <source id="tri-positions">
          <float_array id="tri-positions-array" count="9">0 0 0 1 0 0 0 1 0</float_array>
          <technique_common>
            <accessor source="#tri-positions-array" count="3" stride="3">
              <param name="X" type="float"/><param name="Y" type="float"/>
              <param name="Z" type="float"/>
            </accessor>
          </technique_common>
        </source>
        <vertices id="tri-vertices">
          <input semantic="POSITION" source="#tri-positions"/>
        </vertices>
        <triangles count="1">
          <input semantic="VERTEX" source="#tri-vertices" offset="0"/>
          <p>)" +
         indices +
         R"(</p>
        </triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="Scene" name="Scene">
      <node id="tri" name="tri"><instance_geometry url="#tri-mesh"/></node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#Scene"/></scene>
</COLLADA>
)";
}

namespace {

uint32_t bigEndian32(const std::string& bytes, size_t at) {
  uint32_t v = 0;
  for (size_t i = 0; i < 4; ++i) {
    v = (v << 8) | static_cast<uint8_t>(bytes[at + i]);
  }
  return v;
}

}  // namespace

PngHeader parsePngHeader(const std::string& bytes) {
  static const std::string kSignature("\x89PNG\r\n\x1a\n", 8);
  PngHeader header;
  if (bytes.size() < 33 || bytes.compare(0, 8, kSignature) != 0) return header;
  // The first chunk: length 13, type IHDR, width, height, ...
  if (bigEndian32(bytes, 8) != 13 || bytes.compare(12, 4, "IHDR") != 0) {
    return header;
  }
  header.width = bigEndian32(bytes, 16);
  header.height = bigEndian32(bytes, 20);
  header.valid = true;
  return header;
}

namespace {

std::string trim(const std::string& text) {
  const size_t first = text.find_first_not_of(' ');
  if (first == std::string::npos) return "";
  return text.substr(first, text.find_last_not_of(' ') - first + 1);
}

}  // namespace

// The body rows of the markdown table whose header line starts with
// `header`, as trimmed cells; empty when there is no such table.
std::vector<std::vector<std::string>> tableRows(const std::string& text,
                                                const std::string& header) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(text);
  std::string line;
  bool in_table = false;
  int skip = 0;
  while (std::getline(in, line)) {
    if (!in_table) {
      if (line.rfind(header, 0) == 0) {
        in_table = true;
        skip = 1;  // the |---| line
      }
      continue;
    }
    if (line.empty() || line[0] != '|') break;
    if (skip > 0) {
      --skip;
      continue;
    }
    std::vector<std::string> cells;
    std::istringstream row(line.substr(1));
    std::string cell;
    while (std::getline(row, cell, '|')) cells.push_back(trim(cell));
    rows.push_back(cells);
  }
  return rows;
}

// The number a cell spells; NaN when it is not entirely a number.
double number(const std::string& cell) {
  char* end = nullptr;
  const double value = std::strtod(cell.c_str(), &end);
  return (cell.empty() || *end != '\0') ? std::nan("") : value;
}

TransformList bendAt(const Rig& rig, int joint, double degrees,
                     const Eigen::Vector3f& axis) {
  const Skeleton& skeleton = rig.skeleton;
  const Eigen::Vector3f pivot = skeleton.bindGlobals()[joint].translation();
  const Eigen::Affine3f turn =
      Eigen::Translation3f(pivot) *
      Eigen::AngleAxisf(
          static_cast<float>(degrees * 3.14159265358979323846 / 180), axis) *
      Eigen::Translation3f(-pivot);
  TransformList skinning(skeleton.jointCount(), Eigen::Affine3f::Identity());
  for (int j = 0; j < skeleton.jointCount(); ++j) {
    int a = j;
    while (a >= 0 && a != joint) a = skeleton.joints[a].parent;
    if (a == joint) skinning[j] = turn;
  }
  return skinning;
}

TransformList everyJointBent(const Rig& rig, double degrees) {
  const AnimationClip bend = makeBendClip(
      rig.skeleton, static_cast<float>(degrees * 3.14159265358979323846 / 180));
  return skinningTransforms(
      rig.skeleton,
      globalTransforms(rig.skeleton,
                       bend.sampleLocal(rig.skeleton, bend.duration)));
}

std::vector<TransformList> clipPoses(const Rig& rig, int frames) {
  std::vector<TransformList> poses;
  const AnimationClip clip =
      rig.clips.empty() ? makeBendClip(rig.skeleton, 1.5f) : rig.clips.front();
  for (int f = 0; f < frames; ++f) {
    const double t = clip.start + clip.duration * f / std::max(frames - 1, 1);
    poses.push_back(skinningTransforms(
        rig.skeleton,
        globalTransforms(rig.skeleton, clip.sampleLocal(rig.skeleton, t))));
  }
  return poses;
}

DecodedPng decodePng(const std::string& bytes, const std::string& what) {
  DecodedPng png;
  int channels = 0;
  stbi_uc* pixels = stbi_load_from_memory(
      reinterpret_cast<const stbi_uc*>(bytes.data()),
      static_cast<int>(bytes.size()), &png.width, &png.height, &channels, 3);
  if (!pixels) {
    ADD_FAILURE() << what
                  << ": stb_image cannot decode it: " << stbi_failure_reason();
    return DecodedPng{};
  }
  png.rgb.assign(pixels, pixels + size_t(png.width) * png.height * 3);
  stbi_image_free(pixels);
  return png;
}

DecodedPng decodePngFile(const std::string& path) {
  return decodePng(readFile(path), path);
}

}  // namespace isk::test
