#include "operator_plots.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>

#include "field_pictures.hpp"
#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"
#include "isk/fields/field_composition.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/tools/procedural.hpp"

namespace isk::samples {
namespace {

namespace fs = std::filesystem;

constexpr double kPi = 3.14159265358979323846;

// The bend pictures: a square of this side (model units) in the bending
// plane, centred this far from the elbow towards the inside of the fold so
// that the folded forearm stays in view at 135 degrees. The arm is 7.4
// long, the elbow at 3 from the shoulder and 2.6 from the wrist, the arm's
// radius about 0.45 there.
constexpr double kBendWindow = 3.0;
constexpr double kBendWindowShift = 0.5;
// The areas are measured within this distance of the elbow: the elbow's
// fold, without the wrist (whose pair gets the same operator) at 2.6.
constexpr double kMeasureRadius = 1.4;

// Iso-curve colours of the operator panels.
constexpr Rgb kIsoCurve = {70, 70, 70};
constexpr Rgb kCaption = {0, 0, 0};
constexpr Rgb kPanelFrame = {160, 160, 160};

using Glyph = std::array<const char*, 7>;

// A 5 x 7 pixel font: capital letters, digits and a few signs, enough for
// captions without a font library.
const std::map<char, Glyph>& glyphs() {
  static const std::map<char, Glyph> font = {
      {' ', {"     ", "     ", "     ", "     ", "     ", "     ", "     "}},
      {'0', {" ### ", "#   #", "#  ##", "# # #", "##  #", "#   #", " ### "}},
      {'1', {"  #  ", " ##  ", "  #  ", "  #  ", "  #  ", "  #  ", " ### "}},
      {'2', {" ### ", "#   #", "    #", "   # ", "  #  ", " #   ", "#####"}},
      {'3', {"#####", "   # ", "  #  ", "   # ", "    #", "#   #", " ### "}},
      {'4', {"   # ", "  ## ", " # # ", "#  # ", "#####", "   # ", "   # "}},
      {'5', {"#####", "#    ", "#### ", "    #", "    #", "#   #", " ### "}},
      {'6', {"  ## ", " #   ", "#    ", "#### ", "#   #", "#   #", " ### "}},
      {'7', {"#####", "    #", "   # ", "  #  ", " #   ", " #   ", " #   "}},
      {'8', {" ### ", "#   #", "#   #", " ### ", "#   #", "#   #", " ### "}},
      {'9', {" ### ", "#   #", "#   #", " ####", "    #", "   # ", " ##  "}},
      {'A', {" ### ", "#   #", "#   #", "#####", "#   #", "#   #", "#   #"}},
      {'B', {"#### ", "#   #", "#   #", "#### ", "#   #", "#   #", "#### "}},
      {'C', {" ### ", "#   #", "#    ", "#    ", "#    ", "#   #", " ### "}},
      {'D', {"#### ", "#   #", "#   #", "#   #", "#   #", "#   #", "#### "}},
      {'E', {"#####", "#    ", "#    ", "#### ", "#    ", "#    ", "#####"}},
      {'F', {"#####", "#    ", "#    ", "#### ", "#    ", "#    ", "#    "}},
      {'G', {" ### ", "#   #", "#    ", "# ###", "#   #", "#   #", " ####"}},
      {'H', {"#   #", "#   #", "#   #", "#####", "#   #", "#   #", "#   #"}},
      {'I', {" ### ", "  #  ", "  #  ", "  #  ", "  #  ", "  #  ", " ### "}},
      {'J', {"  ###", "   # ", "   # ", "   # ", "   # ", "#  # ", " ##  "}},
      {'K', {"#   #", "#  # ", "# #  ", "##   ", "# #  ", "#  # ", "#   #"}},
      {'L', {"#    ", "#    ", "#    ", "#    ", "#    ", "#    ", "#####"}},
      {'M', {"#   #", "## ##", "# # #", "# # #", "#   #", "#   #", "#   #"}},
      {'N', {"#   #", "#   #", "##  #", "# # #", "#  ##", "#   #", "#   #"}},
      {'O', {" ### ", "#   #", "#   #", "#   #", "#   #", "#   #", " ### "}},
      {'P', {"#### ", "#   #", "#   #", "#### ", "#    ", "#    ", "#    "}},
      {'Q', {" ### ", "#   #", "#   #", "#   #", "# # #", "#  # ", " ## #"}},
      {'R', {"#### ", "#   #", "#   #", "#### ", "# #  ", "#  # ", "#   #"}},
      {'S', {" ####", "#    ", "#    ", " ### ", "    #", "    #", "#### "}},
      {'T', {"#####", "  #  ", "  #  ", "  #  ", "  #  ", "  #  ", "  #  "}},
      {'U', {"#   #", "#   #", "#   #", "#   #", "#   #", "#   #", " ### "}},
      {'V', {"#   #", "#   #", "#   #", "#   #", "#   #", " # # ", "  #  "}},
      {'W', {"#   #", "#   #", "#   #", "# # #", "# # #", "# # #", " # # "}},
      {'X', {"#   #", "#   #", " # # ", "  #  ", " # # ", "#   #", "#   #"}},
      {'Y', {"#   #", "#   #", " # # ", "  #  ", "  #  ", "  #  ", "  #  "}},
      {'Z', {"#####", "    #", "   # ", "  #  ", " #   ", "#    ", "#####"}},
      {'=', {"     ", "     ", "#####", "     ", "#####", "     ", "     "}},
      {'/', {"     ", "    #", "   # ", "  #  ", " #   ", "#    ", "     "}},
      {'.', {"     ", "     ", "     ", "     ", "     ", " ##  ", " ##  "}},
      {'-', {"     ", "     ", "     ", "#####", "     ", "     ", "     "}},
      {'(', {"   # ", "  #  ", " #   ", " #   ", " #   ", "  #  ", "   # "}},
      {')', {" #   ", "  #  ", "   # ", "   # ", "   # ", "  #  ", " #   "}},
      {':', {"     ", " ##  ", " ##  ", "     ", " ##  ", " ##  ", "     "}},
      {';', {"     ", " ##  ", " ##  ", "     ", " ##  ", "  #  ", " #   "}},
  };
  return font;
}

// Drawn for a character the font lacks.
constexpr Glyph kBoxGlyph = {"#####", "#   #", "#   #", "#   #",
                             "#   #", "#   #", "#####"};

int textWidth(const std::string& text, int scale) {
  return text.empty() ? 0 : static_cast<int>(text.size()) * 6 * scale - scale;
}

void blit(Image& target, const Image& source, int x0, int y0) {
  for (int y = 0; y < source.height; ++y) {
    for (int x = 0; x < source.width; ++x) {
      target.set(x0 + x, y0 + y, source.get(x, y));
    }
  }
}

// A 1-pixel frame just outside the panel at (x0, y0), within the margin.
void drawFrame(Image& image, int x0, int y0, int size) {
  for (int i = -1; i <= size; ++i) {
    for (const auto& [x, y] :
         {std::pair{x0 + i, y0 - 1}, std::pair{x0 + i, y0 + size},
          std::pair{x0 - 1, y0 + i}, std::pair{x0 + size, y0 + i}}) {
      if (x >= 0 && y >= 0 && x < image.width && y < image.height) {
        image.set(x, y, kPanelFrame);
      }
    }
  }
}

// The caption over a panel, shortened to `fallback` when it does not fit.
void drawCaption(Image& image, const PanelLayout& layout, int column, int row,
                 const std::string& caption, const std::string& fallback) {
  const int scale = layout.captionScale();
  const std::string& text =
      textWidth(caption, scale) <= layout.panel ? caption : fallback;
  drawText(image, layout.panelX(column),
           layout.panelY(row) - layout.captionHeight() + 2, text, scale,
           kCaption);
}

std::string upper(std::string text) {
  for (char& c : text) {
    c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  return text;
}

std::string fixed(double value, int digits) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(digits) << value;
  return out.str();
}

std::string degreesName(int degrees) {
  std::ostringstream out;
  out << std::setw(3) << std::setfill('0') << degrees;
  return out.str();
}

void checkOptions(const OperatorPlotOptions& options) {
  if (options.size < 64 || options.size > 2048) {
    throw Error(ErrorCode::kInvalidArgument,
                "operator plots: size must be 64 to 2048 pixels, got " +
                    std::to_string(options.size));
  }
  if (options.table_resolution < 8 || options.table_resolution > 256) {
    throw Error(ErrorCode::kInvalidArgument,
                "operator plots: table resolution must be 8 to 256 nodes per "
                "axis, got " +
                    std::to_string(options.table_resolution));
  }
}

void makeFolder(const std::string& out_dir) {
  std::error_code ec;
  if (fs::exists(out_dir, ec) && !fs::is_directory(out_dir, ec)) {
    throw Error(ErrorCode::kIo, out_dir + " is a file, not a folder");
  }
  fs::create_directories(out_dir, ec);
  if (ec) {
    throw Error(ErrorCode::kIo,
                out_dir + ": cannot create the folder: " + ec.message());
  }
}

}  // namespace

const std::vector<CompositionOperator>& plottedOperators() {
  static const std::vector<CompositionOperator> ops = {
      CompositionOperator::kUnion, CompositionOperator::kBlend,
      CompositionOperator::kBulge};
  return ops;
}

const std::vector<double>& operatorPanelThetas() {
  static const std::vector<double> thetas = {0, kPi / 16, kPi / 8, 3 * kPi / 16,
                                             kThetaUnion};
  return thetas;
}

std::string thetaLabel(double theta) {
  // theta in sixteenths of pi, reduced.
  const int sixteenths = static_cast<int>(std::lround(theta * 16 / kPi));
  if (std::abs(theta - sixteenths * kPi / 16) > 1e-9) return fixed(theta, 3);
  if (sixteenths == 0) return "0";
  int numerator = sixteenths, denominator = 16;
  while (numerator % 2 == 0 && denominator > 1) {
    numerator /= 2;
    denominator /= 2;
  }
  std::string text = (numerator == 1 ? "" : std::to_string(numerator)) + "PI";
  if (denominator > 1) text += "/" + std::to_string(denominator);
  return text;
}

const std::vector<int>& bendAngles() {
  static const std::vector<int> angles = {0, 45, 90, 135};
  return angles;
}

int PanelLayout::captionScale() const { return std::max(1, panel / 192); }

int PanelLayout::captionHeight() const { return 7 * captionScale() + 4; }

int PanelLayout::width() const {
  return columns * panel + (columns + 1) * margin();
}

int PanelLayout::height() const {
  return rows * (captionHeight() + panel) + (rows + 1) * margin();
}

int PanelLayout::panelX(int column) const {
  return margin() + column * (panel + margin());
}

int PanelLayout::panelY(int row) const {
  return margin() + row * (captionHeight() + panel + margin()) +
         captionHeight();
}

void drawText(Image& image, int x, int y, const std::string& text, int scale,
              const Rgb& colour) {
  const std::map<char, Glyph>& font = glyphs();
  for (size_t i = 0; i < text.size(); ++i) {
    const char c =
        static_cast<char>(std::toupper(static_cast<unsigned char>(text[i])));
    const auto found = font.find(c);
    const Glyph& glyph = found == font.end() ? kBoxGlyph : found->second;
    const int left = x + static_cast<int>(i) * 6 * scale;
    for (int row = 0; row < 7; ++row) {
      for (int col = 0; col < 5; ++col) {
        if (glyph[row][col] != '#') continue;
        for (int dy = 0; dy < scale; ++dy) {
          for (int dx = 0; dx < scale; ++dx) {
            const int px = left + col * scale + dx, py = y + row * scale + dy;
            if (px >= 0 && py >= 0 && px < image.width && py < image.height) {
              image.set(px, py, colour);
            }
          }
        }
      }
    }
  }
}

OperatorPanel evaluateOperatorPanel(CompositionOperator op, double theta,
                                    int size, int table_resolution) {
  OperatorPanel panel;
  panel.values.assign(static_cast<size_t>(size) * size, 0.f);
  std::shared_ptr<const OperatorTable> table;
  if (op != CompositionOperator::kUnion) {
    table = sharedOperatorTable(op, table_resolution, nullptr, &panel.warnings);
  }
  // Per image row, so the threads never share a maximum.
  std::vector<double> row_error(size, 0.0);
  parallelRows(size, [&](int first, int last) {
    for (int y = first; y < last; ++y) {
      const double f2 = 1.0 - (y + 0.5) / size;
      for (int x = 0; x < size; ++x) {
        const double f1 = (x + 0.5) / size;
        const double g = evaluateOperator(op, f1, f2, theta).g;
        panel.values[static_cast<size_t>(y) * size + x] = static_cast<float>(g);
        if (table) {
          float sampled[3];
          table->sample(static_cast<float>(f1), static_cast<float>(f2),
                        static_cast<float>(theta), sampled);
          row_error[y] = std::max(row_error[y], std::abs(sampled[0] - g));
        }
      }
    }
  });
  if (table) {
    panel.max_table_error =
        *std::max_element(row_error.begin(), row_error.end());
  }
  return panel;
}

Image renderOperatorPanel(const std::vector<float>& values, int size) {
  Image image(size, size);
  auto at = [&](int x, int y) { return values[size_t(y) * size + x]; };
  auto crosses = [](float a, float b, float level) {
    return (a > level) != (b > level);
  };
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const float f = at(x, y);
      Rgb c = fieldColour(f);
      // The 0.5 curve on both pixels of a crossing pair (2 pixels wide), the
      // others on the pixel before the crossing only (1 pixel).
      const bool on_half = (x > 0 && crosses(f, at(x - 1, y), 0.5f)) ||
                           (x + 1 < size && crosses(f, at(x + 1, y), 0.5f)) ||
                           (y > 0 && crosses(f, at(x, y - 1), 0.5f)) ||
                           (y + 1 < size && crosses(f, at(x, y + 1), 0.5f));
      if (on_half) {
        c = palette::kIsoLine;
      } else {
        for (int k = 1; k <= 9; ++k) {
          const float level = 0.1f * k;
          if (k != 5 && ((x + 1 < size && crosses(f, at(x + 1, y), level)) ||
                         (y + 1 < size && crosses(f, at(x, y + 1), level)))) {
            c = kIsoCurve;
            break;
          }
        }
      }
      image.set(x, y, c);
    }
  }
  return image;
}

TransformList bendSkinning(const Skeleton& skeleton, int joint,
                           const Eigen::Vector3f& axis, double degrees) {
  if (joint < 0 || joint >= skeleton.jointCount()) {
    throw Error(ErrorCode::kInvalidArgument,
                "bendSkinning: no joint " + std::to_string(joint) + " (" +
                    std::to_string(skeleton.jointCount()) + " joints)");
  }
  if (!(axis.norm() > 0.f)) {
    throw Error(ErrorCode::kInvalidArgument, "bendSkinning: zero axis");
  }
  // Skinning transforms are identity at the bind pose, so turning a joint's
  // subtree rigidly about the joint is that rotation for each of them.
  const Eigen::Vector3f pivot = skeleton.bindGlobals()[joint].translation();
  const Eigen::Affine3f rotation =
      Eigen::Translation3f(pivot) *
      Eigen::AngleAxisf(static_cast<float>(degrees * kPi / 180.0),
                        axis.normalized()) *
      Eigen::Translation3f(-pivot);
  TransformList skinning(skeleton.jointCount(), Eigen::Affine3f::Identity());
  for (int j = 0; j < skeleton.jointCount(); ++j) {
    for (int a = j; a >= 0; a = skeleton.joints[a].parent) {
      if (a == joint) {
        skinning[j] = rotation;
        break;
      }
    }
  }
  return skinning;
}

OperatorPlotsReport writeOperatorPlots(const std::string& out_dir,
                                       const OperatorPlotOptions& options) {
  checkOptions(options);
  makeFolder(out_dir);
  const fs::path dir(out_dir);
  const int size = options.size;
  OperatorPlotsReport report;
  report.size = size;
  report.window = kBendWindow;
  report.measure_radius = kMeasureRadius;

  // The operators' iso-curves, one panel per theta.
  const auto pictures_start = std::chrono::steady_clock::now();
  const std::vector<double>& thetas = operatorPanelThetas();
  for (const CompositionOperator op : plottedOperators()) {
    PanelLayout layout;
    layout.panel = size;
    layout.columns = static_cast<int>(thetas.size());
    Image image(layout.width(), layout.height());
    for (size_t c = 0; c < thetas.size(); ++c) {
      const OperatorPanel panel =
          evaluateOperatorPanel(op, thetas[c], size, options.table_resolution);
      for (const std::string& warning : panel.warnings)
        std::cerr << options.label << ": warning: " << warning << "\n";
      const int column = static_cast<int>(c);
      blit(image, renderOperatorPanel(panel.values, size),
           layout.panelX(column), layout.panelY(0));
      drawFrame(image, layout.panelX(column), layout.panelY(0), size);
      const std::string theta = "THETA=" + thetaLabel(thetas[c]);
      drawCaption(image, layout, column, 0,
                  upper(compositionOperatorName(op)) + " " + theta, theta);
      report.table_errors.push_back({op, thetas[c], panel.max_table_error});
    }
    const std::string file =
        std::string("operator_") + compositionOperatorName(op) + ".png";
    writePng((dir / file).string(), image);
    report.files.push_back(file);
  }
  report.picture_ms += millisecondsSince(pictures_start);

  // The arm's fields, once per operator (the composition chosen at build
  // time, as the skinning would use it).
  const auto fields_start = std::chrono::steady_clock::now();
  const Rig rig = makeBuiltinRig("arm");
  const Skeleton& skeleton = rig.skeleton;
  const int elbow = skeleton.find("elbow");
  const int wrist = skeleton.find("wrist");
  if (elbow < 0 || wrist < 0) {
    throw Error(ErrorCode::kInternal,
                "operator plots: the builtin arm has no 'elbow' or 'wrist'");
  }
  std::vector<ImplicitFields> fields;
  for (const CompositionOperator op : plottedOperators()) {
    ImplicitFieldsOptions build;
    build.composition.default_operator = op;
    build.composition.table_resolution = options.table_resolution;
    fields.push_back(buildFieldsWithProgress(
        rig, build,
        options.label + ": " + compositionOperatorName(op) + " fields",
        options.label + ": warning: "));
  }
  report.field_ms = millisecondsSince(fields_start);

  // The bending plane: u along the forearm at rest, v towards the inside
  // of the fold (the forearm turns towards +v), the axis its normal.
  const auto bends_start = std::chrono::steady_clock::now();
  const TransformList bind_globals = skeleton.bindGlobals();
  const Eigen::Vector3d elbow_at =
      bind_globals[elbow].translation().cast<double>();
  const Eigen::Vector3d along =
      (bind_globals[wrist].translation().cast<double>() - elbow_at)
          .normalized();
  Eigen::Vector3d axis = along.cross(Eigen::Vector3d::UnitY());
  if (axis.norm() < 1e-3) axis = along.cross(Eigen::Vector3d::UnitZ());
  axis.normalize();
  SlicePlane plane;
  plane.u = along;
  plane.v = axis.cross(along);
  plane.normal = axis;
  plane.origin = elbow_at + kBendWindowShift * plane.v;
  plane.u_min = plane.v_min = -kBendWindow / 2;
  plane.u_max = plane.v_max = kBendWindow / 2;
  plane.pixel = kBendWindow / size;
  plane.width = plane.height = size;
  plane.how = "the arm's bending plane around the elbow";

  const std::vector<int>& angles = bendAngles();
  const size_t op_count = plottedOperators().size();
  // values[op][angle]: the composed field at the pixels.
  std::vector<std::vector<std::vector<float>>> values(
      op_count, std::vector<std::vector<float>>(angles.size()));
  std::vector<std::vector<Eigen::Vector2d>> joint_dots(angles.size());
  for (size_t a = 0; a < angles.size(); ++a) {
    const TransformList skinning =
        bendSkinning(skeleton, elbow, axis.cast<float>(), angles[a]);
    for (int j = 0; j < skeleton.jointCount(); ++j) {
      joint_dots[a].push_back(plane.toImage(
          (skinning[j] * bind_globals[j].translation()).cast<double>()));
    }
    for (size_t o = 0; o < op_count; ++o) {
      SliceEvaluator evaluator(fields[o], skinning, plane);
      values[o][a] = evaluator.baked(SliceEvaluator::kComposed);
    }
  }

  // The pixels within kMeasureRadius of the elbow (it stays in place).
  const Eigen::Vector2d elbow_pixel = plane.toImage(elbow_at);
  const double radius_pixels = kMeasureRadius / plane.pixel;
  std::vector<size_t> measured;
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      if ((Eigen::Vector2d(x + 0.5, y + 0.5) - elbow_pixel).norm() <=
          radius_pixels) {
        measured.push_back(static_cast<size_t>(y) * size + x);
      }
    }
  }

  PanelLayout grid;
  grid.panel = size;
  grid.columns = static_cast<int>(angles.size());
  grid.rows = static_cast<int>(op_count);
  Image grid_image(grid.width(), grid.height());
  const size_t union_row = 0;  // plottedOperators() starts with the union
  for (size_t o = 0; o < op_count; ++o) {
    const CompositionOperator op = plottedOperators()[o];
    for (size_t a = 0; a < angles.size(); ++a) {
      const std::vector<float>& f = values[o][a];
      const std::vector<float>& u = values[union_row][a];
      BendResult result;
      result.op = op;
      result.degrees = angles[a];
      result.file = std::string("bend_") + compositionOperatorName(op) + "_" +
                    degreesName(angles[a]) + ".png";
      long union_inside = 0;
      for (const size_t p : measured) {
        result.inside_pixels += f[p] >= 0.5f;
        union_inside += u[p] >= 0.5f;
        result.max_from_union =
            std::max(result.max_from_union, double(std::abs(f[p] - u[p])));
      }
      result.measured_pixels = static_cast<long>(measured.size());
      result.inside_fraction =
          double(result.inside_pixels) / std::max<size_t>(1, measured.size());
      result.inside_minus_union = result.inside_pixels - union_inside;

      const Image picture = renderSlice(f, size, size, {}, joint_dots[a]);
      writePng((dir / result.file).string(), picture);
      report.files.push_back(result.file);
      const int row = static_cast<int>(o), column = static_cast<int>(a);
      blit(grid_image, picture, grid.panelX(column), grid.panelY(row));
      drawFrame(grid_image, grid.panelX(column), grid.panelY(row), size);
      const std::string angle = std::to_string(angles[a]) + " DEG";
      drawCaption(grid_image, grid, column, row,
                  upper(compositionOperatorName(op)) + " " + angle, angle);
      report.bends.push_back(result);
    }
  }
  writePng((dir / "bend_grid.png").string(), grid_image);
  report.files.push_back("bend_grid.png");
  report.picture_ms += millisecondsSince(bends_start);
  return report;
}

std::string formatTableErrors(const OperatorPlotsReport& report) {
  std::ostringstream out;
  out << "| operator |";
  for (const double theta : operatorPanelThetas()) {
    std::string label = thetaLabel(theta);
    for (char& c : label) {
      c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    }
    out << " theta = " << label << " |";
  }
  out << "\n|---|";
  for (size_t i = 0; i < operatorPanelThetas().size(); ++i) out << "---:|";
  out << "\n";
  for (const CompositionOperator op : plottedOperators()) {
    out << "| " << compositionOperatorName(op) << " |";
    for (const TableError& e : report.table_errors) {
      if (e.op != op) continue;
      std::ostringstream cell;
      if (e.max_error) {
        cell << std::scientific << std::setprecision(2) << *e.max_error;
      } else {
        cell << "- (exact max)";
      }
      out << " " << cell.str() << " |";
    }
    out << "\n";
  }
  return out.str();
}

std::string formatBendTable(const OperatorPlotsReport& report) {
  std::ostringstream out;
  out << "| operator | elbow bend (degrees) | inside pixels (f >= 0.5) | "
         "inside fraction | inside - union (pixels) | max abs(f - union) | "
         "picture |\n"
      << "|---|---:|---:|---:|---:|---:|---|\n";
  for (const BendResult& b : report.bends) {
    out << "| " << compositionOperatorName(b.op) << " | " << b.degrees << " | "
        << b.inside_pixels << " | " << fixed(b.inside_fraction, 4) << " | "
        << (b.inside_minus_union > 0 ? "+" : "") << b.inside_minus_union
        << " | " << fixed(b.max_from_union, 4) << " | " << b.file << " |\n";
  }
  return out.str();
}

}  // namespace isk::samples
