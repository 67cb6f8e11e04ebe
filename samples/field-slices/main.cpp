// isk-field-slices: pictures of a rig's implicit fields in a plane along
// its skeleton, like Figures 2f and 3c of Vaillant et al. 2013: the composed
// field (composed.png) and every bone's field (field_<joint>.png), inside
// (f > 0.5) in red, outside in blue, the 0.5 iso line in black, the mesh's
// section in green and the joints in yellow; index.md lists the files, the
// plane and the fields' statistics. See README.md.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "field_pictures.hpp"
#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/io/export.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/procedural.hpp"
#include "skin_runner.hpp"

namespace {

namespace fs = std::filesystem;
using isk::samples::SliceEvaluator;
using isk::samples::SlicePlane;
using isk::samples::SliceStats;
using isk::samples::SliceView;

constexpr const char* kProgram = "isk-field-slices";

struct Options {
  std::string rig = "arm";
  std::string out_dir = "out/field-slices";
  int size = 512;
  int grid = 32;
  std::string field = "baked";
  std::string pose = "bind";
  std::string clip;
};

std::string joinNames(const std::vector<std::string>& names) {
  std::string text;
  for (const std::string& n : names) text += (text.empty() ? "" : ", ") + n;
  return text;
}

// A builtin name ("arm" or "builtin:arm") builds a procedural rig; anything
// else must be an existing file.
isk::Rig loadInput(const std::string& input) {
  const std::vector<std::string> builtins = isk::builtinRigNames();
  if (std::find(builtins.begin(), builtins.end(), input) != builtins.end()) {
    return isk::makeBuiltinRig(input);
  }
  if (isk::samples::isBuiltinInput(input)) return isk::samples::loadRig(input);
  std::error_code ec;
  if (!fs::exists(input, ec)) {
    throw isk::Error(isk::ErrorCode::kIo,
                     "no such file '" + input + "', and no builtin rig of " +
                         "that name (builtin rigs: " + joinNames(builtins) +
                         ")");
  }
  if (fs::is_directory(input, ec)) {
    throw isk::Error(isk::ErrorCode::kIo,
                     "'" + input + "' is a folder, not a rig file");
  }
  return isk::samples::loadRig(input, isk::samples::guardedImportOptions());
}

// "bind", or a time in seconds from the start of the clip.
struct PoseChoice {
  bool bind = true;
  double seconds = 0;
};

PoseChoice parsePose(const std::string& text) {
  PoseChoice choice;
  if (text.empty() || text == "bind") return choice;
  char* end = nullptr;
  const double seconds = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0' || !std::isfinite(seconds) ||
      seconds < 0) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     "--pose: expected 'bind' or a time in seconds (>= 0), "
                     "got '" +
                         text + "'");
  }
  choice.bind = false;
  choice.seconds = seconds;
  return choice;
}

// File-name-safe form of a joint name: letters, digits, '-', '_' and '.'.
std::string safeName(const std::string& name) {
  std::string out;
  for (char c : name) {
    const bool keep = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                      (c >= '0' && c <= '9') || c == '-' || c == '_' ||
                      c == '.';
    out += keep ? c : '_';
  }
  if (out.empty() || out.find_first_not_of('.') == std::string::npos) {
    out = "joint";
  }
  return out;
}

// How far two evaluations of one picture are apart.
struct Agreement {
  float max_difference = 0;  // largest |a - b| over the pixels
  double iso_flips = 0;      // fraction of pixels inside in one, not other
};

Agreement compare(const std::vector<float>& a, const std::vector<float>& b) {
  Agreement g;
  size_t flips = 0;
  for (size_t p = 0; p < a.size(); ++p) {
    g.max_difference = std::max(g.max_difference, std::abs(a[p] - b[p]));
    flips += (a[p] > 0.5f) != (b[p] > 0.5f);
  }
  g.iso_flips = a.empty() ? 0 : static_cast<double>(flips) / a.size();
  return g;
}

std::string formatVector(const Eigen::Vector3d& v) {
  std::ostringstream out;
  out << std::setprecision(4) << "(" << v.x() << ", " << v.y() << ", " << v.z()
      << ")";
  return out.str();
}

std::string percent(double fraction) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(1) << 100.0 * fraction << "%";
  return out.str();
}

std::string fixed(double value, int digits = 3) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(digits) << value;
  return out.str();
}

// One written picture, for the summary and index.md.
struct Picture {
  std::string file;
  std::string what;  // "composed (union of 3 fields)" / "field of 'elbow'"
  std::string joint;
  SliceStats stats;
  Agreement agreement;
};

int run(const Options& options) {
  const PoseChoice pose = parsePose(options.pose);

  const auto load_start = std::chrono::steady_clock::now();
  const isk::Rig rig = loadInput(options.rig);
  const double load_ms = isk::millisecondsSince(load_start);
  for (const std::string& warning : rig.warnings) {
    std::cerr << "warning: " << warning << "\n";
  }
  const isk::Skeleton& skeleton = rig.skeleton;

  // The pose: identity skinning at the bind pose, else the clip's.
  isk::TransformList skinning = isk::bindPoseSkinning(skeleton);
  std::string pose_text = "bind pose";
  if (!pose.bind) {
    std::string note;
    const isk::AnimationClip clip =
        isk::samples::selectClip(rig, options.clip, &note);
    if (!note.empty()) std::cerr << kProgram << ": " << note << "\n";
    if (pose.seconds > clip.duration + 1e-9) {
      std::ostringstream message;
      message << "--pose " << options.pose << ": past the end of clip '"
              << clip.name << "' (" << clip.duration << " s long)";
      throw isk::Error(isk::ErrorCode::kInvalidArgument, message.str());
    }
    skinning =
        isk::samples::clipSkinning(skeleton, clip, clip.start + pose.seconds);
    std::ostringstream text;
    text << "clip '" << clip.name << "' at " << pose.seconds
         << " s (mesh section: dual quaternion skinning)";
    pose_text = text.str();
  } else if (!options.clip.empty()) {
    std::cerr << kProgram << ": --clip is ignored at the bind pose (give "
              << "--pose SECONDS)\n";
  }

  // The fields, with progress on stderr: one update per stage and tenth.
  isk::ImplicitFieldsOptions build_options;
  build_options.grid_resolution = options.grid;
  const isk::ImplicitFields fields = isk::samples::buildFieldsWithProgress(
      rig, build_options, "building fields", "warning: ");
  const int field_count = fields.grids.fieldCount();
  if (field_count == 0) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     rig.source + ": no bone got a field (see the warnings)");
  }

  // The mesh in the pose (geometric skinning; identity at the bind pose)
  // and the plane along the posed joints.
  const isk::Matrix3Xf positions =
      pose.bind ? rig.mesh.positions
                : isk::samples::dqsPositions(rig, skinning);
  const SliceView view =
      isk::samples::makeSliceView(rig, skinning, positions, options.size);
  const SlicePlane& plane = view.plane;

  const bool analytic = options.field == "analytic";
  SliceEvaluator evaluator(fields, skinning, plane);

  std::error_code ec;
  const fs::path out_dir(options.out_dir);
  if (fs::exists(out_dir, ec) && !fs::is_directory(out_dir, ec)) {
    throw isk::Error(isk::ErrorCode::kIo,
                     "--out " + options.out_dir + " is a file, not a folder");
  }
  fs::create_directories(out_dir, ec);
  if (ec) {
    throw isk::Error(isk::ErrorCode::kIo,
                     "--out " + options.out_dir +
                         ": cannot create the folder: " + ec.message());
  }

  std::vector<Picture> pictures;
  auto emit = [&](Picture picture, const std::vector<float>& values) {
    picture.stats = isk::samples::writeSlicePicture(
        (out_dir / picture.file).string(), values, view);
    std::cout << kProgram << ": wrote " << (out_dir / picture.file).string()
              << " (" << plane.width << "x" << plane.height << ", "
              << picture.what << "): f in [" << fixed(picture.stats.min) << ", "
              << fixed(picture.stats.max) << "], inside "
              << percent(picture.stats.inside) << ", support "
              << percent(picture.stats.support) << "\n";
    pictures.push_back(std::move(picture));
  };

  Picture composed;
  composed.file = "composed.png";
  composed.what =
      "composed field of " + std::to_string(field_count) + " fields (" +
      isk::describeComposition(fields.composition, rig.skeleton) + ")";
  {
    const std::vector<float> baked = evaluator.baked(SliceEvaluator::kComposed);
    const std::vector<float> exact =
        evaluator.analytic(SliceEvaluator::kComposed);
    composed.agreement = compare(baked, exact);
    emit(composed, analytic ? exact : baked);
  }

  std::set<std::string> used = {"composed"};
  for (int i = 0; i < field_count; ++i) {
    const int joint = fields.grids.grids[i].joint;
    const std::string name = skeleton.joints[joint].name;
    std::string stem = "field_" + safeName(name);
    if (used.count(stem)) stem += "_" + std::to_string(joint);
    used.insert(stem);
    Picture picture;
    picture.file = stem + ".png";
    picture.joint = name;
    picture.what = "field of joint '" + name + "'";
    const std::vector<float> baked = evaluator.baked(i);
    const std::vector<float> exact = evaluator.analytic(i);
    picture.agreement = compare(baked, exact);
    emit(picture, analytic ? exact : baked);
  }

  // index.md
  std::ostringstream md;
  md << "# Implicit field slices: " << rig.source << "\n\n"
     << "Written by `isk-field-slices`: the fields of Vaillant et al. 2013 "
        "(section 4) in a plane along the skeleton, as in the paper's "
        "Figures 2f and 3c.\n\n"
     << "- rig: `" << rig.source << "`: " << rig.mesh.vertexCount()
     << " vertices, " << rig.mesh.triangleCount() << " triangles, "
     << skeleton.jointCount() << " joints, " << field_count << " fields\n"
     << "- pose: " << pose_text << "\n"
     << "- picture drawn from: "
     << (analytic ? "the analytic fields (HRBF through t_r)"
                  : "the baked grids (trilinear)")
     << "; grids " << options.grid << "^3 per field, "
     << fixed(fields.grids.bytes() / (1024.0 * 1024.0), 2) << " MiB\n"
     << "- composition: "
     << isk::describeComposition(fields.composition, rig.skeleton) << "\n"
     << "- plane: through " << formatVector(plane.origin) << " (centroid of "
     << view.joints.size() << " joints), spanned by " << plane.how << "\n"
     << "  - u (image right) = " << formatVector(plane.u) << "\n"
     << "  - v (image up) = " << formatVector(plane.v) << "\n"
     << "  - normal = " << formatVector(plane.normal) << "\n"
     << "- image: " << plane.width << " x " << plane.height << " pixels, "
     << std::setprecision(4) << plane.pixel << " model units per pixel, u in ["
     << plane.u_min << ", " << plane.u_max << "], v in [" << plane.v_min << ", "
     << plane.v_max << "] (mesh bounding box projected, plus 10% "
     << "margin)\n"
     << "- colours: white f = 0 (outside the support), pale to deep blue "
        "0 < f < 0.5, light to dark red 0.5 < f <= 1 (inside), black: the "
        "0.5 iso line, darker bands: iso lines every 0.1, green: the mesh's "
        "section by the plane, yellow dots: joints projected on the plane\n"
     << "- timings: load " << fixed(load_ms, 1) << " ms, fields "
     << fixed(fields.times.total(), 1) << " ms (partition "
     << fixed(fields.times.partition_ms, 1) << ", sampling "
     << fixed(fields.times.sampling_ms, 1) << ", fitting "
     << fixed(fields.times.fitting_ms, 1) << ", baking "
     << fixed(fields.times.baking_ms, 1) << ", iso values "
     << fixed(fields.times.iso_ms, 1) << "), slice evaluation baked "
     << fixed(evaluator.bakedMs(), 1) << " ms, analytic "
     << fixed(evaluator.analyticMs(), 1) << " ms\n\n";
  md << "| file | picture | f min | f max | inside (f > 0.5) | support "
        "(f > 0) | max abs(baked - analytic) | pixels inside in one only |\n"
     << "|---|---|---|---|---|---|---|---|\n";
  for (const Picture& p : pictures) {
    md << "| [" << p.file << "](" << p.file << ") | " << p.what << " | "
       << fixed(p.stats.min) << " | " << fixed(p.stats.max) << " | "
       << percent(p.stats.inside) << " | " << percent(p.stats.support) << " | "
       << fixed(p.agreement.max_difference) << " | "
       << percent(p.agreement.iso_flips) << " |\n";
  }
  if (!fields.warnings.empty()) {
    md << "\n## Warnings of the field build\n\n";
    for (const std::string& w : fields.warnings) md << "- " << w << "\n";
  }
  const std::string index = (out_dir / "index.md").string();
  isk::writeTextFile(index, md.str());
  std::cout << kProgram << ": wrote " << index << " (" << pictures.size()
            << " pictures, " << field_count << " fields of " << rig.source
            << ")\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  CLI::App app{
      "Writes PNG slices of a rig's implicit fields (composed and per bone) "
      "in a plane along its skeleton, like Figures 2f and 3c of Vaillant et "
      "al. 2013, with an index.md."};
  app.add_option("--rig", options.rig,
                 "builtin rig (cylinder, finger, arm, sleeved-arm, leg; also "
                 "builtin:NAME) or "
                 "an asset file (glTF, FBX, COLLADA, .x, ...)")
      ->capture_default_str();
  app.add_option("--out", options.out_dir, "output folder")
      ->capture_default_str();
  app.add_option("--size", options.size, "longest image side, in pixels")
      ->check(CLI::Range(16, 4096))
      ->capture_default_str();
  app.add_option("--grid", options.grid,
                 "baked grid resolution (nodes per axis)")
      ->check(CLI::Range(2, 256))
      ->capture_default_str();
  app.add_option("--field", options.field,
                 "what draws the pictures: baked (the grids) or analytic")
      ->check(CLI::IsMember({"baked", "analytic"}))
      ->capture_default_str();
  app.add_option("--pose", options.pose,
                 "bind, or a time in seconds from the start of the clip")
      ->capture_default_str();
  app.add_option("--clip", options.clip,
                 "clip name or index for --pose (default: clip 0; a "
                 "procedural bend when the rig has none)");
  CLI11_PARSE(app, argc, argv);

  try {
    return run(options);
  } catch (const std::exception& error) {
    std::cerr << kProgram << ": error: " << error.what() << "\n";
  }
  return 1;
}
