// Runs the built isk-demo executable (ISK_DEMO_EXE), the project's main job,
// on a few frames and checks what it writes: exit code 0, summary.md (and
// stdout) with the skinning table (LBS, DQS and implicit per rig, filled
// with numbers), the pictures table and the implicit-fields table, the
// frames of every method, the side-by-side pictures of the three methods at
// each rig's most bent frame (three panels, the implicit panel different
// from the DQS panel at the fold, contact vertices tinted), the field
// pictures of both poses, and the composition operators' pictures and
// tables (out/operators/). Without the data folder it still succeeds on the
// embedded rigs and says that CesiumMan was skipped.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "data_folder.hpp"
#include "mesh_render.hpp"
#include "operator_plots.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using test::RunOutput;
using test::ScopedTempDir;

namespace fs = std::filesystem;

using test::number;
using test::tableRows;

// The embedded rigs of the demo, in the order of its tables, and the one
// from the data folder.
const std::vector<std::string> kEmbeddedRigs = {"arm", "cylinder",
                                                "cylinder-135"};
const std::string kAssetRig = "CesiumMan";
const std::vector<std::string> kMethods = {"lbs", "dqs", "implicit"};
// Side of each square panel of compare.png and closeup.png.
constexpr int kPanelSize = 400;
// Frames per clip of the runs below: the last of 3 is the procedural
// clips' most bent frame.
const std::string kFrames = "3";

// The demo with the data folder (the default, or $ISK_DATA_DIR), run once
// for the tests that read its output.
class DemoRun : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScopedTempDir;
    out_ = *dir_ / "out";
    args_ = {"--out", out_, "--frames", kFrames};
    run_ = test::runProgram(ISK_DEMO_EXE, args_);
    summary_ = test::readFile(out_ + "/summary.md");
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }

  // The rigs this run covers: CesiumMan when the data folder is there.
  static std::vector<std::string> rigs() {
    std::vector<std::string> rigs = kEmbeddedRigs;
    if (test::haveAssets()) rigs.push_back(kAssetRig);
    return rigs;
  }

  static ScopedTempDir* dir_;
  static std::string out_;
  static std::vector<std::string> args_;
  static RunOutput run_;
  static std::string summary_;
};

ScopedTempDir* DemoRun::dir_ = nullptr;
std::string DemoRun::out_;
std::vector<std::string> DemoRun::args_;
RunOutput DemoRun::run_;
std::string DemoRun::summary_;

// The skinning table of `text`: one row per rig and method, in order, every
// cell a number where one is due.
void expectSkinningTable(const std::string& text,
                         const std::vector<std::string>& rigs) {
  const auto rows = tableRows(text, "| rig | clip | method | device |");
  ASSERT_EQ(rows.size(), rigs.size() * kMethods.size()) << text;
  for (size_t r = 0; r < rows.size(); ++r) {
    const std::vector<std::string>& row = rows[r];
    ASSERT_EQ(row.size(), 13u) << text;
    const std::string& rig = rigs[r / kMethods.size()];
    const std::string& method = kMethods[r % kMethods.size()];
    const std::string where = rig + " " + method;
    EXPECT_EQ(row[0], rig);
    EXPECT_EQ(row[2], method) << where;
    // The OpenCL tests never skip: there is a device (PoCL in CI).
    EXPECT_NE(row[3].find("/"), std::string::npos) << where << ": " << row[3];
    EXPECT_EQ(row[4], kFrames) << where;
    EXPECT_GE(number(row[5]), 0.0) << where << ": " << row[5];  // ms/frame
    const double volume_min = number(row[6]), volume_max = number(row[7]);
    EXPECT_NEAR(volume_min, 1.0, 0.1) << where << ": " << row[6];
    EXPECT_LE(volume_min, volume_max) << where;
    EXPECT_NEAR(volume_max, 1.0, 0.1) << where << ": " << row[7];
    const double intersections_max = number(row[8]);
    const double intersections_total = number(row[9]);
    EXPECT_GE(intersections_max, 0.0) << where << ": " << row[8];
    EXPECT_GE(intersections_total, intersections_max) << where;
    if (method == "implicit") {
      EXPECT_GE(number(row[10]), 0.0) << where << ": " << row[10];
    } else {
      EXPECT_EQ(row[10], "-") << where;  // contacts: implicit only
    }
    EXPECT_GE(number(row[11]), 0.0) << where << ": " << row[11];
    EXPECT_LE(number(row[12]), method == "implicit" ? 1e-2 : 1e-4)
        << where << ": " << row[12];
  }
}

TEST_F(DemoRun, WritesTheTablesFramesAndFieldPictures) {
  ASSERT_EQ(run_.exit_code, 0) << test::describeRun("isk-demo", args_, run_);
  ASSERT_FALSE(summary_.empty()) << "no " << out_ << "/summary.md";
  EXPECT_EQ(summary_.rfind("# isk-demo summary", 0), 0u) << summary_;
  EXPECT_NE(summary_.find("Frames: "), std::string::npos) << summary_;
  const std::vector<std::string> rigs = DemoRun::rigs();

  // The skinning table, in the summary and on stdout.
  for (const std::string* text : {&summary_, &run_.output}) {
    expectSkinningTable(*text, rigs);
  }
  if (test::haveAssets()) {
    EXPECT_EQ(run_.output.find("skipped"), std::string::npos) << run_.output;
  } else {
    EXPECT_NE(run_.output.find("CesiumMan skipped"), std::string::npos)
        << run_.output;
  }

  // Every method's frames, implicit included.
  for (const std::string& rig : rigs) {
    for (const std::string& method : kMethods) {
      for (const std::string frame :
           {"frame_0000.obj", "frame_0001.obj", "frame_0002.obj"}) {
        const std::string path = out_ + "/" + rig + "/" + method + "/" + frame;
        EXPECT_TRUE(fs::is_regular_file(path)) << path;
      }
      EXPECT_FALSE(
          fs::exists(out_ + "/" + rig + "/" + method + "/frame_0003.obj"));
    }
  }

  // The fields table: one row per rig with its own fields (cylinder-135
  // shares the cylinder's), every cell a number where one is due, OpenCL in
  // agreement with the reference.
  std::vector<std::string> field_rigs = {"arm", "cylinder"};
  if (test::haveAssets()) field_rigs.push_back(kAssetRig);
  for (const std::string* text : {&summary_, &run_.output}) {
    const auto field_rows = tableRows(*text, "| rig | fields |");
    ASSERT_EQ(field_rows.size(), field_rigs.size()) << *text;
    for (size_t r = 0; r < field_rigs.size(); ++r) {
      const std::vector<std::string>& row = field_rows[r];
      ASSERT_EQ(row.size(), 10u) << *text;
      const std::string& rig = field_rigs[r];
      EXPECT_EQ(row[0], rig);
      if (rig == kAssetRig) {
        EXPECT_GT(number(row[1]), 2.0) << rig;  // one per bone with skin
      } else {
        EXPECT_EQ(row[1], rig == "arm" ? "3" : "2") << rig;
      }
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
      EXPECT_TRUE(row[7] == "buffer" || row[7] == "image") << row[7];
      EXPECT_LE(number(row[8]), row[7] == "image" ? 1e-2 : 1e-4) << row[8];
      EXPECT_EQ(row[9], rig + "/fields/composed.png, " + rig +
                            "/fields/composed_bent.png");
    }
  }

  // The field pictures: PNG files whose longer side is 512 pixels; the
  // bent procedural rigs leave the line of the bind pose, so their picture
  // is taller.
  std::map<std::string, test::PngHeader> headers;
  for (const std::string& rig : field_rigs) {
    for (const std::string file : {"composed.png", "composed_bent.png"}) {
      const std::string path = out_ + "/" + rig + "/fields/" + file;
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
  EXPECT_FALSE(fs::exists(out_ + "/cylinder-135/fields"));

  // The operators' pictures (isk-operator-plots at 256 pixels) and their
  // two tables: the table errors, and one row per operator and bend.
  for (const std::string* text : {&summary_, &run_.output}) {
    EXPECT_EQ(tableRows(*text, "| operator | theta = 0 |").size(), 3u) << *text;
    const auto bends = tableRows(*text, "| operator | elbow bend");
    EXPECT_EQ(bends.size(), 12u) << *text;  // 3 operators x 4 bends
    for (const auto& row : bends) {
      ASSERT_EQ(row.size(), 7u) << *text;
      EXPECT_GT(number(row[2]), 0.0) << row[2];  // inside pixels
      EXPECT_GE(number(row[5]), 0.0) << row[5];  // max abs(f - union)
    }
  }
  EXPECT_NE(summary_.find("## Composition operators"), std::string::npos);
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
    const std::string path = out_ + "/operators/" + file;
    const test::PngHeader header = test::parsePngHeader(test::readFile(path));
    ASSERT_TRUE(header.valid) << path << " is missing or not a PNG";
    EXPECT_EQ(header.width, static_cast<uint32_t>(size.first)) << path;
    EXPECT_EQ(header.height, static_cast<uint32_t>(size.second)) << path;
  }

  // No temporary file is left behind.
  for (const auto& entry : fs::recursive_directory_iterator(out_)) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos)
        << entry.path();
  }
}

// A decoded RGB picture (empty when it cannot be decoded).
// A decoded picture with its pixels as samples::Rgb.
struct Picture : test::DecodedPng {
  samples::Rgb at(int x, int y) const {
    const uint8_t* p = DecodedPng::at(x, y);
    return {p[0], p[1], p[2]};
  }
};

Picture decodePng(const std::string& path) {
  return Picture{test::decodePngFile(path)};
}

// Pixel (x, y) of panel p (0: LBS, 1: DQS, 2: implicit), the panels' square
// areas lying at the bottom of the picture, kPanelGap apart.
samples::Rgb panelPixel(const Picture& picture, int p, int x, int y) {
  return picture.at(p * (kPanelSize + samples::kPanelGap) + x,
                    picture.height - kPanelSize + y);
}

bool isBackground(const samples::Rgb& c) {
  return c == samples::RenderStyle{}.background;
}
// The contact tint: green well above red and blue (the skin is grey, the
// inside-out skin red).
bool isContactGreen(const samples::Rgb& c) {
  return c[1] >= 90 && c[1] - c[0] >= 50 && c[1] - c[2] >= 50;
}

// Any green cast: the tint blended into grey across a triangle.
bool isTinted(const samples::Rgb& c) {
  return c[1] - c[0] > 8 && c[1] - c[2] > 8;
}

struct PanelCounts {
  long mesh = 0;       // pixels the mesh covers
  long green = 0;      // contact tint
  long differing = 0;  // in the window, against the other panel
  long window = 0;     // pixels of the window
};

// Counts over panel p; `differing` compares it with panel q in the window
// [lo, hi) x [lo, hi) of panel pixels: a pixel differs when a channel is off
// by more than 24 and it has no green cast (a different shape, not only
// the tint).
PanelCounts countPanel(const Picture& picture, int p, int q, int lo, int hi) {
  PanelCounts counts;
  for (int y = 0; y < kPanelSize; ++y) {
    for (int x = 0; x < kPanelSize; ++x) {
      const samples::Rgb c = panelPixel(picture, p, x, y);
      counts.mesh += !isBackground(c);
      counts.green += isContactGreen(c);
      if (x < lo || x >= hi || y < lo || y >= hi) continue;
      ++counts.window;
      if (isTinted(c)) continue;
      const samples::Rgb d = panelPixel(picture, q, x, y);
      for (int k = 0; k < 3; ++k) {
        if (std::abs(int(c[k]) - int(d[k])) > 24) {
          ++counts.differing;
          break;
        }
      }
    }
  }
  return counts;
}

// out/<rig>/animation.glb: the three methods side by side, one morph target
// per frame, one weights channel per mesh (the writer's own checks are in
// gltf_export_test.cpp).
TEST_F(DemoRun, WritesAnAnimatedGltfPerRig) {
  ASSERT_EQ(run_.exit_code, 0) << test::describeRun("isk-demo", args_, run_);
  for (const std::string& rig : DemoRun::rigs()) {
    const std::string path = out_ + "/" + rig + "/animation.glb";
    const std::string bytes = test::readFile(path);
    ASSERT_GT(bytes.size(), 20u) << path;
    EXPECT_EQ(bytes.substr(0, 4), "glTF") << path;
    uint32_t json_length = 0;
    for (int i = 3; i >= 0; --i)
      json_length =
          (json_length << 8) | static_cast<unsigned char>(bytes[12 + i]);
    ASSERT_LE(20u + json_length, bytes.size()) << path;
    const nlohmann::json doc =
        nlohmann::json::parse(bytes.substr(20, json_length));
    ASSERT_EQ(doc["meshes"].size(), kMethods.size()) << path;
    for (size_t m = 0; m < kMethods.size(); ++m) {
      EXPECT_EQ(doc["meshes"][m]["name"], kMethods[m]) << path;
      EXPECT_EQ(doc["meshes"][m]["primitives"][0]["targets"].size(),
                static_cast<size_t>(std::stoi(kFrames)))
          << path;
    }
    EXPECT_EQ(doc["animations"][0]["channels"].size(), kMethods.size()) << path;
    // Side by side: distinct x offsets.
    EXPECT_LT(doc["nodes"][0]["translation"][0].get<double>(),
              doc["nodes"][2]["translation"][0].get<double>())
        << path;
  }
  EXPECT_NE(run_.output.find("animation.glb"), std::string::npos);
}

TEST_F(DemoRun, ComparePicturesShowTheFoldAndTheContact) {
  ASSERT_EQ(run_.exit_code, 0) << test::describeRun("isk-demo", args_, run_);
  const std::vector<std::string> rigs = DemoRun::rigs();

  // The pictures table: one row per rig, at the most bent frame (the last
  // for the procedural bends: elbow and bone1 at their full angle).
  for (const std::string* text : {&summary_, &run_.output}) {
    const auto rows = tableRows(*text, "| rig | frame | time (s) |");
    ASSERT_EQ(rows.size(), rigs.size()) << *text;
    for (size_t r = 0; r < rigs.size(); ++r) {
      const std::vector<std::string>& row = rows[r];
      ASSERT_EQ(row.size(), 10u) << *text;
      const std::string& rig = rigs[r];
      EXPECT_EQ(row[0], rig);
      const std::map<std::string, std::pair<std::string, double>> bends = {
          {"arm", {"elbow", 90}},
          {"cylinder", {"bone1", 90}},
          {"cylinder-135", {"bone1", 135}}};
      if (const auto bend = bends.find(rig); bend != bends.end()) {
        EXPECT_EQ(row[1], "2") << rig;
        EXPECT_NEAR(number(row[2]), 1.0, 1e-9) << rig;
        EXPECT_EQ(row[3], bend->second.first) << rig;
        EXPECT_NEAR(number(row[4]), bend->second.second, 0.5) << rig;
      } else {
        EXPECT_GE(number(row[1]), 0.0) << rig;
        EXPECT_GT(number(row[4]), 10.0) << rig << ": a walk bends its knees";
      }
      for (int c = 5; c <= 8; ++c) EXPECT_GE(number(row[c]), 0.0) << row[c];
      EXPECT_EQ(row[9], rig + "/compare.png, " + rig + "/closeup.png");
    }
  }
  const auto rows = tableRows(summary_, "| rig | frame | time (s) |");
  ASSERT_EQ(rows.size(), rigs.size());

  for (size_t r = 0; r < rigs.size(); ++r) {
    const std::string& rig = rigs[r];
    const double contacts = number(rows[r][8]);
    // Bent to 135 degrees the cylinder's halves press against each other:
    // implicit skinning stops vertices there.
    if (rig == "cylinder-135") {
      EXPECT_GT(contacts, 0.0) << rig;
    }
    for (const std::string file : {"compare.png", "closeup.png"}) {
      const std::string path = out_ + "/" + rig + "/" + file;
      const Picture picture = decodePng(path);
      ASSERT_GT(picture.width, 0) << path;
      // Three square panels side by side under the title and captions.
      ASSERT_EQ(picture.width, 3 * kPanelSize + 2 * samples::kPanelGap) << path;
      ASSERT_GT(picture.height, kPanelSize + 48) << path;

      // The close-up is centred on the fold (between the most bent joint
      // and the crease of its inner side): in its middle half the implicit
      // skin must have another shape than DQS's in more than 1% of the
      // pixels (4-18% in practice); over the whole picture, where the fold
      // is a small part, in more than 0.5%.
      const bool close_up = file == std::string("closeup.png");
      const int lo = close_up ? kPanelSize / 4 : 0;
      const int hi = close_up ? 3 * kPanelSize / 4 : kPanelSize;
      PanelCounts counts[3];
      for (int p = 0; p < 3; ++p) counts[p] = countPanel(picture, p, 1, lo, hi);
      const long panel = long(kPanelSize) * kPanelSize;
      for (int p = 0; p < 3; ++p) {
        EXPECT_GT(counts[p].mesh, panel / 20)
            << path << " panel " << p << " shows almost no mesh";
        EXPECT_LT(counts[p].mesh, panel) << path << " panel " << p;
      }
      EXPECT_GT(counts[2].differing, counts[2].window / (close_up ? 100 : 200))
          << path << ": the implicit panel differs from the DQS panel in "
          << counts[2].differing << " of " << counts[2].window
          << " pixels compared";
      EXPECT_GT(counts[0].differing, 0)
          << path << ": LBS and DQS look the same";
      // The contact vertices are tinted in the implicit panel only.
      EXPECT_EQ(counts[0].green, 0) << path;
      EXPECT_EQ(counts[1].green, 0) << path;
      if (contacts > 0 && close_up) {
        EXPECT_GT(counts[2].green, 20)
            << path << ": " << contacts << " contact vertices, no green";
      }
    }
  }
}

TEST(DemoTest, WithoutTheDataFolderSkipsCesiumMan) {
  ScopedTempDir dir;
  const std::string out = dir / "out";
  const std::string missing = dir / "no-data-folder";
  const std::string environment =
      "ISK_DATA_DIR=" + test::shellQuote(missing) + " ";
  const std::vector<std::string> args = {"--out", out, "--frames", kFrames};
  const RunOutput run = test::runProgram(ISK_DEMO_EXE, args, environment);
  ASSERT_EQ(run.exit_code, 0) << test::describeRun("isk-demo", args, run);

  // Said on the command line and in the summary, with the folder and why.
  const std::string summary = test::readFile(out + "/summary.md");
  for (const std::string* text : {&summary, &run.output}) {
    EXPECT_NE(text->find("CesiumMan skipped: the data folder " + missing +
                         " does not exist"),
              std::string::npos)
        << *text;
    EXPECT_NE(text->find("ISK_DATA_DIR"), std::string::npos) << *text;
    // The embedded rigs still have every method.
    expectSkinningTable(*text, kEmbeddedRigs);
    EXPECT_EQ(tableRows(*text, "| rig | frame | time (s) |").size(),
              kEmbeddedRigs.size())
        << *text;
  }
  EXPECT_FALSE(fs::exists(out + "/" + kAssetRig));
  for (const std::string& rig : kEmbeddedRigs) {
    const test::PngHeader header =
        test::parsePngHeader(test::readFile(out + "/" + rig + "/compare.png"));
    EXPECT_TRUE(header.valid) << rig << "/compare.png";
  }
}

}  // namespace
}  // namespace isk
