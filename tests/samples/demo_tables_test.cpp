// The demo's host-only parts (samples/common/demo_tables.hpp and
// demo_views.hpp), without a device: the frames per clip, the rows and
// Markdown tables, summary.md, the agreement messages, the most bent frame
// of a clip and the views, colours and texts of the comparison pictures.
#include "demo_tables.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>
#include <vector>

#include "demo_views.hpp"
#include "field_pictures.hpp"
#include "isk/rig/animation.hpp"
#include "isk/tools/procedural.hpp"
#include "isk/tools/self_intersection.hpp"
#include "mesh_render.hpp"
#include "skin_runner.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

namespace demo = samples::demo;
using samples::RunResult;
using test::number;
using test::tableRows;

constexpr double kPi = 3.14159265358979323846;

AnimationClip clipOf(const std::string& name, double duration) {
  AnimationClip clip;
  clip.name = name;
  clip.duration = duration;
  return clip;
}

RunResult madeUpResult() {
  RunResult result;
  result.frames = 3;
  result.frame.median = 1.5;
  result.self_intersections = {2, 5, 1};
  result.contact_vertices = {3, 9, 6};
  result.volume_ratio_min = 0.95;
  result.volume_ratio_max = 1.01;
  return result;
}

double angleDegrees(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  const double cosine = a.normalized().dot(b.normalized());
  return std::acos(std::clamp(cosine, -1.0, 1.0)) * 180 / kPi;
}

TEST(DemoTables, FramesPerClipAreCappedUnlessGiven) {
  const demo::FramePlan one_second = demo::planFrames(0, clipOf("bend", 1));
  EXPECT_EQ(one_second.full_count, 31);
  EXPECT_EQ(one_second.count, 31);
  const demo::FramePlan long_clip = demo::planFrames(0, clipOf("walk", 4));
  EXPECT_EQ(long_clip.full_count, 121);
  EXPECT_EQ(long_clip.count, demo::kDefaultMaxFrames);
  const demo::FramePlan given = demo::planFrames(3, clipOf("walk", 4));
  EXPECT_EQ(given.count, 3);
  EXPECT_EQ(given.full_count, 121);

  EXPECT_EQ(demo::describeFramePlan("arm", long_clip),
            "arm 31 of the 121 at 30 per second");
  EXPECT_EQ(demo::formatFrameNote({"arm 31 of the 31 at 30 per second",
                                   "cylinder 31 of the 31 at 30 per second"},
                                  0),
            "Frames per clip (uniformly over the clip): arm 31 of the 31 at "
            "30 per second; cylinder 31 of the 31 at 30 per second (at most "
            "31 by default; --frames N to change).");
  EXPECT_EQ(demo::formatFrameNote({"arm 3 of the 31 at 30 per second"}, 3),
            "Frames per clip (uniformly over the clip): arm 3 of the 31 at 30 "
            "per second (--frames 3).");
}

TEST(DemoTables, RowSumsUpTheRun) {
  const demo::Row dqs = demo::makeRow("arm", clipOf("bend", 1),
                                      demo::kMethods[1], "dev", madeUpResult());
  EXPECT_EQ(dqs.rig, "arm");
  EXPECT_EQ(dqs.clip, "bend (1.00 s)");
  EXPECT_EQ(dqs.method, "dqs");
  EXPECT_EQ(dqs.device, "dev");
  EXPECT_EQ(dqs.frames, 3);
  EXPECT_EQ(dqs.median_ms, 1.5);
  EXPECT_EQ(dqs.intersections_max, 5);
  EXPECT_EQ(dqs.intersections_total, 8);
  EXPECT_FALSE(dqs.contact_median.has_value());  // implicit only
  const demo::Row implicit = demo::makeRow(
      "arm", clipOf("bend", 1), demo::kMethods[2], "dev", madeUpResult());
  ASSERT_TRUE(implicit.contact_median.has_value());
  EXPECT_EQ(*implicit.contact_median, 6);
}

TEST(DemoTables, SkinningTableHasACellPerColumn) {
  demo::Row opencl = demo::makeRow("arm", clipOf("bend", 1), demo::kMethods[2],
                                   "PoCL / cpu", madeUpResult());
  opencl.reference_ms = 4.25;
  opencl.max_difference = 3.5e-5;
  RunResult no_volume = madeUpResult();
  no_volume.volume_ratio_min.reset();
  no_volume.volume_ratio_max.reset();
  const demo::Row reference =
      demo::makeRow("flat", clipOf("bend", 1), demo::kMethods[0],
                    "reference (CPU)", no_volume);
  const std::string table = demo::formatTable({opencl, reference});
  const auto rows = tableRows(table, "| rig | clip | method | device |");
  ASSERT_EQ(rows.size(), 2u) << table;
  ASSERT_EQ(rows[0].size(), 13u) << table;
  EXPECT_EQ(rows[0][0], "arm");
  EXPECT_EQ(rows[0][1], "bend (1.00 s)");
  EXPECT_EQ(rows[0][2], "implicit");
  EXPECT_EQ(rows[0][3], "PoCL / cpu");
  EXPECT_EQ(rows[0][4], "3");
  EXPECT_EQ(rows[0][5], "1.500");
  EXPECT_EQ(rows[0][6], "0.9500");
  EXPECT_EQ(rows[0][7], "1.0100");
  EXPECT_EQ(rows[0][8], "5");
  EXPECT_EQ(rows[0][9], "8");
  EXPECT_EQ(rows[0][10], "6");
  EXPECT_EQ(rows[0][11], "4.250");
  EXPECT_EQ(rows[0][12], "3.50e-05");
  ASSERT_EQ(rows[1].size(), 13u) << table;
  EXPECT_EQ(rows[1][6], "n/a");
  EXPECT_EQ(rows[1][7], "n/a");
  EXPECT_EQ(rows[1][10], "-");
  EXPECT_EQ(rows[1][11], "-");
  EXPECT_EQ(rows[1][12], "-");
}

TEST(DemoTables, FieldRowDescribesTheBuiltFields) {
  const ImplicitFields& fields = test::implicitFieldsOf("cylinder");
  const demo::FieldRow row = demo::describeFields("cylinder", fields);
  EXPECT_EQ(row.rig, "cylinder");
  EXPECT_EQ(row.fields, fields.grids.fieldCount());
  EXPECT_GT(row.fields, 0);
  EXPECT_GT(row.samples_min, 0);
  EXPECT_LE(row.samples_min, row.samples_max);
  EXPECT_NEAR(row.mib, fields.grids.bytes() / (1024.0 * 1024.0), 1e-12);
  EXPECT_GE(row.iso_mean, 0);
  EXPECT_LE(row.iso_mean, row.iso_max);
  EXPECT_LE(row.iso_max, 0.5);
  // The OpenCL columns are the caller's.
  EXPECT_EQ(row.storage, "n/a");
  EXPECT_FALSE(row.max_difference.has_value());
  EXPECT_TRUE(row.pictures.empty());
}

TEST(DemoTables, FieldTableSaysWhichFieldsCameFromTheCache) {
  demo::FieldRow built;
  built.rig = "arm";
  built.fields = 3;
  built.samples_min = 40;
  built.samples_max = 60;
  built.pictures = {"arm/fields/composed.png", "arm/fields/composed_bent.png"};
  demo::FieldRow cached = built;
  cached.rig = "CesiumMan";
  cached.cached = true;
  cached.storage = "image";
  cached.max_difference = 2e-6;
  const std::string uncached_table = demo::formatFieldTable({built});
  EXPECT_EQ(uncached_table.find("field cache"), std::string::npos);
  const std::string table = demo::formatFieldTable({built, cached});
  const auto rows = tableRows(table, "| rig | fields | samples per field |");
  ASSERT_EQ(rows.size(), 2u) << table;
  ASSERT_EQ(rows[0].size(), 10u) << table;
  EXPECT_EQ(rows[0][2], "40-60");
  EXPECT_EQ(rows[0][7], "n/a");
  EXPECT_EQ(rows[0][8], "-");
  EXPECT_EQ(rows[0][9],
            "arm/fields/composed.png, arm/fields/composed_bent.png");
  EXPECT_EQ(rows[1][8], "2.00e-06");
  EXPECT_NE(table.find("fit+bake column gives the load: CesiumMan\n"),
            std::string::npos)
      << table;
}

TEST(DemoTables, SummaryHoldsEveryTableAndTheSkippedRigs) {
  demo::Summary summary;
  summary.out_dir = "out";
  summary.operators_dir = "out/operators";
  summary.frame_note = "Frames per clip: a note.";
  summary.rows = {demo::makeRow("arm", clipOf("bend", 1), demo::kMethods[0],
                                "dev", madeUpResult())};
  summary.notes = {"CesiumMan skipped: no data"};
  demo::PictureRow picture;
  picture.rig = "arm";
  picture.pictures = {"arm/compare.png", "arm/closeup.png"};
  summary.picture_rows = {picture};
  summary.table_errors = "ERRORS TABLE\n";
  summary.bend_table = "BEND TABLE\n";
  summary.measure_radius = 1.5;

  const std::string printed = demo::formatStdoutSummary(summary);
  EXPECT_EQ(printed.rfind("Frames per clip: a note.\n\n| rig | clip |", 0), 0u)
      << printed;
  EXPECT_NE(printed.find("\nCesiumMan skipped: no data.\n"), std::string::npos);
  EXPECT_EQ(tableRows(printed, "| rig | frame |").size(), 1u) << printed;
  EXPECT_EQ(printed.substr(printed.size() - 11), "BEND TABLE\n");

  const std::string md = demo::formatSummaryMarkdown(summary);
  EXPECT_EQ(md.rfind("# isk-demo summary\n\nFrames: out/<rig>/<method>/", 0),
            0u);
  EXPECT_NE(md.find("LBS and DQS within 1e-04, implicit within 1e-02"),
            std::string::npos);
  EXPECT_NE(md.find("seen 35 degrees off the bend axis"), std::string::npos);
  EXPECT_NE(md.find("Pictures in out/operators (see"), std::string::npos);
  EXPECT_NE(md.find("within 1.5 model units of the elbow"), std::string::npos)
      << md;
  EXPECT_NE(md.find("\nCesiumMan skipped: no data.\n"), std::string::npos);
  EXPECT_EQ(tableRows(md, "| rig | clip | method |").size(), 1u);
  EXPECT_EQ(tableRows(md, "| rig | frame |").size(), 1u);
  EXPECT_EQ(md.substr(md.size() - 11), "BEND TABLE\n");
}

TEST(DemoTables, EachDisagreementHasItsMessage) {
  EXPECT_TRUE(demo::agreementFailures({}).empty());
  const std::vector<std::string> all =
      demo::agreementFailures({false, false, false});
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(all[0],
            "isk-demo: OpenCL and the CPU reference differ by more than "
            "0.0001 of the bounding-box diagonal");
  EXPECT_EQ(all[1],
            "isk-demo: implicit skinning on OpenCL and on the CPU reference "
            "differ by more than 0.01 of the bounding-box diagonal");
  EXPECT_EQ(all[2],
            "isk-demo: OpenCL and CPU reference field values differ by more "
            "than 0.0001 (buffer) or 0.0001 (image)");
  demo::Agreement fields_only;
  fields_only.fields = false;
  ASSERT_EQ(demo::agreementFailures(fields_only).size(), 1u);
}

// The builtin cylinder bent by 90 degrees at its middle joint, in 3 frames.
struct BentCylinder {
  Rig rig = makeBuiltinRig("cylinder");
  AnimationClip clip = makeBendClip(rig.skeleton, kPi / 2, 1.0);
  std::vector<double> times = samples::frameTimes(clip, 3);
};

TEST(DemoViews, MostBentFrameIsTheBendClipsLast) {
  const BentCylinder cylinder;
  const demo::BentFrame bent =
      demo::mostBentFrame(cylinder.rig.skeleton, cylinder.clip, cylinder.times);
  EXPECT_EQ(bent.frame, 2);
  ASSERT_GE(bent.joint, 0);
  EXPECT_GE(cylinder.rig.skeleton.joints[bent.joint].parent, 0);
  EXPECT_NEAR(bent.degrees, 90, 0.5);
  EXPECT_NEAR(bent.axis.norm(), 1, 1e-5);
  // The bend of a chain along +x turns about an axis across it.
  EXPECT_LT(std::abs(bent.axis.x()), 1e-3);
  EXPECT_TRUE(bent.child_position.has_value());

  // At the first frame alone nothing is bent yet.
  const demo::BentFrame rest = demo::mostBentFrame(
      cylinder.rig.skeleton, cylinder.clip, {cylinder.times.front()});
  EXPECT_EQ(rest.frame, 0);
  EXPECT_NEAR(rest.degrees, 0, 1e-3);
}

TEST(DemoViews, ViewsLookAlongTheBendAndCloseInOnTheFold) {
  const BentCylinder cylinder;
  const demo::BentFrame bent =
      demo::mostBentFrame(cylinder.rig.skeleton, cylinder.clip, cylinder.times);
  const TransformList skinning = samples::clipSkinning(
      cylinder.rig.skeleton, cylinder.clip, cylinder.times[bent.frame]);
  const Matrix3Xf posed = samples::dqsPositions(cylinder.rig, skinning);
  const Matrix3Xf positions[demo::kMethodCount] = {posed, posed, posed};
  const demo::ComparisonViews views =
      demo::comparisonViews(cylinder.rig, bent, positions);

  // Along the bend axis (either way), the fold in profile.
  EXPECT_NEAR(std::abs(views.whole.direction.normalized().dot(bent.axis)), 1,
              1e-4);
  EXPECT_LT(views.close.half_height, views.whole.half_height);
  EXPECT_LT((views.close.target - bent.joint_position).norm(),
            (views.whole.target - bent.joint_position).norm());
  // Turned towards the inside of the fold.
  EXPECT_NEAR(angleDegrees(views.close.direction, views.whole.direction),
              demo::kCloseUpTiltDegrees, 0.1);
  EXPECT_EQ(views.close_legend,
            "seen 35 deg off the bend axis, from inside the fold");
}

TEST(DemoViews, PictureRowCountsContactsAndTextsNameThem) {
  const BentCylinder cylinder;
  const demo::BentFrame bent =
      demo::mostBentFrame(cylinder.rig.skeleton, cylinder.clip, cylinder.times);
  const Matrix3Xf& rest = cylinder.rig.mesh.positions;
  const Matrix3Xf positions[demo::kMethodCount] = {rest, rest, rest};
  std::vector<TrackState> states(cylinder.rig.mesh.vertexCount(),
                                 TrackState::kConverged);
  states[3] = states[7] = TrackState::kContact;
  const std::vector<int> groups = coincidentVertexGroups(rest);
  const demo::PictureRow row = demo::describePictures(
      "cylinder", cylinder.rig, bent, 1.0, positions, states, groups);
  EXPECT_EQ(row.rig, "cylinder");
  EXPECT_EQ(row.frame, 2);
  EXPECT_EQ(row.joint, cylinder.rig.skeleton.joints[bent.joint].name);
  EXPECT_EQ(row.contacts, 2);
  for (int m = 0; m < demo::kMethodCount; ++m) {
    EXPECT_EQ(row.intersections[m], 0) << "the rest mesh, method " << m;
  }

  const std::vector<samples::Rgb> colours =
      demo::contactColours(cylinder.rig.mesh.vertexCount(), states);
  ASSERT_EQ(colours.size(), states.size());
  EXPECT_EQ(colours[3], demo::kContactColour);
  EXPECT_EQ(colours[7], demo::kContactColour);
  EXPECT_EQ(colours[0], samples::RenderStyle{}.front);

  const std::vector<std::string> captions = demo::methodCaptions(row);
  ASSERT_EQ(captions.size(), 3u);
  EXPECT_EQ(captions[0], "LBS\n0 self-intersections");
  EXPECT_EQ(captions[1], "DQS\n0 self-intersections");
  EXPECT_EQ(captions[2],
            "implicit\n0 self-intersections\n2 contact vertices (green)");
  EXPECT_EQ(
      demo::pictureTitle(row, bent, 3),
      "cylinder, frame 2 of 0-2 (t = 1.00 s): " + row.joint + " bent 90 deg");
}

}  // namespace
}  // namespace isk
