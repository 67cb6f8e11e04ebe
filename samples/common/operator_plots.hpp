// Pictures of the composition operators of implicit skinning (Vaillant et
// al. 2013, section 4.2), shared by isk-operator-plots and the demo:
//
// - each operator's iso-curves over the (f1, f2) unit square, one panel per
//   theta (operator_<op>.png), from the direct operators (evaluateOperator),
//   with the largest |table - direct| value of each panel;
// - the composed field of the procedural arm around its elbow, bent by 0,
//   45, 90 and 135 degrees, per operator (bend_<op>_<deg>.png and
//   bend_grid.png): the paper's Figure 5(c), with the inside area and how
//   far each operator's field is from the union's.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "isk/core/types.hpp"
#include "isk/fields/composition_operator.hpp"
#include "isk/rig/skeleton.hpp"
#include "slice_image.hpp"

namespace isk::samples {

// The operators drawn, in the order of the pictures' rows and the tables.
const std::vector<CompositionOperator>& plottedOperators();

// theta of the operator panels, left to right: 0 (strongest blend, full
// bulge), pi/16, pi/8, 3pi/16 and pi/4 (the union for every operator).
const std::vector<double>& operatorPanelThetas();
// "0", "PI/16", "PI/8", "3PI/16", "PI/4": theta as the captions spell it.
std::string thetaLabel(double theta);

// Elbow bends of the Figure 5(c) pictures, in degrees: 0, 45, 90, 135.
const std::vector<int>& bendAngles();

// Square panels side by side in rows, each under a caption strip, with a
// white margin around every panel.
struct PanelLayout {
  int panel = 0;  // side of a panel, pixels
  int columns = 1, rows = 1;

  static int margin() { return 4; }
  // Caption glyphs are 5 x 7 pixels scaled by this (1 up to 191 pixels).
  int captionScale() const;
  int captionHeight() const;
  int width() const;
  int height() const;
  // Top-left pixel of a panel's field (under its caption).
  int panelX(int column) const;
  int panelY(int row) const;
};

// Draws `text` (letters, digits, space and = / . - ( ) : ; others are
// drawn as a box) with its top-left corner at (x, y), glyphs 5 x 7 pixels
// scaled by `scale`; pixels outside the image are skipped.
void drawText(Image& image, int x, int y, const std::string& text, int scale,
              const Rgb& colour);

// One panel of operator iso-curves (`size` x `size` pixels, f1 right from
// 0 to 1, f2 up from 0 to 1) drawn from the direct operator, and how far its
// baked table is from it there.
struct OperatorPanel {
  std::vector<float> values;  // g at the pixel centres, row-major, top first
  // Largest |table - direct| g over the pixels; unset for the union (no
  // table: the max is exact).
  std::optional<double> max_table_error;
  // The operator table cache's trouble, if any (an unusable or unwritable
  // file: the table was baked again); the library prints nothing.
  std::vector<std::string> warnings;
};
OperatorPanel evaluateOperatorPanel(CompositionOperator op, double theta,
                                    int size, int table_resolution);

// Paints panel values: the field palette (fieldColour), iso-curves at 0.1,
// ..., 0.9 in dark grey (1 pixel) and the 0.5 curve in black (2 pixels).
Image renderOperatorPanel(const std::vector<float>& values, int size);

// The skinning transforms of `skeleton` with joint `joint` and everything
// below it rotated by `degrees` about `axis` (model space, through the
// joint's bind position); identity elsewhere.
TransformList bendSkinning(const Skeleton& skeleton, int joint,
                           const Eigen::Vector3f& axis, double degrees);

struct OperatorPlotOptions {
  // Side of every operator panel and bend picture, pixels (64 to 2048).
  int size = 384;
  // Nodes per axis of the operator tables: those compared with the direct
  // operators and those the bend pictures' compositions use (8 to 256).
  int table_resolution = 128;
  // Prefix of the progress and warning lines on stderr.
  std::string label = "operator plots";
};

// An operator panel's table error (OperatorPanel::max_table_error).
struct TableError {
  CompositionOperator op = CompositionOperator::kUnion;
  double theta = 0;
  std::optional<double> max_error;
};

// One bend picture and what it shows.
struct BendResult {
  CompositionOperator op = CompositionOperator::kUnion;
  int degrees = 0;
  std::string file;  // relative to the output folder
  // Measured over the pixels within OperatorPlotsReport::measure_radius of
  // the elbow (measured_pixels of them):
  long measured_pixels = 0;
  long inside_pixels = 0;       // pixels with f >= 0.5
  double inside_fraction = 0;   // inside_pixels / measured_pixels
  long inside_minus_union = 0;  // inside_pixels minus the union's
  double max_from_union = 0;    // largest |f - f_union|
};

struct OperatorPlotsReport {
  std::vector<std::string> files;  // written, relative to the output folder
  std::vector<TableError> table_errors;  // operator-major, theta order
  std::vector<BendResult> bends;         // operator-major, angle order
  int size = 0;                          // pixels of a panel / bend picture
  double window = 0;  // side of the bend pictures, model units
  // The bend results are measured within this distance of the elbow.
  double measure_radius = 0;
  double field_ms = 0;    // building the arm's fields and compositions
  double picture_ms = 0;  // evaluating and writing every picture
};

// Writes every picture into `out_dir` (created when missing), each file
// through a temporary file renamed when complete; progress of the field
// builds and their warnings on stderr. Throws isk::Error(kInvalidArgument)
// for options out of range and isk::Error(kIo) when a file or the folder
// cannot be written.
OperatorPlotsReport writeOperatorPlots(const std::string& out_dir,
                                       const OperatorPlotOptions& options);

// Markdown tables of a report: the table errors (operator, then one column
// per theta) and the bend results (one row per operator and angle).
std::string formatTableErrors(const OperatorPlotsReport& report);
std::string formatBendTable(const OperatorPlotsReport& report);

}  // namespace isk::samples
