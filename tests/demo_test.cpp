// Runs the built isk-demo executable (ISK_DEMO_EXE), the project's main job,
// on a few frames and checks what it writes: exit code 0, summary.md (and
// stdout) with the skinning table and the implicit-fields table filled with
// numbers for both rigs, the field pictures of both poses as PNG files, and
// the composition operators' pictures and tables (out/operators/).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "operator_plots.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using test::RunOutput;
using test::ScopedTempDir;

namespace fs = std::filesystem;

// The rigs of the demo, in the order of its tables.
const std::vector<std::string> kRigs = {"arm", "cylinder"};

using test::number;
using test::tableRows;

TEST(DemoTest, WritesBothTablesAndTheFieldPictures) {
  ScopedTempDir dir;
  const std::string out = dir / "out";
  // 3 frames per clip: a middle frame, and a short run on PoCL.
  const std::vector<std::string> args = {"--out", out, "--frames", "3"};
  const RunOutput run = test::runProgram(ISK_DEMO_EXE, args);
  ASSERT_EQ(run.exit_code, 0) << test::describeRun("isk-demo", args, run);

  const std::string summary = test::readFile(out + "/summary.md");
  ASSERT_FALSE(summary.empty()) << "no " << out << "/summary.md";
  EXPECT_EQ(summary.rfind("# isk-demo summary", 0), 0u) << summary;
  EXPECT_NE(summary.find("Frames: "), std::string::npos) << summary;

  // The skinning table: every rig, method and device, 3 frames each.
  for (const std::string* text : {&summary, &run.output}) {
    const auto skin_rows = tableRows(*text, "| rig | method | device |");
    EXPECT_EQ(skin_rows.size(), 8u) << *text;  // 2 rigs x 2 methods x 2
    for (const auto& row : skin_rows) {
      ASSERT_EQ(row.size(), 8u) << *text;
      EXPECT_EQ(row[3], "3") << *text;
      EXPECT_GE(number(row[4]), 0.0) << row[4];         // ms/frame
      EXPECT_NEAR(number(row[5]), 1.0, 0.1) << row[5];  // volume ratio min
    }
  }

  // The fields table: one row per rig, every cell a number where one is
  // due, OpenCL in agreement with the reference.
  for (const std::string* text : {&summary, &run.output}) {
    const auto field_rows = tableRows(*text, "| rig | fields |");
    ASSERT_EQ(field_rows.size(), kRigs.size()) << *text;
    for (size_t r = 0; r < kRigs.size(); ++r) {
      const std::vector<std::string>& row = field_rows[r];
      ASSERT_EQ(row.size(), 10u) << *text;
      const std::string& rig = kRigs[r];
      EXPECT_EQ(row[0], rig);
      EXPECT_EQ(row[1], rig == "arm" ? "3" : "2") << rig;  // bones with parts
      const size_t dash = row[2].find('-');
      ASSERT_NE(dash, std::string::npos) << row[2];
      const double samples_min = number(row[2].substr(0, dash));
      const double samples_max = number(row[2].substr(dash + 1));
      EXPECT_GE(samples_min, 4) << row[2];
      EXPECT_LE(samples_min, samples_max) << row[2];
      EXPECT_GT(number(row[3]), 0.0) << row[3];  // fit+bake ms
      EXPECT_GT(number(row[4]), 0.0) << row[4];  // MiB
      const double iso_mean = number(row[5]), iso_max = number(row[6]);
      EXPECT_GE(iso_mean, 0.0) << row[5];
      EXPECT_LE(iso_mean, iso_max) << row[5] << " " << row[6];
      EXPECT_LE(iso_max, 0.5) << row[6];
      // The OpenCL tests never skip: there is a device (PoCL in CI).
      EXPECT_TRUE(row[7] == "buffer" || row[7] == "image") << row[7];
      EXPECT_LE(number(row[8]), row[7] == "image" ? 1e-2 : 1e-4) << row[8];
      EXPECT_EQ(row[9], rig + "/fields/composed.png, " + rig +
                            "/fields/composed_bent.png");
    }
  }

  // The pictures: PNG files whose longer side is 512 pixels; the bent arm
  // leaves the line of the bind pose, so its picture is taller.
  std::map<std::string, test::PngHeader> headers;
  for (const std::string& rig : kRigs) {
    for (const std::string file : {"composed.png", "composed_bent.png"}) {
      const std::string path = out + "/" + rig + "/fields/" + file;
      const test::PngHeader header = test::parsePngHeader(test::readFile(path));
      ASSERT_TRUE(header.valid) << path << " is missing or not a PNG";
      EXPECT_EQ(std::max(header.width, header.height), 512u) << path;
      headers[rig + "/" + file] = header;
    }
  }
  EXPECT_GT(headers["arm/composed_bent.png"].height,
            headers["arm/composed.png"].height);
  EXPECT_GT(headers["cylinder/composed_bent.png"].height,
            headers["cylinder/composed.png"].height);
  // The operators' pictures (isk-operator-plots at 256 pixels) and their
  // two tables: the table errors, and one row per operator and bend.
  for (const std::string* text : {&summary, &run.output}) {
    EXPECT_EQ(tableRows(*text, "| operator | theta = 0 |").size(), 3u) << *text;
    const auto bends = tableRows(*text, "| operator | elbow bend");
    EXPECT_EQ(bends.size(), 12u) << *text;  // 3 operators x 4 bends
    for (const auto& row : bends) {
      ASSERT_EQ(row.size(), 7u) << *text;
      EXPECT_GT(number(row[2]), 0.0) << row[2];  // inside pixels
      EXPECT_GE(number(row[5]), 0.0) << row[5];  // max abs(f - union)
    }
  }
  EXPECT_NE(summary.find("## Composition operators"), std::string::npos);
  const int operator_size = 256;
  samples::PanelLayout panels;
  panels.panel = operator_size;
  panels.columns = 5;
  samples::PanelLayout grid;
  grid.panel = operator_size;
  grid.columns = 4;
  grid.rows = 3;
  std::map<std::string, std::pair<int, int>> operator_pictures = {
      {"bend_grid.png", {grid.width(), grid.height()}}};
  for (const std::string op : {"union", "blend", "bulge"}) {
    operator_pictures["operator_" + op + ".png"] = {panels.width(),
                                                    panels.height()};
    for (const std::string deg : {"000", "045", "090", "135"}) {
      operator_pictures["bend_" + op + "_" + deg + ".png"] = {operator_size,
                                                              operator_size};
    }
  }
  for (const auto& [file, size] : operator_pictures) {
    const std::string path = out + "/operators/" + file;
    const test::PngHeader header = test::parsePngHeader(test::readFile(path));
    ASSERT_TRUE(header.valid) << path << " is missing or not a PNG";
    EXPECT_EQ(header.width, static_cast<uint32_t>(size.first)) << path;
    EXPECT_EQ(header.height, static_cast<uint32_t>(size.second)) << path;
  }

  // No temporary file is left behind.
  for (const auto& entry : fs::recursive_directory_iterator(out)) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos)
        << entry.path();
  }
}

}  // namespace
}  // namespace isk
