// isk/rig/pose_anchor.hpp: the anchor step, where a pose stands, rounded to
// whole steps, zero where it cannot be placed, and taken out of a pose.
#include "isk/rig/pose_anchor.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace isk {
namespace {

TEST(PoseAnchor, StepIsThePowerOfTwoAtLeastTheDiagonal) {
  EXPECT_EQ(anchorStep(1.8f), 2.f);
  EXPECT_EQ(anchorStep(2.f), 2.f);
  EXPECT_EQ(anchorStep(2.01f), 4.f);
  EXPECT_EQ(anchorStep(0.3f), 0.5f);
  EXPECT_EQ(anchorStep(150.f), 256.f);
  EXPECT_EQ(anchorStep(0.f), 1.f);
  EXPECT_EQ(anchorStep(-3.f), 1.f);
  EXPECT_EQ(anchorStep(std::numeric_limits<float>::quiet_NaN()), 1.f);
  EXPECT_EQ(anchorStep(std::numeric_limits<float>::infinity()), 1.f);
}

// Three joints carrying the rest centre (0.4, 0.9, 0) by `offset`, one of
// them turned a quarter about z about the centre.
TransformList posedAt(const Eigen::Vector3f& offset) {
  const Eigen::Vector3f center(0.4f, 0.9f, 0.f);
  TransformList pose(3, Eigen::Affine3f::Identity());
  pose[1] = Eigen::Translation3f(center) *
            Eigen::AngleAxisf(static_cast<float>(M_PI / 2),
                              Eigen::Vector3f::UnitZ()) *
            Eigen::Translation3f(-center);
  for (Eigen::Affine3f& t : pose) t.pretranslate(offset);
  return pose;
}

TEST(PoseAnchor, IsZeroNearTheOriginAndWholeStepsFarFromIt) {
  const std::vector<Eigen::Vector3f> centers(3,
                                             Eigen::Vector3f(0.4f, 0.9f, 0.f));
  // The centres' mean stays at (0.4, 0.9, 0), then (3.4, 0.9, -3.9): within
  // kAnchorFreeSteps steps of 2.
  EXPECT_EQ(poseAnchor(posedAt(Eigen::Vector3f::Zero()), centers, 2.f),
            Eigen::Vector3f::Zero());
  EXPECT_EQ(poseAnchor(posedAt(Eigen::Vector3f(3.f, 0.f, -3.9f)), centers, 2.f),
            Eigen::Vector3f::Zero());
  // 61.4 / 2 rounds to 31, -32.1 / 2 to -16, 0.9 / 2 to 0.
  EXPECT_EQ(
      poseAnchor(posedAt(Eigen::Vector3f(61.f, 0.f, -32.1f)), centers, 2.f),
      Eigen::Vector3f(62.f, 0.f, -32.f));
  // Moved by whole steps, the anchor moves with it.
  const Eigen::Vector3f steps(1024.f, -512.f, 256.f);
  EXPECT_EQ(poseAnchor(posedAt(steps), centers, 2.f), steps);
  // A coarser step rounds the same pose elsewhere: 61.4 / 16 to 4, -32.1 /
  // 16 to -2; with a step of 64 it is within the free steps.
  EXPECT_EQ(
      poseAnchor(posedAt(Eigen::Vector3f(61.f, 0.f, -32.1f)), centers, 16.f),
      Eigen::Vector3f(64.f, 0.f, -32.f));
  EXPECT_EQ(
      poseAnchor(posedAt(Eigen::Vector3f(61.f, 0.f, -32.1f)), centers, 64.f),
      Eigen::Vector3f::Zero());
}

TEST(PoseAnchor, IsZeroForPosesItCannotPlace) {
  const std::vector<Eigen::Vector3f> centers(3, Eigen::Vector3f::Zero());
  const TransformList far = posedAt(Eigen::Vector3f(100.f, 0.f, 0.f));
  ASSERT_NE(poseAnchor(far, centers, 2.f), Eigen::Vector3f::Zero());
  EXPECT_EQ(poseAnchor({}, {}, 2.f), Eigen::Vector3f::Zero());
  // Sizes that do not match (the skinner then names the pose's size).
  EXPECT_EQ(poseAnchor(far, {Eigen::Vector3f::Zero()}, 2.f),
            Eigen::Vector3f::Zero());
  // A non-finite transform (the skinner then names the joint).
  TransformList bad = far;
  bad[2].translation().x() = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(poseAnchor(bad, centers, 2.f), Eigen::Vector3f::Zero());
  bad[2].translation().x() = std::numeric_limits<float>::infinity();
  EXPECT_EQ(poseAnchor(bad, centers, 2.f), Eigen::Vector3f::Zero());
  EXPECT_EQ(poseAnchor(far, centers, 0.f), Eigen::Vector3f::Zero());
}

TEST(PoseAnchor, SubtractAnchorTakesItOutOfEveryTranslation) {
  TransformList pose = posedAt(Eigen::Vector3f(64.f, 2.f, -8.f));
  const TransformList given = pose;
  subtractAnchor(Eigen::Vector3f(64.f, 2.f, -8.f), pose);
  ASSERT_EQ(pose.size(), given.size());
  for (size_t j = 0; j < pose.size(); ++j) {
    EXPECT_EQ(pose[j].linear(), given[j].linear()) << "joint " << j;
    EXPECT_EQ(pose[j].translation(),
              given[j].translation() - Eigen::Vector3f(64.f, 2.f, -8.f))
        << "joint " << j;
  }
}

TEST(PoseAnchor, RestCentersAreTheBoundingBoxCentreOncePerJoint) {
  Matrix3Xf rest(3, 3);
  rest << 0.f, 0.f, 0.f,  //
      2.f, 1.f, -4.f,     //
      1.f, 3.f, 0.f;
  const std::vector<Eigen::Vector3f> centers = restCenters(rest, 2);
  ASSERT_EQ(centers.size(), 2u);
  for (const Eigen::Vector3f& c : centers)
    EXPECT_EQ(c, Eigen::Vector3f(1.f, 1.5f, -2.f));
  EXPECT_EQ(restCenters(Matrix3Xf(0, 3), 1).front(), Eigen::Vector3f::Zero());
  EXPECT_TRUE(restCenters(rest, 0).empty());
}

}  // namespace
}  // namespace isk
