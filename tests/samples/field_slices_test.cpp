// Runs the built isk-field-slices executable (ISK_FIELD_SLICES_EXE) and
// checks its contract: exit codes, one PNG for the composed field and one per
// bone field at the requested size, pictures that show inside (red), outside
// (blue), the 0.5 iso line (black) and the mesh section (green), index.md,
// and clear errors for bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "data_folder.hpp"
#include "isk/fields/bone_partition.hpp"
#include "isk/rig/rig.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using test::ScopedTempDir;

namespace fs = std::filesystem;

using test::parsePngHeader;
using test::PngHeader;
using test::readFile;
using test::RunOutput;

RunOutput runSlices(const std::vector<std::string>& args) {
  return test::runProgram(ISK_FIELD_SLICES_EXE, args);
}

std::string describe(const std::vector<std::string>& args,
                     const RunOutput& run) {
  return test::describeRun("isk-field-slices", args, run);
}

// Pixels of each kind the picture's palette draws.
struct PixelCounts {
  int width = 0, height = 0;
  long total = 0;
  long red = 0;    // inside, f > 0.5
  long blue = 0;   // outside, 0 < f < 0.5
  long white = 0;  // f = 0 (outside every support)
  long iso = 0;    // the black 0.5 iso line
  long mesh = 0;   // the green mesh section
  long joint = 0;  // yellow joint dots
  double redFraction() const { return total ? double(red) / total : 0; }
};

PixelCounts countPixels(const std::string& path) {
  const test::DecodedPng png = test::decodePngFile(path);
  PixelCounts counts;
  if (!png.valid()) return counts;
  counts.width = png.width;
  counts.height = png.height;
  const uint8_t* pixels = png.rgb.data();
  counts.total = long(counts.width) * counts.height;
  for (long i = 0; i < counts.total; ++i) {
    const int r = pixels[3 * i], g = pixels[3 * i + 1], b = pixels[3 * i + 2];
    if (r >= 120 && r - g >= 60 && r - b >= 60) {
      ++counts.red;
    } else if (b >= 100 && b - r >= 30 && b - g >= 25) {
      ++counts.blue;
    } else if (r == 255 && g == 255 && b == 255) {
      ++counts.white;
    } else if (r <= 30 && g <= 30 && b <= 30) {
      ++counts.iso;
    } else if (g >= 150 && r <= 80 && b <= 80) {
      ++counts.mesh;
    } else if (r >= 200 && g >= 180 && b <= 60) {
      ++counts.joint;
    }
  }
  return counts;
}

// The PNG files of a folder, sorted.
std::vector<std::string> pngFiles(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() == ".png") names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  return names;
}

// No temporary file of the atomic writes is left behind.
void expectNoTemporaries(const fs::path& dir) {
  for (const auto& entry : fs::directory_iterator(dir)) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos)
        << entry.path();
  }
}

// `file` is a PNG of exactly width x height, by its header and by stb.
void expectPngSize(const std::string& file, uint32_t width, uint32_t height) {
  const PngHeader header = parsePngHeader(readFile(file));
  ASSERT_TRUE(header.valid) << file << " is not a PNG";
  EXPECT_EQ(header.width, width) << file;
  EXPECT_EQ(header.height, height) << file;
}

// The expected file names of the arm's bone fields.
// A composed picture has inside, outside, the 0.5 iso and the mesh section,
// and its inside covers a fraction of the picture within the bounds given.
void expectComposedPicture(const PixelCounts& picture, double min_red_fraction,
                           double max_red_fraction) {
  EXPECT_GT(picture.red, 0);
  EXPECT_GT(picture.blue, 0);
  EXPECT_GT(picture.iso, 0);
  EXPECT_GT(picture.mesh, 0);
  EXPECT_GT(picture.redFraction(), min_red_fraction) << picture.red;
  EXPECT_LT(picture.redFraction(), max_red_fraction) << picture.red;
}

std::vector<std::string> armFieldFiles() {
  const Rig rig = makeBuiltinRig("arm");
  const BonePartition partition = partitionMesh(rig);
  std::vector<std::string> names;
  for (int joint : partition.field_joints) {
    names.push_back("field_" + rig.skeleton.joints[joint].name + ".png");
  }
  return names;
}

TEST(FieldSlicesTest, ArmWritesComposedAndPerFieldPictures) {
  ScopedTempDir dir;
  const std::string out = dir / "slices";
  const std::vector<std::string> args = {"--rig",  "arm", "--out",  out,
                                         "--size", "256", "--grid", "24"};
  const RunOutput run = runSlices(args);
  ASSERT_EQ(run.exit_code, 0) << describe(args, run);

  std::vector<std::string> expected = armFieldFiles();
  ASSERT_FALSE(expected.empty());
  expected.push_back("composed.png");
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(pngFiles(out), expected);
  expectNoTemporaries(out);

  // The arm lies along x: the longer side is the width, 256 pixels.
  const PngHeader composed_header =
      parsePngHeader(readFile(dir / "slices/composed.png"));
  ASSERT_TRUE(composed_header.valid);
  EXPECT_EQ(composed_header.width, 256u);
  EXPECT_GT(composed_header.height, 16u);
  EXPECT_LT(composed_header.height, 256u);
  for (const std::string& name : expected) {
    expectPngSize(dir / ("slices/" + name), composed_header.width,
                  composed_header.height);
    // One summary line per file.
    EXPECT_NE(run.output.find(name + " ("), std::string::npos) << name << "\n"
                                                               << run.output;
  }

  const PixelCounts composed = countPixels(dir / "slices/composed.png");
  EXPECT_EQ(composed.width, int(composed_header.width));
  // The arm's section fills a good part of its box, not all of it.
  expectComposedPicture(composed, 0.08, 0.6);
  EXPECT_GT(composed.white, 0);
  EXPECT_GT(composed.joint, 0);

  // Each bone's field: its own inside, smaller than the union's.
  for (const std::string& name : armFieldFiles()) {
    const PixelCounts field = countPixels(dir / ("slices/" + name));
    EXPECT_GT(field.red, 0) << name;
    EXPECT_GT(field.blue, 0) << name;
    EXPECT_GT(field.iso, 0) << name;
    EXPECT_GT(field.mesh, 0) << name;
    EXPECT_LT(field.red, composed.red) << name;
  }

  // index.md names the rig and every picture.
  const std::string index = readFile(dir / "slices/index.md");
  EXPECT_NE(index.find("builtin:arm"), std::string::npos) << index;
  EXPECT_NE(index.find("plane"), std::string::npos) << index;
  for (const std::string& name : expected) {
    EXPECT_NE(index.find(name), std::string::npos) << name << "\n" << index;
  }
}

TEST(FieldSlicesTest, AnalyticAndBakedPicturesAgree) {
  ScopedTempDir dir;
  const std::vector<std::string> baked_args = {"--rig",       "finger", "--out",
                                               dir / "baked", "--size", "160"};
  const RunOutput baked = runSlices(baked_args);
  ASSERT_EQ(baked.exit_code, 0) << describe(baked_args, baked);
  const std::vector<std::string> analytic_args = {
      "--rig",  "finger", "--out",   dir / "analytic",
      "--size", "160",    "--field", "analytic"};
  const RunOutput analytic = runSlices(analytic_args);
  ASSERT_EQ(analytic.exit_code, 0) << describe(analytic_args, analytic);
  EXPECT_EQ(pngFiles(dir / "baked"), pngFiles(dir / "analytic"));
  const PixelCounts a = countPixels(dir / "baked/composed.png");
  const PixelCounts b = countPixels(dir / "analytic/composed.png");
  ASSERT_GT(a.red, 0);
  ASSERT_GT(b.red, 0);
  // 32^3 trilinear grids move the 0.5 iso line by a pixel or so.
  EXPECT_NEAR(double(a.red) / b.red, 1.0, 0.05) << a.red << " " << b.red;
}

TEST(FieldSlicesTest, PosedArmFollowsTheBend) {
  ScopedTempDir dir;
  const std::vector<std::string> args = {"--rig",  "arm", "--out",  dir / "p",
                                         "--size", "128", "--pose", "0.8"};
  const RunOutput run = runSlices(args);
  ASSERT_EQ(run.exit_code, 0) << describe(args, run);
  const PixelCounts composed = countPixels(dir / "p/composed.png");
  EXPECT_EQ(std::max(composed.width, composed.height), 128);
  EXPECT_GT(composed.red, 0);
  EXPECT_GT(composed.iso, 0);
  EXPECT_GT(composed.mesh, 0);
  EXPECT_NE(readFile(dir / "p/index.md").find("0.8 s"), std::string::npos);
}

TEST(FieldSlicesTest, KeepsOtherFilesAndReplacesItsOwn) {
  ScopedTempDir dir;
  fs::create_directories(dir.path() / "out");
  std::ofstream(dir / "out/notes.txt") << "keep me\n";
  std::ofstream(dir / "out/composed.png") << "an old picture\n";
  const std::vector<std::string> args = {"--rig",     "cylinder", "--out",
                                         dir / "out", "--size",   "64"};
  const RunOutput run = runSlices(args);
  ASSERT_EQ(run.exit_code, 0) << describe(args, run);
  EXPECT_EQ(readFile(dir / "out/notes.txt"), "keep me\n");
  EXPECT_TRUE(parsePngHeader(readFile(dir / "out/composed.png")).valid);
  expectNoTemporaries(dir.path() / "out");
}

TEST(FieldSlicesTest, BadInputsExitNonZeroWithAMessage) {
  ScopedTempDir dir;
  const std::string missing = dir / "no_such_model.glb";
  const RunOutput run = runSlices({"--rig", missing, "--out", dir / "out"});
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find(missing), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("isk-field-slices: error:"), std::string::npos)
      << run.output;

  const std::string garbage = dir / "garbage.glb";
  std::ofstream(garbage) << "this is not a glTF file";
  const std::vector<std::vector<std::string>> cases = {
      {"--rig", garbage},
      {"--rig", "no_such_rig"},
      {"--rig", "builtin:no_such_rig"},
      {"--rig", dir.path().string()},
      {"--size", "0"},
      {"--size", "many"},
      {"--grid", "1"},
      {"--grid", "-4"},
      {"--field", "magic"},
      {"--pose", "soon"},
      {"--pose", "-1"},
      {"--pose", "1e9"},
      {"--pose", "0.5", "--clip", "no_such_clip"},
      {"--no-such-option"},
  };
  for (std::vector<std::string> args : cases) {
    args.insert(args.end(), {"--out", dir / "out"});
    const RunOutput bad = runSlices(args);
    EXPECT_NE(bad.exit_code, 0) << describe(args, bad);
    EXPECT_FALSE(bad.output.empty()) << describe(args, bad);
  }
  // Nothing was written for any of them.
  EXPECT_FALSE(fs::exists(dir / "out/composed.png"));
  const RunOutput bad_rig = runSlices({"--rig", "no_such_rig"});
  EXPECT_NE(bad_rig.output.find("arm"), std::string::npos) << bad_rig.output;
}

TEST(FieldSlicesTest, CesiumManAsset) {
  if (!test::haveAssets()) {
    GTEST_SKIP() << test::missingAssetsMessage(
        "isk-field-slices on CesiumMan.glb");
  }
  ScopedTempDir dir;
  const std::string input = samples::dataFile("CesiumMan.glb");
  const std::vector<std::string> args = {"--rig",  input, "--out",  dir / "cm",
                                         "--size", "200", "--grid", "16"};
  const RunOutput run = runSlices(args);
  ASSERT_EQ(run.exit_code, 0) << describe(args, run);

  const Rig& rig = test::loadAsset("CesiumMan.glb");
  const BonePartition partition = partitionMesh(rig);
  std::set<std::string> field_joints;
  for (int joint : partition.field_joints) {
    field_joints.insert(rig.skeleton.joints[joint].name);
  }
  const std::vector<std::string> files = pngFiles(dir / "cm");
  ASSERT_TRUE(std::find(files.begin(), files.end(), "composed.png") !=
              files.end());
  // One picture per field: at most one per joint with a part (a fit that
  // fails leaves a joint without a field), all the same size.
  EXPECT_GE(files.size(), 2u);
  EXPECT_LE(files.size(), field_joints.size() + 1);
  const PngHeader header = parsePngHeader(readFile(dir / "cm/composed.png"));
  ASSERT_TRUE(header.valid);
  EXPECT_EQ(std::max(header.width, header.height), 200u);
  for (const std::string& name : files) {
    expectPngSize(dir / ("cm/" + name), header.width, header.height);
  }
  // A standing figure: arms, legs and head in red, far from filling its box.
  expectComposedPicture(countPixels(dir / "cm/composed.png"), 0.03, 0.5);
  EXPECT_NE(readFile(dir / "cm/index.md").find("CesiumMan.glb"),
            std::string::npos);
}

}  // namespace
}  // namespace isk
