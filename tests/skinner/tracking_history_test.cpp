// History-dependent tracking (isk/tracking/tracking_history.hpp,
// ImplicitSkinnerOptions::tracking_mode): when a frame starts from the last
// one (first frame, small turns, a jump past the reset angle, resetHistory),
// that a start from skinning gives the 2013 frame bit for bit, that a
// replay gives the same frames, and that the OpenCL skinner follows the CPU
// reference over a bend sequence, on the procedural rigs and on the shared
// assets.
#include "isk/tracking/tracking_history.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "isk/core/error.hpp"
#include "isk/implicit_crowd.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

std::vector<int> parentsOf(const Rig& rig) {
  std::vector<int> parents;
  for (const Joint& joint : rig.skeleton.joints)
    parents.push_back(joint.parent);
  return parents;
}

// `frames` poses of every joint bent from 0 to `degrees` (the clip of
// isk-skin's --clip bend:DEGREES).
std::vector<TransformList> bendSequence(const Rig& rig, float degrees,
                                        int frames) {
  const AnimationClip clip = makeBendClip(
      rig.skeleton, degrees * static_cast<float>(M_PI) / 180.f, 1.0);
  std::vector<TransformList> poses;
  for (int f = 0; f < frames; ++f)
    poses.push_back(skinningTransforms(
        rig.skeleton,
        globalTransforms(rig.skeleton,
                         clip.sampleLocal(rig.skeleton, f / static_cast<double>(
                                                                frames - 1)))));
  return poses;
}

ImplicitSkinnerOptions historyOptions() {
  ImplicitSkinnerOptions options;
  options.tracking_mode = TrackingMode::kHistory;
  return options;
}

TEST(TrackingHistory, TurnsAreMeasuredRelativeToTheParent) {
  const Rig rig = makeBuiltinRig("arm");
  const std::vector<int> parents = parentsOf(rig);
  const TransformList rest = bindPoseSkinning(rig.skeleton);
  const int elbow = rig.skeleton.find("elbow");
  ASSERT_GE(elbow, 0);
  EXPECT_NEAR(
      largestRelativeTurnDegrees(parents, rest, test::bendAt(rig, elbow, 40.0)),
      40.f, 1e-2f);
  // The whole character turned: no joint turned relative to its parent.
  const Eigen::Affine3f turn(
      Eigen::AngleAxisf(2.f, Eigen::Vector3f(1.f, 2.f, 3.f).normalized()));
  TransformList turned = rest;
  for (Eigen::Affine3f& t : turned) t = turn * t;
  EXPECT_LT(largestRelativeTurnDegrees(parents, rest, turned), 1e-2f);
}

TEST(TrackingHistory, AFrameStartsFromTheLastUnlessFirstJumpedOrReset) {
  const Rig rig = makeBuiltinRig("arm");
  const int elbow = rig.skeleton.find("elbow");
  TrackingHistory history(parentsOf(rig), 30.f);
  EXPECT_FALSE(history.next(test::bendAt(rig, elbow, 0.0)));   // first
  EXPECT_TRUE(history.next(test::bendAt(rig, elbow, 20.0)));   // 20 degrees
  EXPECT_FALSE(history.next(test::bendAt(rig, elbow, 60.0)));  // 40: a jump
  EXPECT_TRUE(history.next(test::bendAt(rig, elbow, 70.0)));
  history.reset();
  EXPECT_FALSE(history.next(test::bendAt(rig, elbow, 75.0)));
  EXPECT_TRUE(history.next(test::bendAt(rig, elbow, 75.0)));
  // Another skeleton's pose (another joint count) starts afresh.
  EXPECT_FALSE(history.next(TransformList(2)));
}

// Over a bend sequence, the history skinners (CPU and OpenCL): the first
// frame and the frame after resetHistory() or a jump are the 2013 frames
// (bit for bit on the CPU); the frames between start from the last and
// differ from the 2013 ones; a second skinner replays the same frames bit
// for bit; the OpenCL frames follow the CPU's.
void checkHistoryFrames(const std::string& name,
                        const std::vector<TransformList>& poses) {
  const Rig& rig = test::rigNamed(name);
  const auto fields =
      std::make_shared<const ImplicitFields>(test::implicitFieldsOf(name));
  CpuImplicitSkinner cpu2013(rig, fields), cpu(rig, fields, historyOptions()),
      replay(rig, fields, historyOptions());
  const auto context = test::sharedContext();
  ImplicitSkinner cl(context, rig, fields, historyOptions());
  CpuSkinning dqs(rig.mesh, rig.weights, rig.skeleton.jointCount());
  const float diagonal = rig.boundingBoxDiagonal();
  const float tolerance = (context->info().is_gpu ? 2e-2f : 5e-4f) * diagonal;
  Matrix3Xf positions;
  bool history_moved = false, tracked = false;
  for (size_t f = 0; f < poses.size(); ++f) {
    SCOPED_TRACE("frame " + std::to_string(f));
    if (f == poses.size() / 2) {
      cpu.resetHistory();
      replay.resetHistory();
      cl.resetHistory();
    }
    cpu2013.run(poses[f]);
    cpu.run(poses[f]);
    replay.run(poses[f]);
    cl.run(poses[f]);
    cl.readPositions(positions);
    dqs.run(SkinningMethod::kDualQuaternion, poses[f], false);
    tracked = tracked ||
              test::largestRowDistance(cpu2013.positions(), dqs.positions())
                      .distance > 1e-4f * diagonal;
    ASSERT_TRUE(cpu.positions() == replay.positions()) << "replay differs";
    const auto cl_cpu = test::largestRowDistance(positions, cpu.positions());
    int beyond = 0;
    for (int v = 0; v < positions.rows(); ++v)
      beyond += (positions.row(v) - cpu.positions().row(v)).norm() > tolerance;
    EXPECT_LE(beyond, 0.01 * positions.rows())
        << name << ": OpenCL off the reference, worst vertex " << cl_cpu.row
        << " by " << cl_cpu.distance / diagonal << " of the diagonal";
    const bool restart = f == 0 || f == poses.size() / 2;
    if (restart) {
      EXPECT_TRUE(cpu.positions() == cpu2013.positions())
          << name << ": a restart is not the 2013 frame";
    } else {
      history_moved = history_moved || test::largestRowDistance(
                                           cpu.positions(), cpu2013.positions())
                                               .distance > 1e-4f * diagonal;
    }
  }
  // (Where tracking leaves every vertex on DQS, as on an open quad, so
  // does the history.)
  if (tracked)
    EXPECT_TRUE(history_moved) << name << ": no frame differs from 2013";
}

TEST(TrackingHistory, FramesOnProceduralRigs) {
  for (const std::string& name : builtinRigNames()) {
    SCOPED_TRACE(name);
    checkHistoryFrames(name, test::clipPoses(test::rigNamed(name), 8));
  }
}

TEST(TrackingHistory, FramesOnEverySharedAsset) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("the assets' history frames");
  for (const std::string& file : test::assetNames()) {
    SCOPED_TRACE(file);
    checkHistoryFrames(file, bendSequence(test::rigNamed(file), 60.f, 6));
  }
}

// Bent to 120 degrees and released: a start from the last frame is taken
// only by the vertices the last frame stopped at a contact or in a crease,
// so once the pose no longer presses skin on skin the frames are the 2013
// ones again, bit for bit -- the rest pose within two frames of coming back.
TEST(TrackingHistory, BendAndReleaseReturnsToTheRestPose) {
  for (const char* name : {"cylinder", "leg"}) {
    SCOPED_TRACE(name);
    const Rig& rig = test::rigNamed(name);
    const auto fields =
        std::make_shared<const ImplicitFields>(test::implicitFieldsOf(name));
    std::vector<TransformList> poses = bendSequence(rig, 120.f, 12);
    for (int f = 10; f >= 0; --f) poses.push_back(poses[f]);
    const TransformList rest = bindPoseSkinning(rig.skeleton);
    for (int f = 0; f < 3; ++f) poses.push_back(rest);
    CpuImplicitSkinner history(rig, fields, historyOptions()),
        cpu2013(rig, fields);
    bool differed = false;
    for (const TransformList& pose : poses) {
      history.run(pose);
      cpu2013.run(pose);
      differed = differed || !(history.positions() == cpu2013.positions());
    }
    EXPECT_TRUE(differed) << "the bend never started from the last frame";
    EXPECT_TRUE(history.positions() == cpu2013.positions());
    EXPECT_LE(test::largestRowDistance(history.positions(), rig.mesh.positions)
                  .distance,
              1e-5f * rig.boundingBoxDiagonal());
  }
}

// A pose that jumps past history_reset_degrees starts from skinning: the
// 2013 frame; below it, the frame starts from the last.
TEST(TrackingHistory, APoseJumpStartsFromSkinning) {
  const Rig& rig = test::rigNamed("leg");
  const auto fields =
      std::make_shared<const ImplicitFields>(test::implicitFieldsOf("leg"));
  const std::vector<TransformList> poses = bendSequence(rig, 150.f, 6);
  ImplicitSkinnerOptions options = historyOptions();
  options.history_reset_degrees = 20.f;  // the sequence turns 30 a frame
  ImplicitSkinnerOptions wider = historyOptions();
  wider.history_reset_degrees = 40.f;
  CpuImplicitSkinner jumping(rig, fields, options),
      following(rig, fields, wider), cpu2013(rig, fields);
  bool followed = false;
  for (const TransformList& pose : poses) {
    jumping.run(pose);
    following.run(pose);
    cpu2013.run(pose);
    EXPECT_TRUE(jumping.positions() == cpu2013.positions());
    followed = followed || !(following.positions() == cpu2013.positions());
  }
  EXPECT_TRUE(followed)
      << "below the reset angle no frame started from the last";
}

TEST(TrackingHistory, OptionsAreCheckedAndACrowdTakesThe2013ModeOnly) {
  ImplicitSkinnerOptions options = historyOptions();
  options.history_reset_degrees = 200.f;
  EXPECT_NE(options.validate().reason().find("history_reset_degrees"),
            std::string::npos);
  options.history_reset_degrees = 30.f;
  EXPECT_TRUE(static_cast<bool>(options.validate()));
  options.tracking.history_keep = 1.5f;
  EXPECT_NE(options.validate().reason().find("history_keep"),
            std::string::npos);
  options.tracking.history_keep = 0.5f;
  EXPECT_STREQ(trackingModeName(TrackingMode::kHistory), "history");
  EXPECT_STREQ(trackingModeName(TrackingMode::k2013), "2013");
  const Rig& rig = test::rigNamed("arm");
  try {
    ImplicitCrowd crowd(test::sharedContext(), rig, 2, options);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("tracking mode history"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace isk
