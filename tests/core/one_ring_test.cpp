// One-rings and mean value coordinates (isk/core/one_ring.hpp): welding of seam
// copies, ring kinds, the weights reproducing each vertex in its tangent
// plane, and the documented fallbacks (boundary, irregular, negative
// weights), on hand-made meshes, the procedural rigs and the assets.
#include "isk/core/one_ring.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "isk/core/error.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

// A fan of `n` triangles around vertex 0 at the origin, neighbours on the
// unit circle in the xy plane (counter-clockwise seen from +z), closed.
struct Fan {
  Matrix3Xf positions;
  TriangleMatrix triangles;
};
Fan closedFan(int n, float lift = 0.f) {
  Fan fan;
  fan.positions.resize(n + 1, 3);
  fan.positions.row(0) << 0, 0, lift;
  for (int j = 0; j < n; ++j) {
    const float a = 2.f * static_cast<float>(M_PI) * j / n;
    fan.positions.row(j + 1) << std::cos(a), std::sin(a), 0;
  }
  fan.triangles.resize(n, 3);
  for (int j = 0; j < n; ++j) fan.triangles.row(j) << 0, j + 1, (j + 1) % n + 1;
  return fan;
}

// The weights reproduce vertex v from its ring projected on the ring's
// plane: |sum_j w_j q_j - v| in the plane. Returns the largest error over
// the vertices with mean value weights, and the first offending vertex.
struct Reproduction {
  double error = 0;
  int vertex = -1;
};
Reproduction reproduction(const OneRings& rings, const RelaxationWeights& w,
                          const Matrix3Xf& positions) {
  Reproduction worst;
  for (int v = 0; v < rings.vertexCount(); ++v) {
    if (w.rules[v] != RelaxationRule::kMeanValue) continue;
    const uint32_t begin = rings.offsets[v], end = rings.offsets[v + 1];
    const Eigen::Vector3d x = positions.row(v).cast<double>();
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    for (uint32_t i = begin; i < end; ++i) {
      const uint32_t j = i + 1 < end ? i + 1 : begin;
      normal +=
          (positions.row(rings.neighbours[i]).cast<double>().transpose() - x)
              .cross(positions.row(rings.neighbours[j])
                         .cast<double>()
                         .transpose() -
                     x);
    }
    normal.normalize();
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double scale = 0;
    for (uint32_t i = begin; i < end; ++i) {
      Eigen::Vector3d e =
          positions.row(rings.neighbours[i]).cast<double>().transpose() - x;
      scale = std::max(scale, e.norm());
      e -= e.dot(normal) * normal;
      sum += w.weights[i] * e;
    }
    const double error = sum.norm() / scale;
    if (error > worst.error) worst = {error, v};
  }
  return worst;
}

TEST(OneRings, ClosedFanGivesOrderedRingAndMeanValueWeights) {
  const Fan fan = closedFan(6, 0.3f);
  const OneRings rings = OneRings::build(fan.positions, fan.triangles);
  // The centre is interior; the rim vertices lie on the open border.
  EXPECT_EQ(rings.kinds[0], RingKind::kClosed);
  for (int v = 1; v <= 6; ++v) EXPECT_EQ(rings.kinds[v], RingKind::kBoundary);
  ASSERT_EQ(rings.offsets[1] - rings.offsets[0], 6u);
  // Consecutive neighbours share a triangle with the centre.
  for (uint32_t i = 0; i < 6; ++i) {
    const int a = rings.neighbours[i], b = rings.neighbours[(i + 1) % 6];
    EXPECT_TRUE(std::abs(a - b) == 1 || std::abs(a - b) == 5) << a << " " << b;
  }
  const RelaxationWeights w = RelaxationWeights::build(rings, fan.positions);
  EXPECT_EQ(w.rules[0], RelaxationRule::kMeanValue);
  double sum = 0;
  for (uint32_t i = rings.offsets[0]; i < rings.offsets[1]; ++i) {
    EXPECT_NEAR(w.weights[i], 1.0 / 6.0, 1e-6);  // a regular fan
    sum += w.weights[i];
  }
  EXPECT_NEAR(sum, 1.0, 1e-6);
  for (int v = 1; v <= 6; ++v) EXPECT_EQ(w.rules[v], RelaxationRule::kFixed);
}

TEST(OneRings, IrregularFanReproducesTheCentre) {
  Fan fan = closedFan(7);
  // Move the neighbours: radii and angles vary, still star-shaped.
  const float radii[] = {1.f, 0.5f, 2.f, 1.3f, 0.8f, 1.7f, 1.1f};
  for (int j = 0; j < 7; ++j) {
    const float a = 2.f * static_cast<float>(M_PI) * (j + 0.3f * (j % 2)) / 7;
    fan.positions.row(j + 1) << radii[j] * std::cos(a), radii[j] * std::sin(a),
        0.1f * j;
  }
  const OneRings rings = OneRings::build(fan.positions, fan.triangles);
  const RelaxationWeights w = RelaxationWeights::build(rings, fan.positions);
  ASSERT_EQ(w.rules[0], RelaxationRule::kMeanValue);
  for (uint32_t i = rings.offsets[0]; i < rings.offsets[1]; ++i)
    EXPECT_GT(w.weights[i], 0.f);
  EXPECT_LT(reproduction(rings, w, fan.positions).error, 1e-5);
}

TEST(OneRings, NonStarShapedRingClampsNegativeWeights) {
  // A closed ring around the origin whose polygon turns back on itself
  // (q4 -> q5 goes clockwise seen from the centre): the centre is outside
  // the polygon's kernel and q5's mean value weight comes out negative.
  Fan fan = closedFan(7);
  const float ring[7][2] = {{1.f, 0.f},     {0.f, 1.f},      {-1.f, 0.f},
                            {-0.1f, -0.5f}, {-0.5f, -0.45f}, {-0.6f, -0.8f},
                            {0.5f, -1.f}};
  for (int j = 0; j < 7; ++j)
    fan.positions.row(j + 1) << ring[j][0], ring[j][1], 0;
  const OneRings rings = OneRings::build(fan.positions, fan.triangles);
  const RelaxationWeights w = RelaxationWeights::build(rings, fan.positions);
  EXPECT_EQ(w.rules[0], RelaxationRule::kClampedMean)
      << relaxationRuleName(w.rules[0]);
  double sum = 0;
  int zeros = 0;
  for (uint32_t i = rings.offsets[0]; i < rings.offsets[1]; ++i) {
    EXPECT_GE(w.weights[i], 0.f) << i;
    zeros += w.weights[i] == 0.f;
    sum += w.weights[i];
  }
  EXPECT_GE(zeros, 1);
  EXPECT_NEAR(sum, 1.0, 1e-6);
  EXPECT_EQ(w.count(RelaxationRule::kClampedMean), 1);
}

TEST(OneRings, SeamCopiesAreWeldedToOneRepresentative) {
  // The cylinder with its seam split: copies of the first column of
  // vertices, and the last column of triangles using the copies.
  CylinderRigOptions options;
  options.rings = 12;
  options.segments = 10;
  const Rig rig = makeCylinderRig(options);
  const OneRings whole =
      OneRings::build(rig.mesh.positions, rig.mesh.triangles);
  ASSERT_EQ(whole.count(RingKind::kClosed), rig.mesh.vertexCount());

  Matrix3Xf positions = rig.mesh.positions;
  TriangleMatrix triangles = rig.mesh.triangles;
  const int n = rig.mesh.vertexCount();
  std::vector<int> copy_of(n, -1);
  // Copy every vertex of the seam at angle 0 (z = 0, y > 0: the cylinder
  // runs along x) and make the triangles on its negative-z side use the
  // copies.
  std::vector<int> seam;
  for (int v = 0; v < n; ++v)
    if (std::abs(positions(v, 2)) < 1e-6f && positions(v, 1) > 0.5f)
      seam.push_back(v);
  ASSERT_GT(seam.size(), 5u);
  positions.conservativeResize(n + seam.size(), 3);
  for (size_t k = 0; k < seam.size(); ++k) {
    positions.row(n + k) = positions.row(seam[k]);
    copy_of[seam[k]] = n + static_cast<int>(k);
  }
  for (Eigen::Index t = 0; t < triangles.rows(); ++t) {
    float z = 0;
    for (int c = 0; c < 3; ++c) z += positions(triangles(t, c), 2);
    if (z >= 0) continue;
    for (int c = 0; c < 3; ++c)
      if (copy_of[triangles(t, c)] >= 0)
        triangles(t, c) = copy_of[triangles(t, c)];
  }
  const OneRings rings = OneRings::build(positions, triangles);
  EXPECT_EQ(rings.count(RingKind::kDuplicate), static_cast<int>(seam.size()));
  for (size_t k = 0; k < seam.size(); ++k) {
    EXPECT_EQ(rings.representative[n + k], seam[k]);
    EXPECT_EQ(rings.kinds[seam[k]], RingKind::kClosed) << seam[k];
    EXPECT_EQ(rings.offsets[n + k + 1] - rings.offsets[n + k], 0u);
  }
  // Welded, the split mesh has the rings of the whole one.
  for (int v = 0; v < n; ++v) {
    const std::set<int> a(whole.neighbours.begin() + whole.offsets[v],
                          whole.neighbours.begin() + whole.offsets[v + 1]);
    const std::set<int> b(rings.neighbours.begin() + rings.offsets[v],
                          rings.neighbours.begin() + rings.offsets[v + 1]);
    ASSERT_EQ(a, b) << "vertex " << v;
  }
}

TEST(OneRings, NonManifoldEdgeMakesIrregularRingsWithUniformWeights) {
  // Three triangles on one edge (0, 1).
  Matrix3Xf positions(5, 3);
  positions << 0, 0, 0, 1, 0, 0, 0.5f, 1, 0, 0.5f, -1, 0, 0.5f, 0, 1;
  TriangleMatrix triangles(3, 3);
  triangles << 0, 1, 2, 1, 0, 3, 0, 1, 4;
  const OneRings rings = OneRings::build(positions, triangles);
  const RelaxationWeights w = RelaxationWeights::build(rings, positions);
  int irregular = 0;
  for (int v = 0; v < 5; ++v) {
    if (rings.kinds[v] != RingKind::kIrregular) continue;
    ++irregular;
    EXPECT_EQ(w.rules[v], RelaxationRule::kUniform) << v;
    const uint32_t count = rings.offsets[v + 1] - rings.offsets[v];
    for (uint32_t i = rings.offsets[v]; i < rings.offsets[v + 1]; ++i)
      EXPECT_FLOAT_EQ(w.weights[i], 1.f / count);
  }
  EXPECT_GE(irregular, 3);  // the refused face's corners
  EXPECT_FALSE(w.describe().empty());
}

TEST(OneRings, BadIndexNamesTheTriangle) {
  Fan fan = closedFan(5);
  fan.triangles(3, 2) = 17;
  try {
    OneRings::build(fan.positions, fan.triangles);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("triangle 3"), std::string::npos)
        << e.what();
  }
}

void checkRig(const Rig& rig, bool expect_closed) {
  const OneRings rings =
      OneRings::build(rig.mesh.positions, rig.mesh.triangles);
  const RelaxationWeights w =
      RelaxationWeights::build(rings, rig.mesh.positions);
  ASSERT_EQ(rings.vertexCount(), rig.mesh.vertexCount());
  ASSERT_EQ(w.weights.size(), rings.neighbours.size());
  if (expect_closed)
    EXPECT_EQ(rings.count(RingKind::kClosed), rig.mesh.vertexCount());
  const Reproduction r = reproduction(rings, w, rig.mesh.positions);
  EXPECT_LT(r.error, 1e-4) << "first worst vertex " << r.vertex;
  for (int v = 0; v < rings.vertexCount(); ++v) {
    const RingKind kind = rings.kinds[v];
    const RelaxationRule rule = w.rules[v];
    // Documented: boundary, isolated and duplicate vertices are fixed;
    // closed and irregular ones are relaxed by some rule.
    const bool fixed = kind == RingKind::kBoundary ||
                       kind == RingKind::kIsolated ||
                       kind == RingKind::kDuplicate;
    ASSERT_EQ(rule == RelaxationRule::kFixed, fixed)
        << "vertex " << v << " " << ringKindName(kind) << " "
        << relaxationRuleName(rule);
    double sum = 0;
    for (uint32_t i = rings.offsets[v]; i < rings.offsets[v + 1]; ++i) {
      ASSERT_GE(w.weights[i], 0.f) << "vertex " << v;
      sum += w.weights[i];
    }
    if (!fixed) ASSERT_NEAR(sum, 1.0, 1e-5) << "vertex " << v;
  }
}

TEST(OneRings, ProceduralRigsAreClosedAndReproduced) {
  for (const std::string& name : builtinRigNames()) {
    SCOPED_TRACE(name);
    checkRig(makeBuiltinRig(name), /*expect_closed=*/true);
  }
}

TEST(OneRings, AssetsFollowTheDocumentedRules) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("one-rings of the assets");
  for (const std::string& name : test::assetNames()) {
    SCOPED_TRACE(name);
    checkRig(test::loadAsset(name), /*expect_closed=*/false);
  }
}

}  // namespace
}  // namespace isk
