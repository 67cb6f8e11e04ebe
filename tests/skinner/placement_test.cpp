// Where a character stands (ImplicitSkinnerOptions::anchor_pose,
// isk/rig/pose_anchor.hpp): a pose moved to two places far from the origin,
// whole anchor steps apart, gives the same frame, moved, up to the rounding
// of the final addition -- on both backends, in the 2013 and the history
// modes, on the procedural rigs and on every shared asset at a deep bend.
// Computed in the given coordinates instead, float rounding out there is
// amplified where skin meets skin and the frames part.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "isk/implicit_skinner.hpp"
#include "isk/rig/pose_anchor.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

// Two places far out: (64, -32, 16) and (-16, 8, -128) anchor steps of the
// rig, tens to hundreds of metres for a human.
Eigen::Vector3f farOffset(const Rig& rig, int which) {
  return anchorStep(rig.boundingBoxDiagonal()) *
         (which == 0 ? Eigen::Vector3f(64.f, -32.f, 16.f)
                     : Eigen::Vector3f(-16.f, 8.f, -128.f));
}

// The float spacing of coordinates up to twice the offsets' largest: moved
// by the offsets, translations on this grid stay exact.
float spacingAt(float largest) {
  return std::ldexp(1.f, std::ilogb(2.f * largest) - 23);
}

// `poses` with their translations rounded to multiples of `spacing`.
std::vector<TransformList> onGrid(std::vector<TransformList> poses,
                                  float spacing) {
  for (TransformList& pose : poses)
    for (Eigen::Affine3f& t : pose)
      t.translation() = (t.translation() / spacing).array().round() * spacing;
  return poses;
}

std::vector<TransformList> moved(std::vector<TransformList> poses,
                                 const Eigen::Vector3f& offset) {
  for (TransformList& pose : poses)
    for (Eigen::Affine3f& t : pose) t.pretranslate(offset);
  return poses;
}

// The frames of `poses` in sequence (one skinner), positions and normals.
template <typename Skinner>
void runFrames(Skinner& skinner, const std::vector<TransformList>& poses,
               std::vector<Matrix3Xf>& positions,
               std::vector<Matrix3Xf>& normals,
               std::vector<Eigen::Vector3f>& anchors) {
  for (const TransformList& pose : poses) {
    skinner.run(pose);
    positions.emplace_back();
    normals.emplace_back();
    skinner.readPositions(positions.back());
    skinner.readNormals(normals.back());
    anchors.push_back(skinner.anchor());
  }
}

// The frames of `poses` moved to either far place, with the CPU reference
// and on OpenCL: the same positions moved (within the rounding of adding the
// anchor back) and the same normals, every frame; near the origin the
// anchor is zero (the frames computed as given).
void checkSameFramesFarOut(const std::string& name,
                           const std::vector<TransformList>& given,
                           const ImplicitSkinnerOptions& options) {
  const Rig& rig = test::rigNamed(name);
  const Eigen::Vector3f offsets[2] = {farOffset(rig, 0), farOffset(rig, 1)};
  const float spacing = spacingAt(std::max(offsets[0].cwiseAbs().maxCoeff(),
                                           offsets[1].cwiseAbs().maxCoeff()));
  const std::vector<TransformList> near = onGrid(given, spacing);
  const std::shared_ptr<const ImplicitFields> fields(
      &test::implicitFieldsOf(name), [](const ImplicitFields*) {});
  for (const bool device : {false, true}) {
    SCOPED_TRACE(device ? "OpenCL" : "CPU reference");
    std::vector<Matrix3Xf> positions[3], normals[3];
    std::vector<Eigen::Vector3f> anchors[3];
    for (int place = 0; place < 3; ++place) {
      const std::vector<TransformList> poses =
          place < 2 ? moved(near, offsets[place]) : near;
      if (device) {
        ImplicitSkinner skinner(test::sharedContext(), rig, fields, options);
        runFrames(skinner, poses, positions[place], normals[place],
                  anchors[place]);
      } else {
        CpuImplicitSkinner skinner(rig, fields, options);
        runFrames(skinner, poses, positions[place], normals[place],
                  anchors[place]);
      }
    }
    for (size_t f = 0; f < near.size(); ++f) {
      SCOPED_TRACE("frame " + std::to_string(f));
      EXPECT_EQ(anchors[2][f], Eigen::Vector3f::Zero());
      EXPECT_EQ(anchors[1][f] - offsets[1], anchors[0][f] - offsets[0]);
      Matrix3Xf back[2];
      for (int place = 0; place < 2; ++place) {
        ASSERT_TRUE(positions[place][f].allFinite());
        back[place] = positions[place][f];
        back[place].rowwise() -= offsets[place].transpose();
      }
      const test::RowMismatch p = test::largestRowDistance(back[1], back[0]);
      EXPECT_LE(p.distance, 2.f * spacing)
          << "vertex " << p.row << " ("
          << p.distance / rig.boundingBoxDiagonal() << " of the diagonal)";
      const test::RowMismatch n =
          test::largestRowDistance(normals[1][f], normals[0][f]);
      EXPECT_LE(n.distance, 1e-6f) << "normal of vertex " << n.row;
    }
  }
}

TEST(Placement, FarOutGivesTheSameFramesMovedOnProceduralRigs) {
  ImplicitSkinnerOptions history;
  history.tracking_mode = TrackingMode::kHistory;
  for (const std::string& name : builtinRigNames()) {
    SCOPED_TRACE(name);
    const Rig& rig = test::rigNamed(name);
    // A deep bend (where the tracking is most sensitive) and a few frames of
    // the clip, in each mode.
    std::vector<TransformList> poses = test::clipPoses(rig, 4);
    poses.push_back(test::everyJointBent(rig, 135.0));
    {
      SCOPED_TRACE("2013 mode");
      checkSameFramesFarOut(name, poses, {});
    }
    {
      SCOPED_TRACE("history mode");
      checkSameFramesFarOut(name, poses, history);
    }
  }
}

TEST(Placement, FarOutGivesTheSameFrameMovedOnAssets) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("assets placed far out");
  for (const std::string& name : test::assetNames()) {
    SCOPED_TRACE(name);
    const Rig& rig = test::rigNamed(name);
    checkSameFramesFarOut(name, {test::everyJointBent(rig, 90.0)}, {});
  }
}

}  // namespace
}  // namespace isk
