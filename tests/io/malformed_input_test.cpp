// Malformed input (issue 7, Reliability): every bad file or rig either gives
// a correct result or an isk::Error whose message names the file, mesh,
// joint or vertex -- never a crash, a hang or NaN in the output.
//
// - Files: byte-mutated copies (truncated, bytes overwritten, random bytes
//   behind a valid header) of every shared asset and of procedural rigs
//   written as glTF and GLB, made in a temporary folder.
// - Rigs built in code: degenerate geometry (a single triangle, degenerate,
//   duplicate and non-manifold triangles, open boundaries, disconnected
//   parts, a flat mesh, a mesh of one point), skeletons (joints without
//   vertices, zero-length bones, several hundred joints), weights (many
//   influences, unnormalised), and invalid data (no skeleton, NaN/inf
//   positions or weights, vertices without weights, bad indices).
//
// What loads or builds goes through the whole pipeline: rig validation, the
// implicit fields, LBS and DQS, and implicit skinning frames, on the CPU
// reference and on OpenCL (PoCL in CI); every output position and normal
// must be finite.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "data_folder.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/core/error.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/io/import.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/rig/rig.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tools/procedural.hpp"
#include "rig_gltf.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

namespace fs = std::filesystem;
using test::ScopedTempDir;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr double kPi = 3.14159265358979323846;

// Index of the first row holding a non-finite value, -1 when none.
int firstNonFiniteRow(const Matrix3Xf& m) {
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    if (!m.row(r).allFinite()) return static_cast<int>(r);
  }
  return -1;
}

// Adds a failure naming `what` and the first non-finite row of positions or
// normals (or a wrong row count); true when both are finite and complete.
bool expectFinite(const std::string& what, int vertices,
                  const Matrix3Xf& positions, const Matrix3Xf& normals) {
  if (positions.rows() != vertices || normals.rows() != vertices) {
    ADD_FAILURE() << what << ": " << positions.rows() << " positions and "
                  << normals.rows() << " normals for " << vertices
                  << " vertices";
    return false;
  }
  const int p = firstNonFiniteRow(positions), n = firstNonFiniteRow(normals);
  if (p >= 0)
    ADD_FAILURE() << what << ": vertex " << p << " position is not finite";
  if (n >= 0)
    ADD_FAILURE() << what << ": vertex " << n << " normal is not finite";
  return p < 0 && n < 0;
}

// Poses a rig goes through: the bind pose, its first clip (or a bend of
// every joint) at its middle and end, and a 120-degree bend at its deepest
// joint.
std::vector<TransformList> testPoses(const Rig& rig) {
  std::vector<TransformList> poses = {bindPoseSkinning(rig.skeleton)};
  for (const TransformList& pose : test::clipPoses(rig, 3)) {
    poses.push_back(pose);
  }
  poses.erase(poses.begin() + 1);  // the clip's start is about the bind pose
  int deepest = 0, depth = -1;
  for (int j = 0; j < rig.skeleton.jointCount(); ++j) {
    int d = 0;
    for (int a = rig.skeleton.joints[j].parent; a >= 0;
         a = rig.skeleton.joints[a].parent) {
      ++d;
    }
    if (d > depth && d < 8) deepest = j, depth = d;
  }
  poses.push_back(test::bendAt(rig, deepest, 120.0));
  return poses;
}

struct PipelineOptions {
  bool implicit = true;      // fields and implicit frames too
  int grid_resolution = 16;  // of the fields (32 by default: quicker)
};

// Runs `rig` through the whole pipeline (see the file comment) and checks
// every output is finite. Failures name `name`, the stage, device and pose.
void runWholePipeline(const std::string& name, const Rig& rig,
                      const PipelineOptions& options = {}) {
  SCOPED_TRACE(name);
  const Validation valid = rig.validate();
  ASSERT_TRUE(valid.isOk()) << name << ": " << valid.reason();
  const int n = rig.mesh.vertexCount();
  const int joints = rig.skeleton.jointCount();
  const std::vector<TransformList> poses = testPoses(rig);
  Matrix3Xf positions, normals;

  CpuSkinning cpu(rig.mesh, rig.weights, joints);
  ClSkinning cl(test::sharedContext(), rig.mesh, rig.weights, joints);
  for (const SkinningMethod method :
       {SkinningMethod::kLinearBlend, SkinningMethod::kDualQuaternion}) {
    for (size_t p = 0; p < poses.size(); ++p) {
      const std::string where = name + " " + skinningMethodName(method) +
                                " pose " + std::to_string(p);
      cpu.run(method, poses[p]);
      cpu.readPositions(positions);
      cpu.readNormals(normals);
      if (!expectFinite(where + " (reference)", n, positions, normals)) return;
      cl.run(method, poses[p]);
      cl.readPositions(positions);
      cl.readNormals(normals);
      if (!expectFinite(where + " (OpenCL)", n, positions, normals)) return;
    }
  }
  if (!options.implicit) return;

  ImplicitSkinnerOptions implicit;
  implicit.fields.grid_resolution = options.grid_resolution;
  implicit.fields.threads = 1;
  auto fields = std::make_shared<const ImplicitFields>(
      buildImplicitFields(rig, implicit.fields));
  for (size_t v = 0; v < fields->iso_values.size(); ++v) {
    ASSERT_TRUE(std::isfinite(fields->iso_values[v]))
        << name << ": iso value of vertex " << v;
  }
  CpuImplicitSkinner reference(rig, fields, implicit);
  ImplicitSkinner device(test::sharedContext(), rig, fields, implicit);
  for (size_t p = 0; p < poses.size(); ++p) {
    const std::string where = name + " implicit pose " + std::to_string(p);
    reference.run(poses[p]);
    if (!expectFinite(where + " (reference)", n, reference.positions(),
                      reference.normals())) {
      return;
    }
    device.run(poses[p]);
    device.readPositions(positions);
    device.readNormals(normals);
    if (!expectFinite(where + " (OpenCL)", n, positions, normals)) return;
  }
}

// Calls `build` expecting isk::Error(kInvalidArgument) whose message holds
// every string of `named`.
void expectInvalid(const std::string& what, const std::function<void()>& build,
                   const std::vector<std::string>& named) {
  try {
    build();
    ADD_FAILURE() << what << ": no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument)
        << what << ": " << e.what();
    for (const std::string& s : named) {
      EXPECT_NE(std::string(e.what()).find(s), std::string::npos)
          << what << ": '" << s << "' not in: " << e.what();
    }
  } catch (const std::exception& e) {
    ADD_FAILURE() << what << ": not an isk::Error: " << e.what();
  }
}

// ---------------------------------------------------------------------------
// Rigs built in code.

// Area-weighted normals; +z where a vertex has no non-degenerate triangle.
void computeNormals(Mesh& mesh) {
  mesh.normals = Matrix3Xf::Zero(mesh.vertexCount(), 3);
  for (int f = 0; f < mesh.triangleCount(); ++f) {
    const Eigen::RowVector3f a = mesh.positions.row(mesh.triangles(f, 0));
    const Eigen::RowVector3f b = mesh.positions.row(mesh.triangles(f, 1));
    const Eigen::RowVector3f c = mesh.positions.row(mesh.triangles(f, 2));
    const Eigen::RowVector3f nrm = (b - a).cross(c - a);
    for (int k = 0; k < 3; ++k) mesh.normals.row(mesh.triangles(f, k)) += nrm;
  }
  for (int v = 0; v < mesh.vertexCount(); ++v) {
    const float length = mesh.normals.row(v).norm();
    if (length > 0.f) {
      mesh.normals.row(v) /= length;
    } else {
      mesh.normals.row(v) << 0.f, 0.f, 1.f;
    }
  }
}

// A chain of `count` joints along +x, `spacing` apart, from the origin.
Skeleton chainSkeleton(int count, float spacing) {
  Skeleton skeleton;
  for (int j = 0; j < count; ++j) {
    Joint joint;
    joint.name = "j" + std::to_string(j);
    joint.parent = j - 1;
    joint.rest_local = Eigen::Translation3f(j == 0 ? 0.f : spacing, 0.f, 0.f) *
                       Eigen::Affine3f::Identity();
    joint.inverse_bind = Eigen::Translation3f(-spacing * j, 0.f, 0.f) *
                         Eigen::Affine3f::Identity();
    joint.is_skin_joint = true;
    skeleton.joints.push_back(joint);
  }
  return skeleton;
}

// A rig of `positions` and `triangles` on a chain of `joints` joints, each
// vertex weighted to the joint nearest along x (and its neighbour, blended).
Rig rigFrom(const std::string& name, const Matrix3Xf& positions,
            const TriangleMatrix& triangles, int joints, float spacing) {
  Rig rig;
  rig.source = "builtin:" + name;
  rig.mesh.positions = positions;
  rig.mesh.triangles = triangles;
  rig.mesh.parts = {{name, 0, static_cast<int>(positions.rows()), 0,
                     static_cast<int>(triangles.rows())}};
  computeNormals(rig.mesh);
  rig.skeleton = chainSkeleton(joints, spacing);
  std::vector<std::vector<std::pair<int, float>>> lists(positions.rows());
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    const float x = positions(v, 0) / spacing;
    const int j = std::clamp(static_cast<int>(std::floor(x)), 0, joints - 1);
    const float t = std::clamp(x - j, 0.f, 1.f);
    if (j + 1 < joints && t > 0.5f) {
      lists[v] = {{j, 1.5f - t}, {j + 1, t - 0.5f}};
    } else {
      lists[v] = {{j, 1.f}};
    }
  }
  rig.weights = SkinWeights::fromLists(lists);
  rig.weights.normalize();
  rig.weights.sortByWeight();
  rig.clips.push_back(
      makeBendClip(rig.skeleton, static_cast<float>(kPi / 2), 1.0));
  return rig;
}

// A small closed cylinder on `bones` bones (the procedural builder's).
Rig smallCylinder(int bones = 2, int rings = 16, int segments = 10) {
  CylinderRigOptions options;
  options.bones = bones;
  options.rings = rings;
  options.segments = segments;
  return makeCylinderRig(options);
}

// Appends triangles to a rig's mesh (and its part's count).
void addTriangles(Rig& rig, const std::vector<Eigen::RowVector3i>& extra) {
  const int first = rig.mesh.triangleCount();
  rig.mesh.triangles.conservativeResize(first + extra.size(), 3);
  for (size_t i = 0; i < extra.size(); ++i)
    rig.mesh.triangles.row(first + i) = extra[i];
  rig.mesh.parts.back().triangle_count += static_cast<int>(extra.size());
}

// Appends vertices with `joint`'s full weight; returns the first's index.
int addVertices(Rig& rig, const std::vector<Eigen::RowVector3f>& extra,
                int joint) {
  const int first = rig.mesh.vertexCount();
  rig.mesh.positions.conservativeResize(first + extra.size(), 3);
  rig.mesh.normals.conservativeResize(first + extra.size(), 3);
  for (size_t i = 0; i < extra.size(); ++i) {
    rig.mesh.positions.row(first + i) = extra[i];
    rig.mesh.normals.row(first + i) << 0.f, 0.f, 1.f;
  }
  rig.mesh.parts.back().vertex_count += static_cast<int>(extra.size());
  for (size_t i = 0; i < extra.size(); ++i) {
    rig.weights.joints.push_back(joint);
    rig.weights.weights.push_back(1.f);
    rig.weights.offsets.push_back(
        static_cast<uint32_t>(rig.weights.joints.size()));
  }
  return first;
}

// Rigs that are valid but unusual: each must run through the whole pipeline
// with finite output.
struct OddRig {
  std::string name;
  std::function<Rig()> make;
  PipelineOptions options;
};

std::vector<OddRig> oddRigs() {
  std::vector<OddRig> rigs;
  rigs.push_back({"single triangle", [] {
                    Matrix3Xf p(3, 3);
                    p << 0, 0, 0, 2, 0, 0, 1, 1, 0;
                    TriangleMatrix t(1, 3);
                    t << 0, 1, 2;
                    return rigFrom("single_triangle", p, t, 2, 1.f);
                  }});
  rigs.push_back({"single triangle, one joint", [] {
                    Matrix3Xf p(3, 3);
                    p << 0, 0, 0, 1, 0, 0, 0, 1, 0;
                    TriangleMatrix t(1, 3);
                    t << 0, 1, 2;
                    return rigFrom("one_joint", p, t, 1, 1.f);
                  }});
  rigs.push_back({"degenerate triangles", [] {
                    Rig rig = smallCylinder();
                    // Repeated indices, and a collinear (zero-area) one.
                    addTriangles(rig, {{0, 0, 1}, {2, 2, 2}, {3, 4, 3}});
                    const Eigen::RowVector3f a = rig.mesh.positions.row(5);
                    const Eigen::RowVector3f b = rig.mesh.positions.row(6);
                    const int v = addVertices(rig, {0.5f * (a + b)}, 0);
                    addTriangles(rig, {{5, v, 6}});
                    return rig;
                  }});
  rigs.push_back({"duplicate triangles", [] {
                    Rig rig = smallCylinder();
                    std::vector<Eigen::RowVector3i> copies;
                    for (int f = 0; f < rig.mesh.triangleCount(); f += 3) {
                      copies.push_back(rig.mesh.triangles.row(f));
                      const Eigen::RowVector3i t = rig.mesh.triangles.row(f);
                      copies.push_back({t(0), t(2), t(1)});  // flipped too
                    }
                    addTriangles(rig, copies);
                    return rig;
                  }});
  rigs.push_back({"non-manifold edges and vertices", [] {
                    Rig rig = smallCylinder();
                    // Fins: a third and fourth triangle on existing edges.
                    std::vector<Eigen::RowVector3i> fins;
                    for (int f = 0; f < rig.mesh.triangleCount(); f += 17) {
                      const Eigen::RowVector3i t = rig.mesh.triangles.row(f);
                      const Eigen::RowVector3f mid =
                          0.5f * (rig.mesh.positions.row(t(0)) +
                                  rig.mesh.positions.row(t(1)));
                      const int v = addVertices(
                          rig, {mid + Eigen::RowVector3f(0.f, 0.f, 3.f)}, 0);
                      fins.push_back({t(0), t(1), v});
                      fins.push_back({t(1), t(0), v});
                    }
                    // A bow tie: two triangles meeting at one vertex only.
                    const int b = addVertices(rig,
                                              {{1.f, 3.f, 0.f},
                                               {1.5f, 3.5f, 0.f},
                                               {1.f, 3.5f, 0.f},
                                               {0.5f, 2.5f, 0.f},
                                               {1.f, 2.5f, 0.f}},
                                              0);
                    fins.push_back({b, b + 1, b + 2});
                    fins.push_back({b, b + 3, b + 4});
                    addTriangles(rig, fins);
                    return rig;
                  }});
  rigs.push_back({"open boundary", [] {
                    Rig rig = smallCylinder();
                    // Drop every triangle touching the ends: two holes.
                    const float length = rig.mesh.positions.col(0).maxCoeff();
                    std::vector<Eigen::RowVector3i> kept;
                    for (int f = 0; f < rig.mesh.triangleCount(); ++f) {
                      bool end = false;
                      for (int k = 0; k < 3; ++k) {
                        const float x =
                            rig.mesh.positions(rig.mesh.triangles(f, k), 0);
                        end |= x < 0.3f || x > length - 0.3f;
                      }
                      if (!end) kept.push_back(rig.mesh.triangles.row(f));
                    }
                    rig.mesh.triangles.resize(kept.size(), 3);
                    for (size_t i = 0; i < kept.size(); ++i)
                      rig.mesh.triangles.row(i) = kept[i];
                    rig.mesh.parts.back().triangle_count =
                        static_cast<int>(kept.size());
                    return rig;
                  }});
  rigs.push_back({"disconnected parts", [] {
                    Rig rig = smallCylinder();
                    const int n = rig.mesh.vertexCount();
                    const int f = rig.mesh.triangleCount();
                    rig.mesh.positions.conservativeResize(2 * n, 3);
                    rig.mesh.normals.conservativeResize(2 * n, 3);
                    rig.mesh.triangles.conservativeResize(2 * f, 3);
                    for (int v = 0; v < n; ++v) {
                      rig.mesh.positions.row(n + v) =
                          rig.mesh.positions.row(v) +
                          Eigen::RowVector3f(0, 4, 0);
                      rig.mesh.normals.row(n + v) = rig.mesh.normals.row(v);
                    }
                    rig.mesh.triangles.bottomRows(f) =
                        rig.mesh.triangles.topRows(f).array() + n;
                    rig.mesh.parts.push_back({"copy", n, n, f, f});
                    const uint32_t influences = rig.weights.offsets.back();
                    for (int v = 0; v < n; ++v) {
                      rig.weights.offsets.push_back(influences +
                                                    rig.weights.offsets[v + 1]);
                    }
                    for (uint32_t i = 0; i < influences; ++i) {
                      rig.weights.joints.push_back(rig.weights.joints[i]);
                      rig.weights.weights.push_back(rig.weights.weights[i]);
                    }
                    // And a lone triangle far away, on the root.
                    addVertices(rig, {{0, -9, 0}, {1, -9, 0}, {0, -8, 0}}, 0);
                    addTriangles(rig, {{2 * n, 2 * n + 1, 2 * n + 2}});
                    return rig;
                  }});
  rigs.push_back({"flat mesh", [] {
                    const int cols = 9, rows = 4;
                    Matrix3Xf p(cols * rows, 3);
                    for (int r = 0; r < rows; ++r) {
                      for (int c = 0; c < cols; ++c) {
                        p.row(r * cols + c) << c * 0.5f, r * 0.5f, 0.f;
                      }
                    }
                    TriangleMatrix t(2 * (cols - 1) * (rows - 1), 3);
                    int k = 0;
                    for (int r = 0; r + 1 < rows; ++r) {
                      for (int c = 0; c + 1 < cols; ++c) {
                        const int a = r * cols + c;
                        t.row(k++) << a, a + 1, a + cols + 1;
                        t.row(k++) << a, a + cols + 1, a + cols;
                      }
                    }
                    return rigFrom("flat", p, t, 3, 1.5f);
                  }});
  rigs.push_back({"every vertex at one point", [] {
                    Matrix3Xf p = Matrix3Xf::Constant(6, 3, 1.f);
                    TriangleMatrix t(4, 3);
                    t << 0, 1, 2, 2, 3, 4, 3, 4, 5, 5, 0, 1;
                    return rigFrom("point", p, t, 2, 1.f);
                  }});
  rigs.push_back({"joints without vertices", [] {
                    Rig rig = smallCylinder();
                    // Leaves below the last joint, and a second root.
                    const int last = rig.skeleton.jointCount() - 1;
                    for (int k = 0; k < 3; ++k) {
                      Joint extra = rig.skeleton.joints[last];
                      extra.name = "unweighted" + std::to_string(k);
                      extra.parent =
                          k == 0 ? last : rig.skeleton.jointCount() - 1;
                      rig.skeleton.joints.push_back(extra);
                    }
                    Joint root = rig.skeleton.joints[0];
                    root.name = "lone_root";
                    root.parent = -1;
                    rig.skeleton.joints.push_back(root);
                    rig.clips.clear();
                    return rig;
                  }});
  rigs.push_back(
      {"zero-length bone", [] {
         Rig rig = smallCylinder(3);
         // Joint 2 sits on joint 1: a bone of length 0.
         const float at =
             -rig.skeleton.joints[1].inverse_bind.translation().x();
         rig.skeleton.joints[2].rest_local = Eigen::Affine3f::Identity();
         rig.skeleton.joints[2].inverse_bind =
             Eigen::Translation3f(-at, 0.f, 0.f) * Eigen::Affine3f::Identity();
         rig.clips.clear();
         return rig;
       }});
  rigs.push_back({"every vertex on 40 joints", [] {
                    Rig rig = smallCylinder(40, 41, 8);
                    std::vector<std::vector<std::pair<int, float>>> lists(
                        rig.mesh.vertexCount());
                    for (int v = 0; v < rig.mesh.vertexCount(); ++v) {
                      for (int j = 0; j < 40; ++j) {
                        lists[v].push_back({j, 1.f + 0.01f * ((v + j) % 7)});
                      }
                    }
                    rig.weights = SkinWeights::fromLists(lists);
                    rig.weights.normalize();
                    rig.weights.sortByWeight();
                    return rig;
                  }});
  rigs.push_back({"unnormalised weights, normalized", [] {
                    Rig rig = smallCylinder();
                    for (size_t i = 0; i < rig.weights.weights.size(); ++i) {
                      rig.weights.weights[i] *= 0.001f + 3.f * (i % 5);
                    }
                    rig.weights.normalize();
                    return rig;
                  }});
  rigs.push_back({"300 joints",
                  [] {
                    // A long tube, 1 ring per joint, 6 vertices per ring.
                    const int joints = 300, segments = 6;
                    const int rings = joints + 1;
                    Matrix3Xf p(rings * segments + 2, 3);
                    std::vector<Eigen::RowVector3i> t;
                    for (int r = 0; r < rings; ++r) {
                      for (int s = 0; s < segments; ++s) {
                        const double a = 2 * kPi * s / segments;
                        p.row(r * segments + s) << float(r),
                            0.4f * float(std::cos(a)),
                            0.4f * float(std::sin(a));
                      }
                    }
                    const int cap0 = rings * segments, cap1 = cap0 + 1;
                    p.row(cap0) << 0.f, 0.f, 0.f;
                    p.row(cap1) << float(rings - 1), 0.f, 0.f;
                    for (int r = 0; r + 1 < rings; ++r) {
                      for (int s = 0; s < segments; ++s) {
                        const int a = r * segments + s;
                        const int b = r * segments + (s + 1) % segments;
                        t.push_back({a, b, b + segments});
                        t.push_back({a, b + segments, a + segments});
                      }
                    }
                    for (int s = 0; s < segments; ++s) {
                      const int s1 = (s + 1) % segments;
                      t.push_back({cap0, s1, s});
                      const int last = (rings - 1) * segments;
                      t.push_back({cap1, last + s, last + s1});
                    }
                    TriangleMatrix tm(t.size(), 3);
                    for (size_t i = 0; i < t.size(); ++i) tm.row(i) = t[i];
                    return rigFrom("long_tube", p, tm, joints, 1.f);
                  },
                  {true, 8}});
  return rigs;
}

TEST(MalformedRigs, UnusualButValidRigsRunTheWholePipelineFinite) {
  for (const OddRig& odd : oddRigs()) {
    const auto start = std::chrono::steady_clock::now();
    Rig rig;
    try {
      rig = odd.make();
    } catch (const std::exception& e) {
      ADD_FAILURE() << odd.name << ": building the rig threw " << e.what();
      continue;
    }
    try {
      runWholePipeline(odd.name, rig, odd.options);
    } catch (const Error& e) {
      ADD_FAILURE() << odd.name << ": " << errorCodeName(e.code()) << ": "
                    << e.what();
    }
    std::printf("[ odd rig ] %-36s %5d vertices %4d joints %7.0f ms\n",
                odd.name.c_str(), rig.mesh.vertexCount(),
                rig.skeleton.jointCount(),
                std::chrono::duration<double, std::milli>(
                    std::chrono::steady_clock::now() - start)
                    .count());
  }
}

// Rigs that are invalid: every builder and skinner refuses them with
// kInvalidArgument naming what is wrong.
struct BadRig {
  std::string name;
  std::function<void(Rig&)> spoil;
  std::vector<std::string> named;  // in the message
};

std::vector<BadRig> badRigs() {
  auto set_weight = [](float w) {
    return [w](Rig& rig) { rig.weights.weights[rig.weights.offsets[7]] = w; };
  };
  return {
      {"no skeleton",
       [](Rig& rig) { rig.skeleton.joints.clear(); },
       {"no joint"}},
      {"vertex without weight",
       [](Rig& rig) {
         std::vector<std::vector<std::pair<int, float>>> lists(
             rig.mesh.vertexCount(), {{0, 1.f}});
         lists[9].clear();
         rig.weights = SkinWeights::fromLists(lists);
       },
       {"mesh 'cylinder' vertex 9", "no skin weight"}},
      {"NaN position",
       [](Rig& rig) { rig.mesh.positions(11, 1) = kNaN; },
       {"mesh 'cylinder' vertex 11", "non-finite position"}},
      {"infinite position",
       [](Rig& rig) { rig.mesh.positions(12, 0) = -kInf; },
       {"mesh 'cylinder' vertex 12", "non-finite position"}},
      {"NaN normal",
       [](Rig& rig) { rig.mesh.normals(13, 2) = kNaN; },
       {"mesh 'cylinder' vertex 13", "non-finite normal"}},
      {"NaN weight", set_weight(kNaN), {"vertex 7", "invalid weight"}},
      {"infinite weight", set_weight(kInf), {"vertex 7", "invalid weight"}},
      {"negative weight", set_weight(-0.5f), {"vertex 7"}},
      {"unnormalised weights", set_weight(3.f), {"vertex 7", "summing to"}},
      {"weight on a joint that does not exist",
       [](Rig& rig) { rig.weights.joints[rig.weights.offsets[7]] = 99; },
       {"vertex 7", "joint 99"}},
      {"weights for fewer vertices",
       [](Rig& rig) {
         rig.weights.offsets.pop_back();
         rig.weights.offsets.back() = rig.weights.joints.size();
       },
       {"rows for"}},
      {"triangle index out of range",
       [](Rig& rig) { rig.mesh.triangles(5, 1) = rig.mesh.vertexCount(); },
       {"triangle 5", "refers to vertex"}},
      {"negative triangle index",
       [](Rig& rig) { rig.mesh.triangles(6, 2) = -1; },
       {"triangle 6"}},
      {"no triangle",
       [](Rig& rig) { rig.mesh.triangles.resize(0, 3); },
       {"no triangle"}},
      {"normals missing",
       [](Rig& rig) { rig.mesh.normals.resize(3, 3); },
       {"normals have 3 rows"}},
      {"NaN joint transform",
       [](Rig& rig) { rig.skeleton.joints[1].inverse_bind(0, 3) = kNaN; },
       {"joint '", "non-finite transform"}},
      {"child before its parent",
       [](Rig& rig) { rig.skeleton.joints[0].parent = 1; },
       {"parents must precede children"}},
      {"sheared bind transform",
       [](Rig& rig) {
         rig.skeleton.joints[1].inverse_bind.linear()(0, 1) = 0.7f;
       },
       {"joint '", "non-rigid"}},
  };
}

TEST(MalformedRigs, InvalidRigsAreRefusedNamingWhatIsWrong) {
  const Rig good = smallCylinder();
  ASSERT_TRUE(good.validate().isOk());
  for (const BadRig& bad : badRigs()) {
    Rig rig = good;
    bad.spoil(rig);
    const Validation valid = rig.validate();
    EXPECT_FALSE(valid.isOk()) << bad.name;
    for (const std::string& s : bad.named) {
      EXPECT_NE(valid.reason().find(s), std::string::npos)
          << bad.name << ": '" << s << "' not in: " << valid.reason();
    }
    const int joints = rig.skeleton.jointCount();
    // Each entry point refuses it (the geometric skinners check only the
    // mesh and weights, the implicit ones the whole rig).
    const bool skeleton_only = bad.name == "NaN joint transform" ||
                               bad.name == "child before its parent" ||
                               bad.name == "sheared bind transform";
    if (!skeleton_only) {
      expectInvalid(bad.name + ": CpuSkinning",
                    [&] { CpuSkinning(rig.mesh, rig.weights, joints); }, {});
      expectInvalid(bad.name + ": ClSkinning",
                    [&] {
                      ClSkinning(test::sharedContext(), rig.mesh, rig.weights,
                                 joints);
                    },
                    {});
    }
    expectInvalid(
        bad.name + ": buildImplicitFields", [&] { buildImplicitFields(rig); },
        bad.named);
    expectInvalid(
        bad.name + ": CpuImplicitSkinner",
        [&] { CpuImplicitSkinner skinner(rig); }, bad.named);
    expectInvalid(
        bad.name + ": ImplicitSkinner",
        [&] { ImplicitSkinner skinner(test::sharedContext(), rig); },
        bad.named);
  }
}

// ---------------------------------------------------------------------------
// Byte-mutated files.

struct Mutant {
  std::string label;
  std::string bytes;
};

// Copies of `bytes` cut short, with bytes overwritten, or random bytes behind
// the first 32 (the format's header): the same ones every run (fixed seed).
std::vector<Mutant> mutantsOf(const std::string& bytes, unsigned seed) {
  std::vector<Mutant> mutants;
  const size_t size = bytes.size();
  for (const double fraction : {0.0, 0.02, 0.1, 0.25, 0.5, 0.75, 0.9, 0.99}) {
    const size_t cut = static_cast<size_t>(fraction * size);
    mutants.push_back({"truncated to " + std::to_string(cut) + " bytes",
                       bytes.substr(0, cut)});
  }
  mutants.push_back({"last byte cut", bytes.substr(0, size - 1)});
  std::mt19937 random(seed);
  for (const int flips : {1, 4, 16, 64, 256}) {
    for (int copy = 0; copy < 3; ++copy) {
      std::string mutated = bytes;
      for (int k = 0; k < flips; ++k) {
        mutated[random() % size] = static_cast<char>(random());
      }
      mutants.push_back({std::to_string(flips) + " bytes overwritten (copy " +
                             std::to_string(copy) + ")",
                         mutated});
    }
  }
  // A run of zeros and a run of 0xff in the middle (counts, offsets).
  for (const char fill : {'\0', '\xff'}) {
    std::string mutated = bytes;
    const size_t at = size / 3, length = std::min<size_t>(64, size - at);
    mutated.replace(at, length, length, fill);
    mutants.push_back({std::string("64 bytes of ") + (fill ? "0xff" : "zero") +
                           " at " + std::to_string(at),
                       mutated});
  }
  std::string noise = bytes.substr(0, std::min<size_t>(32, size));
  while (noise.size() < std::min<size_t>(size, 1 << 16)) {
    noise += static_cast<char>(random());
  }
  mutants.push_back({"random bytes behind the header", noise});
  return mutants;
}

struct MutationTally {
  int loaded = 0, refused = 0;
};

// Imports every mutant of `bytes` (written as `name` in `dir`): each either
// loads into a valid rig that skins to finite output (whole pipeline for
// the first one that loads, when `implicit`), or throws isk::Error with a
// message that starts with the file's path.
MutationTally checkMutants(const ScopedTempDir& dir, const std::string& name,
                           const std::string& bytes, unsigned seed,
                           bool implicit) {
  MutationTally tally;
  const std::vector<Mutant> mutants = mutantsOf(bytes, seed);
  for (size_t m = 0; m < mutants.size(); ++m) {
    const std::string what =
        name + " mutant " + std::to_string(m) + " (" + mutants[m].label + ")";
    const std::string path = test::writeBytes(
        dir.file("m" + std::to_string(m) + "_" + name), mutants[m].bytes);
    Rig rig;
    try {
      rig = importRig(path);
    } catch (const Error& e) {
      ++tally.refused;
      EXPECT_TRUE(e.code() == ErrorCode::kMalformedAsset ||
                  e.code() == ErrorCode::kIo)
          << what << ": " << errorCodeName(e.code()) << ": " << e.what();
      EXPECT_EQ(std::string(e.what()).rfind(path, 0), 0u)
          << what << ": the message does not start with the file: " << e.what();
      continue;
    } catch (const std::exception& e) {
      ADD_FAILURE() << what << ": not an isk::Error: " << e.what();
      continue;
    }
    ++tally.loaded;
    PipelineOptions options;
    options.implicit = implicit && tally.loaded == 1;
    try {
      runWholePipeline(what, rig, options);
    } catch (const Error& e) {
      ADD_FAILURE() << what << " loaded but failed later: " << e.what();
    }
  }
  return tally;
}

TEST(MalformedFiles, MutatedProceduralRigFilesLoadOrNameTheFile) {
  ScopedTempDir dir;
  CylinderRigOptions options;
  options.bones = 3;
  options.rings = 12;
  options.segments = 8;
  const Rig rig = makeCylinderRig(options);
  const struct {
    const char* name;
    std::string bytes;
  } files[] = {{"cylinder.gltf", test::rigGltf(rig)},
               {"cylinder.glb", test::rigGlb(rig)}};
  for (const auto& file : files) {
    // The unmutated file loads: the mutations start from a good file.
    const Rig loaded =
        importRig(test::writeBytes(dir.file(file.name), file.bytes));
    ASSERT_EQ(loaded.mesh.vertexCount(), rig.mesh.vertexCount()) << file.name;
    const MutationTally tally =
        checkMutants(dir, file.name, file.bytes, 11, /*implicit=*/true);
    std::printf("[ mutants ] %-28s %3d loaded, %3d refused\n", file.name,
                tally.loaded, tally.refused);
    EXPECT_GT(tally.refused, 0) << file.name;
  }
}

TEST(MalformedFiles, MutatedAssetsLoadOrNameTheFile) {
  if (!test::haveAssets()) {
    GTEST_SKIP() << test::missingAssetsMessage(
        "the byte-mutated copies of every asset (the same mutations run on "
        "procedural rigs written as glTF and GLB)");
  }
  ScopedTempDir dir;
  unsigned seed = 1;
  for (const std::string& name : test::assetNames()) {
    const std::string bytes = test::readFile(samples::dataFile(name));
    ASSERT_FALSE(bytes.empty()) << name;
    const auto start = std::chrono::steady_clock::now();
    const bool small = bytes.size() < 200000;
    const MutationTally tally = checkMutants(dir, name, bytes, seed++, small);
    std::printf("[ mutants ] %-28s %3d loaded, %3d refused, %6.0f ms\n",
                name.c_str(), tally.loaded, tally.refused,
                std::chrono::duration<double, std::milli>(
                    std::chrono::steady_clock::now() - start)
                    .count());
    EXPECT_GT(tally.refused, 0) << name;
  }
}

// Several hundred joints through a file: the 300-joint tube written as GLB
// loads with every joint and weight, and skins to finite output.
TEST(MalformedFiles, SeveralHundredJointsLoadFromAFile) {
  Rig tube;
  for (const OddRig& odd : oddRigs()) {
    if (odd.name == "300 joints") tube = odd.make();
  }
  ASSERT_EQ(tube.skeleton.jointCount(), 300);
  ScopedTempDir dir;
  const std::string path =
      test::writeBytes(dir.file("tube300.glb"), test::rigGlb(tube));
  const Rig rig = importRig(path);
  EXPECT_EQ(rig.skeleton.jointCount(), 300);
  EXPECT_EQ(rig.skeleton.skinJointCount(), 300);
  ASSERT_EQ(rig.mesh.vertexCount(), tube.mesh.vertexCount());
  EXPECT_EQ(rig.weights.joints, tube.weights.joints);
  PipelineOptions options;
  options.implicit = false;  // MalformedRigs runs it on the same rig
  runWholePipeline("tube300.glb", rig, options);
}

// NaN and infinite positions and weights in a file name the mesh and vertex
// (glTF and GLB of a procedural rig, one value spoiled at a time).
TEST(MalformedFiles, NonFiniteValuesInAFileNameTheVertex) {
  ScopedTempDir dir;
  const Rig good = smallCylinder();
  struct Case {
    std::string name;
    std::function<void(Rig&)> spoil;
    std::vector<std::string> named;
  };
  const std::vector<Case> cases = {
      {"nan_position",
       [](Rig& r) { r.mesh.positions(11, 1) = kNaN; },
       {"mesh 'cylinder' vertex 11", "non-finite position"}},
      {"inf_position",
       [](Rig& r) { r.mesh.positions(12, 2) = kInf; },
       {"mesh 'cylinder' vertex 12", "non-finite position"}},
      {"nan_weight",
       [](Rig& r) { r.weights.weights[r.weights.offsets[7]] = kNaN; },
       {"vertex 7"}},
      {"inf_weight",
       [](Rig& r) { r.weights.weights[r.weights.offsets[8]] = kInf; },
       {"vertex 8"}},
  };
  for (const Case& c : cases) {
    Rig rig = good;
    c.spoil(rig);
    for (const bool binary : {false, true}) {
      const std::string path =
          test::writeBytes(dir.file(c.name + (binary ? ".glb" : ".gltf")),
                           binary ? test::rigGlb(rig) : test::rigGltf(rig));
      try {
        const Rig loaded = importRig(path);
        ADD_FAILURE() << path << " loaded";
      } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::kMalformedAsset) << e.what();
        EXPECT_EQ(std::string(e.what()).rfind(path, 0), 0u) << e.what();
        for (const std::string& s : c.named) {
          EXPECT_NE(std::string(e.what()).find(s), std::string::npos)
              << path << ": '" << s << "' not in: " << e.what();
        }
      }
    }
  }
}

// Random bytes under every extension Assimp might pick an importer by, and
// files that hold only a valid header.
TEST(MalformedFiles, RandomBytesAndBareHeadersNameTheFile) {
  ScopedTempDir dir;
  std::mt19937 random(5);
  const std::vector<std::pair<std::string, std::string>> headers = {
      {".glb", std::string("glTF\x02\0\0\0\x40\0\0\0", 12)},
      {".gltf", "{\"asset\": {\"version\": \"2.0\"}, \"meshes\": [{"},
      {".fbx", std::string("Kaydara FBX Binary  \0\x1a\0", 23)},
      {".fbx", "; FBX 7.4.0 project file\nObjects: {\n"},
      {".dae",
       "<?xml version=\"1.0\"?><COLLADA "
       "xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" "
       "version=\"1.4.1\"><library_geometries>"},
      {".x", "xof 0303txt 0032\nFrame {\n"},
      {".x", "xof 0303bin 0032"},
      {".obj", "v 0 0 0\nf 1 2 3\n"},
  };
  for (size_t h = 0; h < headers.size(); ++h) {
    for (const size_t tail : {size_t(0), size_t(7), size_t(4096)}) {
      std::string bytes = headers[h].second;
      for (size_t k = 0; k < tail; ++k) bytes += static_cast<char>(random());
      const std::string path =
          test::writeBytes(dir.file("h" + std::to_string(h) + "_" +
                                    std::to_string(tail) + headers[h].first),
                           bytes);
      try {
        importRig(path);
        ADD_FAILURE() << path << " loaded";
      } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::kMalformedAsset) << e.what();
        EXPECT_EQ(std::string(e.what()).rfind(path, 0), 0u) << e.what();
      } catch (const std::exception& e) {
        ADD_FAILURE() << path << ": not an isk::Error: " << e.what();
      }
    }
  }
}

}  // namespace
}  // namespace isk
