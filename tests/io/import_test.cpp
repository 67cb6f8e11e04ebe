// Tests of isk::importRig: the shared assets load with the counts Assimp 5.2
// gives, a procedural rig survives a glTF round trip, and every kind of bad
// file is rejected with an error naming the file and what is wrong in it.
#include "isk/io/import.hpp"

#include <gtest/gtest.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "data_folder.hpp"
#include "isk/core/error.hpp"
#include "isk/tools/procedural.hpp"
#include "rig_gltf.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using test::readFile;
using test::ScopedTempDir;

namespace fs = std::filesystem;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

std::string writeFile(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  EXPECT_TRUE(out.good()) << "cannot write " << path;
  return path;
}

std::string jsonFloats(const float* values, int count) {
  std::ostringstream s;
  s.precision(9);
  s << "[";
  for (int i = 0; i < count; ++i) s << (i ? "," : "") << values[i];
  s << "]";
  return s.str();
}

// Column-major 16 floats, as glTF stores matrices.
std::vector<float> columnMajor(const Eigen::Affine3f& t) {
  const Eigen::Matrix4f m = t.matrix();
  return std::vector<float>(m.data(), m.data() + 16);
}

// Hand-written glTF 2.0 files: binary data goes into one buffer embedded as a
// base64 data URI; the caller writes the scene JSON around the accessors.
class GltfWriter {
 public:
  // Returns the accessor index. `type` is "SCALAR", "VEC3", "MAT4"...
  int addFloats(const std::vector<float>& values, const char* type,
                int components) {
    return add(values.data(), values.size() * sizeof(float), 5126, type,
               static_cast<int>(values.size()) / components);
  }
  int addUShorts(const std::vector<uint16_t>& values, const char* type,
                 int components) {
    return add(values.data(), values.size() * sizeof(uint16_t), 5123, type,
               static_cast<int>(values.size()) / components);
  }
  int addUInts(const std::vector<uint32_t>& values) {
    return add(values.data(), values.size() * sizeof(uint32_t), 5125, "SCALAR",
               static_cast<int>(values.size()));
  }

  // `scene` holds the other top-level members, without braces
  // ("\"nodes\": [...], \"meshes\": [...]").
  std::string json(const std::string& scene) const {
    std::string views, accessors;
    for (size_t i = 0; i < views_.size(); ++i) {
      views += (i ? "," : "") + views_[i];
      accessors += (i ? "," : "") + accessors_[i];
    }
    return "{\"asset\": {\"version\": \"2.0\"},\n\"buffers\": "
           "[{\"byteLength\": " +
           std::to_string(bin_.size()) +
           ", \"uri\": \"data:application/octet-stream;base64," +
           test::base64Encode(bin_) + "\"}],\n\"bufferViews\": [" + views +
           "],\n\"accessors\": [" + accessors + "],\n" + scene + "}\n";
  }

 private:
  int add(const void* data, size_t bytes, int component_type, const char* type,
          int count) {
    while (bin_.size() % 4) bin_ += '\0';
    const size_t offset = bin_.size();
    bin_.append(static_cast<const char*>(data), bytes);
    const int index = static_cast<int>(views_.size());
    views_.push_back(
        "{\"buffer\": 0, \"byteOffset\": " + std::to_string(offset) +
        ", \"byteLength\": " + std::to_string(bytes) + "}");
    accessors_.push_back(
        "{\"bufferView\": " + std::to_string(index) +
        ", \"componentType\": " + std::to_string(component_type) +
        ", \"count\": " + std::to_string(count) + ", \"type\": \"" + type +
        "\"}");
    return index;
  }

  std::string bin_;
  std::vector<std::string> views_;
  std::vector<std::string> accessors_;
};

// A skinned quad (4 vertices, 2 triangles) in the x-y plane, on a two-joint
// chain "root" -> "child" (at y = 1). Each knob breaks one thing.
struct QuadScene {
  std::vector<float> positions = {0, 0, 0, 1, 0, 0, 1, 2, 0, 0, 2, 0};
  // Per vertex: weight of root, weight of child.
  std::vector<float> weights = {1, 0, 1, 0, 0, 1, 0, 1};
  Eigen::Affine3f child_inverse_bind =
      Eigen::Affine3f(Eigen::Translation3f(0.f, -1.f, 0.f));
  bool skin = true;
  bool mesh = true;
  // Extra meshes without skin: one under "child", one at the scene top.
  bool rigid_mesh_under_joint = false;
  bool free_mesh = false;
  // A second primitive of lines in the skinned mesh.
  bool lines = false;
  // A clip rotating "child"; `nan_key` poisons its second key.
  bool animation = true;
  std::string animation_name = "wave";
  bool nan_key = false;
};

std::string quadGltf(const QuadScene& q) {
  GltfWriter w;
  const int position = w.addFloats(q.positions, "VEC3", 3);
  std::vector<uint16_t> joints;
  for (int v = 0; v < 4; ++v) joints.insert(joints.end(), {0, 1, 0, 0});
  std::vector<float> weights;
  for (int v = 0; v < 4; ++v) {
    weights.insert(weights.end(),
                   {q.weights[2 * v], q.weights[2 * v + 1], 0, 0});
  }
  const int joint_accessor = w.addUShorts(joints, "VEC4", 4);
  const int weight_accessor = w.addFloats(weights, "VEC4", 4);
  const int indices = w.addUShorts({0, 1, 2, 0, 2, 3}, "SCALAR", 1);
  std::vector<float> binds = columnMajor(Eigen::Affine3f::Identity());
  const std::vector<float> child = columnMajor(q.child_inverse_bind);
  binds.insert(binds.end(), child.begin(), child.end());
  const int bind_accessor = w.addFloats(binds, "MAT4", 16);
  const int times = w.addFloats({0.f, 0.5f, 1.f}, "SCALAR", 1);
  const float s = std::sqrt(0.5f);
  const int rotations =
      w.addFloats({0, 0, 0, 1, 0, 0, q.nan_key ? kNaN : 0.38268343f,
                   0.92387953f, 0, 0, s, s},
                  "VEC4", 4);

  std::string attributes = "\"POSITION\": " + std::to_string(position);
  if (q.skin) {
    attributes += ", \"JOINTS_0\": " + std::to_string(joint_accessor) +
                  ", \"WEIGHTS_0\": " + std::to_string(weight_accessor);
  }
  std::string primitive = "{\"attributes\": {" + attributes +
                          "}, \"indices\": " + std::to_string(indices) + "}";
  if (q.lines) {
    const int line_indices = w.addUShorts({0, 1, 1, 2}, "SCALAR", 1);
    primitive += ", {\"attributes\": {" + attributes +
                 "}, \"indices\": " + std::to_string(line_indices) +
                 ", \"mode\": 1}";
  }
  const std::string plain_primitive =
      "{\"attributes\": {\"POSITION\": " + std::to_string(position) +
      "}, \"indices\": " + std::to_string(indices) + "}";
  // Nodes: 0 root, 1 child, 2 skinned mesh, 3 rigid mesh, 4 free mesh.
  std::string child_node = "{\"name\": \"child\", \"translation\": [0, 1, 0]";
  if (q.rigid_mesh_under_joint) child_node += ", \"children\": [3]";
  child_node += "}";
  std::string nodes = "{\"name\": \"root\", \"children\": [1]}, " + child_node;
  std::string scene_nodes = "0";
  std::string meshes;
  if (q.mesh) {
    nodes += ", {\"name\": \"quad_node\", \"mesh\": 0" +
             std::string(q.skin ? ", \"skin\": 0" : "") + "}";
    scene_nodes += ", 2";
    meshes = "{\"name\": \"quad\", \"primitives\": [" + primitive + "]}, " +
             "{\"name\": \"plate\", \"primitives\": [" + plain_primitive +
             "]}, {\"name\": \"loose\", \"primitives\": [" + plain_primitive +
             "]}";
    nodes +=
        ", {\"name\": \"plate_node\", \"mesh\": 1, \"translation\": [0, 0, 1]}";
    nodes += ", {\"name\": \"loose_node\", \"mesh\": 2}";
    if (q.free_mesh) scene_nodes += ", 4";
  }
  std::string scene = "\"scene\": 0, \"scenes\": [{\"nodes\": [" + scene_nodes +
                      "]}],\n\"nodes\": [" + nodes + "]";
  if (q.mesh) scene += ",\n\"meshes\": [" + meshes + "]";
  if (q.skin) {
    scene += ",\n\"skins\": [{\"joints\": [0, 1], \"inverseBindMatrices\": " +
             std::to_string(bind_accessor) + "}]";
  }
  if (q.animation) {
    const std::string name = q.animation_name.empty()
                                 ? ""
                                 : "\"name\": \"" + q.animation_name + "\", ";
    scene += ",\n\"animations\": [{" + name +
             "\"samplers\": [{\"input\": " + std::to_string(times) +
             ", \"output\": " + std::to_string(rotations) +
             ", \"interpolation\": \"LINEAR\"}], \"channels\": [{\"sampler\": "
             "0, \"target\": {\"node\": 1, \"path\": \"rotation\"}}]}]";
  }
  return w.json(scene);
}

// Writes a rig (at most 4 influences per vertex) as glTF: the mesh, the
// skeleton as nodes, the skin and every clip's rotation tracks.
std::string rigGltf(const Rig& rig) {
  GltfWriter w;
  const Mesh& mesh = rig.mesh;
  const int n = mesh.vertexCount();
  std::vector<float> positions(mesh.positions.data(),
                               mesh.positions.data() + 3 * n);
  std::vector<float> normals(mesh.normals.data(), mesh.normals.data() + 3 * n);
  std::vector<uint16_t> joints(4 * n, 0);
  std::vector<float> weights(4 * n, 0.f);
  for (int v = 0; v < n; ++v) {
    for (int k = 0; k < rig.weights.influenceCount(v) && k < 4; ++k) {
      joints[4 * v + k] =
          uint16_t(rig.weights.joints[rig.weights.offsets[v] + k]);
      weights[4 * v + k] = rig.weights.weights[rig.weights.offsets[v] + k];
    }
  }
  std::vector<uint32_t> indices(
      mesh.triangles.data(), mesh.triangles.data() + 3 * mesh.triangleCount());
  const int position = w.addFloats(positions, "VEC3", 3);
  const int normal = w.addFloats(normals, "VEC3", 3);
  const int joint_accessor = w.addUShorts(joints, "VEC4", 4);
  const int weight_accessor = w.addFloats(weights, "VEC4", 4);
  const int index_accessor = w.addUInts(indices);
  std::vector<float> binds;
  for (const Joint& joint : rig.skeleton.joints) {
    const std::vector<float> m = columnMajor(joint.inverse_bind);
    binds.insert(binds.end(), m.begin(), m.end());
  }
  const int bind_accessor = w.addFloats(binds, "MAT4", 16);

  // Nodes: the joints in skeleton order, then the mesh node.
  const Skeleton& skeleton = rig.skeleton;
  std::string nodes, roots, joint_list;
  for (int j = 0; j < skeleton.jointCount(); ++j) {
    std::string children;
    for (int c = 0; c < skeleton.jointCount(); ++c) {
      if (skeleton.joints[c].parent == j) {
        children += (children.empty() ? "" : ", ") + std::to_string(c);
      }
    }
    const Eigen::Affine3f local =
        skeleton.joints[j].parent < 0
            ? skeleton.root_parent * skeleton.joints[j].rest_local
            : skeleton.joints[j].rest_local;
    nodes += "{\"name\": \"" + skeleton.joints[j].name +
             "\", \"matrix\": " + jsonFloats(columnMajor(local).data(), 16) +
             (children.empty() ? "" : ", \"children\": [" + children + "]") +
             "},\n";
    if (skeleton.joints[j].parent < 0) roots += std::to_string(j) + ", ";
    joint_list += (j ? ", " : "") + std::to_string(j);
  }
  nodes += "{\"name\": \"skin_node\", \"mesh\": 0, \"skin\": 0}";
  roots += std::to_string(skeleton.jointCount());

  std::string animations;
  for (const AnimationClip& clip : rig.clips) {
    std::string samplers, channels;
    for (const JointChannel& channel : clip.channels) {
      if (channel.rotations.empty()) continue;
      std::vector<float> times(channel.rotation_times.begin(),
                               channel.rotation_times.end());
      std::vector<float> keys;
      for (const Eigen::Quaternionf& q : channel.rotations) {
        keys.insert(keys.end(), {q.x(), q.y(), q.z(), q.w()});
      }
      const int input = w.addFloats(times, "SCALAR", 1);
      const int output = w.addFloats(keys, "VEC4", 4);
      const int sampler =
          static_cast<int>(std::count(samplers.begin(), samplers.end(), '{'));
      samplers += std::string(samplers.empty() ? "" : ", ") +
                  "{\"input\": " + std::to_string(input) +
                  ", \"output\": " + std::to_string(output) + "}";
      channels += std::string(channels.empty() ? "" : ", ") +
                  "{\"sampler\": " + std::to_string(sampler) +
                  ", \"target\": {\"node\": " + std::to_string(channel.joint) +
                  ", \"path\": \"rotation\"}}";
    }
    animations += std::string(animations.empty() ? "" : ", ") +
                  "{\"name\": \"" + clip.name + "\", \"samplers\": [" +
                  samplers + "], \"channels\": [" + channels + "]}";
  }

  const std::string scene =
      "\"scene\": 0, \"scenes\": [{\"nodes\": [" + roots + "]}],\n" +
      "\"nodes\": [" + nodes + "],\n\"meshes\": [{\"name\": \"" +
      mesh.parts.at(0).name + "\", \"primitives\": [{\"attributes\": " +
      "{\"POSITION\": " + std::to_string(position) +
      ", \"NORMAL\": " + std::to_string(normal) +
      ", \"JOINTS_0\": " + std::to_string(joint_accessor) +
      ", \"WEIGHTS_0\": " + std::to_string(weight_accessor) +
      "}, \"indices\": " + std::to_string(index_accessor) + "}]}],\n" +
      "\"skins\": [{\"joints\": [" + joint_list +
      "], \"inverseBindMatrices\": " + std::to_string(bind_accessor) + "}],\n" +
      "\"animations\": [" + animations + "]";
  return w.json(scene);
}

// The properties every imported rig has, whatever its source.
void expectWellFormed(const Rig& rig) {
  const Validation valid = rig.validate();
  EXPECT_TRUE(valid.isOk()) << valid.reason();
  const SkinWeights& w = rig.weights;
  ASSERT_EQ(w.vertexCount(), rig.mesh.vertexCount());
  for (int v = 0; v < w.vertexCount(); ++v) {
    double sum = 0;
    for (uint32_t i = w.offsets[v]; i < w.offsets[v + 1]; ++i) {
      ASSERT_GT(w.weights[i], 0.f) << rig.mesh.describeVertex(v);
      if (i > w.offsets[v]) {
        ASSERT_LE(w.weights[i], w.weights[i - 1])
            << rig.mesh.describeVertex(v) << ": influences not sorted";
      }
      sum += w.weights[i];
    }
    ASSERT_NEAR(sum, 1.0, 1e-5) << rig.mesh.describeVertex(v);
  }
  for (int v = 0; v < rig.mesh.vertexCount(); ++v) {
    ASSERT_NEAR(rig.mesh.normals.row(v).norm(), 1.f, 1e-4f)
        << rig.mesh.describeVertex(v);
  }
  int covered = 0, covered_triangles = 0;
  for (const MeshPart& part : rig.mesh.parts) {
    EXPECT_EQ(part.first_vertex, covered) << part.name;
    EXPECT_EQ(part.first_triangle, covered_triangles) << part.name;
    covered += part.vertex_count;
    covered_triangles += part.triangle_count;
  }
  EXPECT_EQ(covered, rig.mesh.vertexCount());
  EXPECT_EQ(covered_triangles, rig.mesh.triangleCount());

  // Bind transforms: finite, s * R with s > 0, and rest globals finite.
  const Skeleton& skeleton = rig.skeleton;
  const TransformList binds = skeleton.bindGlobals();
  TransformList rest(skeleton.joints.size());
  for (int j = 0; j < skeleton.jointCount(); ++j) {
    const Joint& joint = skeleton.joints[j];
    ASSERT_LT(joint.parent, j) << joint.name;
    rest[j] = (joint.parent < 0 ? skeleton.root_parent : rest[joint.parent]) *
              joint.rest_local;
    ASSERT_TRUE(binds[j].matrix().allFinite()) << joint.name;
    ASSERT_TRUE(rest[j].matrix().allFinite()) << joint.name;
    const Eigen::Vector3d sigma =
        Eigen::JacobiSVD<Eigen::Matrix3d>(binds[j].linear().cast<double>())
            .singularValues();
    EXPECT_LE(sigma(0) - sigma(2), 1e-3 * sigma(0)) << joint.name;
    EXPECT_GT(binds[j].linear().determinant(), 0.f) << joint.name;
  }
  for (const AnimationClip& clip : rig.clips) {
    EXPECT_FALSE(clip.name.empty());
    EXPECT_GE(clip.duration, 0.0) << clip.name;
    for (const JointChannel& channel : clip.channels) {
      for (double t : channel.rotation_times) {
        EXPECT_GE(t, clip.start - 1e-9) << clip.name;
        EXPECT_LE(t, clip.start + clip.duration + 1e-9) << clip.name;
      }
    }
  }
}

// Largest distance between the mesh and the mesh skinned (linear blend) with
// the rest pose: zero when the rest pose is the bind pose.
float restPoseError(const Rig& rig) {
  const Skeleton& skeleton = rig.skeleton;
  TransformList skin(skeleton.joints.size());
  TransformList rest(skeleton.joints.size());
  for (int j = 0; j < skeleton.jointCount(); ++j) {
    const Joint& joint = skeleton.joints[j];
    rest[j] = (joint.parent < 0 ? skeleton.root_parent : rest[joint.parent]) *
              joint.rest_local;
    skin[j] = rest[j] * joint.inverse_bind;
  }
  float worst = 0.f;
  for (int v = 0; v < rig.mesh.vertexCount(); ++v) {
    const Eigen::Vector3f p = rig.mesh.positions.row(v).transpose();
    Eigen::Vector3f q = Eigen::Vector3f::Zero();
    for (uint32_t i = rig.weights.offsets[v]; i < rig.weights.offsets[v + 1];
         ++i) {
      q += rig.weights.weights[i] * (skin[rig.weights.joints[i]] * p);
    }
    worst = std::max(worst, (q - p).norm());
  }
  return worst;
}

// ---------------------------------------------------------------------------
// Shared assets.

struct AssetCounts {
  const char* file;
  int vertices;
  int triangles;
  int joints;
  int skin_joints;
  int clips;
  int parts;
  bool rest_is_bind;  // the node transforms reproduce the bind pose
};

// Measured with Assimp 5.2.5 after Triangulate | JoinIdenticalVertices.
// - anim_test.x: 485 vertices (the data README's 497 counts before joining);
//   its skin names joint3 and joint4, which have no frame in the file: they
//   become fixed root joints, hence 4 joints. Its joints' rest pose differs
//   slightly from the bind pose.
// - animation_with_skeleton.fbx: 14 bones plus "Armature" and two "_end"
//   tips; the README's 13 leaves out the root bone. Bone.005/006 rest in
//   another pose than their bind pose.
// - human-addon-animations.glb: the skin lists 66 joints (the README's 53
//   are those carrying weight); CesiumMan adds the "Armature" node,
//   quad_skin its "Armature" and 10 "_end" tips.
// - RobotExpressive.glb: 19 meshes after Assimp splits multi-material ones.
const AssetCounts kAssets[] = {
    {"RiggedSimple.dae", 96, 188, 3, 2, 1, 1, true},
    {"anim_test.x", 485, 840, 4, 4, 1, 1, false},
    {"CesiumMan.glb", 2612, 4672, 20, 19, 1, 1, true},
    {"human-addon-animations.glb", 7798, 13713, 66, 66, 37, 1, true},
    {"RobotExpressive.glb", 7068, 3238, 43, 43, 14, 19, true},
    {"animation_with_skeleton.fbx", 2464, 2112, 17, 14, 1, 1, false},
    {"quad_skin.glb", 4, 2, 21, 10, 0, 1, true},
};

// Test names and failure messages show the file, not the struct's bytes.
void PrintTo(const AssetCounts& counts, std::ostream* os) {
  *os << counts.file;
}

class ImportAssetTest : public testing::TestWithParam<AssetCounts> {};

TEST_P(ImportAssetTest, LoadsWithExpectedCounts) {
  const AssetCounts& expected = GetParam();
  if (!test::haveAssets()) {
    GTEST_SKIP() << test::missingAssetsMessage(std::string("loading ") +
                                               expected.file);
  }
  const Rig rig = importRig(samples::dataFile(expected.file));
  EXPECT_EQ(rig.mesh.vertexCount(), expected.vertices);
  EXPECT_EQ(rig.mesh.triangleCount(), expected.triangles);
  EXPECT_EQ(rig.skeleton.jointCount(), expected.joints);
  EXPECT_EQ(rig.skeleton.skinJointCount(), expected.skin_joints);
  EXPECT_EQ(static_cast<int>(rig.clips.size()), expected.clips);
  EXPECT_EQ(static_cast<int>(rig.mesh.parts.size()), expected.parts);
  EXPECT_EQ(rig.source, samples::dataFile(expected.file));
  expectWellFormed(rig);
  if (expected.rest_is_bind) {
    EXPECT_LT(restPoseError(rig), 1e-5f * rig.boundingBoxDiagonal());
  }
}

// "anim_test.x" -> "anim_test_x": test names allow only [A-Za-z0-9_].
std::string assetTestName(const testing::TestParamInfo<AssetCounts>& info) {
  std::string name = info.param.file;
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name;
}

INSTANTIATE_TEST_SUITE_P(Import, ImportAssetTest, testing::ValuesIn(kAssets),
                         assetTestName);

TEST(ImportAssets, WarnsAboutUnnormalizedWeights) {
  if (!test::haveAssets()) {
    GTEST_SKIP() << test::missingAssetsMessage(
        "the weight normalization warning of animation_with_skeleton.fbx");
  }
  const Rig rig = importRig(samples::dataFile("animation_with_skeleton.fbx"));
  bool found = false;
  for (const std::string& warning : rig.warnings) {
    // "mesh 'Cube.001': 2464 of 2464 vertices had weight sums off 1 (from
    // 0.936526 to 1.37651): normalized"
    if (warning.find("mesh 'Cube.001'") != std::string::npos &&
        warning.find("normalized") != std::string::npos &&
        warning.find("0.93") != std::string::npos &&
        warning.find("1.37") != std::string::npos) {
      found = true;
    }
  }
  EXPECT_TRUE(found) << "no normalization warning among " << rig.warnings.size()
                     << " warnings";
  EXPECT_EQ(rig.weights.maxInfluences(), 6);
}

TEST(ImportAssets, FbxUnitScaleIsAccepted) {
  if (!test::haveAssets()) {
    GTEST_SKIP() << test::missingAssetsMessage("the FBX unit scale check");
  }
  // The mesh node scales by (121, 100, 100) and the bone offsets by
  // (1.21, 1, 1): the bind transforms keep one uniform scale of 100.
  const Rig rig = importRig(samples::dataFile("animation_with_skeleton.fbx"));
  const int bone = rig.skeleton.find("Bone.003");
  ASSERT_GE(bone, 0);
  const Eigen::Vector3f scales =
      rig.skeleton.bindGlobals()[bone].linear().colwise().norm();
  EXPECT_NEAR(scales.x(), 100.f, 0.1f);
  EXPECT_NEAR(scales.y(), 100.f, 0.1f);
  EXPECT_NEAR(scales.z(), 100.f, 0.1f);
}

TEST(ImportAssets, DuplicateNodeNamesResolveToBones) {
  if (!test::haveAssets()) {
    GTEST_SKIP() << test::missingAssetsMessage(
        "the RobotExpressive name check");
  }
  // RobotExpressive has mesh nodes named like bones ("Head", "Torso"): the
  // joints must be the bone nodes, which have parents in the skeleton.
  const Rig rig = importRig(samples::dataFile("RobotExpressive.glb"));
  const int head = rig.skeleton.find("Head");
  ASSERT_GE(head, 0);
  EXPECT_EQ(rig.skeleton.joints[rig.skeleton.joints[head].parent].name, "Neck");
}

TEST(ImportAssets, NodelessBonesBecomeFixedRoots) {
  if (!test::haveAssets()) {
    GTEST_SKIP() << test::missingAssetsMessage("the anim_test.x bone check");
  }
  const Rig rig = importRig(samples::dataFile("anim_test.x"));
  const int joint3 = rig.skeleton.find("joint3");
  ASSERT_GE(joint3, 0);
  EXPECT_EQ(rig.skeleton.joints[joint3].parent, -1);
  bool warned = false;
  for (const std::string& warning : rig.warnings) {
    warned |= warning.find("'joint3'") != std::string::npos;
  }
  EXPECT_TRUE(warned);
}

TEST(ImportAssets, TruncatedAssetsAreRejected) {
  if (!test::haveAssets()) {
    GTEST_SKIP() << test::missingAssetsMessage("the truncated-asset checks");
  }
  ScopedTempDir dir;
  for (const char* file : {"CesiumMan.glb", "RiggedSimple.dae", "anim_test.x",
                           "animation_with_skeleton.fbx"}) {
    const std::string bytes = readFile(samples::dataFile(file));
    const std::string path =
        writeFile(dir.file(std::string("truncated_") + file),
                  bytes.substr(0, bytes.size() / 2));
    try {
      importRig(path);
      ADD_FAILURE() << path << " loaded";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kMalformedAsset) << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos)
          << e.what();
    }
  }
}

// ---------------------------------------------------------------------------
// Files written by the test.

// Imports `path` expecting an error with `code` whose message holds the path
// and every string of `named`.
void expectImportError(const std::string& path, ErrorCode code,
                       const std::vector<std::string>& named) {
  try {
    const Rig rig = importRig(path);
    ADD_FAILURE() << path << " loaded (" << rig.mesh.vertexCount()
                  << " vertices)";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(e.code(), code) << message;
    EXPECT_EQ(message.rfind(path, 0), 0u)
        << "not prefixed by the path: " << message;
    for (const std::string& what : named) {
      EXPECT_NE(message.find(what), std::string::npos)
          << "'" << what << "' not in: " << message;
    }
  }
}

TEST(ImportGltf, SkinnedQuadLoads) {
  ScopedTempDir dir;
  const std::string path = writeFile(dir.file("quad.gltf"), quadGltf({}));
  const Rig rig = importRig(path);
  EXPECT_EQ(rig.mesh.vertexCount(), 4);
  EXPECT_EQ(rig.mesh.triangleCount(), 2);
  ASSERT_EQ(rig.skeleton.jointCount(), 2);
  EXPECT_EQ(rig.skeleton.joints[0].name, "root");
  EXPECT_EQ(rig.skeleton.joints[1].name, "child");
  EXPECT_EQ(rig.skeleton.joints[1].parent, 0);
  ASSERT_EQ(rig.clips.size(), 1u);
  EXPECT_EQ(rig.clips[0].name, "wave");
  EXPECT_NEAR(rig.clips[0].start, 0.0, 1e-6);
  EXPECT_NEAR(rig.clips[0].duration, 1.0, 1e-6);
  ASSERT_EQ(rig.clips[0].channels.size(), 1u);
  EXPECT_EQ(rig.clips[0].channels[0].joint, 1);
  EXPECT_EQ(rig.clips[0].channels[0].rotations.size(), 3u);
  // No normals in the file: computed from the triangles (+z here).
  for (int v = 0; v < 4; ++v) {
    EXPECT_NEAR(rig.mesh.normals(v, 2), 1.f, 1e-6f);
  }
  expectWellFormed(rig);
  EXPECT_LT(restPoseError(rig), 1e-6f);
}

TEST(ImportGltf, NormalizesWeightsWithWarning) {
  ScopedTempDir dir;
  QuadScene q;
  q.weights = {0.5f, 0.f, 1.f, 0.f, 0.3f, 0.3f, 0.f, 1.f};
  const std::string path = writeFile(dir.file("light.gltf"), quadGltf(q));
  const Rig rig = importRig(path);
  expectWellFormed(rig);
  bool found = false;
  for (const std::string& warning : rig.warnings) {
    found |= warning.find("mesh 'quad'") != std::string::npos &&
             warning.find("2 of 4 vertices") != std::string::npos &&
             warning.find("0.5") != std::string::npos &&
             warning.find("0.6") != std::string::npos;
  }
  EXPECT_TRUE(found);
}

TEST(ImportGltf, NamesUnnamedClips) {
  ScopedTempDir dir;
  QuadScene q;
  q.animation_name.clear();
  const Rig rig = importRig(writeFile(dir.file("unnamed.gltf"), quadGltf(q)));
  ASSERT_EQ(rig.clips.size(), 1u);
  EXPECT_EQ(rig.clips[0].name, "clip0");
}

TEST(ImportGltf, SkipsLinePrimitivesWithWarning) {
  ScopedTempDir dir;
  QuadScene q;
  q.lines = true;
  const Rig rig = importRig(writeFile(dir.file("lines.gltf"), quadGltf(q)));
  expectWellFormed(rig);
  EXPECT_EQ(rig.mesh.triangleCount(), 2);
  ASSERT_EQ(rig.mesh.parts.size(), 1u);
  bool warned = false;
  for (const std::string& warning : rig.warnings) {
    warned |= warning.find("points or lines") != std::string::npos;
  }
  EXPECT_TRUE(warned);
}

TEST(ImportGltf, AttachesUnskinnedMeshBelowJointRigidly) {
  ScopedTempDir dir;
  QuadScene q;
  q.rigid_mesh_under_joint = true;
  q.free_mesh = true;
  const std::string path = writeFile(dir.file("rigid.gltf"), quadGltf(q));
  const Rig rig = importRig(path);
  expectWellFormed(rig);
  // Assimp orders meshes as it meets their nodes; "loose" is skipped.
  ASSERT_EQ(rig.mesh.parts.size(), 2u);
  const auto found =
      std::find_if(rig.mesh.parts.begin(), rig.mesh.parts.end(),
                   [](const MeshPart& part) { return part.name == "plate"; });
  ASSERT_NE(found, rig.mesh.parts.end());
  const MeshPart& plate = *found;
  EXPECT_EQ(plate.vertex_count, 4);
  for (int v = plate.first_vertex; v < plate.first_vertex + 4; ++v) {
    ASSERT_EQ(rig.weights.influenceCount(v), 1);
    EXPECT_EQ(rig.weights.joints[rig.weights.offsets[v]], 1u);
    // Placed by its node: child (y + 1) then plate node (z + 1).
    EXPECT_NEAR(rig.mesh.positions(v, 2), 1.f, 1e-6f);
  }
  EXPECT_NEAR(rig.mesh.positions(plate.first_vertex, 1), 1.f, 1e-6f);
  int rigid_warnings = 0, skip_warnings = 0;
  for (const std::string& warning : rig.warnings) {
    rigid_warnings += warning.find("mesh 'plate'") != std::string::npos &&
                      warning.find("'child'") != std::string::npos;
    skip_warnings += warning.find("mesh 'loose'") != std::string::npos &&
                     warning.find("skipped") != std::string::npos;
  }
  EXPECT_EQ(rigid_warnings, 1);
  EXPECT_EQ(skip_warnings, 1);
  EXPECT_LT(restPoseError(rig), 1e-6f);
}

TEST(ImportGltf, ProceduralRigRoundTrips) {
  CylinderRigOptions options;
  options.bones = 3;
  options.rings = 24;
  options.segments = 16;
  const Rig original = makeCylinderRig(options);
  ASSERT_LE(original.weights.maxInfluences(), 4);
  ScopedTempDir dir;
  const std::string path =
      writeFile(dir.file("cylinder.gltf"), rigGltf(original));
  const Rig rig = importRig(path);
  expectWellFormed(rig);

  const float tolerance = 1e-5f * original.boundingBoxDiagonal();
  ASSERT_EQ(rig.mesh.vertexCount(), original.mesh.vertexCount());
  ASSERT_EQ(rig.mesh.triangleCount(), original.mesh.triangleCount());
  for (int v = 0; v < rig.mesh.vertexCount(); ++v) {
    ASSERT_LT(
        (rig.mesh.positions.row(v) - original.mesh.positions.row(v)).norm(),
        tolerance)
        << "vertex " << v;
    ASSERT_LT((rig.mesh.normals.row(v) - original.mesh.normals.row(v)).norm(),
              1e-5f)
        << "vertex " << v;
  }
  EXPECT_TRUE(rig.mesh.triangles == original.mesh.triangles);
  EXPECT_EQ(rig.weights.offsets, original.weights.offsets);
  EXPECT_EQ(rig.weights.joints, original.weights.joints);
  for (size_t i = 0; i < rig.weights.weights.size(); ++i) {
    ASSERT_NEAR(rig.weights.weights[i], original.weights.weights[i], 1e-6f);
  }
  ASSERT_EQ(rig.skeleton.jointCount(), original.skeleton.jointCount());
  for (int j = 0; j < rig.skeleton.jointCount(); ++j) {
    const Joint& a = rig.skeleton.joints[j];
    const Joint& b = original.skeleton.joints[j];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.parent, b.parent) << a.name;
    EXPECT_TRUE(
        a.inverse_bind.matrix().isApprox(b.inverse_bind.matrix(), 1e-5f))
        << a.name;
    EXPECT_TRUE(a.rest_local.matrix().isApprox(b.rest_local.matrix(), 1e-5f))
        << a.name;
  }
  ASSERT_EQ(rig.clips.size(), original.clips.size());
  for (size_t c = 0; c < rig.clips.size(); ++c) {
    const AnimationClip& a = rig.clips[c];
    const AnimationClip& b = original.clips[c];
    EXPECT_EQ(a.name, b.name);
    for (double t :
         {b.start, b.start + 0.37 * b.duration, b.start + b.duration}) {
      const TransformList la = a.sampleLocal(rig.skeleton, t);
      const TransformList lb = b.sampleLocal(original.skeleton, t);
      for (size_t j = 0; j < la.size(); ++j) {
        EXPECT_TRUE(la[j].matrix().isApprox(lb[j].matrix(), 1e-4f))
            << a.name << " t=" << t << " joint " << j;
      }
    }
  }
}

TEST(ImportErrors, MissingFileIsAnIoError) {
  ScopedTempDir dir;
  expectImportError(dir.file("absent.glb"), ErrorCode::kIo, {"absent.glb"});
  expectImportError(dir.file(""), ErrorCode::kIo, {"directory"});
}

TEST(ImportErrors, EmptyAndRandomFilesAreMalformed) {
  ScopedTempDir dir;
  std::mt19937 random(7);
  for (const char* extension :
       {".glb", ".gltf", ".fbx", ".dae", ".x", ".obj"}) {
    const std::string empty =
        writeFile(dir.file(std::string("empty") + extension), "");
    expectImportError(empty, ErrorCode::kMalformedAsset, {});
    std::string noise(4096, '\0');
    for (char& c : noise) c = static_cast<char>(random());
    const std::string path =
        writeFile(dir.file(std::string("noise") + extension), noise);
    expectImportError(path, ErrorCode::kMalformedAsset, {});
  }
}

TEST(ImportErrors, TruncatedGltfIsMalformed) {
  ScopedTempDir dir;
  const std::string text = quadGltf({});
  const std::string path =
      writeFile(dir.file("cut.gltf"), text.substr(0, text.size() / 2));
  expectImportError(path, ErrorCode::kMalformedAsset, {});
}

TEST(ImportErrors, MeshWithoutSkeleton) {
  ScopedTempDir dir;
  QuadScene q;
  q.skin = false;
  q.animation = false;
  expectImportError(writeFile(dir.file("static.gltf"), quadGltf(q)),
                    ErrorCode::kMalformedAsset, {"no skeleton"});
  // The same from another format.
  const std::string obj =
      "o box\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
      "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
  expectImportError(writeFile(dir.file("static.obj"), obj),
                    ErrorCode::kMalformedAsset, {"no skeleton"});
}

TEST(ImportErrors, FileWithoutMesh) {
  ScopedTempDir dir;
  QuadScene q;
  q.mesh = false;
  q.skin = false;
  expectImportError(writeFile(dir.file("bones_only.gltf"), quadGltf(q)),
                    ErrorCode::kMalformedAsset, {"no mesh"});
  expectImportError(writeFile(dir.file("nothing.obj"),
                              "# an OBJ file without any geometry\n"),
                    ErrorCode::kMalformedAsset, {"no mesh"});
}

TEST(ImportErrors, VertexWithoutWeight) {
  ScopedTempDir dir;
  QuadScene q;
  q.weights[4] = q.weights[5] = 0.f;  // vertex 2
  expectImportError(writeFile(dir.file("unweighted.gltf"), quadGltf(q)),
                    ErrorCode::kMalformedAsset,
                    {"mesh 'quad' vertex 2 has no skin weight"});
}

TEST(ImportErrors, NonFinitePosition) {
  ScopedTempDir dir;
  QuadScene q;
  q.positions[3 * 3 + 1] = kNaN;  // vertex 3
  expectImportError(writeFile(dir.file("nan.gltf"), quadGltf(q)),
                    ErrorCode::kMalformedAsset,
                    {"mesh 'quad' vertex 3", "non-finite position"});
  q.positions[3 * 3 + 1] = std::numeric_limits<float>::infinity();
  expectImportError(writeFile(dir.file("inf.gltf"), quadGltf(q)),
                    ErrorCode::kMalformedAsset,
                    {"mesh 'quad' vertex 3", "non-finite position"});
}

TEST(ImportErrors, NonFiniteAnimationKey) {
  ScopedTempDir dir;
  QuadScene q;
  q.nan_key = true;
  expectImportError(writeFile(dir.file("nan_key.gltf"), quadGltf(q)),
                    ErrorCode::kMalformedAsset,
                    {"clip 'wave' channel 'child'", "rotation"});
}

TEST(ImportErrors, NonUniformScaleInInverseBind) {
  ScopedTempDir dir;
  QuadScene q;
  q.child_inverse_bind = Eigen::Affine3f(Eigen::Scaling(1.f, 2.f, 1.f)) *
                         Eigen::Translation3f(0.f, -1.f, 0.f);
  expectImportError(writeFile(dir.file("stretched.gltf"), quadGltf(q)),
                    ErrorCode::kMalformedAsset,
                    {"joint 'child'", "non-uniform scale"});
  // A uniform scale (a unit conversion) is fine.
  q.child_inverse_bind = Eigen::Affine3f(Eigen::Scaling(100.f)) *
                         Eigen::Translation3f(0.f, -1.f, 0.f);
  EXPECT_NO_THROW(importRig(writeFile(dir.file("scaled.gltf"), quadGltf(q))));
  // A mirror is not a rotation.
  q.child_inverse_bind = Eigen::Affine3f(Eigen::Scaling(-1.f, 1.f, 1.f)) *
                         Eigen::Translation3f(0.f, -1.f, 0.f);
  expectImportError(writeFile(dir.file("mirrored.gltf"), quadGltf(q)),
                    ErrorCode::kMalformedAsset, {"joint 'child'", "mirrored"});
}

// Progress goes through every stage and ends at 1, on a procedural rig
// written as glTF and on the largest shared asset.
void expectProgressReported(const std::string& path) {
  std::vector<std::pair<std::string, float>> calls;
  ImportOptions options;
  options.progress = [&](const char* stage, float fraction) {
    calls.emplace_back(stage, fraction);
  };
  importRig(path, options);
  ASSERT_FALSE(calls.empty()) << path;
  std::set<std::string> stages;
  for (const auto& [stage, fraction] : calls) {
    stages.insert(stage);
    EXPECT_GE(fraction, 0.f);
    EXPECT_LE(fraction, 1.f);
  }
  EXPECT_EQ(stages,
            (std::set<std::string>{"reading", "processing", "building"}));
  EXPECT_EQ(calls.back().first, "building");
  EXPECT_FLOAT_EQ(calls.back().second, 1.f);
}

TEST(ImportProgress, ReportsEveryStageOnAProceduralRig) {
  ScopedTempDir dir;
  CylinderRigOptions options;
  options.rings = 12;
  options.segments = 8;
  expectProgressReported(
      writeFile(dir.file("cylinder.gltf"), rigGltf(makeCylinderRig(options))));
}

TEST(ImportProgress, ReportsEveryStageOnAnAsset) {
  if (!test::haveAssets()) {
    GTEST_SKIP() << test::missingAssetsMessage("import progress on an asset");
  }
  expectProgressReported(samples::dataFile("human-addon-animations.glb"));
}

}  // namespace
}  // namespace isk
