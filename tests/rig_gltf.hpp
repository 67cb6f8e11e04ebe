// Writes a rig as a small glTF 2.0 file (JSON with its buffer embedded as a
// base64 data URI) or GLB, so that tests can make rig files without the
// shared assets: the mesh with normals, the skeleton as nodes, the skin (at
// most 4 influences per vertex: the largest) and no clip.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "isk/rig/rig.hpp"

namespace isk::test {

inline std::string base64Encode(const std::string& bytes) {
  static const char* table =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const uint32_t n = (uint8_t(bytes[i]) << 16) |
                       (uint8_t(bytes[i + 1]) << 8) | uint8_t(bytes[i + 2]);
    for (int k = 3; k >= 0; --k) out += table[(n >> (6 * k)) & 63];
  }
  if (i + 1 == bytes.size()) {
    const uint32_t n = uint8_t(bytes[i]) << 16;
    out += table[(n >> 18) & 63];
    out += table[(n >> 12) & 63];
    out += "==";
  } else if (i + 2 == bytes.size()) {
    const uint32_t n = (uint8_t(bytes[i]) << 16) | (uint8_t(bytes[i + 1]) << 8);
    out += table[(n >> 18) & 63];
    out += table[(n >> 12) & 63];
    out += table[(n >> 6) & 63];
    out += '=';
  }
  return out;
}

// The glTF JSON of `rig` and its binary buffer. With `embed`, the buffer is
// a data URI inside the JSON; otherwise it is the GLB's BIN chunk.
// With `clip_end` > 0, a clip "hold" keeps the last joint still from time 0
// to `clip_end` seconds (two rotation keys).
inline std::string rigGltfJson(const Rig& rig, bool embed, std::string* bin,
                               double clip_end = 0) {
  std::string data;
  std::vector<std::string> views, accessors;
  auto add = [&](const void* bytes, size_t size, int component,
                 const char* type, size_t count,
                 const std::string& extra = "") {
    while (data.size() % 4) data += '\0';
    views.push_back(
        "{\"buffer\":0,\"byteOffset\":" + std::to_string(data.size()) +
        ",\"byteLength\":" + std::to_string(size) + "}");
    data.append(static_cast<const char*>(bytes), size);
    accessors.push_back("{\"bufferView\":" + std::to_string(views.size() - 1) +
                        ",\"componentType\":" + std::to_string(component) +
                        ",\"count\":" + std::to_string(count) + ",\"type\":\"" +
                        type + "\"" + extra + "}");
    return accessors.size() - 1;
  };
  const Mesh& mesh = rig.mesh;
  const int n = mesh.vertexCount();
  std::vector<float> positions(3 * n), normals(3 * n), weights(4 * n, 0.f);
  std::vector<uint16_t> joints(4 * n, 0);
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (int v = 0; v < n; ++v) {
    for (int c = 0; c < 3; ++c) {
      positions[3 * v + c] = mesh.positions(v, c);
      normals[3 * v + c] = mesh.normals(v, c);
      lo[c] = std::min(lo[c], mesh.positions(v, c));
      hi[c] = std::max(hi[c], mesh.positions(v, c));
    }
    const int count = std::min(rig.weights.influenceCount(v), 4);
    float sum = 0.f;
    for (int k = 0; k < count; ++k)
      sum += rig.weights.weights[rig.weights.offsets[v] + k];
    for (int k = 0; k < count; ++k) {
      joints[4 * v + k] =
          uint16_t(rig.weights.joints[rig.weights.offsets[v] + k]);
      weights[4 * v + k] =
          rig.weights.weights[rig.weights.offsets[v] + k] / sum;
    }
  }
  std::vector<uint32_t> indices(3 * mesh.triangleCount());
  for (int f = 0; f < mesh.triangleCount(); ++f) {
    for (int c = 0; c < 3; ++c) indices[3 * f + c] = mesh.triangles(f, c);
  }
  auto bounds = [](const float* a) {
    return "[" + std::to_string(a[0]) + "," + std::to_string(a[1]) + "," +
           std::to_string(a[2]) + "]";
  };
  // min and max are written when finite (JSON has no inf or NaN).
  const bool finite_bounds =
      std::isfinite(lo[0] + lo[1] + lo[2] + hi[0] + hi[1] + hi[2]);
  const size_t position =
      add(positions.data(), positions.size() * 4, 5126, "VEC3", n,
          finite_bounds ? ",\"min\":" + bounds(lo) + ",\"max\":" + bounds(hi)
                        : std::string());
  const size_t normal =
      add(normals.data(), normals.size() * 4, 5126, "VEC3", n);
  const size_t joint = add(joints.data(), joints.size() * 2, 5123, "VEC4", n);
  const size_t weight =
      add(weights.data(), weights.size() * 4, 5126, "VEC4", n);
  const size_t index =
      add(indices.data(), indices.size() * 4, 5125, "SCALAR", indices.size());
  std::vector<float> binds;
  for (const Joint& j : rig.skeleton.joints) {
    const Eigen::Matrix4f m = j.inverse_bind.matrix();
    binds.insert(binds.end(), m.data(), m.data() + 16);
  }
  const size_t bind = add(binds.data(), binds.size() * 4, 5126, "MAT4",
                          rig.skeleton.jointCount());

  std::string animations;
  if (clip_end > 0) {
    const std::vector<float> times = {0.f, static_cast<float>(clip_end)};
    const std::vector<float> keys = {0, 0, 0, 1, 0, 0, 0, 1};
    const size_t input =
        add(times.data(), 8, 5126, "SCALAR", 2,
            ",\"min\":[0],\"max\":[" + std::to_string(times[1]) + "]");
    const size_t output = add(keys.data(), 32, 5126, "VEC4", 2);
    animations =
        ",\"animations\":[{\"name\":\"hold\",\"samplers\":[{"
        "\"input\":" +
        std::to_string(input) + ",\"output\":" + std::to_string(output) +
        "}],\"channels\":[{\"sampler\":0,\"target\":{\"node\":" +
        std::to_string(rig.skeleton.jointCount() - 1) +
        ",\"path\":\"rotation\"}}]}]";
  }

  const Skeleton& skeleton = rig.skeleton;
  std::string nodes, roots, joint_list;
  for (int j = 0; j < skeleton.jointCount(); ++j) {
    std::string children;
    for (int c = 0; c < skeleton.jointCount(); ++c) {
      if (skeleton.joints[c].parent == j) {
        children += (children.empty() ? "" : ",") + std::to_string(c);
      }
    }
    const Eigen::Affine3f local =
        skeleton.joints[j].parent < 0
            ? skeleton.root_parent * skeleton.joints[j].rest_local
            : skeleton.joints[j].rest_local;
    std::string matrix;
    for (int k = 0; k < 16; ++k) {
      matrix += (k ? "," : "") + std::to_string(local.matrix().data()[k]);
    }
    nodes += "{\"name\":\"" + skeleton.joints[j].name + "\",\"matrix\":[" +
             matrix + "]" +
             (children.empty() ? "" : ",\"children\":[" + children + "]") +
             "},";
    if (skeleton.joints[j].parent < 0) roots += std::to_string(j) + ",";
    joint_list += (j ? "," : "") + std::to_string(j);
  }
  nodes += "{\"name\":\"skin_node\",\"mesh\":0,\"skin\":0}";
  roots += std::to_string(skeleton.jointCount());
  std::string view_list, accessor_list;
  for (size_t i = 0; i < views.size(); ++i) {
    view_list += (i ? "," : "") + views[i];
    accessor_list += (i ? "," : "") + accessors[i];
  }
  const std::string part = mesh.parts.empty() ? "skin" : mesh.parts[0].name;
  std::string buffer = "{\"byteLength\":" + std::to_string(data.size());
  if (embed) {
    buffer += ",\"uri\":\"data:application/octet-stream;base64," +
              base64Encode(data) + "\"";
  }
  buffer += "}";
  if (bin) *bin = data;
  return "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[" + buffer +
         "],\"bufferViews\":[" + view_list + "],\"accessors\":[" +
         accessor_list + "],\"scene\":0,\"scenes\":[{\"nodes\":[" + roots +
         "]}],\"nodes\":[" + nodes + "],\"meshes\":[{\"name\":\"" + part +
         "\",\"primitives\":[{\"attributes\":{\"POSITION\":" +
         std::to_string(position) + ",\"NORMAL\":" + std::to_string(normal) +
         ",\"JOINTS_0\":" + std::to_string(joint) +
         ",\"WEIGHTS_0\":" + std::to_string(weight) +
         "},\"indices\":" + std::to_string(index) +
         "}]}],\"skins\":[{\"joints\":[" + joint_list +
         "],\"inverseBindMatrices\":" + std::to_string(bind) + "}]" +
         animations + "}";
}

// `rig` as glTF text with its buffer embedded.
inline std::string rigGltf(const Rig& rig, double clip_end = 0) {
  return rigGltfJson(rig, true, nullptr, clip_end);
}

// `rig` as a binary GLB file (JSON chunk, BIN chunk).
inline std::string rigGlb(const Rig& rig) {
  std::string bin;
  std::string json = rigGltfJson(rig, false, &bin);
  while (json.size() % 4) json += ' ';
  while (bin.size() % 4) bin += '\0';
  auto u32 = [](uint32_t value) {
    std::string s(4, '\0');
    for (int k = 0; k < 4; ++k) s[k] = char((value >> (8 * k)) & 0xff);
    return s;
  };
  const uint32_t total = 12 + 8 + json.size() + 8 + bin.size();
  return "glTF" + u32(2) + u32(total) + u32(json.size()) + "JSON" + json +
         u32(bin.size()) + std::string("BIN\0", 4) + bin;
}

inline std::string writeBytes(const std::string& path,
                              const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

}  // namespace isk::test
