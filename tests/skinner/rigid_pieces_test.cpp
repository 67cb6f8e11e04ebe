// Rigid pieces (ImplicitFieldsOptions::rigid_pieces): the welded components
// of a mesh bound wholly to one joint are found exactly, the mode decides
// whether they stay on skinning (auto: when they hold half the mesh or
// more), and kept rigid they are where DQS puts them on both skinners. On
// the procedural arm with a plate bolted to its forearm, and on
// RobotExpressive (a robot of rigid plates) and the other assets.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "isk/fields/implicit_fields.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

Eigen::Vector3f bindPosition(const Skeleton& skeleton, int joint) {
  return skeleton.joints[joint].inverse_bind.inverse().translation();
}

// How the plate's vertices are bound.
enum class Binding {
  kOneJoint,    // all to the forearm's joint, weight 1: a rigid piece
  kOneBlended,  // the same, but one vertex half to the wrist
  kTwoJoints,   // half the vertices to the forearm, half to the wrist
};

struct Plated {
  Rig rig;
  std::vector<int> plate;  // the plate's vertices (ascending)
};

// The procedural arm with a closed box of `n` x `n` quads a face beside its
// forearm, touching its skin near the elbow (where the upper arm's field
// reaches it as the elbow bends).
Plated platedArm(int n, Binding binding) {
  Plated out{makeBuiltinRig("arm"), {}};
  Rig& rig = out.rig;
  const int elbow = rig.skeleton.find("elbow");
  const int wrist = rig.skeleton.find("wrist");
  const Eigen::Vector3f a = bindPosition(rig.skeleton, elbow);
  const Eigen::Vector3f b = bindPosition(rig.skeleton, wrist);
  const Eigen::Vector3f axis = (b - a).normalized();
  const Eigen::Vector3f side = axis.unitOrthogonal();
  const Eigen::Vector3f third = axis.cross(side);
  const Eigen::Vector3f middle = a + 0.25f * (b - a);
  float radius = 0;  // the forearm's, there
  for (int v = 0; v < rig.mesh.vertexCount(); ++v) {
    const Eigen::Vector3f p = rig.mesh.positions.row(v).transpose() - middle;
    if (std::abs(p.dot(axis)) < 0.1f * (b - a).norm())
      radius = std::max(radius, (p - p.dot(axis) * axis).norm());
  }
  const float half = 0.2f * (b - a).norm();
  const Eigen::Vector3f centre = middle + (radius + half) * side;

  // Six faces of (n + 1)^2 vertices (their edges duplicated: welded by
  // position into one closed piece), outward normals.
  std::vector<Eigen::Vector3f> points, normals;
  std::vector<Eigen::Vector3i> corners;
  const Eigen::Vector3f frame[3] = {axis, side, third};
  const int first = rig.mesh.vertexCount();
  for (int face = 0; face < 6; ++face) {
    const int k = face / 2;
    const float sign = face % 2 ? -1.f : 1.f;
    const Eigen::Vector3f normal = sign * frame[k];
    const Eigen::Vector3f u = frame[(k + 1) % 3];
    const Eigen::Vector3f w = sign * frame[(k + 2) % 3];
    const int base = first + static_cast<int>(points.size());
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= n; ++j) {
        const float s = 2.f * i / n - 1.f, t = 2.f * j / n - 1.f;
        points.push_back(centre + half * (normal + s * u + t * w));
        normals.push_back(normal);
      }
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const int p = base + i * (n + 1) + j;
        corners.emplace_back(p, p + n + 1, p + n + 2);
        corners.emplace_back(p, p + n + 2, p + 1);
      }
  }
  const int added = static_cast<int>(points.size());
  Mesh& mesh = rig.mesh;
  Matrix3Xf positions(first + added, 3), all_normals(first + added, 3);
  positions.topRows(first) = mesh.positions;
  all_normals.topRows(first) = mesh.normals;
  positions.bottomRows(added) = test::positionsOf(points);
  all_normals.bottomRows(added) = test::positionsOf(normals);
  const TriangleMatrix plate_triangles = test::trianglesOf(corners);
  TriangleMatrix triangles(mesh.triangles.rows() + plate_triangles.rows(), 3);
  triangles.topRows(mesh.triangles.rows()) = mesh.triangles;
  triangles.bottomRows(plate_triangles.rows()) = plate_triangles;
  mesh.positions = std::move(positions);
  mesh.normals = std::move(all_normals);
  mesh.triangles = std::move(triangles);
  mesh.parts.push_back(
      {"plate", first, added,
       static_cast<int>(mesh.triangles.rows() - plate_triangles.rows()),
       static_cast<int>(plate_triangles.rows())});

  std::vector<std::vector<std::pair<int, float>>> lists(first + added);
  for (int v = 0; v < first; ++v)
    for (uint32_t i = rig.weights.offsets[v]; i < rig.weights.offsets[v + 1];
         ++i)
      lists[v].emplace_back(static_cast<int>(rig.weights.joints[i]),
                            rig.weights.weights[i]);
  for (int i = 0; i < added; ++i) {
    const int v = first + i;
    if (binding == Binding::kTwoJoints && i >= added / 2)
      lists[v] = {{wrist, 1.f}};
    else if (binding == Binding::kOneBlended && i == added / 2)
      lists[v] = {{elbow, 0.5f}, {wrist, 0.5f}};
    else
      lists[v] = {{elbow, 1.f}};
    out.plate.push_back(v);
  }
  rig.weights = SkinWeights::fromLists(lists);
  rig.weights.sortByWeight();
  rig.source = "the procedural arm with a plate on its forearm";
  EXPECT_TRUE(rig.validate().isOk()) << rig.validate().reason();
  return out;
}

ImplicitFieldsOptions withMode(RigidPieces mode) {
  ImplicitFieldsOptions options;
  options.rigid_pieces = mode;
  return options;
}

TEST(RigidPieces, NamesParseBack) {
  for (const RigidPieces mode :
       {RigidPieces::kAuto, RigidPieces::kRigid, RigidPieces::kTracked}) {
    RigidPieces parsed = RigidPieces::kTracked;
    EXPECT_TRUE(parseRigidPieces(rigidPiecesName(mode), &parsed));
    EXPECT_EQ(parsed, mode);
  }
  RigidPieces parsed = RigidPieces::kAuto;
  EXPECT_FALSE(parseRigidPieces("bolted", &parsed));
  EXPECT_EQ(parsed, RigidPieces::kAuto);
}

// Exactly the plate, when and only when all of it is bound to one joint;
// the procedural rigs alone have none (their skin is blended).
TEST(RigidPieces, FoundOnProceduralRigs) {
  for (const std::string& name : builtinRigNames())
    EXPECT_TRUE(rigidPieceVertices(makeBuiltinRig(name)).empty()) << name;
  const Plated plated = platedArm(3, Binding::kOneJoint);
  EXPECT_EQ(rigidPieceVertices(plated.rig), plated.plate);
  EXPECT_TRUE(
      rigidPieceVertices(platedArm(3, Binding::kOneBlended).rig).empty());
  EXPECT_TRUE(
      rigidPieceVertices(platedArm(3, Binding::kTwoJoints).rig).empty());
}

// RobotExpressive is bolted plates and skinned hands; the mannequins have
// rigid segments (a minority of their vertices); the skinned characters
// none.
TEST(RigidPieces, FoundOnAssets) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("the assets' rigid pieces");
  for (const std::string& name : test::assetNames()) {
    const Rig& rig = test::loadAsset(name);
    const std::vector<int> pieces = rigidPieceVertices(rig);
    const double share =
        static_cast<double>(pieces.size()) / rig.mesh.vertexCount();
    std::cout << "[ rigid    ] " << name << ": " << pieces.size() << " of "
              << rig.mesh.vertexCount() << " vertices in rigid pieces\n";
    for (const int v : pieces) {
      float largest = 0;
      for (uint32_t i = rig.weights.offsets[v]; i < rig.weights.offsets[v + 1];
           ++i)
        largest = std::max(largest, rig.weights.weights[i]);
      ASSERT_GE(largest, kRigidPieceWeight) << name << " vertex " << v;
    }
    if (name == "RobotExpressive.glb") {
      EXPECT_GE(share, kRigidCharacterShare);
    } else if (name == "human-addon-animations.glb" ||
               name == "human-female.glb") {
      EXPECT_GT(share, 0.1);
      EXPECT_LT(share, kRigidCharacterShare);
    } else if (name == "CesiumMan.glb" || name == "fox-animations.glb" ||
               name == "horse-animations.glb") {
      EXPECT_TRUE(pieces.empty()) << name;
    }
  }
}

// auto keeps the plate rigid only when it holds half the mesh or more;
// rigid always; tracked never. Rigid pieces have iso value 0 and are among
// the untracked vertices; the grids do not change.
TEST(RigidPieces, TheModeDecidesWhichStayOnSkinning) {
  const Plated small = platedArm(3, Binding::kOneJoint);
  const Plated large = platedArm(26, Binding::kOneJoint);
  ASSERT_LT(small.plate.size(), 0.5 * small.rig.mesh.vertexCount());
  ASSERT_GE(large.plate.size(), 0.5 * large.rig.mesh.vertexCount());
  struct Case {
    const Plated* plated;
    RigidPieces mode;
    bool rigid;
  };
  const Case cases[] = {{&small, RigidPieces::kAuto, false},
                        {&small, RigidPieces::kRigid, true},
                        {&small, RigidPieces::kTracked, false},
                        {&large, RigidPieces::kAuto, true},
                        {&large, RigidPieces::kTracked, false}};
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(rigidPiecesName(c.mode)) + ", plate of " +
                 std::to_string(c.plated->plate.size()) + " vertices");
    const ImplicitFields fields =
        buildImplicitFields(c.plated->rig, withMode(c.mode));
    if (c.rigid) {
      EXPECT_EQ(fields.rigid_piece_vertices, c.plated->plate);
      EXPECT_EQ(fields.untracked_vertices, c.plated->plate);
      for (const int v : c.plated->plate)
        ASSERT_EQ(fields.iso_values[v], 0.f) << "vertex " << v;
    } else {
      EXPECT_TRUE(fields.rigid_piece_vertices.empty());
      EXPECT_TRUE(fields.untracked_vertices.empty());
      int tracked = 0;
      for (const int v : c.plated->plate) tracked += fields.iso_values[v] > 0;
      EXPECT_GT(tracked, 0);
    }
  }
  // Untracked joints and rigid pieces together: both, once each, ascending.
  ImplicitFieldsOptions both = withMode(RigidPieces::kRigid);
  both.untracked_joints = {"shoulder"};
  const ImplicitFields fields = buildImplicitFields(small.rig, both);
  EXPECT_TRUE(std::is_sorted(fields.untracked_vertices.begin(),
                             fields.untracked_vertices.end()));
  EXPECT_TRUE(std::adjacent_find(fields.untracked_vertices.begin(),
                                 fields.untracked_vertices.end()) ==
              fields.untracked_vertices.end());
  EXPECT_GT(fields.untracked_vertices.size(), small.plate.size());
  EXPECT_TRUE(std::includes(fields.untracked_vertices.begin(),
                            fields.untracked_vertices.end(),
                            small.plate.begin(), small.plate.end()));
}

// Kept rigid, the plate is where DQS puts it on the reference (exactly
// without the smoothing; within 0.1% of the diagonal with it) and on
// OpenCL; its edges keep their rest lengths. Tracked, the march bends it.
TEST(RigidPieces, StayRigidOnBothSkinnersOnAProceduralRig) {
  const Plated plated = platedArm(3, Binding::kOneJoint);
  const Rig& rig = plated.rig;
  const auto rigid = std::make_shared<const ImplicitFields>(
      buildImplicitFields(rig, withMode(RigidPieces::kRigid)));
  const auto tracked = std::make_shared<const ImplicitFields>(
      buildImplicitFields(rig, withMode(RigidPieces::kTracked)));
  ImplicitSkinnerOptions unsmoothed;
  unsmoothed.tracking.smoothing_steps = 0;
  unsmoothed.tracking.crease_steps = 0;
  CpuImplicitSkinner cpu(rig, rigid), exact(rig, rigid, unsmoothed),
      bent(rig, tracked);
  const auto context = test::sharedContext();
  ImplicitSkinner cl(context, rig, rigid);
  const float diagonal = rig.boundingBoxDiagonal();
  const float tolerance = (context->info().is_gpu ? 2e-2f : 5e-4f) * diagonal;
  Matrix3Xf positions;
  double tracked_move = 0;
  for (const TransformList& pose : test::clipPoses(rig, 4)) {
    CpuSkinning dqs(rig.mesh, rig.weights, rig.skeleton.jointCount());
    dqs.run(SkinningMethod::kDualQuaternion, pose);
    cpu.run(pose);
    exact.run(pose);
    bent.run(pose);
    cl.run(pose);
    cl.readPositions(positions);
    for (const int v : plated.plate) {
      ASSERT_EQ(exact.positions().row(v), dqs.positions().row(v))
          << "vertex " << v;
      ASSERT_LE((cpu.positions().row(v) - dqs.positions().row(v)).norm(),
                1e-3f * diagonal)
          << "vertex " << v;
      ASSERT_LE((positions.row(v) - dqs.positions().row(v)).norm(), tolerance)
          << "vertex " << v;
      tracked_move = std::max<double>(
          tracked_move,
          (bent.positions().row(v) - dqs.positions().row(v)).norm() / diagonal);
    }
    // Rigid: the plate's edges keep their rest lengths.
    for (Eigen::Index f = rig.mesh.parts.back().first_triangle;
         f < rig.mesh.triangles.rows(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int a = rig.mesh.triangles(f, k);
        const int b = rig.mesh.triangles(f, (k + 1) % 3);
        const float rest =
            (rig.mesh.positions.row(a) - rig.mesh.positions.row(b)).norm();
        const float now =
            (exact.positions().row(a) - exact.positions().row(b)).norm();
        ASSERT_NEAR(now, rest, 1e-4f * rest) << "edge " << a << "-" << b;
      }
  }
  std::cout << "[ rigid    ] tracked, the plate moved up to "
            << 100 * tracked_move << "% of the diagonal from DQS\n";
  EXPECT_GT(tracked_move, 1e-4);
}

// RobotExpressive bent 90 degrees: its plates kept rigid (auto: they hold
// most of its vertices) keep the volume near the rest's and strain its
// edges less than the march over every plate.
TEST(RigidPieces, KeepARobotsPlatesOnAnAsset) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("RobotExpressive's plates");
  const std::string name = "RobotExpressive.glb";
  const Rig& rig = test::rigNamed(name);
  const auto fields = std::make_shared<const ImplicitFields>(
      buildImplicitFields(rig, withMode(RigidPieces::kAuto)));
  EXPECT_EQ(fields->rigid_piece_vertices, rigidPieceVertices(rig));
  CpuImplicitSkinner rigid(rig, fields);
  CpuImplicitSkinner tracked(
      rig, std::make_shared<const ImplicitFields>(
               buildImplicitFields(rig, withMode(RigidPieces::kTracked))));
  const double rest = enclosedVolume(rig.mesh.positions, rig.mesh.triangles);
  const AnimationClip bend = makeBendClip(rig.skeleton, M_PI / 2);
  double rigid_volume = 2, tracked_volume = 2;
  for (const double t : {0.5, 1.0}) {
    const TransformList pose = skinningTransforms(
        rig.skeleton,
        globalTransforms(rig.skeleton, bend.sampleLocal(rig.skeleton, t)));
    rigid.run(pose);
    tracked.run(pose);
    rigid_volume =
        std::min(rigid_volume,
                 enclosedVolume(rigid.positions(), rig.mesh.triangles) / rest);
    tracked_volume = std::min(
        tracked_volume,
        enclosedVolume(tracked.positions(), rig.mesh.triangles) / rest);
  }
  std::cout << "[ rigid    ] " << name
            << " bent 90 degrees: smallest volume, plates rigid "
            << rigid_volume << ", tracked " << tracked_volume << "\n";
  EXPECT_GT(rigid_volume, 0.98);
  EXPECT_GT(rigid_volume, tracked_volume + 0.05);
}

}  // namespace
}  // namespace isk
