// isk-skin's report and summary lines (samples/common/skin_report.hpp),
// assembled from results made up here, without a device: the report's
// fields for each method and quality measure, the implicit fields' section
// with and without a measured drift, and the stderr lines word for word
// (the parts by new pairs beyond DQS's among them).
#include "skin_report.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using samples::RunResult;
using samples::skin::IsoDrift;
using samples::skin::Options;

// A 3-frame run with made-up measures.
RunResult madeUpResult() {
  RunResult result;
  result.frames = 3;
  result.frame = {1.23456, 2.0, 0.5};
  result.stage_median = {{"upload", 0.25}, {"skinning", 0.75}};
  result.self_intersections = {4, 0, 2};
  result.rest_volume = 25.5;
  result.volume_ratio_min = 0.98765;
  result.volume_ratio_max = 1.0;
  result.rest_pose_error = 0;
  result.files = {"o/frame_0000.obj", "o/frame_0001.obj", "o/frame_0002.obj"};
  return result;
}

Options madeUpOptions(const std::string& method) {
  Options options;
  options.input = "builtin:cylinder";
  options.method = method;
  options.out_dir = "o";
  return options;
}

TEST(IskSkinReport, ReportHoldsTheRunAndItsQuality) {
  const Rig rig = makeBuiltinRig("cylinder");
  const nlohmann::json report = samples::skin::makeReport(
      madeUpOptions("dqs"), rig, "bend", {}, {10, 5}, madeUpResult(), nullptr);
  EXPECT_EQ(report["input"], "builtin:cylinder");
  EXPECT_EQ(report["vertices"], rig.mesh.vertexCount());
  EXPECT_EQ(report["triangles"], rig.mesh.triangleCount());
  EXPECT_EQ(report["joints"], rig.skeleton.jointCount());
  EXPECT_EQ(report["frames"], 3);
  EXPECT_EQ(report["method"], "dqs");
  EXPECT_EQ(report["clip"], "bend");
  EXPECT_EQ(report["device"], "reference");
  EXPECT_EQ(report["precompute_ms"], 15.0);
  EXPECT_EQ(report["precompute_breakdown_ms"]["load"], 10.0);
  EXPECT_EQ(report["precompute_breakdown_ms"]["build_upload"], 5.0);
  EXPECT_EQ(report["frame_ms"]["median"], 1.23456);
  EXPECT_EQ(report["frame_ms"]["p95"], 2.0);
  EXPECT_EQ(report["frame_ms"]["min"], 0.5);
  EXPECT_EQ(report["stage_ms"]["skinning"], 0.75);
  EXPECT_EQ(report["quality"]["volume_ratio"]["min"], 0.98765);
  EXPECT_EQ(report["quality"]["volume_ratio"]["max"], 1.0);
  EXPECT_FALSE(report["quality"].contains("volume_note"));
  EXPECT_EQ(report["quality"]["rest_volume"], 25.5);
  EXPECT_EQ(report["quality"]["self_intersections"]["max"], 4);
  EXPECT_EQ(report["quality"]["self_intersections"]["total"], 6);
  EXPECT_FALSE(report["quality"].contains("contact_vertices"));
  EXPECT_EQ(report["out"], "o");
  EXPECT_EQ(report["format"], "obj");
  EXPECT_FALSE(report.contains("implicit"));
}

TEST(IskSkinReport, NoVolumeRatioNoOutNoSelfIntersections) {
  const Rig rig = makeBuiltinRig("cylinder");
  Options options = madeUpOptions("lbs");
  options.out_dir.clear();
  RunResult result = madeUpResult();
  result.volume_ratio_min.reset();
  result.volume_ratio_max.reset();
  result.self_intersections.clear();
  const nlohmann::json report =
      samples::skin::makeReport(options, rig, "bend", {}, {}, result, nullptr);
  EXPECT_TRUE(report["quality"]["volume_ratio"].is_null());
  EXPECT_NE(report["quality"]["volume_note"].get<std::string>().find(
                "encloses about no volume"),
            std::string::npos);
  EXPECT_FALSE(report["quality"].contains("self_intersections"));
  EXPECT_TRUE(report["out"].is_null());
}

TEST(IskSkinReport, ImplicitMethodAddsContactsAndTracking) {
  const Rig rig = makeBuiltinRig("cylinder");
  Options options = madeUpOptions("implicit");
  options.tracking.rounds = 7;
  RunResult result = madeUpResult();
  result.contact_vertices = {10, 30, 20, 40};
  const nlohmann::json section = {{"fields", 2}};
  const nlohmann::json report =
      samples::skin::makeReport(options, rig, "bend", {}, {}, result, &section);
  EXPECT_EQ(report["quality"]["contact_vertices"], 25.0);
  EXPECT_EQ(report["implicit"]["fields"], 2);
  EXPECT_EQ(report["implicit"]["tracking"]["rounds"], 7);
  EXPECT_EQ(report["implicit"]["tracking"]["base_skinning"], "dqs");
  EXPECT_EQ(report["implicit"]["tracking"]["sigma"], options.tracking.sigma);
  // Without a tracking mesh there is nothing to describe.
  EXPECT_FALSE(report["implicit"].contains("relaxation_weights"));
}

// Per frame and summarized: how many vertices changed tracking state since
// the frame before (none before the first).
TEST(IskSkinReport, ImplicitMethodReportsStateChanges) {
  const Rig rig = makeBuiltinRig("cylinder");
  Options options = madeUpOptions("implicit");
  RunResult result = madeUpResult();
  result.quality.resize(3);
  result.state_changes = {std::nullopt, 4, 8};
  const nlohmann::json report =
      samples::skin::makeReport(options, rig, "bend", {}, {}, result, nullptr);
  const nlohmann::json& quality = report["quality"];
  ASSERT_EQ(quality["frames"].size(), 3u) << quality;
  EXPECT_TRUE(quality["frames"][0]["state_changes"].is_null());
  EXPECT_EQ(quality["frames"][1]["state_changes"], 4);
  EXPECT_EQ(quality["frames"][2]["state_changes"], 8);
  EXPECT_EQ(quality["state_changes"]["mean"], 6.0);
  EXPECT_EQ(quality["state_changes"]["max"], 8);
  EXPECT_NE(quality["measures"].get<std::string>().find("state_changes"),
            std::string::npos);
  EXPECT_NE(samples::skin::formatRunSummary(options, "bend", "reference (CPU)",
                                            result)
                .find("; tracking state changes per frame mean 6, max 8"),
            std::string::npos);

  // One frame: nothing to compare, so no summary.
  result.quality.resize(1);
  result.state_changes = {std::nullopt};
  const nlohmann::json one =
      samples::skin::makeReport(options, rig, "bend", {}, {}, result, nullptr);
  EXPECT_TRUE(one["quality"]["state_changes"].is_null());
  EXPECT_EQ(samples::skin::formatRunSummary(options, "bend", "reference (CPU)",
                                            result)
                .find("state changes"),
            std::string::npos);

  // Skinning alone has no tracking states.
  result.state_changes.clear();
  const nlohmann::json dqs = samples::skin::makeReport(
      madeUpOptions("dqs"), rig, "bend", {}, {}, result, nullptr);
  EXPECT_FALSE(dqs["quality"].contains("state_changes"));
  EXPECT_FALSE(dqs["quality"]["frames"][0].contains("state_changes"));
}

TEST(IskSkinReport, ImplicitFieldsSectionWithAndWithoutDrift) {
  const Rig& rig = test::rigNamed("arm");
  const ImplicitFields& fields = test::implicitFieldsOf("arm");
  IsoDrift drift;
  drift.build_ms = 12;
  drift.tracked_vertices = 100;
  const nlohmann::json unmeasured =
      samples::skin::implicitFieldsSection(fields, rig.skeleton, drift);
  EXPECT_EQ(unmeasured["fields"], fields.grids.fieldCount());
  EXPECT_EQ(unmeasured["composition"],
            describeComposition(fields.composition, rig.skeleton));
  EXPECT_EQ(unmeasured["grid_precision"], "float");
  EXPECT_EQ(unmeasured["evaluation"], "reference");
  EXPECT_EQ(unmeasured["build_ms"], 12.0);
  EXPECT_EQ(unmeasured["tracked_vertices"], 100);
  EXPECT_TRUE(unmeasured["iso_drift"].is_null());
  EXPECT_TRUE(unmeasured["field_ms"].is_null());
  EXPECT_EQ(unmeasured["drift_note"],
            "no vertex lies inside a field's support: nothing to measure");
  EXPECT_TRUE(unmeasured["operators"].is_object());

  drift.evaluation = "opencl (buffer)";
  drift.mean = 0.01;
  drift.max = 0.2;
  drift.field_ms = 3;
  const nlohmann::json measured =
      samples::skin::implicitFieldsSection(fields, rig.skeleton, drift);
  EXPECT_EQ(measured["evaluation"], "opencl (buffer)");
  EXPECT_EQ(measured["iso_drift"]["mean"], 0.01);
  EXPECT_EQ(measured["iso_drift"]["max"], 0.2);
  EXPECT_EQ(measured["field_ms"], 3.0);
  EXPECT_FALSE(measured.contains("drift_note"));
}

TEST(IskSkinReport, SummaryLineWordForWord) {
  EXPECT_EQ(samples::skin::formatRunSummary(madeUpOptions("dqs"), "bend",
                                            "reference (CPU)", madeUpResult()),
            "isk-skin: 3 frames of clip 'bend' (dqs on reference (CPU)): "
            "median 1.235 ms/frame, p95 2 ms; volume ratio 0.9877 to 1; "
            "rest-pose error 0; new self-intersecting pairs max 4 (0 at rest); "
            "wrote 3 files to o\n");

  Options options = madeUpOptions("implicit");
  options.out_dir.clear();
  RunResult result = madeUpResult();
  result.frames = 1;
  result.volume_ratio_min.reset();
  result.self_intersections.clear();
  result.contact_vertices = {7};
  EXPECT_EQ(
      samples::skin::formatRunSummary(options, "walk", "PoCL / cpu", result),
      "isk-skin: 1 frame of clip 'walk' (implicit on PoCL / cpu): "
      "median 1.235 ms/frame, p95 2 ms; volume ratio n/a; rest-pose "
      "error 0; contact vertices median 7\n");
}

TEST(IskSkinReport, IsoDriftLineWordForWord) {
  IsoDrift drift;
  EXPECT_EQ(samples::skin::formatIsoDriftSummary("union everywhere", drift),
            "isk-skin: implicit fields (union everywhere): no iso drift to "
            "measure\n");
  drift.mean = 0.0123456;
  drift.max = 0.5;
  drift.field_ms = 1.5;
  EXPECT_EQ(samples::skin::formatIsoDriftSummary("blend at elbow", drift),
            "isk-skin: implicit fields (blend at elbow): iso drift mean "
            "0.01235, max 0.5; field evaluation 1.5 ms/frame\n");
}

TEST(IskSkinReport, PartsByExcessPairsLineWordForWord) {
  // Two frames of a 3-joint cylinder: part 1 has more new pairs than DQS,
  // part 2 more still, part 0 fewer.
  const Rig rig = makeCylinderRig();
  RunResult result = madeUpResult();
  for (int frame = 0; frame < 2; ++frame) {
    FrameQuality q;
    for (int part = 0; part < 3; ++part) {
      PartQuality p;
      p.part = part;
      p.edges = 10;
      p.new_pairs = part == 0 ? 1 : part == 1 ? 3 : 5;
      p.dqs_new_pairs = part == 0 ? 4 : 2;
      q.parts.push_back(p);
    }
    result.quality.push_back(q);
  }
  const std::vector<std::string> names = {rig.skeleton.joints[0].name,
                                          rig.skeleton.joints[1].name,
                                          rig.skeleton.joints[2].name};
  EXPECT_EQ(samples::skin::formatPairPartsSummary(result, rig.skeleton),
            "isk-skin: parts whose new intersecting pairs exceed DQS's most: " +
                names[2] + " 10 (DQS 4); " + names[1] +
                " 6 (DQS 4) (summed over the frames; --untracked-joint keeps "
                "a part on skinning)\n");
  EXPECT_EQ(samples::skin::formatPairPartsSummary(result, rig.skeleton, 1),
            "isk-skin: parts whose new intersecting pairs exceed DQS's most: " +
                names[2] +
                " 10 (DQS 4) (summed over the frames; --untracked-joint keeps "
                "a part on skinning)\n");
  // No part beyond DQS's, or no frame measured: no line.
  for (FrameQuality& q : result.quality)
    for (PartQuality& p : q.parts) p.dqs_new_pairs = p.new_pairs;
  EXPECT_EQ(samples::skin::formatPairPartsSummary(result, rig.skeleton), "");
  result.quality.clear();
  EXPECT_EQ(samples::skin::formatPairPartsSummary(result, rig.skeleton), "");
}

}  // namespace
}  // namespace isk
