// isk-skin: skins a rig over an animation clip, writes the frames and a JSON
// report of timings and quality. See README.md for the options.
#include <CLI/CLI.hpp>
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "isk/error.hpp"
#include "isk/export.hpp"
#include "isk/procedural.hpp"
#include "skin_runner.hpp"

namespace {

namespace fs = std::filesystem;
using isk::samples::FrameSkinner;
using isk::samples::RunResult;

constexpr int kNotImplementedExit = 2;

struct Options {
  std::string input;
  std::string clip;
  int frames = 0;  // 0: 30 per second of the clip
  std::string method = "dqs";
  std::string device = "auto";
  std::string out_dir;
  std::string report;
  std::string format = "obj";
  bool overwrite = false;
};

double millisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now() - start)
      .count();
}

bool samePath(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  const bool same = fs::equivalent(a, b, ec);
  return !ec && same;
}

nlohmann::json makeReport(const Options& options, const isk::Rig& rig,
                          const isk::AnimationClip& clip,
                          const FrameSkinner& skinner, double load_ms,
                          double setup_ms, const RunResult& result) {
  nlohmann::json report;
  report["input"] = options.input;
  report["vertices"] = rig.mesh.vertexCount();
  report["triangles"] = rig.mesh.triangleCount();
  report["joints"] = rig.skeleton.jointCount();
  report["skin_joints"] = rig.skeleton.skinJointCount();
  report["frames"] = result.frames;
  report["method"] = options.method;
  report["clip"] = clip.name;
  if (const isk::ClDeviceInfo* info = skinner.deviceInfo()) {
    report["device"] = {{"platform", info->platform},
                        {"name", info->name},
                        {"version", info->version}};
  } else {
    report["device"] = "reference";
  }
  report["precompute_ms"] = load_ms + setup_ms;
  report["precompute_breakdown_ms"] = {{"load", load_ms},
                                       {"build_upload", setup_ms}};
  report["frame_ms"] = {{"median", result.frame.median},
                        {"p95", result.frame.p95},
                        {"min", result.frame.min}};
  report["stage_ms"] = {{"skinning", result.stage_median.skinning_ms},
                        {"normals", result.stage_median.normals_ms},
                        {"upload", result.stage_median.upload_ms},
                        {"readback", result.stage_median.readback_ms}};
  nlohmann::json quality;
  if (result.volume_ratio_min) {
    quality["volume_ratio"] = {{"min", *result.volume_ratio_min},
                               {"max", *result.volume_ratio_max}};
  } else {
    quality["volume_ratio"] = nullptr;
    quality["volume_note"] =
        "the rest pose encloses about no volume (open or flat mesh): no "
        "ratio";
  }
  quality["rest_volume"] = result.rest_volume;
  quality["rest_pose_error"] = result.rest_pose_error;
  report["quality"] = quality;
  report["out"] = options.out_dir.empty() ? nlohmann::json(nullptr)
                                          : nlohmann::json(options.out_dir);
  report["format"] = options.format;
  return report;
}

int run(const Options& options) {
  if (options.input == "builtin:list") {
    for (const std::string& name : isk::builtinRigNames()) {
      std::cout << "builtin:" << name << "\n";
    }
    return 0;
  }
  if (options.method == "implicit") {
    std::cerr << "isk-skin: --method implicit is not implemented yet\n";
    return kNotImplementedExit;
  }
  const isk::SkinningMethod method = options.method == "lbs"
                                         ? isk::SkinningMethod::kLinearBlend
                                         : isk::SkinningMethod::kDualQuaternion;
  const isk::MeshFormat format =
      options.format == "ply" ? isk::MeshFormat::kPly : isk::MeshFormat::kObj;

  const auto load_start = std::chrono::steady_clock::now();
  const isk::Rig rig = isk::samples::loadRig(options.input);
  const double load_ms = millisecondsSince(load_start);
  for (const std::string& warning : rig.warnings) {
    std::cerr << "warning: " << warning << "\n";
  }

  std::string clip_note;
  const isk::AnimationClip clip =
      isk::samples::selectClip(rig, options.clip, &clip_note);
  if (!clip_note.empty()) std::cerr << "isk-skin: " << clip_note << "\n";
  const int frames = options.frames > 0 ? options.frames
                                        : isk::samples::defaultFrameCount(clip);

  // The input is never a target: neither the report nor a frame file.
  const bool input_is_file = options.input.rfind("builtin:", 0) != 0;
  if (input_is_file && !options.report.empty() &&
      samePath(options.report, options.input)) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     "--report " + options.report + " is the input file");
  }
  if (!options.out_dir.empty()) {
    isk::samples::prepareOutputFolder(options.out_dir, options.overwrite,
                                      input_is_file ? options.input : "");
  }

  const auto setup_start = std::chrono::steady_clock::now();
  FrameSkinner skinner(rig, options.device);
  const double setup_ms = millisecondsSince(setup_start);

  isk::samples::RunOptions run_options;
  run_options.method = method;
  run_options.times = isk::samples::frameTimes(clip, frames);
  run_options.out_dir = options.out_dir;
  run_options.format = format;
  run_options.progress = frames > 5;
  const RunResult result =
      isk::samples::runFrames(rig, clip, skinner, run_options);

  if (!options.report.empty()) {
    const fs::path parent = fs::path(options.report).parent_path();
    if (!parent.empty()) fs::create_directories(parent);
    const nlohmann::json report =
        makeReport(options, rig, clip, skinner, load_ms, setup_ms, result);
    isk::writeTextFile(options.report, report.dump(2) + "\n");
  }

  std::cerr << std::setprecision(4) << "isk-skin: " << result.frames << " frame"
            << (result.frames == 1 ? "" : "s") << " of clip '" << clip.name
            << "' (" << options.method << " on " << skinner.describe()
            << "): median " << result.frame.median << " ms/frame, p95 "
            << result.frame.p95 << " ms; volume ratio ";
  if (result.volume_ratio_min) {
    std::cerr << *result.volume_ratio_min << " to " << *result.volume_ratio_max;
  } else {
    std::cerr << "n/a";
  }
  std::cerr << "; rest-pose error " << result.rest_pose_error;
  if (!options.out_dir.empty()) {
    std::cerr << "; wrote " << result.files.size() << " files to "
              << options.out_dir;
  }
  std::cerr << "\n";
  return 0;
}

// Accepts auto, reference, gpu, cpu and opencl:N (N a device index).
std::string checkDevice(const std::string& value) {
  if (value == "auto" || value == "reference" || value == "gpu" ||
      value == "cpu") {
    return {};
  }
  const std::string prefix = "opencl:";
  if (value.rfind(prefix, 0) == 0 && value.size() > prefix.size() &&
      value.find_first_not_of("0123456789", prefix.size()) ==
          std::string::npos) {
    return {};
  }
  return "expected auto, reference or opencl:N, got '" + value + "'";
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  CLI::App app{
      "Skins a rig (asset file or builtin:NAME) over an animation clip on an "
      "OpenCL device or the CPU reference; writes frames and a JSON report."};
  app.add_option("INPUT", options.input,
                 "asset file (glTF, FBX, COLLADA, .x, ...) or builtin:NAME; "
                 "builtin:list lists the names")
      ->required();
  app.add_option("--clip", options.clip,
                 "clip name or index (default: clip 0; a procedural bend "
                 "when the rig has none)");
  app.add_option("--frames", options.frames,
                 "frames sampled uniformly over the clip (default: 30 per "
                 "second, plus one)")
      ->check(CLI::Range(1, 10000000));
  app.add_option("--method", options.method, "lbs, dqs or implicit")
      ->check(CLI::IsMember({"lbs", "dqs", "implicit"}))
      ->capture_default_str();
  app.add_option("--device", options.device,
                 "auto (default OpenCL device; ISK_DEVICE overrides), "
                 "reference (CPU) or opencl:N")
      ->check(CLI::Validator(checkDevice, "DEVICE"))
      ->capture_default_str();
  app.add_option("--out", options.out_dir,
                 "folder for frame_0000.obj, frame_0001.obj, ...");
  app.add_option("--report", options.report, "JSON report file");
  app.add_option("--format", options.format, "frame file format: obj or ply")
      ->check(CLI::IsMember({"obj", "ply"}))
      ->capture_default_str();
  app.add_flag("--overwrite", options.overwrite,
               "replace the frame files of an earlier run in --out");
  CLI11_PARSE(app, argc, argv);

  try {
    return run(options);
  } catch (const isk::Error& error) {
    std::cerr << "isk-skin: error: " << error.what() << "\n";
  } catch (const std::exception& error) {
    std::cerr << "isk-skin: error: " << error.what() << "\n";
  }
  return 1;
}
