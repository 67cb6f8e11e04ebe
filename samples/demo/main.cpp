// isk-demo: skins the procedural "arm" and "cylinder" rigs with LBS and DQS
// on the default OpenCL device and on the CPU reference, writes the OpenCL
// frames under out/<rig>/<method>/ and a summary table (stdout and
// out/summary.md). Needs no input file.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "isk/error.hpp"
#include "isk/export.hpp"
#include "isk/mesh_metrics.hpp"
#include "skin_runner.hpp"

namespace {

namespace fs = std::filesystem;
using isk::samples::FrameSkinner;
using isk::samples::RunResult;

// OpenCL and reference outputs agree to float rounding; this bound (relative
// to the bounding-box diagonal) only flags real disagreements.
constexpr double kAgreementTolerance = 1e-4;

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

int run(const std::string& out_dir, int frames, const std::string& device) {
  const std::vector<std::string> rig_names = {"arm", "cylinder"};
  const std::vector<isk::SkinningMethod> methods = {
      isk::SkinningMethod::kLinearBlend, isk::SkinningMethod::kDualQuaternion};

  std::vector<Row> rows;
  bool all_agree = true;
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
  }

  std::string table = formatTable(rows);
  std::cout << table;
  const std::string summary_path = (fs::path(out_dir) / "summary.md").string();
  isk::writeTextFile(summary_path, "# isk-demo summary\n\nFrames: " + out_dir +
                                       "/<rig>/<method>/frame_XXXX.obj\n\n" +
                                       table);
  std::cerr << "isk-demo: wrote " << summary_path << "\n";
  if (!all_agree) {
    std::cerr << "isk-demo: OpenCL and the CPU reference differ by more than "
              << kAgreementTolerance << " of the bounding-box diagonal\n";
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::string out_dir = "out";
  int frames = 0;
  std::string device = "auto";
  CLI::App app{
      "Skins the builtin arm and cylinder rigs with LBS and DQS on OpenCL and "
      "on the CPU reference; writes frames and a summary table."};
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
