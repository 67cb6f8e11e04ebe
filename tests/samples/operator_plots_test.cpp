// Runs the built isk-operator-plots executable (ISK_OPERATOR_PLOTS_EXE) and
// checks its contract: exit code 0, every picture a PNG of its size, the
// operators' panels showing each operator (blend and union apart at theta =
// 0, equal at pi/4), tables close to the direct operators, the bend pictures
// and their table showing Figure 5(c)'s physics, and clear errors for bad
// arguments.
#include "operator_plots.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "isk/fields/composition_operator.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using samples::PanelLayout;
using test::RunOutput;
using test::ScopedTempDir;

// Small pictures keep the run short; the areas still differ by tens of
// pixels where the physics says they should.
constexpr int kSize = 128;

const std::vector<std::string> kOperators = {"union", "blend", "bulge"};
const std::vector<std::string> kAngles = {"000", "045", "090", "135"};

// One run of the sample per test process, into a folder kept until exit.
struct SharedRun {
  ScopedTempDir dir;
  std::string out;
  std::vector<std::string> args;
  RunOutput run;
};

const SharedRun& sharedRun() {
  static const SharedRun* shared = [] {
    auto* s = new SharedRun;
    s->out = s->dir / "plots";
    s->args = {"--out", s->out, "--size", std::to_string(kSize)};
    s->run = test::runProgram(ISK_OPERATOR_PLOTS_EXE, s->args);
    return s;
  }();
  return *shared;
}

std::string describe(const std::vector<std::string>& args,
                     const RunOutput& run) {
  return test::describeRun("isk-operator-plots", args, run);
}

// A decoded picture, 3 bytes a pixel.
struct Picture : test::DecodedPng {
  // The palette's inside (red) and outside (blue) colours, iso lines and
  // contours included (darkened, still red or blue).
  bool red(int x, int y) const {
    const unsigned char* p = at(x, y);
    return p[0] >= 120 && p[0] - p[1] >= 60 && p[0] - p[2] >= 60;
  }
  bool blue(int x, int y) const {
    const unsigned char* p = at(x, y);
    return p[2] >= 100 && p[2] - p[0] >= 30 && p[2] >= p[1];
  }
  long redCount() const {
    long count = 0;
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) count += red(x, y);
    }
    return count;
  }
};

Picture decode(const std::string& path) {
  return Picture{test::decodePngFile(path)};
}

void expectPngSize(const std::string& path, int width, int height) {
  const test::PngHeader header = test::parsePngHeader(test::readFile(path));
  ASSERT_TRUE(header.valid) << path << " is missing or not a PNG";
  EXPECT_EQ(header.width, static_cast<uint32_t>(width)) << path;
  EXPECT_EQ(header.height, static_cast<uint32_t>(height)) << path;
}

using test::number;
using test::tableRows;

// One row of the bend table.
struct Bend {
  double inside = 0, inside_minus_union = 0, max_from_union = 0;
};

// The bend table of `text` by "<op> <degrees>"; fails when it is malformed.
std::map<std::string, Bend> bendTable(const std::string& text) {
  std::map<std::string, Bend> bends;
  for (const auto& row : tableRows(text, "| operator | elbow bend")) {
    if (row.size() != 7u) {
      ADD_FAILURE() << "bend table row of " << row.size() << " cells";
      continue;
    }
    Bend bend;
    bend.inside = number(row[2]);
    bend.inside_minus_union = number(row[4]);
    bend.max_from_union = number(row[5]);
    EXPECT_FALSE(
        std::isnan(bend.inside + bend.inside_minus_union + bend.max_from_union))
        << row[2] << " " << row[4] << " " << row[5];
    EXPECT_EQ(row[6],
              "bend_" + row[0] + "_" +
                  std::string(3 - std::min<size_t>(3, row[1].size()), '0') +
                  row[1] + ".png");
    bends[row[0] + " " + row[1]] = bend;
  }
  return bends;
}

TEST(OperatorPlotsTest, WritesEveryPictureAtItsSize) {
  const SharedRun& s = sharedRun();
  ASSERT_EQ(s.run.exit_code, 0) << describe(s.args, s.run);

  PanelLayout operators;
  operators.panel = kSize;
  operators.columns = 5;
  // Five panels side by side, each under its caption.
  EXPECT_GT(operators.width(), 5 * kSize);
  EXPECT_GT(operators.height(), kSize);
  for (const std::string& op : kOperators) {
    expectPngSize(s.out + "/operator_" + op + ".png", operators.width(),
                  operators.height());
    for (const std::string& angle : kAngles) {
      expectPngSize(s.out + "/bend_" + op + "_" + angle + ".png", kSize, kSize);
    }
  }
  PanelLayout grid;
  grid.panel = kSize;
  grid.columns = 4;
  grid.rows = 3;
  EXPECT_GT(grid.width(), 4 * kSize);
  EXPECT_GT(grid.height(), 3 * kSize);
  expectPngSize(s.out + "/bend_grid.png", grid.width(), grid.height());

  // Both tables, on stdout and in summary.md.
  const std::string summary = test::readFile(s.out + "/summary.md");
  ASSERT_FALSE(summary.empty()) << "no " << s.out << "/summary.md";
  for (const std::string* text : {&summary, &s.run.output}) {
    EXPECT_EQ(tableRows(*text, "| operator | theta = 0 |").size(), 3u) << *text;
    EXPECT_EQ(bendTable(*text).size(), 12u) << *text;
  }
  EXPECT_NE(s.run.output.find("wrote 16 pictures"), std::string::npos)
      << s.run.output;
}

TEST(OperatorPlotsTest, PanelsShowEachOperator) {
  const SharedRun& s = sharedRun();
  ASSERT_EQ(s.run.exit_code, 0) << describe(s.args, s.run);
  PanelLayout layout;
  layout.panel = kSize;
  layout.columns = 5;
  // The pixel of (f1, f2) in panel `column` (theta index).
  auto pixel = [&](int column, double f1, double f2) {
    return std::pair<int, int>(
        layout.panelX(column) + static_cast<int>(f1 * kSize),
        layout.panelY(0) + static_cast<int>((1 - f2) * kSize));
  };
  const Picture union_picture = decode(s.out + "/operator_union.png");
  const Picture blend = decode(s.out + "/operator_blend.png");
  const Picture bulge = decode(s.out + "/operator_bulge.png");
  ASSERT_TRUE(union_picture.valid() && blend.valid() && bulge.valid());
  for (int column = 0; column < 5; ++column) {
    // The union is outside at (0.45, 0.45) and inside at (0.55, 0.3) for
    // every theta.
    const auto [x, y] = pixel(column, 0.45, 0.45);
    EXPECT_TRUE(union_picture.blue(x, y)) << "union, panel " << column;
    const auto [xi, yi] = pixel(column, 0.55, 0.3);
    EXPECT_TRUE(union_picture.red(xi, yi)) << "union, panel " << column;
    EXPECT_TRUE(blend.red(xi, yi)) << "blend, panel " << column;
  }
  // theta = 0: the strongest blend, g = |(f1, f2)| there, is inside at
  // (0.45, 0.45) (g = 0.64); theta = pi/4 is the union again.
  {
    const auto [x, y] = pixel(0, 0.45, 0.45);
    EXPECT_TRUE(blend.red(x, y));
    const auto [xu, yu] = pixel(4, 0.45, 0.45);
    EXPECT_TRUE(blend.blue(xu, yu));
  }
  // The full bulge swells the surface where both fields are high:
  // g(0.45, 0.45, 0) = 0.45 + 0.1 Q S > 0.5.
  {
    const auto [x, y] = pixel(0, 0.45, 0.45);
    EXPECT_TRUE(bulge.red(x, y));
    const auto [xu, yu] = pixel(4, 0.45, 0.45);
    EXPECT_TRUE(bulge.blue(xu, yu));
  }

  // Table errors: none for the union (no table), small for the others.
  const auto rows = tableRows(s.run.output, "| operator | theta = 0 |");
  ASSERT_EQ(rows.size(), 3u) << s.run.output;
  for (const auto& row : rows) {
    ASSERT_EQ(row.size(), 6u) << s.run.output;
    for (size_t c = 1; c < row.size(); ++c) {
      if (row[0] == "union") {
        EXPECT_EQ(row[c], "- (exact max)");
      } else {
        EXPECT_LT(number(row[c]), 5e-3) << row[0] << " column " << c;
      }
    }
  }
}

TEST(OperatorPlotsTest, BendPicturesShowFigure5c) {
  const SharedRun& s = sharedRun();
  ASSERT_EQ(s.run.exit_code, 0) << describe(s.args, s.run);
  std::map<std::string, Bend> bends = bendTable(s.run.output);
  ASSERT_EQ(bends.size(), 12u) << s.run.output;
  for (const char* angle : {"0", "45", "90", "135"}) {
    const Bend& u = bends[std::string("union ") + angle];
    EXPECT_EQ(u.inside_minus_union, 0);
    EXPECT_EQ(u.max_from_union, 0);
    EXPECT_GT(u.inside, 0);
  }
  // Straight arm: the elbow at its bind rotation is a union for the blend
  // and the bulge (alpha is capped by the joint's rotation): no bulge.
  const Bend& blend45 = bends["blend 45"];
  for (const char* op : {"blend 0", "bulge 0"}) {
    EXPECT_EQ(bends[op].inside_minus_union, 0) << op << "\n" << s.run.output;
    EXPECT_LT(bends[op].max_from_union, 1e-4) << op << "\n" << s.run.output;
  }
  // 45 degrees (alpha about pi/4 in the fold: theta = 0, the strongest
  // blend): the blend fills the fold, more inside than the union.
  EXPECT_GT(blend45.inside_minus_union, 0.01 * bends["union 45"].inside)
      << s.run.output;
  EXPECT_GT(blend45.max_from_union, 0.1) << s.run.output;
  // From pi/2 on the controller is back to a union in the fold.
  EXPECT_LT(bends["blend 90"].max_from_union, blend45.max_from_union);
  EXPECT_LT(bends["blend 135"].max_from_union, blend45.max_from_union);
  // The bulge grows with the bend up to its amplitude, reached at 90.
  EXPECT_GT(bends["bulge 90"].max_from_union, bends["bulge 45"].max_from_union)
      << s.run.output;
  EXPECT_GT(bends["bulge 90"].max_from_union, 0.8 * kBulgeAmplitude);
  EXPECT_LE(bends["bulge 135"].max_from_union, kBulgeAmplitude + 1e-3);
  EXPECT_GT(bends["bulge 90"].inside_minus_union, 0);

  // The pictures say the same: the blend's red area at 45 degrees exceeds
  // the union's; at 0 degrees they are the same.
  const Picture union0 = decode(s.out + "/bend_union_000.png");
  const Picture blend0_picture = decode(s.out + "/bend_blend_000.png");
  const Picture union45 = decode(s.out + "/bend_union_045.png");
  const Picture blend45_picture = decode(s.out + "/bend_blend_045.png");
  ASSERT_TRUE(union0.valid() && blend0_picture.valid() && union45.valid() &&
              blend45_picture.valid());
  EXPECT_GT(union0.redCount(), kSize * kSize / 10);
  EXPECT_EQ(blend0_picture.redCount(), union0.redCount());
  EXPECT_GT(blend45_picture.redCount(), union45.redCount());
}

TEST(OperatorPlotsTest, BadArgumentsFailWithAMessage) {
  ScopedTempDir dir;
  const std::vector<std::vector<std::string>> bad = {
      {"--size", "10"},
      {"--table-resolution", "1"},
      {"--size", "many"},
      {"--no-such-option"},
  };
  for (std::vector<std::string> args : bad) {
    args.push_back("--out");
    args.push_back(dir / "never");
    const RunOutput run = test::runProgram(ISK_OPERATOR_PLOTS_EXE, args);
    EXPECT_NE(run.exit_code, 0) << describe(args, run);
    EXPECT_NE(run.output.find(args[0]), std::string::npos)
        << describe(args, run);
  }
  // An output folder that is a file.
  const std::string file = dir / "a-file";
  {
    FILE* f = std::fopen(file.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fclose(f);
  }
  const std::vector<std::string> args = {"--out", file, "--size", "64"};
  const RunOutput run = test::runProgram(ISK_OPERATOR_PLOTS_EXE, args);
  EXPECT_EQ(run.exit_code, 1) << describe(args, run);
  EXPECT_NE(run.output.find("isk-operator-plots: error: "), std::string::npos)
      << describe(args, run);
  EXPECT_NE(run.output.find("not a folder"), std::string::npos)
      << describe(args, run);
}

}  // namespace
}  // namespace isk
