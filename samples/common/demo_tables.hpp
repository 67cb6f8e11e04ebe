// The demo's summary: its methods and tolerances, the rows of its tables
// (skinning, pictures, implicit fields), the tables in Markdown, the frame
// counts it samples, summary.md and the exit status. Host only: the rows
// are filled from results, never from a device.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "isk/fields/implicit_fields.hpp"
#include "isk/rig/animation.hpp"
#include "isk/skinning/skinning.hpp"
#include "skin_runner.hpp"

namespace isk::samples::demo {

// OpenCL and reference outputs of LBS and DQS agree to float rounding; this
// bound (relative to the bounding-box diagonal) only flags real
// disagreements.
constexpr double kAgreementTolerance = 1e-4;
// Implicit skinning stops each vertex on threshold tests (converged, contact
// angle) that float rounding can flip between the devices; a flipped stop
// moves a vertex by up to a projection step (at most
// SurfaceTrackingOptions::max_step = 0.02 of the diagonal). This bound, half
// such a step, still flags a real disagreement (a stage missing or wrong on
// one device); PoCL agrees with the reference to ~5e-5.
constexpr double kImplicitAgreementTolerance = 1e-2;

// Largest |OpenCL - reference| field value accepted: both storages
// interpolate in the kernel, so both match to float rounding (GPUs may fuse
// multiply-adds).
constexpr double kFieldTolerance[] = {/*buffer*/ 1e-4, /*image*/ 1e-4};

// Frames per clip by default: the clip sampled uniformly, at most this many
// (30 per second plus one for the 1 s bends of the procedural rigs; fewer
// than 30 per second for longer clips, so the demo stays quick).
constexpr int kDefaultMaxFrames = 31;

// closeup.png looks this far off the bend axis, towards the inside of the
// fold.
constexpr double kCloseUpTiltDegrees = 35;

// The three methods, in the order of the table and of the panels.
struct MethodSpec {
  const char* name;     // table and folder name
  const char* caption;  // panel caption
  bool implicit;
  SkinningMethod method;  // geometric skinning (implicit: its base)
};
constexpr int kMethodCount = 3;
extern const MethodSpec kMethods[kMethodCount];

// `value` printed with the printf `format` ("%.3f").
std::string formatNumber(const char* format, double value);

// The frames of one rig's clip: --frames (`requested` > 0), else the clip
// at 30 per second, at most kDefaultMaxFrames.
struct FramePlan {
  int count = 0;
  int full_count = 0;  // the clip at 30 per second
};
FramePlan planFrames(int requested, const AnimationClip& clip);
// "<rig> N of the M at 30 per second"
std::string describeFramePlan(const std::string& rig, const FramePlan& plan);
// The summary's sentence on the frames per clip, from describeFramePlan's
// texts; `requested` as for planFrames.
std::string formatFrameNote(const std::vector<std::string>& frame_counts,
                            int requested);

// One row of the skinning table: a rig and method on one device.
struct Row {
  std::string rig;
  std::string clip;
  std::string method;
  std::string device;
  int frames = 0;
  double median_ms = 0;
  std::optional<double> reference_ms;  // with an OpenCL device
  std::optional<double> volume_min, volume_max;
  int intersections_max = 0;
  long long intersections_total = 0;
  std::optional<double> contact_median;  // implicit only
  std::optional<double> max_difference;  // with an OpenCL device
};

// The row of `result`, a run of `method` over `clip` on `device`.
Row makeRow(const std::string& rig, const AnimationClip& clip,
            const MethodSpec& method, const std::string& device,
            const RunResult& result);
std::string formatTable(const std::vector<Row>& rows);

// What the pictures of one rig show, for the summary's pictures table.
struct PictureRow {
  std::string rig;
  int frame = 0;
  double time = 0;
  std::string joint = "-";
  double degrees = 0;
  int intersections[kMethodCount] = {};
  int contacts = 0;
  std::vector<std::string> pictures;  // relative to the output folder
};
std::string formatPictureTable(const std::vector<PictureRow>& rows);

// One rig's implicit fields: how they were built, how far the vertices' iso
// values are from the surface's 0.5, how OpenCL agrees with the reference.
struct FieldRow {
  std::string rig;
  int fields = 0;
  int samples_min = 0, samples_max = 0;  // fitted points per field
  double fit_bake_ms = 0;                // the cache read when `cached`
  bool cached = false;                   // fields loaded from the field cache
  double mib = 0;
  double iso_mean = 0, iso_max = 0;  // |iso value - 0.5| over the vertices
  std::string storage = "n/a";       // OpenCL storage, n/a without OpenCL
  std::optional<double> max_difference;
  std::vector<std::string> pictures;  // relative to the output folder
};
// The row of `fields` as built: counts, times, size and iso values (the
// OpenCL columns and the pictures left to the caller).
FieldRow describeFields(const std::string& rig, const ImplicitFields& fields);
std::string formatFieldTable(const std::vector<FieldRow>& rows);

// Everything summary.md and stdout show.
struct Summary {
  std::string out_dir;
  std::string operators_dir;
  std::string frame_note;  // formatFrameNote
  std::vector<Row> rows;
  std::vector<std::string> notes;  // "<rig> skipped: why"
  std::vector<PictureRow> picture_rows;
  std::vector<FieldRow> field_rows;
  std::string table_errors;   // the operator tables' errors
  std::string bend_table;     // the arm's bends with each operator
  double measure_radius = 0;  // of the bend table, model units
};
// The tables as the demo prints them on stdout.
std::string formatStdoutSummary(const Summary& summary);
// summary.md: the tables with what they measure.
std::string formatSummaryMarkdown(const Summary& summary);

// Whether OpenCL agreed with the CPU reference, kind by kind.
struct Agreement {
  bool skinning = true;  // LBS and DQS within kAgreementTolerance
  bool implicit = true;  // within kImplicitAgreementTolerance
  bool fields = true;    // field values within kFieldTolerance
};
// One message per disagreement; the demo fails when there is any.
std::vector<std::string> agreementFailures(const Agreement& agreement);

}  // namespace isk::samples::demo
