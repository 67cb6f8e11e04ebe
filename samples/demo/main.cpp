// isk-demo: skins the procedural "arm" and "cylinder" rigs with LBS and DQS
// on the default OpenCL device and on the CPU reference, writes the OpenCL
// frames under out/<rig>/<method>/ and a summary table (stdout and
// out/summary.md). Then builds each rig's implicit fields, evaluates them at
// the skinned vertices on the OpenCL device and on the CPU reference (bind
// pose and the clip's middle frame), draws the composed field at both poses
// (out/<rig>/fields/composed.png, composed_bent.png) and adds a second table
// on the fields. Last, draws the composition operators (out/operators/, as
// isk-operator-plots does: iso-curves in the (f1, f2) plane and the arm bent
// at the elbow, Figure 5(c)) and adds their tables. Needs no input file.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "field_pictures.hpp"
#include "isk/cl/field_evaluation.hpp"
#include "isk/error.hpp"
#include "isk/export.hpp"
#include "isk/field_evaluation.hpp"
#include "isk/implicit_fields.hpp"
#include "isk/mesh_metrics.hpp"
#include "isk/pose.hpp"
#include "operator_plots.hpp"
#include "skin_runner.hpp"

namespace {

namespace fs = std::filesystem;
using isk::samples::FrameSkinner;
using isk::samples::RunResult;

// OpenCL and reference outputs agree to float rounding; this bound (relative
// to the bounding-box diagonal) only flags real disagreements.
constexpr double kAgreementTolerance = 1e-4;

// Largest |OpenCL - reference| field value accepted: the buffer path matches
// to float rounding, the image path to the device's texture filtering (GPUs
// interpolate with 8-bit weights).
constexpr double kFieldTolerance[] = {/*buffer*/ 1e-4, /*image*/ 1e-2};

// Longer side of the field pictures, in pixels.
constexpr int kPictureSize = 512;
// Side of each operator panel and bend picture: smaller than
// isk-operator-plots' default to keep the demo quick.
constexpr int kOperatorPictureSize = 256;

struct Row {
  std::string rig;
  std::string method;
  std::string device;
  int frames = 0;
  double median_ms = 0;
  std::optional<double> volume_min, volume_max;
  std::optional<double> max_difference;  // OpenCL rows only
};

std::string formatNumber(const char* format, double value) {
  char text[64];
  std::snprintf(text, sizeof(text), format, value);
  return text;
}

std::string formatTable(const std::vector<Row>& rows) {
  std::ostringstream out;
  out << "| rig | method | device | frames | ms/frame (median) | volume ratio "
         "min | volume ratio max | max abs(opencl - reference) / diagonal |\n"
      << "|---|---|---|---:|---:|---:|---:|---:|\n";
  for (const Row& row : rows) {
    out << "| " << row.rig << " | " << row.method << " | " << row.device
        << " | " << row.frames << " | " << formatNumber("%.3f", row.median_ms)
        << " | "
        << (row.volume_min ? formatNumber("%.4f", *row.volume_min) : "n/a")
        << " | "
        << (row.volume_max ? formatNumber("%.4f", *row.volume_max) : "n/a")
        << " | "
        << (row.max_difference ? formatNumber("%.2e", *row.max_difference)
                               : "-")
        << " |\n";
  }
  return out.str();
}

Row makeRow(const std::string& rig, const std::string& method,
            const std::string& device, const RunResult& result) {
  Row row;
  row.rig = rig;
  row.method = method;
  row.device = device;
  row.frames = result.frames;
  row.median_ms = result.frame.median;
  row.volume_min = result.volume_ratio_min;
  row.volume_max = result.volume_ratio_max;
  return row;
}

// One rig's implicit fields: how they were built, how far the vertices' iso
// values are from the surface's 0.5, how OpenCL agrees with the reference.
struct FieldRow {
  std::string rig;
  int fields = 0;
  int samples_min = 0, samples_max = 0;  // fitted points per field
  double fit_bake_ms = 0;
  double mib = 0;
  double iso_mean = 0, iso_max = 0;  // |iso value - 0.5| over the vertices
  std::string storage = "n/a";       // OpenCL storage, n/a without OpenCL
  std::optional<double> max_difference;
  std::vector<std::string> pictures;  // relative to the output folder
};

std::string formatFieldTable(const std::vector<FieldRow>& rows) {
  std::ostringstream out;
  out << "| rig | fields | samples per field | fit+bake ms | field MiB | "
         "mean abs(iso - 0.5) | max abs(iso - 0.5) | OpenCL storage | max "
         "abs(opencl - reference) field value | pictures |\n"
      << "|---|---:|---:|---:|---:|---:|---:|---|---:|---|\n";
  for (const FieldRow& row : rows) {
    std::string pictures;
    for (const std::string& p : row.pictures) {
      pictures += (pictures.empty() ? "" : ", ") + p;
    }
    out << "| " << row.rig << " | " << row.fields << " | " << row.samples_min
        << "-" << row.samples_max << " | "
        << formatNumber("%.1f", row.fit_bake_ms) << " | "
        << formatNumber("%.2f", row.mib) << " | "
        << formatNumber("%.4f", row.iso_mean) << " | "
        << formatNumber("%.4f", row.iso_max) << " | " << row.storage << " | "
        << (row.max_difference ? formatNumber("%.2e", *row.max_difference)
                               : "-")
        << " | " << pictures << " |\n";
  }
  return out.str();
}

// Builds the fields of `rig`, compares OpenCL (when `context` is set) with
// the reference at the skinned vertices of the bind pose and of the clip at
// `bent_time`, and draws both poses under out_dir/<rig>/fields/.
FieldRow runFields(const std::string& rig_name, const isk::Rig& rig,
                   const isk::AnimationClip& clip, double bent_time,
                   const std::shared_ptr<isk::ClContext>& context,
                   const std::string& out_dir) {
  const std::string prefix = "isk-demo: " + rig_name + ": ";
  const isk::ImplicitFields fields = isk::samples::buildFieldsWithProgress(
      rig, {}, prefix + "building fields", prefix + "warning: ");

  FieldRow row;
  row.rig = rig_name;
  row.fields = fields.grids.fieldCount();
  for (size_t i = 0; i < fields.samples.size(); ++i) {
    const int count =
        fields.samples[i].surface.size() + fields.samples[i].closure.size();
    row.samples_min = i == 0 ? count : std::min(row.samples_min, count);
    row.samples_max = i == 0 ? count : std::max(row.samples_max, count);
  }
  row.fit_bake_ms = fields.times.fitting_ms + fields.times.baking_ms;
  row.mib = fields.grids.bytes() / (1024.0 * 1024.0);
  for (const float iso : fields.iso_values) {
    const double off = std::abs(iso - 0.5);
    row.iso_mean += off;
    row.iso_max = std::max(row.iso_max, off);
  }
  if (!fields.iso_values.empty()) row.iso_mean /= fields.iso_values.size();

  // Bind pose: the rest mesh; bent: the clip's middle frame, skinned with
  // DQS like the pictures of isk-field-slices.
  const isk::TransformList bind = isk::bindPoseSkinning(rig.skeleton);
  const isk::TransformList bent =
      isk::samples::clipSkinning(rig.skeleton, clip, bent_time);
  const isk::Matrix3Xf bent_positions = isk::samples::dqsPositions(rig, bent);
  struct Pose {
    const char* picture;
    const isk::TransformList& skinning;
    const isk::Matrix3Xf& positions;
  };
  const Pose poses[] = {{"composed.png", bind, rig.mesh.positions},
                        {"composed_bent.png", bent, bent_positions}};

  std::unique_ptr<isk::ClFieldEvaluation> evaluation;
  if (context && row.fields > 0) {
    evaluation = std::make_unique<isk::ClFieldEvaluation>(
        context, fields.grids, rig.skeleton.jointCount(),
        isk::FieldStorage::kAuto, &fields.composition);
    row.storage = isk::fieldStorageName(evaluation->storage());
    row.max_difference = 0.0;
  }
  const fs::path fields_dir = fs::path(out_dir) / rig_name / "fields";
  fs::create_directories(fields_dir);
  for (const Pose& pose : poses) {
    if (evaluation) {
      const isk::Matrix4Xf reference = isk::evaluateComposedField(
          fields.grids, pose.skinning, pose.positions, &fields.composition);
      isk::Matrix4Xf opencl;
      evaluation->evaluate(pose.skinning, pose.positions, opencl);
      row.max_difference = std::max<double>(
          *row.max_difference,
          (opencl.col(0) - reference.col(0)).cwiseAbs().maxCoeff());
    }
    if (row.fields > 0) {
      isk::samples::writeComposedPicture((fields_dir / pose.picture).string(),
                                         rig, fields, pose.skinning,
                                         pose.positions, kPictureSize);
      row.pictures.push_back(
          (fs::path(rig_name) / "fields" / pose.picture).string());
    }
  }
  std::cerr << prefix << row.fields << " fields, pictures in "
            << fields_dir.string() << "\n";
  return row;
}

int run(const std::string& out_dir, int frames, const std::string& device) {
  const std::vector<std::string> rig_names = {"arm", "cylinder"};
  const std::vector<isk::SkinningMethod> methods = {
      isk::SkinningMethod::kLinearBlend, isk::SkinningMethod::kDualQuaternion};

  std::vector<Row> rows;
  std::vector<FieldRow> field_rows;
  bool all_agree = true;
  bool fields_agree = true;
  // One OpenCL context for the field evaluations, made with the first rig
  // that has an OpenCL device.
  std::shared_ptr<isk::ClContext> field_context;
  for (const std::string& rig_name : rig_names) {
    const isk::Rig rig = isk::samples::loadRig("builtin:" + rig_name);
    const isk::AnimationClip clip = isk::samples::selectClip(rig, "", nullptr);
    const std::vector<double> times = isk::samples::frameTimes(
        clip, frames > 0 ? frames : isk::samples::defaultFrameCount(clip));
    const double diagonal = rig.boundingBoxDiagonal();

    FrameSkinner reference(rig, "reference");
    std::unique_ptr<FrameSkinner> opencl;
    try {
      opencl = std::make_unique<FrameSkinner>(rig, device);
    } catch (const isk::Error& error) {
      if (error.code() != isk::ErrorCode::kNoDevice) throw;
      std::cerr << "isk-demo: no OpenCL device (" << error.what()
                << "); writing the CPU reference frames only\n";
    }
    std::cerr << "isk-demo: " << rig_name << " (" << rig.mesh.vertexCount()
              << " vertices, " << times.size() << " frames of clip '"
              << clip.name << "')\n";

    for (const isk::SkinningMethod method : methods) {
      const std::string method_name = isk::skinningMethodName(method);
      const std::string frames_dir =
          (fs::path(out_dir) / rig_name / method_name).string();
      isk::samples::prepareOutputFolder(frames_dir, /*overwrite=*/true, "");

      // The reference keeps its frames so the OpenCL run can be compared
      // with them frame by frame.
      std::vector<isk::Matrix3Xf> reference_frames;
      isk::samples::RunOptions options;
      options.method = method;
      options.times = times;
      options.on_frame = [&](int, const isk::Matrix3Xf& positions,
                             const isk::Matrix3Xf&) {
        reference_frames.push_back(positions);
      };
      if (!opencl) options.out_dir = frames_dir;
      const RunResult reference_result =
          isk::samples::runFrames(rig, clip, reference, options);
      rows.push_back(
          makeRow(rig_name, method_name, "reference (CPU)", reference_result));
      if (!opencl) continue;

      double max_difference = 0;
      options.out_dir = frames_dir;
      options.on_frame = [&](int frame, const isk::Matrix3Xf& positions,
                             const isk::Matrix3Xf&) {
        const double distance =
            isk::maxVertexDistance(positions, reference_frames[frame]);
        max_difference = std::max(max_difference, distance / diagonal);
      };
      const RunResult opencl_result =
          isk::samples::runFrames(rig, clip, *opencl, options);
      Row row =
          makeRow(rig_name, method_name, opencl->describe(), opencl_result);
      row.max_difference = max_difference;
      rows.push_back(row);
      if (!(max_difference <= kAgreementTolerance)) all_agree = false;
    }

    if (opencl && !opencl->isReference() && !field_context) {
      field_context = isk::ClContext::create(device == "auto" ? "" : device);
    }
    // The clip's middle frame: the bent pose of the second picture.
    const double bent_time = times[times.size() / 2];
    field_rows.push_back(runFields(rig_name, rig, clip, bent_time,
                                   opencl ? field_context : nullptr, out_dir));
    const FieldRow& field_row = field_rows.back();
    if (field_row.max_difference &&
        !(*field_row.max_difference <=
          kFieldTolerance[field_row.storage == "image"])) {
      fields_agree = false;
    }
  }

  // The composition operators' pictures, as isk-operator-plots draws them.
  const std::string operators_dir = (fs::path(out_dir) / "operators").string();
  isk::samples::OperatorPlotOptions operator_options;
  operator_options.size = kOperatorPictureSize;
  operator_options.label = "isk-demo: operators";
  const isk::samples::OperatorPlotsReport operator_report =
      isk::samples::writeOperatorPlots(operators_dir, operator_options);
  std::cerr << "isk-demo: " << operator_report.files.size()
            << " operator pictures in " << operators_dir << "\n";
  const std::string table_errors =
      isk::samples::formatTableErrors(operator_report);
  const std::string bend_table = isk::samples::formatBendTable(operator_report);

  std::string table = formatTable(rows);
  const std::string field_table = formatFieldTable(field_rows);
  std::cout << table << "\n"
            << field_table << "\n"
            << table_errors << "\n"
            << bend_table;
  const std::string summary_path = (fs::path(out_dir) / "summary.md").string();
  isk::writeTextFile(
      summary_path,
      "# isk-demo summary\n\nFrames: " + out_dir +
          "/<rig>/<method>/frame_XXXX.obj\n\n" + table +
          "\n## Implicit fields\n\nOne field per bone (HRBF fit, baked "
          "32^3), evaluated at the skinned vertices (DQS) of the bind pose "
          "and of the clip's middle frame on OpenCL and on the CPU "
          "reference. Pictures (relative to " +
          out_dir +
          "): the composed field at the bind pose (composed.png) and at the "
          "middle frame (composed_bent.png), inside red, outside blue, the "
          "0.5 iso black, the mesh section green.\n\n" +
          field_table + "\n## Composition operators\n\nPictures in " +
          operators_dir +
          " (see samples/operator-plots/README.md): operator_union.png, "
          "operator_blend.png, operator_bulge.png, each operator's "
          "iso-curves over the (f1, f2) unit square for theta = 0, pi/16, "
          "pi/8, 3pi/16 and pi/4 (left to right). Largest abs(table - "
          "direct) operator value over each panel:\n\n" +
          table_errors +
          "\nbend_<op>_<deg>.png and bend_grid.png (the paper's Figure "
          "5(c)): the arm's composed field around its elbow bent by 0, 45, "
          "90 and 135 degrees with each operator at every joint; areas "
          "within " +
          formatNumber("%.1f", operator_report.measure_radius) +
          " model units of the elbow, compared with the union's:\n\n" +
          bend_table);
  std::cerr << "isk-demo: wrote " << summary_path << "\n";
  int status = 0;
  if (!all_agree) {
    std::cerr << "isk-demo: OpenCL and the CPU reference differ by more than "
              << kAgreementTolerance << " of the bounding-box diagonal\n";
    status = 1;
  }
  if (!fields_agree) {
    std::cerr << "isk-demo: OpenCL and CPU reference field values differ by "
                 "more than "
              << kFieldTolerance[0] << " (buffer) or " << kFieldTolerance[1]
              << " (image)\n";
    status = 1;
  }
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  std::string out_dir = "out";
  int frames = 0;
  std::string device = "auto";
  CLI::App app{
      "Skins the builtin arm and cylinder rigs with LBS and DQS on OpenCL and "
      "on the CPU reference, builds and evaluates their implicit fields; "
      "writes frames, field pictures and a summary with two tables."};
  app.add_option("--out", out_dir, "output folder")->capture_default_str();
  app.add_option("--frames", frames,
                 "frames per clip (default: 30 per second of the clip)")
      ->check(CLI::Range(1, 100000));
  app.add_option("--device", device,
                 "OpenCL device: auto, gpu, cpu or opencl:N")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  try {
    return run(out_dir, frames, device);
  } catch (const std::exception& error) {
    std::cerr << "isk-demo: error: " << error.what() << "\n";
  }
  return 1;
}
