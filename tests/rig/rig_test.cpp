// Rig model: procedural rigs, weights, skeleton checks, clip sampling, poses
// and subdivision.
#include <gtest/gtest.h>

#include <map>

#include "isk/core/error.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "isk/tools/procedural.hpp"
#include "isk/tools/subdivide.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

// Number of triangles on each undirected edge: 2 everywhere on a closed
// manifold surface. Returns the first edge that is not.
std::string firstNonManifoldEdge(const TriangleMatrix& triangles) {
  std::map<std::pair<int, int>, int> count;
  for (int f = 0; f < triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      int a = triangles(f, k), b = triangles(f, (k + 1) % 3);
      ++count[{std::min(a, b), std::max(a, b)}];
    }
  }
  for (const auto& [edge, n] : count) {
    if (n != 2) {
      return std::to_string(edge.first) + "-" + std::to_string(edge.second) +
             " has " + std::to_string(n) + " triangles";
    }
  }
  return "";
}

TEST(ProceduralRigs, AreValidClosedAndOutward) {
  for (const std::string& name : builtinRigNames()) {
    SCOPED_TRACE(name);
    const Rig rig = makeBuiltinRig(name);
    EXPECT_TRUE(rig.validate()) << rig.validate().reason();
    EXPECT_EQ(rig.source, "builtin:" + name);
    EXPECT_EQ(firstNonManifoldEdge(rig.mesh.triangles), "");
    EXPECT_GT(enclosedVolume(rig.mesh.positions, rig.mesh.triangles), 0.0)
        << "triangles must wind counter-clockwise seen from outside";
    EXPECT_GE(rig.skeleton.skinJointCount(), 2);
    ASSERT_EQ(rig.clips.size(), 1u);
    EXPECT_EQ(rig.clips[0].name, "bend");
  }
}

TEST(ProceduralRigs, CylinderHasTheRequestedShape) {
  CylinderRigOptions options;
  options.bones = 3;
  options.rings = 100;
  options.segments = 100;
  const Rig rig = makeCylinderRig(options);
  EXPECT_EQ(rig.skeleton.jointCount(), 4);  // 3 bones and a tip
  EXPECT_EQ(rig.skeleton.skinJointCount(), 3);
  // Volume of a radius-1, length-8 cylinder, up to the polygonal section.
  const double volume = enclosedVolume(rig.mesh.positions, rig.mesh.triangles);
  EXPECT_NEAR(volume, 8.0 * 3.14159265, 8.0 * 3.14159265 * 0.005);
  EXPECT_NEAR(rig.boundingBoxDiagonal(), std::sqrt(64.f + 4.f + 4.f), 1e-3f);
  EXPECT_GT(rig.mesh.vertexCount(), 10000);
  // Vertices far from joints belong to one bone, around joints to two.
  EXPECT_EQ(rig.weights.maxInfluences(), 2);
}

TEST(ProceduralRigs, UnknownNamesAndBadOptionsAreRefusedWithTheValidNames) {
  try {
    makeBuiltinRig("octopus");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("cylinder, finger, arm"),
              std::string::npos);
  }
  CylinderRigOptions bad;
  bad.bones = 0;
  EXPECT_THROW(makeCylinderRig(bad), Error);
  bad.bones = 65;
  EXPECT_THROW(makeCylinderRig(bad), Error);
  // Long chains for the benchmarks' joint-count series.
  CylinderRigOptions chain;
  chain.bones = 32;
  chain.length = 96.f;
  chain.rings = 200;
  chain.segments = 16;
  const Rig rig = makeCylinderRig(chain);
  EXPECT_EQ(rig.skeleton.skinJointCount(), 32);
}

TEST(SkinWeights, ListsAreMergedSortedAndNormalized) {
  SkinWeights w = SkinWeights::fromLists(
      {{{2, 0.2f}, {0, 0.5f}, {2, 0.1f}, {1, 0.f}}, {{1, 2.0f}}});
  EXPECT_EQ(w.vertexCount(), 2);
  EXPECT_EQ(w.influenceCount(0), 2);  // joint 2 merged, zero weight dropped
  w.sortByWeight();
  EXPECT_EQ(w.joints[0], 0u);
  EXPECT_FLOAT_EQ(w.weights[1], 0.3f);
  const auto report = w.normalize();
  EXPECT_EQ(report.off_count, 2);
  EXPECT_FLOAT_EQ(report.min_sum, 0.8f);
  EXPECT_FLOAT_EQ(report.max_sum, 2.0f);
  EXPECT_FLOAT_EQ(w.weights[0] + w.weights[1], 1.f);
  EXPECT_TRUE(w.validate(2, 3)) << w.validate(2, 3).reason();
  EXPECT_FALSE(w.validate(2, 2));  // joint 2 out of range
  EXPECT_NE(w.validate(2, 2).reason().find("joint 2"), std::string::npos);
  EXPECT_FALSE(w.validate(3, 3));
}

TEST(SkinWeights, VertexWithoutWeightIsNamedThroughItsMesh) {
  Rig rig = makeCylinderRig();
  rig.mesh.parts[0].name = "Body";
  std::vector<std::vector<std::pair<int, float>>> lists(rig.mesh.vertexCount(),
                                                        {{0, 1.f}});
  lists[17].clear();
  rig.weights = SkinWeights::fromLists(lists);
  const Validation v = rig.validate();
  ASSERT_FALSE(v);
  EXPECT_NE(v.reason().find("mesh 'Body' vertex 17 has no skin weight"),
            std::string::npos)
      << v.reason();
}

TEST(Skeleton, NonRigidBindTransformIsRefusedByName) {
  Rig rig = makeCylinderRig();
  EXPECT_TRUE(rig.skeleton.validate());
  // A uniform scale (a unit conversion) is fine...
  rig.skeleton.joints[1].inverse_bind.linear() *= 100.f;
  EXPECT_TRUE(rig.skeleton.validate()) << rig.skeleton.validate().reason();
  // ...a non-uniform one is not.
  rig.skeleton.joints[1].inverse_bind.linear() =
      Eigen::Vector3f(1.f, 2.f, 1.f).asDiagonal();
  const Validation v = rig.skeleton.validate();
  ASSERT_FALSE(v);
  EXPECT_NE(v.reason().find("joint 'bone1'"), std::string::npos) << v.reason();
  EXPECT_NE(v.reason().find("non-rigid"), std::string::npos);
}

TEST(Skeleton, ParentsMustPrecedeChildren) {
  Rig rig = makeCylinderRig();
  rig.skeleton.joints[0].parent = 1;
  EXPECT_FALSE(rig.skeleton.validate());
}

TEST(Mesh, ValidationNamesTheBadVertexAndTriangle) {
  Rig rig = makeCylinderRig();
  rig.mesh.positions(5, 1) = std::numeric_limits<float>::infinity();
  EXPECT_NE(
      rig.mesh.validate().reason().find("vertex 5 has a non-finite position"),
      std::string::npos);
  rig = makeCylinderRig();
  rig.mesh.triangles(3, 2) = rig.mesh.vertexCount();
  EXPECT_NE(rig.mesh.validate().reason().find("triangle 3"), std::string::npos);
}

TEST(Animation, SamplingInterpolatesAndClamps) {
  Skeleton skeleton;
  Joint joint;
  joint.name = "j";
  joint.rest_local = Eigen::Affine3f::Identity();
  joint.inverse_bind = Eigen::Affine3f::Identity();
  skeleton.joints.push_back(joint);
  AnimationClip clip;
  clip.start = 1.0;
  clip.duration = 2.0;
  JointChannel channel;
  channel.joint = 0;
  channel.translation_times = {1.0, 3.0};
  channel.translations = {Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(4, 0, 0)};
  channel.rotation_times = {1.0, 3.0};
  channel.rotations = {
      Eigen::Quaternionf::Identity(),
      Eigen::Quaternionf(Eigen::AngleAxisf(1.5f, Eigen::Vector3f::UnitZ()))};
  clip.channels.push_back(channel);
  ASSERT_TRUE(clip.validate(skeleton));
  const Eigen::Affine3f mid = clip.sampleLocal(skeleton, 2.0)[0];
  EXPECT_TRUE(mid.translation().isApprox(Eigen::Vector3f(2, 0, 0), 1e-6f));
  EXPECT_NEAR(Eigen::AngleAxisf(mid.linear()).angle(), 0.75f, 1e-5f);
  // Before the first and after the last key the end keys hold.
  EXPECT_TRUE(clip.sampleLocal(skeleton, -5.0)[0].translation().isZero());
  EXPECT_TRUE(clip.sampleLocal(skeleton, 9.0)[0].translation().isApprox(
      Eigen::Vector3f(4, 0, 0)));
  // Decreasing times are refused with the joint's name.
  clip.channels[0].translation_times = {3.0, 1.0};
  const Validation v = clip.validate(skeleton);
  ASSERT_FALSE(v);
  EXPECT_NE(v.reason().find("joint 'j'"), std::string::npos);
}

TEST(Animation, BendClipBendsEveryInnerJointToTheAngle) {
  const Rig rig = makeCylinderRig();
  const AnimationClip clip = makeBendClip(rig.skeleton, 1.2f, 2.0);
  EXPECT_DOUBLE_EQ(clip.duration, 2.0);
  const TransformList start = clip.sampleLocal(rig.skeleton, 0.0);
  const TransformList end = clip.sampleLocal(rig.skeleton, 2.0);
  EXPECT_TRUE(start[1].isApprox(rig.skeleton.joints[1].rest_local, 1e-5f));
  EXPECT_NEAR(Eigen::AngleAxisf(end[1].linear()).angle(), 1.2f, 1e-4f);
  // The bend axis is perpendicular to the bone (+x).
  EXPECT_NEAR(Eigen::AngleAxisf(end[1].linear()).axis().x(), 0.f, 1e-5f);
}

TEST(Pose, RestLocalsGiveTheBindPoseAndIdentitySkinning) {
  for (const std::string& name : builtinRigNames()) {
    const Rig rig = makeBuiltinRig(name);
    TransformList locals;
    for (const Joint& j : rig.skeleton.joints) locals.push_back(j.rest_local);
    const TransformList globals = globalTransforms(rig.skeleton, locals);
    const TransformList bind = rig.skeleton.bindGlobals();
    const TransformList skinning = skinningTransforms(rig.skeleton, globals);
    for (int j = 0; j < rig.skeleton.jointCount(); ++j) {
      EXPECT_TRUE(globals[j].isApprox(bind[j], 1e-5f))
          << name << " joint " << j;
      EXPECT_TRUE(skinning[j].isApprox(Eigen::Affine3f::Identity(), 1e-5f));
    }
  }
}

TEST(Subdivide, QuadruplesTrianglesAndInterpolatesWeights) {
  const Rig rig = makeBuiltinRig("finger");
  const Rig fine = subdivideRig(rig, 1);
  EXPECT_EQ(fine.mesh.triangleCount(), 4 * rig.mesh.triangleCount());
  // Closed manifold: V' = V + E and E = 3F/2.
  EXPECT_EQ(fine.mesh.vertexCount(),
            rig.mesh.vertexCount() + 3 * rig.mesh.triangleCount() / 2);
  EXPECT_TRUE(fine.validate()) << fine.validate().reason();
  EXPECT_EQ(firstNonManifoldEdge(fine.mesh.triangles), "");
  // The surface is the same: volume within the polygonal refinement error.
  EXPECT_NEAR(enclosedVolume(fine.mesh.positions, fine.mesh.triangles),
              enclosedVolume(rig.mesh.positions, rig.mesh.triangles), 1e-3);
  EXPECT_THROW(subdivideRig(rig, -1), Error);
}

}  // namespace
}  // namespace isk
