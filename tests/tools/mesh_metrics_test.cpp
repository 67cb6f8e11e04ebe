// Mesh measures: the covered volume counts the space a closed surface
// encloses once, whatever its winding and however often it encloses it;
// against the enclosed (signed) volume on boxes, on the procedural rigs and
// on the shared assets.
#include "isk/tools/mesh_metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include "isk/core/error.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tools/procedural.hpp"
#include "isk/tools/self_intersection.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

// An axis-aligned box from `lo` to `lo + size`, wound outwards, appended to
// `positions` and `triangles`.
void appendBox(const Eigen::Vector3f& lo, const Eigen::Vector3f& size,
               Matrix3Xf* positions, TriangleMatrix* triangles) {
  const Eigen::Index base = positions->rows();
  positions->conservativeResize(base + 8, 3);
  for (int c = 0; c < 8; ++c)
    positions->row(base + c) = (lo + Eigen::Vector3f((c & 1) ? size.x() : 0.f,
                                                     (c & 2) ? size.y() : 0.f,
                                                     (c & 4) ? size.z() : 0.f))
                                   .transpose();
  const int faces[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6},
                            {0, 1, 4}, {1, 5, 4}, {2, 6, 3}, {3, 6, 7},
                            {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  const Eigen::Index first = triangles->rows();
  triangles->conservativeResize(first + 12, 3);
  for (int f = 0; f < 12; ++f)
    for (int k = 0; k < 3; ++k)
      (*triangles)(first + f, k) = static_cast<int32_t>(base + faces[f][k]);
}

TEST(CoveredVolume, ABoxIsItsVolume) {
  Matrix3Xf positions(0, 3);
  TriangleMatrix triangles(0, 3);
  appendBox({0.f, 0.f, 0.f}, {2.f, 1.f, 0.5f}, &positions, &triangles);
  EXPECT_NEAR(enclosedVolume(positions, triangles), 1.0, 1e-9);
  EXPECT_NEAR(coveredVolume(positions, triangles), 1.0, 1e-9);
}

TEST(CoveredVolume, OverlappingBoxesCountTheOverlapOnce) {
  Matrix3Xf positions(0, 3);
  TriangleMatrix triangles(0, 3);
  appendBox({0.f, 0.f, 0.f}, {1.f, 1.f, 1.f}, &positions, &triangles);
  appendBox({0.5f, 0.f, 0.f}, {1.f, 1.f, 1.f}, &positions, &triangles);
  // The signed volume counts the shared half twice; the union is 1.5.
  EXPECT_NEAR(enclosedVolume(positions, triangles), 2.0, 1e-9);
  EXPECT_NEAR(coveredVolume(positions, triangles), 1.5, 1e-9);
  // A box inside another adds nothing.
  appendBox({0.2f, 0.2f, 0.2f}, {0.5f, 0.5f, 0.5f}, &positions, &triangles);
  EXPECT_NEAR(coveredVolume(positions, triangles), 1.5, 1e-9);
}

TEST(CoveredVolume, AnInsideOutBoxCountsAsSolid) {
  Matrix3Xf positions(0, 3);
  TriangleMatrix triangles(0, 3);
  appendBox({0.f, 0.f, 0.f}, {1.f, 1.f, 1.f}, &positions, &triangles);
  triangles.col(1).swap(triangles.col(2));
  EXPECT_NEAR(enclosedVolume(positions, triangles), -1.0, 1e-9);
  EXPECT_NEAR(coveredVolume(positions, triangles), 1.0, 1e-9);
}

TEST(CoveredVolume, ATurnedBoxIsItsVolumeUpToTheGrid) {
  Matrix3Xf positions(0, 3);
  TriangleMatrix triangles(0, 3);
  appendBox({-0.5f, -0.5f, -0.5f}, {1.f, 1.f, 1.f}, &positions, &triangles);
  const Eigen::Matrix3f turn =
      (Eigen::AngleAxisf(0.6f, Eigen::Vector3f::UnitZ()) *
       Eigen::AngleAxisf(0.4f, Eigen::Vector3f::UnitX()))
          .toRotationMatrix();
  positions = (positions * turn.transpose()).eval();
  EXPECT_NEAR(coveredVolume(positions, triangles), 1.0, 5e-3);
  EXPECT_NEAR(coveredVolume(positions, triangles, 64), 1.0, 3e-2);
}

TEST(CoveredVolume, BadInputIsAClearError) {
  Matrix3Xf positions(0, 3);
  TriangleMatrix triangles(0, 3);
  EXPECT_EQ(coveredVolume(positions, triangles), 0.0);
  appendBox({0.f, 0.f, 0.f}, {1.f, 1.f, 1.f}, &positions, &triangles);
  EXPECT_THROW(coveredVolume(positions, triangles, 0), Error);
  triangles(3, 1) = 8;
  try {
    coveredVolume(positions, triangles);
    FAIL() << "no error for a vertex index out of range";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 3"), std::string::npos)
        << e.what();
  }
}

// At rest a mesh that does not pass through itself covers what it
// encloses.
void checkAgainstEnclosed(const Rig& rig) {
  const Mesh& mesh = rig.mesh;
  const double enclosed =
      std::abs(enclosedVolume(mesh.positions, mesh.triangles));
  const double covered = coveredVolume(mesh.positions, mesh.triangles);
  const std::vector<int> groups = coincidentVertexGroups(mesh.positions);
  const int rest_pairs =
      countSelfIntersections(mesh.positions, mesh.triangles, &groups);
  std::cout << "[ covered volume ] " << rig.source << ": enclosed " << enclosed
            << ", covered " << covered << ", pairs at rest " << rest_pairs
            << "\n";
  // Where it does (layers, parts wound inside out), either may be larger.
  EXPECT_GT(covered, 0.0);
  if (rest_pairs == 0) EXPECT_NEAR(covered, enclosed, 0.01 * enclosed);
}

TEST(CoveredVolume, MatchesTheEnclosedVolumeAtRestOnProceduralRigs) {
  for (const std::string& name : builtinRigNames()) {
    SCOPED_TRACE(name);
    checkAgainstEnclosed(test::rigNamed(name));
  }
  // The cylinder bent to 150 degrees by DQS passes through itself: it
  // covers less than its signed volume says.
  const Rig& rig = test::rigNamed("cylinder");
  const int joint = rig.skeleton.find("bone1");
  ASSERT_GE(joint, 0);
  CpuSkinning dqs(rig.mesh, rig.weights, rig.skeleton.jointCount());
  dqs.run(SkinningMethod::kDualQuaternion, test::bendAt(rig, joint, 150),
          false);
  const double enclosed = enclosedVolume(dqs.positions(), rig.mesh.triangles);
  const double covered = coveredVolume(dqs.positions(), rig.mesh.triangles);
  std::cout << "[ covered volume ] cylinder at 150 degrees: enclosed "
            << enclosed << ", covered " << covered << "\n";
  EXPECT_LT(covered, 0.99 * enclosed);
}

TEST(CoveredVolume, MatchesTheEnclosedVolumeAtRestOnAssets) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("covered volume on assets");
  for (const std::string& name : test::assetNames()) {
    SCOPED_TRACE(name);
    const Rig& rig = test::rigNamed(name);
    if (std::abs(enclosedVolume(rig.mesh.positions, rig.mesh.triangles)) <
        1e-6 * std::pow(rig.boundingBoxDiagonal(), 3))
      continue;  // open or flat: no volume to speak of
    checkAgainstEnclosed(rig);
  }
}

}  // namespace
}  // namespace isk
