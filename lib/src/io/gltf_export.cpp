#include "isk/io/gltf_export.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>

#include "isk/core/error.hpp"
#include "isk/io/export.hpp"

namespace isk {
namespace {

using nlohmann::json;

constexpr int kFloat = 5126;         // componentType FLOAT
constexpr int kUnsignedInt = 5125;   // componentType UNSIGNED_INT
constexpr int kArrayBuffer = 34962;  // bufferView target
constexpr int kElementArrayBuffer = 34963;

// The BIN chunk and the accessors over it.
class BinaryBuilder {
 public:
  // Appends `bytes` as a new buffer view (4-byte aligned) and an accessor.
  int add(const void* data, size_t bytes, int component_type, int count,
          const char* type, int target, json min = nullptr,
          json max = nullptr) {
    while (bin_.size() % 4 != 0) bin_.push_back('\0');
    json view = {
        {"buffer", 0}, {"byteOffset", bin_.size()}, {"byteLength", bytes}};
    if (target != 0) view["target"] = target;
    views_.push_back(view);
    bin_.append(static_cast<const char*>(data), bytes);
    json accessor = {{"bufferView", static_cast<int>(views_.size()) - 1},
                     {"componentType", component_type},
                     {"count", count},
                     {"type", type}};
    if (!min.is_null()) accessor["min"] = min;
    if (!max.is_null()) accessor["max"] = max;
    accessors_.push_back(accessor);
    return static_cast<int>(accessors_.size()) - 1;
  }

  // A VEC3 float accessor with min/max.
  int addVec3(const std::vector<float>& values, bool with_bounds) {
    const int count = static_cast<int>(values.size() / 3);
    json min = nullptr, max = nullptr;
    if (with_bounds) {
      float lo[3], hi[3];
      for (int c = 0; c < 3; ++c) {
        lo[c] = std::numeric_limits<float>::max();
        hi[c] = std::numeric_limits<float>::lowest();
      }
      for (int i = 0; i < count; ++i)
        for (int c = 0; c < 3; ++c) {
          lo[c] = std::min(lo[c], values[3 * i + c]);
          hi[c] = std::max(hi[c], values[3 * i + c]);
        }
      if (count == 0)
        for (int c = 0; c < 3; ++c) lo[c] = hi[c] = 0;
      min = {lo[0], lo[1], lo[2]};
      max = {hi[0], hi[1], hi[2]};
    }
    return add(values.data(), values.size() * sizeof(float), kFloat, count,
               "VEC3", kArrayBuffer, min, max);
  }

  std::string& bin() { return bin_; }
  json& views() { return views_; }
  json& accessors() { return accessors_; }

 private:
  std::string bin_;
  json views_ = json::array();
  json accessors_ = json::array();
};

void appendU32(std::string& out, uint32_t value) {
  const char bytes[4] = {static_cast<char>(value & 0xff),
                         static_cast<char>((value >> 8) & 0xff),
                         static_cast<char>((value >> 16) & 0xff),
                         static_cast<char>((value >> 24) & 0xff)};
  out.append(bytes, 4);
}

void checkFrame(const Matrix3Xf& m, int vertices, const std::string& what) {
  if (m.rows() != vertices)
    throw Error(ErrorCode::kInvalidArgument,
                "writeAnimatedGltf: " + what + " has " +
                    std::to_string(m.rows()) + " rows, expected " +
                    std::to_string(vertices));
  if (!m.allFinite())
    throw Error(ErrorCode::kInvalidArgument,
                "writeAnimatedGltf: " + what + " holds a NaN or infinity");
}

}  // namespace

std::vector<double> gltfFrameTimes(const std::vector<double>& times) {
  bool increasing = true;
  for (size_t k = 0; k < times.size(); ++k)
    if (!std::isfinite(times[k]) || (k > 0 && !(times[k] > times[k - 1])))
      increasing = false;
  if (increasing) return times;
  std::vector<double> out(times.size());
  for (size_t k = 0; k < times.size(); ++k) out[k] = k / 30.0;
  return out;
}

float gltfTrackSpacing(const std::vector<Matrix3Xf>& positions) {
  float lo = std::numeric_limits<float>::max();
  float hi = std::numeric_limits<float>::lowest();
  for (const Matrix3Xf& p : positions) {
    if (p.rows() == 0) continue;
    lo = std::min(lo, p.col(0).minCoeff());
    hi = std::max(hi, p.col(0).maxCoeff());
  }
  if (!(hi >= lo)) return 1e-3f;
  return std::max(1e-3f, 1.2f * (hi - lo));
}

void writeAnimatedGltf(const std::string& path, const TriangleMatrix& triangles,
                       const std::vector<GltfTrack>& tracks,
                       const std::vector<double>& times) {
  const int frames = static_cast<int>(times.size());
  if (frames < 1)
    throw Error(ErrorCode::kInvalidArgument,
                "writeAnimatedGltf: " + path + ": no frame times");
  if (tracks.empty())
    throw Error(ErrorCode::kInvalidArgument,
                "writeAnimatedGltf: " + path + ": no track");
  for (int k = 0; k < frames; ++k) {
    if (!std::isfinite(times[k]) || (k > 0 && !(times[k] > times[k - 1])))
      throw Error(ErrorCode::kInvalidArgument,
                  "writeAnimatedGltf: " + path + ": frame " +
                      std::to_string(k) +
                      "'s time is not finite or not after the previous one");
  }
  const int vertices = static_cast<int>(
      tracks.front().positions.empty() ? 0
                                       : tracks.front().positions[0].rows());
  if (vertices == 0)
    throw Error(ErrorCode::kInvalidArgument,
                "writeAnimatedGltf: " + path + ": track '" +
                    tracks.front().name + "' has no vertex");
  for (const GltfTrack& track : tracks) {
    const std::string name = "track '" + track.name + "'";
    if (static_cast<int>(track.positions.size()) != frames)
      throw Error(ErrorCode::kInvalidArgument,
                  "writeAnimatedGltf: " + name + " has " +
                      std::to_string(track.positions.size()) +
                      " frames of positions, expected " +
                      std::to_string(frames));
    if (!track.normals.empty() &&
        static_cast<int>(track.normals.size()) != frames)
      throw Error(ErrorCode::kInvalidArgument,
                  "writeAnimatedGltf: " + name + " has " +
                      std::to_string(track.normals.size()) +
                      " frames of normals, expected " + std::to_string(frames));
    for (int k = 0; k < frames; ++k) {
      checkFrame(track.positions[k], vertices,
                 name + " frame " + std::to_string(k) + " positions");
      if (!track.normals.empty())
        checkFrame(track.normals[k], vertices,
                   name + " frame " + std::to_string(k) + " normals");
    }
  }
  if (triangles.rows() > 0 &&
      (triangles.minCoeff() < 0 || triangles.maxCoeff() >= vertices))
    throw Error(ErrorCode::kInvalidArgument,
                "writeAnimatedGltf: a triangle index lies outside 0.." +
                    std::to_string(vertices - 1));

  BinaryBuilder builder;
  std::vector<uint32_t> indices(triangles.size());
  for (Eigen::Index t = 0; t < triangles.rows(); ++t)
    for (int c = 0; c < 3; ++c)
      indices[3 * t + c] = static_cast<uint32_t>(triangles(t, c));
  const int index_accessor = builder.add(
      indices.data(), indices.size() * sizeof(uint32_t), kUnsignedInt,
      static_cast<int>(indices.size()), "SCALAR", kElementArrayBuffer);

  auto flatten = [&](const Matrix3Xf& m, const Matrix3Xf* minus) {
    std::vector<float> out(3 * static_cast<size_t>(vertices));
    for (int v = 0; v < vertices; ++v)
      for (int c = 0; c < 3; ++c)
        out[3 * v + c] = minus ? m(v, c) - (*minus)(v, c) : m(v, c);
    return out;
  };

  json meshes = json::array(), nodes = json::array(),
       scene_nodes = json::array();
  json channels = json::array(), samplers = json::array();

  // The animation's input and output, shared by every track.
  std::vector<float> input(frames);
  for (int k = 0; k < frames; ++k)
    input[k] = static_cast<float>(times[k] - times[0]);
  const int input_accessor = builder.add(
      input.data(), input.size() * sizeof(float), kFloat, frames, "SCALAR", 0,
      json::array({input.front()}), json::array({input.back()}));
  std::vector<float> output(static_cast<size_t>(frames) * frames, 0.f);
  for (int k = 0; k < frames; ++k)
    output[static_cast<size_t>(k) * frames + k] = 1;
  const int output_accessor =
      builder.add(output.data(), output.size() * sizeof(float), kFloat,
                  static_cast<int>(output.size()), "SCALAR", 0);

  for (size_t i = 0; i < tracks.size(); ++i) {
    const GltfTrack& track = tracks[i];
    const bool with_normals = !track.normals.empty();
    json attributes = {
        {"POSITION",
         builder.addVec3(flatten(track.positions[0], nullptr), true)}};
    if (with_normals)
      attributes["NORMAL"] =
          builder.addVec3(flatten(track.normals[0], nullptr), false);
    json targets = json::array();
    for (int k = 0; k < frames; ++k) {
      json target = {{"POSITION", builder.addVec3(flatten(track.positions[k],
                                                          &track.positions[0]),
                                                  true)}};
      if (with_normals)
        target["NORMAL"] = builder.addVec3(
            flatten(track.normals[k], &track.normals[0]), false);
      targets.push_back(target);
    }
    std::vector<float> initial(frames, 0.f);
    initial[0] = 1;
    json target_names = json::array();
    for (int k = 0; k < frames; ++k)
      target_names.push_back("frame_" + std::to_string(k));
    meshes.push_back({{"name", track.name},
                      {"primitives", json::array({{{"attributes", attributes},
                                                   {"indices", index_accessor},
                                                   {"mode", 4},
                                                   {"targets", targets}}})},
                      {"weights", initial},
                      {"extras", {{"targetNames", target_names}}}});
    nodes.push_back({{"name", track.name},
                     {"mesh", static_cast<int>(i)},
                     {"translation",
                      {track.offset.x(), track.offset.y(), track.offset.z()}}});
    scene_nodes.push_back(static_cast<int>(i));
    samplers.push_back({{"input", input_accessor},
                        {"output", output_accessor},
                        {"interpolation", "STEP"}});
    channels.push_back(
        {{"sampler", static_cast<int>(i)},
         {"target", {{"node", static_cast<int>(i)}, {"path", "weights"}}}});
  }
  while (builder.bin().size() % 4 != 0) builder.bin().push_back('\0');

  json document = {
      {"asset", {{"version", "2.0"}, {"generator", "isk"}}},
      {"scene", 0},
      {"scenes", json::array({{{"name", "isk"}, {"nodes", scene_nodes}}})},
      {"nodes", nodes},
      {"meshes", meshes},
      {"animations", json::array({{{"name", "frames"},
                                   {"channels", channels},
                                   {"samplers", samplers}}})},
      {"accessors", builder.accessors()},
      {"bufferViews", builder.views()},
      {"buffers", json::array({{{"byteLength", builder.bin().size()}}})}};
  std::string text = document.dump();
  while (text.size() % 4 != 0) text.push_back(' ');

  const uint64_t total = 12 + 8 + text.size() + 8 + builder.bin().size();
  if (total > 0xffffffffull)
    throw Error(ErrorCode::kInvalidArgument,
                "writeAnimatedGltf: " + path + ": " + std::to_string(total) +
                    " bytes exceed the 4 GiB limit of a .glb (fewer frames or "
                    "vertices)");
  std::string glb;
  glb.reserve(static_cast<size_t>(total));
  appendU32(glb, 0x46546C67);  // "glTF"
  appendU32(glb, 2);
  appendU32(glb, static_cast<uint32_t>(total));
  appendU32(glb, static_cast<uint32_t>(text.size()));
  appendU32(glb, 0x4E4F534A);  // "JSON"
  glb += text;
  appendU32(glb, static_cast<uint32_t>(builder.bin().size()));
  appendU32(glb, 0x004E4942);  // "BIN\0"
  glb += builder.bin();
  writeTextFile(path, glb);
}

}  // namespace isk
