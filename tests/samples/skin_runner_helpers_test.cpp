// What isk-skin and the demo share besides the frame loop
// (samples/common/skin_runner.hpp), without a device: builtin inputs, the
// parameter file beside an asset, same-file checks, counts per frame summed
// up, tracking state changes between frames, and the side-by-side layout of
// the animated glTF.
#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include "isk/core/error.hpp"
#include "isk/io/gltf_export.hpp"
#include "isk/io/rig_params.hpp"
#include "isk/rig/animation.hpp"
#include "isk/tools/procedural.hpp"
#include "skin_runner.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using test::ScopedTempDir;

// A track of one frame whose x extent is `width`.
GltfTrack trackOfWidth(const std::string& name, float width) {
  GltfTrack track;
  track.name = name;
  Matrix3Xf positions(2, 3);
  positions << 0, 0, 0,  //
      width, 1, 1;
  track.positions = {positions};
  return track;
}

TEST(SkinRunnerHelpers, BuiltinInputsAreNoFiles) {
  EXPECT_TRUE(samples::isBuiltinInput("builtin:arm"));
  EXPECT_TRUE(samples::isBuiltinInput("builtin:"));
  EXPECT_FALSE(samples::isBuiltinInput("arm.glb"));
  EXPECT_FALSE(samples::isBuiltinInput("data/builtin:arm"));
}

TEST(SkinRunnerHelpers, ParameterFileBesideAnAssetWhenItExists) {
  const ScopedTempDir dir;
  const std::string asset = dir / "man.glb";
  std::ofstream(asset) << "asset";
  EXPECT_EQ(samples::paramsFileBeside(asset), "");
  std::ofstream(rigParamsPathFor(asset)) << "{}";
  EXPECT_EQ(samples::paramsFileBeside(asset), asset + ".isk.json");
  // A builtin rig has no folder to look in.
  EXPECT_EQ(samples::paramsFileBeside("builtin:arm"), "");
}

TEST(SkinRunnerHelpers, SamePathNeedsOneExistingFile) {
  const ScopedTempDir dir;
  const std::string file = dir / "a.json";
  std::ofstream(file) << "{}";
  EXPECT_TRUE(samples::samePath(file, file));
  EXPECT_TRUE(samples::samePath(file, (dir.path() / "." / "a.json").string()));
  EXPECT_FALSE(samples::samePath(file, dir / "b.json"));
  EXPECT_FALSE(samples::samePath(dir / "b.json", dir / "b.json"));
}

TEST(SkinRunnerHelpers, CountsPerFrameSumUp) {
  EXPECT_EQ(samples::medianCount({}), 0);
  EXPECT_EQ(samples::medianCount({5, 1, 3}), 3);
  EXPECT_EQ(samples::medianCount({4, 1, 2, 3}), 2.5);
  const samples::CountTotals totals = samples::countTotals({2, 7, 0, 3});
  EXPECT_EQ(totals.max, 7);
  EXPECT_EQ(totals.total, 12);
  const samples::CountTotals none = samples::countTotals({});
  EXPECT_EQ(none.max, 0);
  EXPECT_EQ(none.total, 0);
}

TEST(SkinRunnerHelpers, StateChangesCountVerticesWhoseStateDiffers) {
  using S = TrackState;
  const std::vector<S> before = {S::kConverged, S::kContact, S::kCrease,
                                 S::kUntracked, S::kLost};
  const std::vector<S> after = {S::kContact, S::kContact, S::kConverged,
                                S::kUntracked, S::kLost};
  EXPECT_EQ(samples::changedStates(before, before), 0);
  EXPECT_EQ(samples::changedStates(before, after), 2);
  EXPECT_EQ(samples::changedStates(after, before), 2);
  try {
    samples::changedStates(before, {S::kContact});
    ADD_FAILURE() << "states of two sizes were compared";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("5 and 1 states"), std::string::npos)
        << e.what();
  }
  // The first frame has no frame before it: left out of the summary.
  const auto summary = samples::summarizeStateChanges({std::nullopt, 4, 8, 0});
  ASSERT_TRUE(summary.has_value());
  EXPECT_DOUBLE_EQ(summary->mean, 4.0);
  EXPECT_EQ(summary->max, 8);
  EXPECT_FALSE(samples::summarizeStateChanges({std::nullopt}).has_value());
  EXPECT_FALSE(samples::summarizeStateChanges({}).has_value());
}

// --clip rest and --clip bend[:DEGREES] on any rig; the rig's own clip of
// that name wins; a bad angle is a clear error.
TEST(SkinRunnerHelpers, RestAndBendClipsOnEveryRig) {
  Rig rig = makeBuiltinRig("arm");
  const std::optional<AnimationClip> rest =
      samples::proceduralClip(rig.skeleton, "rest");
  ASSERT_TRUE(rest);
  EXPECT_EQ(rest->name, "rest");
  EXPECT_TRUE(rest->channels.empty());
  EXPECT_EQ(samples::defaultFrameCount(*rest), 1);
  const std::optional<AnimationClip> bend =
      samples::proceduralClip(rig.skeleton, "bend:60");
  ASSERT_TRUE(bend);
  EXPECT_EQ(bend->name, "bend:60");
  const AnimationClip expected = makeBendClip(
      rig.skeleton, static_cast<float>(3.14159265358979323846 / 3), 1.0);
  const TransformList got = bend->sampleLocal(rig.skeleton, 1.0);
  const TransformList want = expected.sampleLocal(rig.skeleton, 1.0);
  ASSERT_EQ(got.size(), want.size());
  for (size_t j = 0; j < got.size(); ++j)
    EXPECT_TRUE(got[j].isApprox(want[j], 1e-6f)) << "joint " << j;
  ASSERT_TRUE(samples::proceduralClip(rig.skeleton, "bend"));
  EXPECT_EQ(samples::proceduralClip(rig.skeleton, "bend")->name, "bend:90");
  EXPECT_FALSE(samples::proceduralClip(rig.skeleton, "Walk"));
  for (const char* bad :
       {"bend:", "bend:abc", "bend:200", "bend:-5", "bend:nan", "bend:90deg"}) {
    EXPECT_THROW(samples::proceduralClip(rig.skeleton, bad), Error) << bad;
  }
  // A rig without clips takes them too.
  rig.clips.clear();
  EXPECT_EQ(samples::selectClip(rig, "rest", nullptr).name, "rest");
  EXPECT_EQ(samples::selectClip(rig, "bend:120", nullptr).name, "bend:120");
  // The rig's own clip named "rest" is not hidden.
  AnimationClip own = expected;
  own.name = "rest";
  rig.clips = {own};
  EXPECT_FALSE(samples::selectClip(rig, "rest", nullptr).channels.empty());
}

TEST(SkinRunnerHelpers, TracksSitSideBySideAroundTheMiddleOne) {
  std::vector<GltfTrack> tracks = {trackOfWidth("lbs", 2),
                                   trackOfWidth("dqs", 5),
                                   trackOfWidth("implicit", 3)};
  samples::placeSideBySide(tracks);
  std::vector<Matrix3Xf> all;
  for (const GltfTrack& track : tracks) all.push_back(track.positions[0]);
  const float spacing = gltfTrackSpacing(all);
  EXPECT_GT(spacing, 5.f);  // more than the widest
  EXPECT_EQ(tracks[0].offset, Eigen::Vector3f(-spacing, 0, 0));
  EXPECT_EQ(tracks[1].offset, Eigen::Vector3f(0, 0, 0));
  EXPECT_EQ(tracks[2].offset, Eigen::Vector3f(spacing, 0, 0));
  EXPECT_EQ(tracks[0].name, "lbs");  // order and names kept

  std::vector<GltfTrack> two = {trackOfWidth("lbs", 2), trackOfWidth("dqs", 2)};
  samples::placeSideBySide(two);
  EXPECT_FLOAT_EQ(two[1].offset.x() - two[0].offset.x(),
                  gltfTrackSpacing({two[0].positions[0]}));
  EXPECT_FLOAT_EQ(two[0].offset.x(), -two[1].offset.x());
}

}  // namespace
}  // namespace isk
