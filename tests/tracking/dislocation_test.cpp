// The dislocation guard (isk/tracking/dislocation.hpp): its candidates, the
// poses that dislocate them, and what it does to the frames of both
// skinners.
#include "isk/tracking/dislocation.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <set>
#include <string>

#include "isk/core/error.hpp"
#include "isk/fields/bone_partition.hpp"
#include "isk/implicit_crowd.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

CylinderRigOptions longCylinder() {
  CylinderRigOptions o;
  o.bones = 3;
  o.length = 16.f;  // bones of 5.3 radii: a turn at one joint is far away
  o.rings = 64;
  o.segments = 24;
  o.blend_width = 0.5f;
  return o;
}

// A tube skinned smoothly along three bones, whose third bone is a root of
// its own (a rig of two chains under one skin, as anim_test.x's): the skin
// between the second and third parts blends two joints the skeleton does
// not link.
Rig twoChainTube() {
  Rig rig = makeCylinderRig(longCylinder());
  const TransformList globals = rig.skeleton.bindGlobals();
  Joint& third = rig.skeleton.joints[2];
  third.rest_local = rig.skeleton.root_parent.inverse() * globals[2];
  third.parent = -1;
  rig.validate().throwIfFailed("twoChainTube");
  return rig;
}

// The second joint turned by `degrees` about z through its bind position,
// everything else at rest (the third part, a root of its own, stays).
TransformList turnSecond(const Rig& rig, float degrees) {
  TransformList pose(rig.skeleton.jointCount(), Eigen::Affine3f::Identity());
  const Eigen::Vector3f at = rig.skeleton.bindGlobals()[1].translation();
  pose[1] = Eigen::Translation3f(at) *
            Eigen::AngleAxisf(degrees * static_cast<float>(M_PI) / 180.f,
                              Eigen::Vector3f::UnitZ()) *
            Eigen::Translation3f(-at);
  return pose;
}

std::vector<DislocationCandidate> candidatesOf(const Rig& rig) {
  std::vector<int> representative(rig.mesh.vertexCount());
  for (int v = 0; v < rig.mesh.vertexCount(); ++v) representative[v] = v;
  return dislocationCandidates(rig, partitionMesh(rig), representative);
}

TEST(DislocationCandidates, NoneOnALinkedChain) {
  const Rig rig = makeCylinderRig(longCylinder());
  EXPECT_TRUE(candidatesOf(rig).empty());
}

// A thin tube over three linked bones, its weights blended over most of
// each bone (animation_with_skeleton.fbx's kind of skin): the skin beside a
// joint is blended farther than the axis reach from it.
CylinderRigOptions thinWideBlend() {
  CylinderRigOptions o = longCylinder();
  o.radius = 0.25f;  // bones of 21 radii
  o.segments = 16;
  return o;
}

// Linked joints make candidates only far from their joint: none on the
// long cylinder (blends within 3 radii of the joints), some on the thin
// tube, each farther than the axis reach from the joint its two joints
// share.
TEST(DislocationCandidates, LinkedJointsOnlyFarFromTheirJoint) {
  const Rig rig = makeCylinderRig(thinWideBlend());
  const std::vector<DislocationCandidate> candidates = candidatesOf(rig);
  ASSERT_FALSE(candidates.empty());
  const TransformList binds = rig.skeleton.bindGlobals();
  for (const DislocationCandidate& c : candidates) {
    SCOPED_TRACE("vertex " + std::to_string(c.vertex));
    const int child = rig.skeleton.joints[c.other_joint].parent == c.home_joint
                          ? c.other_joint
                          : c.home_joint;
    ASSERT_TRUE(rig.skeleton.joints[c.other_joint].parent == c.home_joint ||
                rig.skeleton.joints[c.home_joint].parent == c.other_joint);
    EXPECT_GT((c.rest - binds[child].translation()).norm(),
              kDislocationAxisReach * c.radius);
  }
}

TEST(DislocationCandidates, TheSkinBetweenTwoChains) {
  const Rig rig = twoChainTube();
  const std::vector<DislocationCandidate> candidates = candidatesOf(rig);
  ASSERT_FALSE(candidates.empty());
  const float third_joint_x = rig.skeleton.bindGlobals()[2].translation().x();
  for (const DislocationCandidate& c : candidates) {
    SCOPED_TRACE("vertex " + std::to_string(c.vertex));
    EXPECT_EQ(std::min(c.home_joint, c.other_joint), 1);
    EXPECT_EQ(std::max(c.home_joint, c.other_joint), 2);
    // Within the blend around the third joint, a bone length wide.
    EXPECT_LT(std::abs(c.rest.x() - third_joint_x), 16.f / 3);
    EXPECT_GT(c.radius, 0.f);
  }
  EXPECT_TRUE(std::is_sorted(
      candidates.begin(), candidates.end(),
      [](const auto& a, const auto& b) { return a.vertex < b.vertex; }));
}

TEST(DislocatedVertices, NoneAtRestNorUnderARigidMotionOfTheWhole) {
  const Rig rig = twoChainTube();
  const std::vector<DislocationCandidate> candidates = candidatesOf(rig);
  const int joints = rig.skeleton.jointCount();
  EXPECT_TRUE(
      dislocatedVertices(candidates,
                         TransformList(joints, Eigen::Affine3f::Identity()))
          .empty());
  const Eigen::Affine3f whole =
      Eigen::Translation3f(3.f, -2.f, 5.f) *
      Eigen::AngleAxisf(1.2f, Eigen::Vector3f(1, 2, 3).normalized());
  EXPECT_TRUE(
      dislocatedVertices(candidates, TransformList(joints, whole)).empty());
}

TEST(DislocatedVertices, ATurnAboutAFarJointOrASlideDislocates) {
  const Rig rig = twoChainTube();
  const std::vector<DislocationCandidate> candidates = candidatesOf(rig);
  std::set<int> candidate_vertices;
  for (const auto& c : candidates) candidate_vertices.insert(c.vertex);
  const std::vector<int> turned =
      dislocatedVertices(candidates, turnSecond(rig, 30.f));
  ASSERT_FALSE(turned.empty());
  for (const int v : turned) EXPECT_TRUE(candidate_vertices.count(v)) << v;
  EXPECT_EQ(std::set<int>(turned.begin(), turned.end()).size(), turned.size());
  // A slide of the second part along the tube by half a radius.
  TransformList slide(rig.skeleton.jointCount(), Eigen::Affine3f::Identity());
  slide[1] = Eigen::Translation3f(0.5f, 0.f, 0.f);
  EXPECT_FALSE(dislocatedVertices(candidates, slide).empty());
  // A turn too small to move any candidate by a tenth of its radius.
  EXPECT_TRUE(dislocatedVertices(candidates, turnSecond(rig, 0.1f)).empty());
}

TEST(DislocatedVertices, NamesACandidateWhoseJointHasNoTransform) {
  const Rig rig = twoChainTube();
  const std::vector<DislocationCandidate> candidates = candidatesOf(rig);
  ASSERT_FALSE(candidates.empty());
  try {
    dislocatedVertices(candidates, TransformList(2));
    FAIL() << "expected isk::Error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("vertex"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("2 transforms"), std::string::npos);
  }
}

struct FrameMeasures {
  double volume_ratio = 0;  // to rest
  float largest_from_dqs = 0;
};

FrameMeasures measure(const Rig& rig, const Matrix3Xf& positions,
                      const TransformList& pose) {
  CpuSkinning dqs(rig.mesh, rig.weights, rig.skeleton.jointCount());
  dqs.run(SkinningMethod::kDualQuaternion, pose);
  FrameMeasures m;
  m.volume_ratio = enclosedVolume(positions, rig.mesh.triangles) /
                   enclosedVolume(rig.mesh.positions, rig.mesh.triangles);
  for (int v = 0; v < positions.rows(); ++v)
    m.largest_from_dqs = std::max(
        m.largest_from_dqs, (positions.row(v) - dqs.positions().row(v)).norm());
  return m;
}

// Where two chains meet, the march without the guard pulls the skin apart
// to follow two fields that moved apart; with it, that skin keeps its
// skinned position and the tube its volume.
TEST(DislocationGuard, KeepsTheSkinBetweenTwoChainsOnSkinning) {
  const test::RigWithFields tube = test::withDefaultFields(twoChainTube());
  const Rig& rig = tube.rig;
  const auto& fields = tube.fields;
  const TransformList pose = turnSecond(rig, 30.f);
  ImplicitSkinnerOptions off;
  off.tracking.dislocation_guard = false;
  CpuImplicitSkinner guarded(rig, fields), unguarded(rig, fields, off);
  guarded.run(pose);
  unguarded.run(pose);
  const FrameMeasures with = measure(rig, guarded.positions(), pose);
  const FrameMeasures without = measure(rig, unguarded.positions(), pose);
  std::cout << "two chains turned 30 degrees: volume " << with.volume_ratio
            << " (unguarded " << without.volume_ratio
            << "), largest distance from DQS " << with.largest_from_dqs
            << " (unguarded " << without.largest_from_dqs << ")\n";
  EXPECT_LE(std::abs(with.volume_ratio - 1), 0.02);
  EXPECT_LT(std::abs(with.volume_ratio - 1),
            std::abs(without.volume_ratio - 1));
  EXPECT_LT(with.largest_from_dqs, 0.7f * without.largest_from_dqs);
  // The dislocated vertices are untracked: exactly at their skinned place.
  CpuSkinning dqs(rig.mesh, rig.weights, rig.skeleton.jointCount());
  dqs.run(SkinningMethod::kDualQuaternion, pose);
  const std::vector<int> dislocated =
      dislocatedVertices(guarded.trackingMesh().dislocation_candidates, pose);
  ASSERT_FALSE(dislocated.empty());
  for (const int v : dislocated) {
    EXPECT_EQ(guarded.tracking().states()[v], TrackState::kUntracked) << v;
  }
}

// On a chain every blend is between linked joints: the guard never acts.
TEST(DislocationGuard, ChangesNoFrameOfALinkedChain) {
  const test::RigWithFields tube =
      test::withDefaultFields(makeCylinderRig(longCylinder()));
  const Rig& rig = tube.rig;
  const auto& fields = tube.fields;
  ImplicitSkinnerOptions off;
  off.tracking.dislocation_guard = false;
  CpuImplicitSkinner guarded(rig, fields), unguarded(rig, fields, off);
  for (const TransformList& pose : test::clipPoses(rig, 4)) {
    guarded.run(pose);
    unguarded.run(pose);
    EXPECT_EQ(guarded.positions(), unguarded.positions());
  }
}

// The kernel path leaves the same vertices untracked: its frames match the
// reference's, guarded and not.
TEST(DislocationGuard, OpenClFramesMatchTheReference) {
  const test::RigWithFields tube = test::withDefaultFields(twoChainTube());
  const Rig& rig = tube.rig;
  const auto& fields = tube.fields;
  const auto context = test::sharedContext();
  const float tolerance =
      (context->info().is_gpu ? 2e-2f : 5e-4f) * rig.boundingBoxDiagonal();
  for (const bool guard : {true, false}) {
    SCOPED_TRACE(guard ? "guarded" : "unguarded");
    ImplicitSkinnerOptions options;
    options.tracking.dislocation_guard = guard;
    CpuImplicitSkinner cpu(rig, fields, options);
    ImplicitSkinner cl(context, rig, fields, options);
    Matrix3Xf positions;
    for (const float degrees : {10.f, 30.f, 45.f}) {
      SCOPED_TRACE(std::to_string(degrees) + " degrees");
      const TransformList pose = turnSecond(rig, degrees);
      cpu.run(pose);
      cl.run(pose);
      cl.readPositions(positions);
      int beyond = 0;
      for (int v = 0; v < positions.rows(); ++v)
        beyond +=
            (positions.row(v) - cpu.positions().row(v)).norm() > tolerance;
      EXPECT_LE(beyond, 0.01 * positions.rows());
    }
  }
}

// A crowd offsets each instance's candidates by its first vertex and joint:
// a chain first, then two instances of the two-chain tube, each frame as
// the tube's own skinner's.
TEST(DislocationGuard, CrowdInstancesMatchTheirOwnSkinner) {
  const test::RigWithFields chain =
      test::withDefaultFields(makeCylinderRig(longCylinder()));
  const test::RigWithFields tube = test::withDefaultFields(twoChainTube());
  const auto context = test::sharedContext();
  ImplicitCrowd crowd(
      context, {{&chain.rig, chain.fields, 1}, {&tube.rig, tube.fields, 2}});
  // The chain has none; each tube instance has the tube's, shifted to the
  // instance's vertices and joints.
  const std::vector<DislocationCandidate> own = candidatesOf(tube.rig);
  const std::vector<DislocationCandidate>& all =
      crowd.trackingMesh().dislocation_candidates;
  ASSERT_EQ(all.size(), 2 * own.size());
  for (int i = 1; i < 3; ++i)
    for (size_t k = 0; k < own.size(); ++k) {
      const DislocationCandidate& c = all[(i - 1) * own.size() + k];
      EXPECT_EQ(c.vertex, own[k].vertex + crowd.instanceFirstVertex(i));
      EXPECT_EQ(c.home_joint, own[k].home_joint + crowd.instanceFirstJoint(i));
      EXPECT_EQ(c.other_joint,
                own[k].other_joint + crowd.instanceFirstJoint(i));
    }
  const float spacing = 3.f * tube.rig.boundingBoxDiagonal();
  auto placed = [&](TransformList pose, int instance) {
    for (Eigen::Affine3f& t : pose)
      t = Eigen::Translation3f(spacing * instance, 0.f, 0.f) * t;
    return pose;
  };
  const std::vector<TransformList> poses = {
      placed(test::clipPoses(chain.rig, 2)[1], 0),
      placed(turnSecond(tube.rig, 30.f), 1),
      placed(turnSecond(tube.rig, 45.f), 2)};
  crowd.run(poses);
  Matrix3Xf positions, alone_positions;
  crowd.readPositions(positions);
  const float tolerance =
      (context->info().is_gpu ? 2e-2f : 5e-4f) * tube.rig.boundingBoxDiagonal();
  for (int i = 1; i < 3; ++i) {
    SCOPED_TRACE("instance " + std::to_string(i));
    ImplicitSkinner alone(context, tube.rig, tube.fields);
    alone.run(poses[i]);
    alone.readPositions(alone_positions);
    const int first = crowd.instanceFirstVertex(i);
    int beyond = 0;
    for (int v = 0; v < alone_positions.rows(); ++v)
      beyond += (positions.row(first + v) - alone_positions.row(v)).norm() >
                tolerance;
    EXPECT_LE(beyond, 0.01 * alone_positions.rows());
  }
}

// The thin tube turned at its second joint: the skin blended far from the
// joint stays on skinning, nearer DQS and its volume than the march alone.
TEST(DislocationGuard, KeepsAWideBlendOfLinkedJointsOnSkinning) {
  const test::RigWithFields tube =
      test::withDefaultFields(makeCylinderRig(thinWideBlend()));
  const Rig& rig = tube.rig;
  ImplicitSkinnerOptions off;
  off.tracking.dislocation_guard = false;
  CpuImplicitSkinner guarded(rig, tube.fields),
      unguarded(rig, tube.fields, off);
  const TransformList pose = turnSecond(rig, 45.f);
  guarded.run(pose);
  unguarded.run(pose);
  const std::vector<int> dislocated =
      dislocatedVertices(guarded.trackingMesh().dislocation_candidates, pose);
  ASSERT_FALSE(dislocated.empty());
  CpuSkinning dqs(rig.mesh, rig.weights, rig.skeleton.jointCount());
  dqs.run(SkinningMethod::kDualQuaternion, pose);
  float off_guarded = 0, off_unguarded = 0;  // the dislocated, from DQS
  for (const int v : dislocated) {
    EXPECT_EQ(guarded.tracking().states()[v], TrackState::kUntracked) << v;
    off_guarded =
        std::max(off_guarded,
                 (guarded.positions().row(v) - dqs.positions().row(v)).norm());
    off_unguarded = std::max(
        off_unguarded,
        (unguarded.positions().row(v) - dqs.positions().row(v)).norm());
  }
  EXPECT_LT(off_guarded, 0.5f * off_unguarded);
  const FrameMeasures with = measure(rig, guarded.positions(), pose);
  const FrameMeasures without = measure(rig, unguarded.positions(), pose);
  std::cout << "thin tube turned 45 degrees: volume " << with.volume_ratio
            << " (unguarded " << without.volume_ratio
            << "), largest distance from DQS " << with.largest_from_dqs
            << " (unguarded " << without.largest_from_dqs << ")\n";
  EXPECT_LE(std::abs(with.volume_ratio - 1),
            std::abs(without.volume_ratio - 1) + 1e-4);
  EXPECT_LE(with.largest_from_dqs, without.largest_from_dqs);
}

// The largest |volume / rest - 1| of the guarded frames over 12 poses of the
// asset's first clip.
double worstVolumeOffRest(const std::string& name) {
  const Rig& rig = test::rigNamed(name);
  CpuImplicitSkinner guarded(rig);
  double worst = 0;
  for (const TransformList& pose : test::clipPoses(rig, 12)) {
    guarded.run(pose);
    worst = std::max(
        worst,
        std::abs(measure(rig, guarded.positions(), pose).volume_ratio - 1));
  }
  std::cout << name << "'s clip: volume off rest by " << worst << " at most\n";
  return worst;
}

// animation_with_skeleton.fbx blends most of its tube over 3 to 5 bones:
// guarded, its clip keeps its volume within 2% of rest, as DQS's.
TEST(DislocationGuard, KeepsAnimationWithSkeletonsVolume) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage(
        "animation_with_skeleton.fbx's clip");
  EXPECT_LE(worstVolumeOffRest("animation_with_skeleton.fbx"), 0.02);
}

// anim_test.x is such a rig (joint3 and joint4 are roots of their own):
// the guard keeps its clip's volume within 2% of rest, as DQS's.
TEST(DislocationGuard, KeepsAnimTestsVolume) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("anim_test.x's clip");
  EXPECT_LE(worstVolumeOffRest("anim_test.x"), 0.02);
}

}  // namespace
}  // namespace isk
