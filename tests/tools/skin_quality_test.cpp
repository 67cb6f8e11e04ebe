// The per-frame quality measures: each measure on frames built to have a
// known value (rest pose, uniform scale, one vertex pushed out, a pop in the
// third frame), the contact region, the summary's worst frame, the measures
// on every asset and procedural rig at rest and bent, the per-part
// measures (the new pairs each part touches among them), and bad input.
#include "isk/tools/skin_quality.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "isk/core/error.hpp"
#include "isk/fields/bone_partition.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tools/procedural.hpp"
#include "isk/tools/self_intersection.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

std::vector<int> groupsOf(const Mesh& mesh) {
  return coincidentVertexGroups(mesh.positions);
}

// How many of `pairs` (triangle indices) have a corner of either triangle
// in `part`: PartQuality::new_pairs, counted directly.
long long pairsTouching(int part, const std::vector<std::pair<int, int>>& pairs,
                        const Mesh& mesh, const std::vector<int>& parts) {
  long long count = 0;
  for (const auto& [a, b] : pairs) {
    bool touches = false;
    for (int c = 0; c < 3; ++c)
      touches = touches || parts[mesh.triangles(a, c)] == part ||
                parts[mesh.triangles(b, c)] == part;
    count += touches ? 1 : 0;
  }
  return count;
}

TEST(SkinQuality, RestPoseMeasuresNothing) {
  const Rig rig = makeCylinderRig();
  SkinQuality quality(rig.mesh, groupsOf(rig.mesh));
  EXPECT_TRUE(quality.restPairs().empty());
  for (int frame = 0; frame < 3; ++frame) {
    const FrameQuality q = quality.measure(rig.mesh.positions, nullptr);
    EXPECT_EQ(q.self_intersections, 0);
    EXPECT_EQ(q.new_self_intersections, 0);
    ASSERT_TRUE(q.volume_ratio);
    EXPECT_NEAR(*q.volume_ratio, 1.0, 1e-9);
    ASSERT_TRUE(q.covered_volume_ratio);
    EXPECT_EQ(*q.covered_volume_ratio, 1.0);
    EXPECT_EQ(q.edge_strain_mean, 0);
    EXPECT_EQ(q.edge_strain_max, 0);
    EXPECT_EQ(q.crumpled_edges, 0);
    EXPECT_EQ(q.dqs_distance_max, 0);
    EXPECT_EQ(q.jitter_mean.has_value(), frame == 2);
    if (q.jitter_max) EXPECT_EQ(*q.jitter_max, 0);
  }
}

TEST(SkinQuality, UniformScaleStrainsEveryEdgeAndScalesTheVolume) {
  const Rig rig = makeCylinderRig();
  SkinQuality quality(rig.mesh, groupsOf(rig.mesh));
  const Matrix3Xf doubled = rig.mesh.positions * 2.f;
  const FrameQuality q = quality.measure(doubled, &rig.mesh.positions);
  EXPECT_NEAR(q.edge_strain_mean, 1.0, 1e-5);
  EXPECT_NEAR(q.edge_strain_max, 1.0, 1e-5);
  EXPECT_EQ(q.crumpled_edges, 0);  // a scale bends no edge
  ASSERT_TRUE(q.volume_ratio);
  EXPECT_NEAR(*q.volume_ratio, 8.0, 1e-4);
  ASSERT_TRUE(q.covered_volume_ratio);
  EXPECT_NEAR(*q.covered_volume_ratio, 8.0, 1e-2);
  EXPECT_EQ(q.new_self_intersections, 0);
  // Against the rest pose as its "DQS frame", far vertices moved by
  // |p| each: the largest is the farthest vertex from the origin.
  double farthest = 0;
  for (int v = 0; v < rig.mesh.vertexCount(); ++v)
    farthest = std::max<double>(farthest, rig.mesh.positions.row(v).norm());
  EXPECT_NEAR(q.dqs_distance_max, farthest / quality.diagonal(), 1e-5);
}

// A vertex of the cylinder's surface half way along its axis (+x).
int midSurfaceVertex(const Mesh& mesh) {
  const float mid_x = 0.5f * (mesh.positions.col(0).minCoeff() +
                              mesh.positions.col(0).maxCoeff());
  int vertex = -1;
  float best = 1e30f;
  for (int i = 0; i < mesh.vertexCount(); ++i) {
    const Eigen::RowVector3f p = mesh.positions.row(i);
    const float d =
        std::abs(p.x() - mid_x) - Eigen::Vector2f(p.y(), p.z()).norm();
    if (d < best) best = d, vertex = i;
  }
  return vertex;
}

// One vertex pushed through the opposite wall of the cylinder: a spike
// whose triangles fold over their neighbours and cross the far side.
TEST(SkinQuality, ASpikeIsCountedAndStrainsItsEdges) {
  const Rig rig = makeCylinderRig();
  const Mesh& mesh = rig.mesh;
  SkinQuality quality(mesh, groupsOf(mesh));
  const int v = midSurfaceVertex(mesh);
  Matrix3Xf spiked = mesh.positions;
  const Eigen::RowVector3f radial(0, spiked(v, 1), spiked(v, 2));
  spiked.row(v) -= 2.5f * radial;  // through the axis and out the far side
  const FrameQuality q = quality.measure(spiked, &mesh.positions);
  EXPECT_GT(q.self_intersections, 0);
  EXPECT_EQ(q.new_self_intersections, q.self_intersections);
  EXPECT_GT(q.edge_strain_max, 1.0);
  EXPECT_LT(q.edge_strain_mean, 0.1);
  // The spike's edges turn by far more than 60 degrees; no other edge does.
  EXPECT_GT(q.crumpled_edges, 0);
  EXPECT_LE(q.crumpled_edges, 12);
  // By part: the spike's crumpled edges are its part's (and perhaps a
  // neighbouring part's, by an edge's other end); DQS, the rest pose, has
  // none.
  SkinQualityOptions options;
  options.vertex_parts = partitionMesh(rig).vertex_joint;
  SkinQuality by_part(mesh, groupsOf(mesh), options);
  const FrameQuality pq = by_part.measure(spiked, &mesh.positions);
  EXPECT_EQ(pq.crumpled_edges, q.crumpled_edges);
  long long in_parts = 0;
  for (const PartQuality& p : pq.parts) {
    EXPECT_EQ(p.dqs_crumpled_edges, 0);
    EXPECT_LE(p.crumpled_edges, q.crumpled_edges);
    if (p.part == options.vertex_parts[v])
      EXPECT_GT(p.crumpled_edges, 0) << "part " << p.part;
    in_parts += p.crumpled_edges;
  }
  EXPECT_GE(in_parts, q.crumpled_edges);
  // The DQS frame (the rest pose here) has no new pair: the spike is not
  // near a contact and its distance is what the frame moved it.
  EXPECT_NEAR(q.dqs_distance_max, 2.5 * radial.norm() / quality.diagonal(),
              1e-5);
  EXPECT_EQ(q.contact_region_vertices, 0);
}

// Two triangles hinged on the edge from the origin along z, the first
// wing along +x, the second at `angle` radians from it around z (pi: flat).
Mesh hingeMesh(float angle) {
  Mesh mesh;
  mesh.positions.resize(4, 3);
  mesh.positions << 0, 0, 0, 0, 0, 1, 1, 0, 0.5f, std::cos(angle),
      std::sin(angle), 0.5f;
  mesh.triangles.resize(2, 3);
  mesh.triangles << 0, 1, 2, 1, 0, 3;
  return mesh;
}

constexpr float kDegree = static_cast<float>(M_PI / 180.0);

// The bending angle's change against the threshold: the hinge is the only
// edge two triangles share; a rigid motion or a scale bends nothing; a
// change through the flat position (+10 to -10 degrees of bending) is 20
// degrees, not 340.
TEST(SkinQuality, CrumpledEdgesAreTheHingesBentPastTheThreshold) {
  const Mesh rest = hingeMesh(170 * kDegree);  // bent 10 degrees
  SkinQuality quality(rest, groupsOf(rest));
  EXPECT_EQ(quality.measure(rest.positions, nullptr).crumpled_edges, 0);
  // Bent to -10, -45 and -55 degrees: changes of 20, 55 and 65 degrees.
  EXPECT_EQ(quality.measure(hingeMesh(-170 * kDegree).positions, nullptr)
                .crumpled_edges,
            0);
  EXPECT_EQ(quality.measure(hingeMesh(-135 * kDegree).positions, nullptr)
                .crumpled_edges,
            0);
  EXPECT_EQ(quality.measure(hingeMesh(-125 * kDegree).positions, nullptr)
                .crumpled_edges,
            1);
  // Folded onto the first wing: 170 degrees.
  EXPECT_EQ(
      quality.measure(hingeMesh(1 * kDegree).positions, nullptr).crumpled_edges,
      1);
  // Turned and scaled as a whole: nothing bends.
  const Eigen::Matrix3f turn =
      Eigen::AngleAxisf(1.0f, Eigen::Vector3f(1, 2, 3).normalized())
          .toRotationMatrix();
  const Matrix3Xf moved = 3.0f * rest.positions * turn.transpose();
  EXPECT_EQ(quality.measure(moved, nullptr).crumpled_edges, 0);

  // A lower threshold counts the 55-degree change; a bad one is refused.
  SkinQualityOptions options;
  options.crumple_degrees = 50;
  SkinQuality strict(rest, groupsOf(rest), options);
  EXPECT_EQ(strict.measure(hingeMesh(-135 * kDegree).positions, nullptr)
                .crumpled_edges,
            1);
  for (const float bad : {0.0f, -1.0f, 181.0f, std::nanf("")}) {
    options.crumple_degrees = bad;
    try {
      SkinQuality(rest, groupsOf(rest), options);
      ADD_FAILURE() << "crumple_degrees " << bad << " was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("crumple_degrees"),
                std::string::npos)
          << e.what();
    }
  }
}

TEST(SkinQuality, VerticesNearAContactAreLeftOutOfTheDistance) {
  const Rig rig = makeCylinderRig();
  const Mesh& mesh = rig.mesh;
  SkinQuality quality(mesh, groupsOf(mesh), {/*contact_radius=*/0.05f});
  Matrix3Xf moved = mesh.positions;
  moved.row(0) += Eigen::RowVector3f(0, 0, 0.1f * quality.diagonal());
  std::vector<uint8_t> contacts(mesh.vertexCount(), 0);
  contacts[0] = 1;
  const FrameQuality near =
      quality.measure(moved, &mesh.positions, &contacts, 3);
  EXPECT_EQ(near.dqs_distance_max, 0);
  EXPECT_GE(near.contact_region_vertices, 1);
  EXPECT_EQ(near.lost_vertices, 3);
  const FrameQuality far = quality.measure(moved, &mesh.positions);
  EXPECT_NEAR(far.dqs_distance_max, 0.1, 1e-5);
  EXPECT_EQ(far.contact_region_vertices, 0);
}

TEST(SkinQuality, JitterIsThePopBeyondTheDqsMotion) {
  const Rig rig = makeCylinderRig();
  const Mesh& mesh = rig.mesh;
  SkinQuality quality(mesh, groupsOf(mesh));
  // Both move steadily (no jitter); then the frame pops one vertex.
  const Eigen::RowVector3f step(0.01f, 0, 0);
  std::vector<Matrix3Xf> frames;
  for (int i = 0; i < 4; ++i) {
    Matrix3Xf f = mesh.positions;
    f.rowwise() += step * static_cast<float>(i);
    frames.push_back(f);
  }
  Matrix3Xf popped = frames[3];
  popped.row(5) += Eigen::RowVector3f(0, 0.02f * quality.diagonal(), 0);
  quality.measure(frames[0], &frames[0]);
  quality.measure(frames[1], &frames[1]);
  const FrameQuality steady = quality.measure(frames[2], &frames[2]);
  ASSERT_TRUE(steady.jitter_max);
  EXPECT_NEAR(*steady.jitter_max, 0, 1e-6);
  const FrameQuality pop = quality.measure(popped, &frames[3]);
  ASSERT_TRUE(pop.jitter_max);
  EXPECT_NEAR(*pop.jitter_max, 0.02, 1e-5);
}

TEST(SkinQuality, SummaryPicksTheWorstFrame) {
  std::vector<FrameQuality> frames(4);
  frames[0].volume_ratio = 0.99;
  frames[1].volume_ratio = 0.95;
  frames[1].new_self_intersections = 3;
  frames[2].volume_ratio = 0.90;
  frames[2].new_self_intersections = 3;
  frames[3].volume_ratio = 1.01;
  frames[3].edge_strain_max = 0.4;
  frames[3].jitter_max = 0.002;
  frames[1].crumpled_edges = 5;
  frames[3].crumpled_edges = 2;
  const QualitySummary s = summarizeQuality(frames);
  EXPECT_EQ(s.frames, 4);
  EXPECT_EQ(s.worst_frame, 2);
  EXPECT_EQ(s.new_self_intersections_max, 3);
  EXPECT_EQ(s.new_self_intersections_total, 6);
  EXPECT_DOUBLE_EQ(*s.volume_ratio_min, 0.90);
  EXPECT_DOUBLE_EQ(*s.volume_ratio_max, 1.01);
  EXPECT_DOUBLE_EQ(s.edge_strain_max, 0.4);
  EXPECT_DOUBLE_EQ(*s.jitter_max, 0.002);
  EXPECT_EQ(s.crumpled_edges_max, 5);
  EXPECT_EQ(s.crumpled_edges_total, 7);
  EXPECT_EQ(summarizeQuality({}).worst_frame, -1);
}

// midSurfaceVertex pushed out radially by half its radius; `vertex`
// receives it.
Matrix3Xf pushedOut(const Mesh& mesh, int* vertex) {
  *vertex = midSurfaceVertex(mesh);
  Matrix3Xf out = mesh.positions;
  out.row(*vertex) +=
      0.5f * Eigen::RowVector3f(0, out(*vertex, 1), out(*vertex, 2));
  return out;
}

TEST(SkinQuality, PartsShowWhereTheFrameDepartsFromDqs) {
  const Rig rig = makeCylinderRig();
  const Mesh& mesh = rig.mesh;
  SkinQualityOptions options;
  options.vertex_parts = partitionMesh(rig).vertex_joint;
  SkinQuality quality(mesh, groupsOf(mesh), options);
  int v = -1;
  const Matrix3Xf bumped = pushedOut(mesh, &v);
  const int bumped_part = options.vertex_parts[v];
  ASSERT_GE(bumped_part, 0);
  const FrameQuality q = quality.measure(bumped, &mesh.positions);
  ASSERT_FALSE(q.parts.empty());
  bool found = false;
  for (size_t k = 0; k < q.parts.size(); ++k) {
    const PartQuality& p = q.parts[k];
    SCOPED_TRACE("part " + std::to_string(p.part));
    if (k > 0) EXPECT_GT(p.part, q.parts[k - 1].part);
    EXPECT_GT(p.edges, 0);
    EXPECT_EQ(p.dqs_edge_strain_mean, 0);  // the rest pose is the DQS frame
    if (p.part == bumped_part) {
      found = true;
      EXPECT_GT(p.edge_strain_mean, 0);
      const double moved =
          (bumped.row(v) - mesh.positions.row(v)).norm() / quality.diagonal();
      EXPECT_NEAR(p.dqs_distance_max, moved, 1e-6);
      EXPECT_NEAR(p.dqs_distance_max, q.dqs_distance_max, 1e-9);
    } else {
      EXPECT_EQ(p.dqs_distance_max, 0);
    }
  }
  EXPECT_TRUE(found);
  // Over a clip: the means over the frames, the largest distance.
  const FrameQuality rest = quality.measure(mesh.positions, &mesh.positions);
  for (const PartQuality& p : rest.parts) EXPECT_EQ(p.edge_strain_mean, 0);
  const QualitySummary summary = summarizeQuality({q, rest});
  ASSERT_EQ(summary.parts.size(), q.parts.size());
  for (size_t k = 0; k < q.parts.size(); ++k) {
    EXPECT_EQ(summary.parts[k].part, q.parts[k].part);
    EXPECT_NEAR(summary.parts[k].edge_strain_mean,
                0.5 * q.parts[k].edge_strain_mean, 1e-12);
    EXPECT_EQ(summary.parts[k].dqs_distance_max, q.parts[k].dqs_distance_max);
    EXPECT_EQ(summary.parts[k].crumpled_edges,
              q.parts[k].crumpled_edges + rest.parts[k].crumpled_edges);
  }
  // Without parts, none are measured.
  SkinQuality plain(mesh, groupsOf(mesh));
  EXPECT_TRUE(plain.measure(bumped, &mesh.positions).parts.empty());
}

TEST(SkinQuality, PartsCountTheNewPairsTheyTouch) {
  const Rig rig = makeCylinderRig();
  const Mesh& mesh = rig.mesh;
  SkinQualityOptions options;
  options.vertex_parts = partitionMesh(rig).vertex_joint;
  SkinQuality quality(mesh, groupsOf(mesh), options);
  const int v = midSurfaceVertex(mesh);
  Matrix3Xf spiked = mesh.positions;
  const Eigen::RowVector3f radial(0, spiked(v, 1), spiked(v, 2));
  spiked.row(v) -= 2.5f * radial;  // through the axis and out the far side
  const FrameQuality q = quality.measure(spiked, &mesh.positions);
  ASSERT_GT(q.new_self_intersections, 0);
  const std::vector<std::pair<int, int>> pairs = quality.lastNewPairs();
  long long spiked_part_pairs = 0;
  for (const PartQuality& p : q.parts) {
    SCOPED_TRACE("part " + std::to_string(p.part));
    EXPECT_EQ(p.new_pairs,
              pairsTouching(p.part, pairs, mesh, options.vertex_parts));
    EXPECT_LE(p.new_pairs, q.new_self_intersections);
    EXPECT_EQ(p.dqs_new_pairs, 0);  // the rest pose is the DQS frame
    if (p.part == options.vertex_parts[v]) spiked_part_pairs = p.new_pairs;
  }
  EXPECT_GT(spiked_part_pairs, 0);
  // The spiked frame as its own DQS frame: DQS's pairs are the frame's;
  // over a clip, the sums.
  const FrameQuality self = quality.measure(spiked, &spiked);
  ASSERT_EQ(self.parts.size(), q.parts.size());
  for (size_t k = 0; k < q.parts.size(); ++k) {
    EXPECT_EQ(self.parts[k].new_pairs, q.parts[k].new_pairs);
    EXPECT_EQ(self.parts[k].dqs_new_pairs, q.parts[k].new_pairs);
  }
  const QualitySummary summary = summarizeQuality({q, self});
  ASSERT_EQ(summary.parts.size(), q.parts.size());
  for (size_t k = 0; k < q.parts.size(); ++k) {
    EXPECT_EQ(summary.parts[k].new_pairs, 2 * q.parts[k].new_pairs);
    EXPECT_EQ(summary.parts[k].dqs_new_pairs, q.parts[k].new_pairs);
  }
}

TEST(SkinQuality, BadSizesAreClearErrors) {
  const Rig rig = makeCylinderRig();
  EXPECT_THROW(SkinQuality(rig.mesh, std::vector<int>(3, 0)), Error);
  std::vector<int> groups = groupsOf(rig.mesh);
  groups[1] = -4;
  EXPECT_THROW(SkinQuality(rig.mesh, groups), Error);
  SkinQuality quality(rig.mesh, groupsOf(rig.mesh));
  EXPECT_THROW(quality.measure(Matrix3Xf::Zero(2, 3), nullptr), Error);
  const Matrix3Xf wrong = Matrix3Xf::Zero(2, 3);
  EXPECT_THROW(quality.measure(rig.mesh.positions, &wrong), Error);
  const std::vector<uint8_t> flags(2, 0);
  EXPECT_THROW(quality.measure(rig.mesh.positions, nullptr, &flags), Error);
  SkinQualityOptions few;
  few.vertex_parts.assign(3, 0);
  EXPECT_THROW(SkinQuality(rig.mesh, groupsOf(rig.mesh), few), Error);
  SkinQualityOptions negative;
  negative.vertex_parts.assign(rig.mesh.vertexCount(), 0);
  negative.vertex_parts[5] = -2;
  try {
    SkinQuality(rig.mesh, groupsOf(rig.mesh), negative);
    ADD_FAILURE() << "a part id of -2 was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 5"), std::string::npos)
        << e.what();
  }
}

// The rest pose measures nothing new on every rig, and DQS of a bend
// measured against itself is 0 away from contact, on the procedural rigs and
// every asset; LBS of the same bend differs from DQS.
void checkRestAndBend(const Rig& rig, const std::string& name,
                      bool bends_every_part) {
  SCOPED_TRACE(name);
  SkinQuality quality(rig.mesh, groupsOf(rig.mesh));
  const FrameQuality rest = quality.measure(rig.mesh.positions, nullptr);
  EXPECT_EQ(rest.new_self_intersections, 0);
  EXPECT_EQ(rest.self_intersections,
            static_cast<int>(quality.restPairs().size()));
  EXPECT_NEAR(rest.edge_strain_max, 0, 1e-6);
  EXPECT_EQ(rest.crumpled_edges, 0);

  const AnimationClip bend = makeBendClip(rig.skeleton, 1.5f, 1.0);
  const TransformList skinning = skinningTransforms(
      rig.skeleton,
      globalTransforms(rig.skeleton, bend.sampleLocal(rig.skeleton, 1.0)));
  CpuSkinning dqs(rig.mesh, rig.weights, rig.skeleton.jointCount());
  dqs.run(SkinningMethod::kDualQuaternion, skinning, false);
  CpuSkinning lbs(rig.mesh, rig.weights, rig.skeleton.jointCount());
  lbs.run(SkinningMethod::kLinearBlend, skinning, false);
  const FrameQuality d = quality.measure(dqs.positions(), nullptr);
  EXPECT_EQ(d.dqs_distance_max, 0);
  EXPECT_GT(d.edge_strain_max, 0);
  const FrameQuality l = quality.measure(lbs.positions(), &dqs.positions());
  EXPECT_GE(l.dqs_distance_max, 0);
  // A bone of an asset may carry no vertex (nothing to strain).
  if (bends_every_part) EXPECT_GT(l.edge_strain_max, 0);
  EXPECT_TRUE(l.jitter_max.has_value());

  // Per part: DQS against itself departs nowhere; LBS's parts hold its
  // largest distance from DQS (contacts included: at least the far one).
  SkinQualityOptions options;
  options.vertex_parts = partitionMesh(rig).vertex_joint;
  SkinQuality by_part(rig.mesh, groupsOf(rig.mesh), options);
  const FrameQuality pd = by_part.measure(dqs.positions(), &dqs.positions());
  ASSERT_FALSE(pd.parts.empty());
  for (const PartQuality& p : pd.parts) {
    EXPECT_EQ(p.edge_strain_mean, p.dqs_edge_strain_mean);
    EXPECT_EQ(p.dqs_distance_max, 0);
    EXPECT_EQ(p.new_pairs, p.dqs_new_pairs);
    EXPECT_EQ(p.crumpled_edges, p.dqs_crumpled_edges);
    EXPECT_EQ(p.new_pairs, pairsTouching(p.part, by_part.lastNewPairs(),
                                         rig.mesh, options.vertex_parts));
  }
  const FrameQuality pl = by_part.measure(lbs.positions(), &dqs.positions());
  double largest = 0;
  for (const PartQuality& p : pl.parts) {
    largest = std::max(largest, p.dqs_distance_max);
    EXPECT_EQ(p.new_pairs, pairsTouching(p.part, by_part.lastNewPairs(),
                                         rig.mesh, options.vertex_parts));
  }
  EXPECT_GE(largest, pl.dqs_distance_max);
  if (bends_every_part) EXPECT_GT(largest, 0);
}

TEST(SkinQuality, RestAndBendOnProceduralRigs) {
  for (const std::string& name : builtinRigNames())
    checkRestAndBend(makeBuiltinRig(name), name, true);
}

TEST(SkinQuality, RestAndBendOnAssets) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("the quality measures");
  for (const std::string& name : test::assetNames())
    checkRestAndBend(test::loadAsset(name), name, false);
}

}  // namespace
}  // namespace isk
