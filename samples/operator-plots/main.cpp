// isk-operator-plots: pictures of the composition operators of implicit
// skinning (Vaillant et al. 2013, section 4.2): each operator's iso-curves
// over the (f1, f2) unit square for five values of theta
// (operator_<op>.png), and the builtin arm's composed field around its elbow
// bent by 0, 45, 90 and 135 degrees with the union, the gradient-based blend
// and the bulge (bend_<op>_<deg>.png, bend_grid.png: the paper's Figure
// 5(c)). Prints the operator tables' largest error against the direct
// operators and a table of the bends' inside areas; summary.md holds both.
// See README.md.
#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>

#include "isk/io/export.hpp"
#include "operator_plots.hpp"

namespace {

namespace fs = std::filesystem;

constexpr const char* kProgram = "isk-operator-plots";

int run(const std::string& out_dir,
        const isk::samples::OperatorPlotOptions& options) {
  const isk::samples::OperatorPlotsReport report =
      isk::samples::writeOperatorPlots(out_dir, options);
  const std::string errors = isk::samples::formatTableErrors(report);
  const std::string bends = isk::samples::formatBendTable(report);
  std::cout << "Largest abs(table - direct) operator value over each panel ("
            << options.table_resolution << "^3 tables):\n\n"
            << errors << "\nThe arm's composed field around the elbow (a "
            << report.window << " x " << report.window << " square, "
            << report.size << " x " << report.size << " pixels; areas within "
            << report.measure_radius << " model units of the elbow):\n\n"
            << bends;

  std::ostringstream md;
  md << "# Composition operators\n\n"
     << "Written by `" << kProgram
     << "` (Vaillant et al. 2013, section 4.2; see "
        "samples/operator-plots/README.md).\n\n"
     << "## Operators in the (f1, f2) plane\n\n"
     << "`operator_union.png`, `operator_blend.png`, `operator_bulge.png`: "
        "g(f1, f2, theta) over the unit square (f1 right, f2 up), one panel "
        "per theta, left to right 0, pi/16, pi/8, 3pi/16, pi/4 (the union); "
        "iso-curves every 0.1 in grey, 0.5 in black; inside (g > 0.5) red, "
        "outside blue. Drawn from the direct operators. Largest "
        "abs(table - direct) g over each panel's "
     << report.size << " x " << report.size << " pixels, "
     << options.table_resolution << "^3 tables:\n\n"
     << errors << "\n"
     << "## Figure 5(c): the arm bent at the elbow\n\n"
     << "`bend_<op>_<deg>.png` and `bend_grid.png` (rows union, blend, "
        "bulge; columns 0, 45, 90, 135 degrees): the composed baked field of "
        "the builtin arm in its bending plane, a "
     << report.window << " x " << report.window
     << " square around the elbow (its centre 0.5 from the elbow towards the "
        "inside of the fold), "
     << report.size << " x " << report.size
     << " pixels; joints in yellow. The fields are built once per operator "
        "(the operator at every joint: the elbow's and the wrist's pair). "
        "Measured over the pixels within "
     << report.measure_radius
     << " model units of the elbow (the wrist, 2.6 away, left out): "
        "`inside pixels`, those with f >= 0.5; `inside - union`, the same "
        "minus the union's at that bend; `max abs(f - union)`, the largest "
        "difference from the union's field there.\n\n"
     << bends << "\nTimes: fields " << std::lround(report.field_ms)
     << " ms, pictures " << std::lround(report.picture_ms) << " ms.\n";
  const std::string summary = (fs::path(out_dir) / "summary.md").string();
  isk::writeTextFile(summary, md.str());
  std::cout << "\n"
            << kProgram << ": wrote " << report.files.size()
            << " pictures and summary.md to " << out_dir << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::string out_dir = "out/operator-plots";
  isk::samples::OperatorPlotOptions options;
  options.label = kProgram;
  CLI::App app{
      "Writes PNG plots of the composition operators' iso-curves in the "
      "(f1, f2) plane for five theta values, and of the builtin arm's "
      "composed field around its elbow bent by 0, 45, 90 and 135 degrees "
      "with the union, the blend and the bulge (Vaillant et al. 2013, "
      "Figure 5(c)), with a summary.md."};
  app.add_option("--out", out_dir, "output folder")->capture_default_str();
  app.add_option("--size", options.size,
                 "side of each operator panel and bend picture, in pixels")
      ->check(CLI::Range(64, 2048))
      ->capture_default_str();
  app.add_option("--table-resolution", options.table_resolution,
                 "nodes per axis of the operator tables (compared with the "
                 "direct operators and used by the compositions)")
      ->check(CLI::Range(8, 256))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  try {
    return run(out_dir, options);
  } catch (const std::exception& error) {
    std::cerr << kProgram << ": error: " << error.what() << "\n";
  }
  return 1;
}
