// isk-skin: skins a rig over an animation clip, writes the frames and a JSON
// report of timings and quality. With composition operators chosen
// (--operator, --joint-operator, ...), it also builds the rig's implicit
// fields and measures each frame's iso drift in the composed field. See
// README.md for the options.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "field_pictures.hpp"
#include "isk/cl/field_evaluation.hpp"
#include "isk/fields/composition_operator.hpp"
#include "isk/core/error.hpp"
#include "isk/io/export.hpp"
#include "isk/fields/field_composition.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/io/gltf_export.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/procedural.hpp"
#include "isk/io/rig_params.hpp"
#include "skin_runner.hpp"

namespace {

namespace fs = std::filesystem;
using isk::samples::FrameSkinner;
using isk::samples::RunResult;

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

  // The import runs in a child process that is stopped after this many
  // seconds (0: in this process, no limit) or past this much memory (MiB,
  // 0: none): some corrupt files make Assimp hang.
  double import_timeout = isk::samples::kImportTimeLimitSeconds;
  double import_memory_mib = 0;

  // Composition operators (the implicit fields are built only when one of
  // these options is given: `composition_given`).
  std::string default_operator = "union";
  std::vector<std::string> joint_operators;  // NAME=OP, as given
  double bulge_strength = 1;
  double blend_theta = 0;
  bool composition_given = false;
  bool operator_given = false;
  bool bulge_strength_given = false, blend_theta_given = false;

  // Animated glTF (--gltf): the run's frames beside LBS and DQS.
  std::string gltf;

  // Per-joint parameters (--params, --save-params, <asset>.isk.json).
  std::string params;
  std::string save_params;

  // Surface tracking (--method implicit); defaults are the paper's.
  isk::SurfaceTrackingOptions tracking;
  std::string grid_precision = "float";  // implicit: "float" or "half"
  bool tracking_given = false;
};

constexpr double kMiB = 1024.0 * 1024.0;
// The most frames the default (30 per second of the clip) may ask for: an
// hour of animation.
constexpr int kMaxDefaultFrames = 108001;

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

// Refuses a --report target that would destroy something: an existing file
// (unless --overwrite), a folder, or a frame file's name in --out. Checked
// before any work, so that a refused run writes nothing.
void checkReportTarget(const Options& options) {
  const fs::path report(options.report);
  std::error_code ec;
  if (fs::is_directory(report, ec)) {
    throw isk::Error(isk::ErrorCode::kIo,
                     "--report " + options.report + ": is a folder");
  }
  if (fs::exists(report, ec) && !options.overwrite) {
    throw isk::Error(isk::ErrorCode::kIo,
                     "--report " + options.report +
                         ": the file exists; pass --overwrite to replace it "
                         "or choose another name");
  }
  if (!options.out_dir.empty()) {
    const fs::path parent =
        report.has_parent_path() ? report.parent_path() : fs::path(".");
    const std::string name = report.filename().string();
    const bool frame_name =
        name.rfind("frame_", 0) == 0 &&
        (name.size() > 4 && (name.compare(name.size() - 4, 4, ".obj") == 0 ||
                             name.compare(name.size() - 4, 4, ".ply") == 0));
    if (frame_name && fs::weakly_canonical(parent, ec) ==
                          fs::weakly_canonical(fs::path(options.out_dir), ec)) {
      throw isk::Error(isk::ErrorCode::kInvalidArgument,
                       "--report " + options.report +
                           ": a frame file of --out would replace it");
    }
  }
}

// The operator choices of the command line. Joint names may hold '=', ' ' or
// ':' (mixamorig:LeftForeArm), so NAME=OP splits at the last '='. Throws
// isk::Error(kInvalidArgument) naming the bad argument.
isk::CompositionOptions parseCompositionOptions(const Options& options) {
  isk::CompositionOptions composition;
  if (!isk::parseCompositionOperator(options.default_operator,
                                     &composition.default_operator)) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     "--operator '" + options.default_operator +
                         "': expected union, blend or bulge");
  }
  // CLI11's range checks let NaN through.
  if (!(options.bulge_strength >= 0 && options.bulge_strength <= 1)) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     "--bulge-strength " +
                         std::to_string(options.bulge_strength) +
                         ": expected a value in [0, 1]");
  }
  if (!(options.blend_theta >= 0 && options.blend_theta <= isk::kThetaUnion)) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     "--blend-theta " + std::to_string(options.blend_theta) +
                         ": expected radians in [0, pi/4]");
  }
  composition.bulge_strength = options.bulge_strength;
  composition.blend_theta = options.blend_theta;
  for (const std::string& arg : options.joint_operators) {
    const std::string where = "--joint-operator '" + arg + "': ";
    const size_t equals = arg.rfind('=');
    if (equals == std::string::npos) {
      throw isk::Error(isk::ErrorCode::kInvalidArgument,
                       where + "expected NAME=OP (OP: union, blend or bulge)");
    }
    const std::string name = arg.substr(0, equals);
    const std::string op_name = arg.substr(equals + 1);
    if (name.empty()) {
      throw isk::Error(isk::ErrorCode::kInvalidArgument,
                       where + "the joint name before '=' is empty");
    }
    isk::CompositionOperator op;
    if (!isk::parseCompositionOperator(op_name, &op)) {
      throw isk::Error(isk::ErrorCode::kInvalidArgument,
                       where + "unknown operator '" + op_name +
                           "' (expected union, blend or bulge)");
    }
    // Two different choices for one joint are a mistake, not "last wins".
    const auto [it, inserted] = composition.joint_operators.emplace(name, op);
    if (!inserted && it->second != op) {
      throw isk::Error(isk::ErrorCode::kInvalidArgument,
                       where + "joint '" + name + "' already has operator " +
                           isk::compositionOperatorName(it->second));
    }
  }
  return composition;
}

// A controller option without a joint of its operator changes nothing: say
// so rather than let it pass silently.
void warnUnusedControllers(const Options& options,
                           const isk::CompositionOptions& composition) {
  auto used = [&](isk::CompositionOperator op) {
    if (composition.default_operator == op) return true;
    for (const auto& entry : composition.joint_operators) {
      if (entry.second == op) return true;
    }
    return false;
  };
  if (options.bulge_strength_given && !used(isk::CompositionOperator::kBulge)) {
    std::cerr << "isk-skin: warning: --bulge-strength has no effect: no joint "
                 "uses bulge\n";
  }
  if (options.blend_theta_given && !used(isk::CompositionOperator::kBlend)) {
    std::cerr << "isk-skin: warning: --blend-theta has no effect: no joint "
                 "uses blend\n";
  }
}

// The rig's implicit fields composed with the chosen operators, evaluated at
// the skinned vertices after each frame: each vertex's drift from its iso
// value |f(v) - iso_v| over the vertices with iso_v > 0 (the others lie
// outside every field). This drift is what the implicit method's projection
// corrects, and it depends on the operators.
class IsoDriftProbe {
 public:
  IsoDriftProbe(const isk::Rig& rig,
                std::shared_ptr<const isk::ImplicitFields> fields,
                double build_ms, FrameSkinner& skinner)
      : rig_(rig),
        fields_(*fields),
        keep_(std::move(fields)),
        build_ms_(build_ms) {
    for (int v = 0; v < static_cast<int>(fields_.iso_values.size()); ++v) {
      if (fields_.iso_values[v] > 0) tracked_.push_back(v);
    }
    if (fields_.grids.fieldCount() > 0 && !skinner.isReference()) {
      const auto upload_start = std::chrono::steady_clock::now();
      device_ = std::make_unique<isk::ClFieldEvaluation>(
          skinner.sharedContext(), fields_.grids, rig.skeleton.jointCount(),
          isk::FieldStorage::kAuto, &fields_.composition);
      upload_ms_ = millisecondsSince(upload_start);
      // One untimed run at the bind pose: PoCL compiles the kernel on its
      // first launch, which would otherwise land in the first frame's time.
      device_->evaluate(isk::bindPoseSkinning(rig.skeleton), rig.mesh.positions,
                        values_);
    }
  }

  // Evaluates the composed field at the frame's output `positions` posed by
  // `skinning` (on the device when there is one).
  void measure(const isk::TransformList& skinning,
               const isk::Matrix3Xf& positions) {
    if (fields_.grids.fieldCount() == 0 || tracked_.empty()) return;
    const auto start = std::chrono::steady_clock::now();
    if (device_) {
      device_->evaluate(skinning, positions, values_);
    } else {
      values_ = isk::evaluateComposedField(fields_.grids, skinning, positions,
                                           &fields_.composition);
    }
    field_ms_.push_back(millisecondsSince(start));
    double sum = 0, largest = 0;
    for (const int v : tracked_) {
      const double drift =
          std::abs(double(values_(v, 0)) - double(fields_.iso_values[v]));
      sum += drift;
      largest = std::max(largest, drift);
    }
    drift_mean_.push_back(sum / tracked_.size());
    drift_max_.push_back(largest);
  }

  bool measured() const { return !drift_mean_.empty(); }
  double driftMean() const {
    return isk::samples::summarize(drift_mean_).median;
  }
  double driftMax() const {
    return *std::max_element(drift_max_.begin(), drift_max_.end());
  }
  double fieldMs() const { return isk::samples::summarize(field_ms_).median; }
  std::string describe() const {
    return isk::describeComposition(fields_.composition, rig_.skeleton);
  }

  nlohmann::json report() const {
    const isk::Composition& composition = fields_.composition;
    nlohmann::json operators = nlohmann::json::object();
    for (const int index : composition.blended_pairs) {
      const isk::FieldPair& pair = composition.pairs[index];
      operators[rig_.skeleton.joints[pair.joint].name] =
          isk::compositionOperatorName(pair.op);
    }
    nlohmann::json section;
    section["composition"] = describe();
    section["operators"] = operators;
    section["fields"] = fields_.grids.fieldCount();
    section["grid_precision"] = isk::gridPrecisionName(fields_.grids.precision);
    section["build_ms"] = build_ms_;
    section["upload_ms"] = upload_ms_;
    section["operator_tables_mib"] = composition.tableBytes() / kMiB;
    section["evaluation"] =
        device_ ? std::string("opencl (") +
                      isk::fieldStorageName(device_->storage()) + ")"
                : std::string("reference");
    section["tracked_vertices"] = tracked_.size();
    if (measured()) {
      section["iso_drift"] = {{"mean", driftMean()}, {"max", driftMax()}};
      section["field_ms"] = fieldMs();
    } else {
      section["iso_drift"] = nullptr;
      section["field_ms"] = nullptr;
      section["drift_note"] =
          fields_.grids.fieldCount() == 0
              ? "the rig has no implicit field: nothing to measure"
              : "no vertex lies inside a field's support: nothing to "
                "measure";
    }
    return section;
  }

 private:
  const isk::Rig& rig_;
  const isk::ImplicitFields& fields_;
  std::shared_ptr<const isk::ImplicitFields> keep_;
  std::vector<int> tracked_;  // vertices with iso value > 0
  std::unique_ptr<isk::ClFieldEvaluation> device_;  // null: CPU reference
  isk::Matrix4Xf values_;
  std::vector<double> drift_mean_, drift_max_, field_ms_;
  double build_ms_ = 0, upload_ms_ = 0;
};

// Median of per-frame counts (0 for none).
double medianCount(const std::vector<int>& counts) {
  return isk::samples::summarize(
             std::vector<double>(counts.begin(), counts.end()))
      .median;
}

nlohmann::json makeReport(const Options& options, const isk::Rig& rig,
                          const isk::AnimationClip& clip,
                          const FrameSkinner& skinner, double load_ms,
                          double setup_ms, const RunResult& result,
                          const IsoDriftProbe* probe) {
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
  nlohmann::json stages = nlohmann::json::object();
  for (const auto& [name, ms] : result.stage_median) stages[name] = ms;
  report["stage_ms"] = stages;
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
  if (!result.self_intersections.empty()) {
    const auto& counts = result.self_intersections;
    long long total = 0;
    for (int c : counts) total += c;
    quality["self_intersections"] = {
        {"max", *std::max_element(counts.begin(), counts.end())},
        {"total", total}};
  }
  if (options.method == "implicit") {
    quality["contact_vertices"] = medianCount(result.contact_vertices);
  }
  report["quality"] = quality;
  report["out"] = options.out_dir.empty() ? nlohmann::json(nullptr)
                                          : nlohmann::json(options.out_dir);
  report["format"] = options.format;
  if (probe) report["implicit"] = probe->report();
  if (options.method == "implicit") {
    const isk::SurfaceTrackingOptions& t = options.tracking;
    report["implicit"]["tracking"] = {
        {"base_skinning", "dqs"},
        {"rounds", t.rounds},
        {"projection_steps", t.projection_steps},
        {"sigma", t.sigma},
        {"contact_angle_degrees", t.contact_angle_degrees},
        {"tolerance", t.tolerance},
        {"relaxation", t.relaxation},
        {"home_contact", t.home_contact},
        {"beta_diffusion", t.beta_diffusion},
        {"smoothing_steps", t.smoothing_steps},
        {"crease_steps", t.crease_steps}};
    if (const isk::TrackingMesh* mesh = skinner.trackingMesh()) {
      report["implicit"]["relaxation_weights"] = mesh->relaxation.describe();
    }
  }
  return report;
}

// The parameters of --params FILE.json (or, without it, of
// <INPUT>.isk.json when that file exists: said on stderr) with the command
// line's operator options on top, as field options; written to
// --save-params. Unset when neither a file nor --save-params is in play.
// Throws isk::Error naming the file, the joint and the key.
std::optional<isk::ImplicitFieldsOptions> loadParams(const Options& options,
                                                     const isk::Rig& rig) {
  const bool input_is_file = options.input.rfind("builtin:", 0) != 0;
  std::string path = options.params;
  if (path.empty() && input_is_file) {
    const std::string beside = isk::rigParamsPathFor(options.input);
    std::error_code ec;
    if (fs::is_regular_file(beside, ec)) {
      path = beside;
      std::cerr << "isk-skin: parameters from " << path
                << " (found next to the asset; --params FILE to choose "
                   "another)\n";
    }
  }
  if (path.empty() && options.save_params.empty()) return std::nullopt;
  isk::RigParams params;
  if (!path.empty()) {
    params = isk::loadRigParams(path, &rig.skeleton);
    if (!options.params.empty())
      std::cerr << "isk-skin: parameters from " << path << "\n";
  }
  // The command line wins over the file, option by option.
  const isk::CompositionOptions cli = parseCompositionOptions(options);
  if (options.operator_given) params.default_operator = cli.default_operator;
  if (options.bulge_strength_given) params.bulge_strength = cli.bulge_strength;
  if (options.blend_theta_given) params.blend_theta = cli.blend_theta;
  for (const auto& [name, op] : cli.joint_operators) {
    if (rig.skeleton.find(name) < 0) continue;  // reported by the validation
    params.joints[name].op = op;
  }
  if (!options.save_params.empty()) {
    if (input_is_file && samePath(options.save_params, options.input)) {
      throw isk::Error(
          isk::ErrorCode::kInvalidArgument,
          "--save-params " + options.save_params + " is the input file");
    }
    // Check what is written reads back (a joint key that no longer fits
    // its operator after a command-line change is an error here).
    isk::parseRigParams(isk::formatRigParams(params), options.save_params,
                        &rig.skeleton);
    const fs::path parent = fs::path(options.save_params).parent_path();
    if (!parent.empty()) fs::create_directories(parent);
    isk::saveRigParams(options.save_params, params);
    std::cerr << "isk-skin: wrote the parameters to " << options.save_params
              << "\n";
  }
  isk::ImplicitFieldsOptions field_options;
  isk::applyRigParams(params, &field_options);
  return field_options;
}

// Where the fields came from (isk/fields/field_cache.hpp).
void reportFieldCache(const isk::ImplicitFields& fields) {
  switch (fields.cache_origin) {
    case isk::FieldCacheOrigin::kOff:
      break;
    case isk::FieldCacheOrigin::kLoaded:
      std::cerr << "isk-skin: fields loaded from the cache "
                << fields.cache_file << "\n";
      break;
    case isk::FieldCacheOrigin::kBuilt:
      std::cerr << "isk-skin: fields built and cached in " << fields.cache_file
                << "\n";
      break;
    case isk::FieldCacheOrigin::kRebuilt:
      std::cerr << "isk-skin: fields rebuilt (" << fields.cache_note
                << ") and cached in " << fields.cache_file << "\n";
      break;
  }
}

// --gltf FILE.glb: refuses the input file and a folder as the target.
void checkGltfTarget(const Options& options) {
  const bool input_is_file = options.input.rfind("builtin:", 0) != 0;
  if (input_is_file && samePath(options.gltf, options.input)) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     "--gltf " + options.gltf + " is the input file");
  }
  std::error_code ec;
  if (fs::is_directory(options.gltf, ec)) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     "--gltf " + options.gltf + " is a folder");
  }
}

// Writes the run's frames (`positions`, `normals`) and, beside them, the
// same frames skinned with LBS and DQS (those the run did not already
// produce) to --gltf as an animated .glb (isk/io/gltf_export.hpp): tracks in
// the order lbs, dqs, implicit, 1.2 bounding-box widths apart.
void writeGltf(const Options& options, const isk::Rig& rig,
               const isk::AnimationClip& clip, FrameSkinner& skinner,
               const std::vector<double>& times,
               std::vector<isk::Matrix3Xf> positions,
               std::vector<isk::Matrix3Xf> normals) {
  std::vector<isk::GltfTrack> tracks;
  for (const std::string name : {"lbs", "dqs"}) {
    isk::GltfTrack track;
    track.name = name;
    if (options.method == name) {
      track.positions = std::move(positions);
      track.normals = std::move(normals);
    } else {
      const isk::SkinningMethod method =
          name == std::string("lbs") ? isk::SkinningMethod::kLinearBlend
                                     : isk::SkinningMethod::kDualQuaternion;
      for (const double t : times) {
        isk::Matrix3Xf p, n;
        skinner.skin(method, isk::samples::clipSkinning(rig.skeleton, clip, t),
                     p, n);
        track.positions.push_back(std::move(p));
        track.normals.push_back(std::move(n));
      }
    }
    tracks.push_back(std::move(track));
  }
  if (options.method == "implicit") {
    isk::GltfTrack track;
    track.name = "implicit";
    track.positions = std::move(positions);
    track.normals = std::move(normals);
    tracks.push_back(std::move(track));
  }
  std::vector<isk::Matrix3Xf> all;
  for (const isk::GltfTrack& track : tracks)
    all.insert(all.end(), track.positions.begin(), track.positions.end());
  const float spacing = isk::gltfTrackSpacing(all);
  for (size_t i = 0; i < tracks.size(); ++i)
    tracks[i].offset = {spacing * (i - (tracks.size() - 1) / 2.f), 0, 0};
  const fs::path parent = fs::path(options.gltf).parent_path();
  if (!parent.empty()) fs::create_directories(parent);
  isk::writeAnimatedGltf(options.gltf, rig.mesh.triangles, tracks,
                         isk::gltfFrameTimes(times));
  std::cerr << "isk-skin: wrote " << options.gltf << " (" << times.size()
            << " frames; " << tracks.size() << " meshes side by side:";
  for (const isk::GltfTrack& track : tracks) std::cerr << " " << track.name;
  std::cerr << ")\n";
}

int run(const Options& options) {
  if (options.input == "builtin:list") {
    for (const std::string& name : isk::builtinRigNames()) {
      std::cout << "builtin:" << name << "\n";
    }
    return 0;
  }
  // Operator and tracking choices are checked before anything heavy.
  const isk::CompositionOptions composition = parseCompositionOptions(options);
  if (const isk::Validation valid = options.tracking.validate(); !valid) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     "surface tracking: " + valid.reason());
  }
  if (options.tracking_given && options.method != "implicit") {
    std::cerr << "isk-skin: warning: the tracking options have no effect "
                 "without --method implicit\n";
  }
  // The input is never written: checked before it is even loaded.
  if (!options.gltf.empty()) checkGltfTarget(options);
  const isk::SkinningMethod method = options.method == "lbs"
                                         ? isk::SkinningMethod::kLinearBlend
                                         : isk::SkinningMethod::kDualQuaternion;
  const isk::MeshFormat format =
      options.format == "ply" ? isk::MeshFormat::kPly : isk::MeshFormat::kObj;

  const auto load_start = std::chrono::steady_clock::now();
  isk::ImportOptions import_options;
  import_options.time_limit_seconds = options.import_timeout;
  import_options.memory_limit_bytes =
      static_cast<uint64_t>(options.import_memory_mib * kMiB);
  const isk::Rig rig = isk::samples::loadRig(options.input, import_options);
  const double load_ms = millisecondsSince(load_start);
  for (const std::string& warning : rig.warnings) {
    std::cerr << "warning: " << warning << "\n";
  }
  // The joint names need the rig; the rest was checked above.
  if (options.composition_given) {
    if (const isk::Validation valid =
            isk::validateCompositionOptions(rig.skeleton, composition);
        !valid) {
      throw isk::Error(isk::ErrorCode::kInvalidArgument,
                       options.input + ": --joint-operator: " + valid.reason());
    }
  }
  // Per-joint parameters: --params, else <asset>.isk.json beside the input,
  // with the command line's operator options on top.
  const std::optional<isk::ImplicitFieldsOptions> params_options =
      loadParams(options, rig);
  if (!params_options) warnUnusedControllers(options, composition);

  std::string clip_note;
  const isk::AnimationClip clip =
      isk::samples::selectClip(rig, options.clip, &clip_note);
  if (!clip_note.empty()) std::cerr << "isk-skin: " << clip_note << "\n";
  const int frames = options.frames > 0 ? options.frames
                                        : isk::samples::defaultFrameCount(clip);
  // A clip of absurd length (a corrupt key time) would run for ever at 30
  // frames per second: say so rather than hang.
  if (options.frames == 0 && frames > kMaxDefaultFrames) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     options.input + ": clip '" + clip.name + "' lasts " +
                         std::to_string(clip.duration) + " s, " +
                         std::to_string(frames) +
                         " frames at 30 per second; pass --frames N");
  }

  // The input is never a target: neither the report nor a frame file.
  const bool input_is_file = options.input.rfind("builtin:", 0) != 0;
  if (input_is_file && !options.report.empty() &&
      samePath(options.report, options.input)) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     "--report " + options.report + " is the input file");
  }
  if (!options.report.empty()) checkReportTarget(options);
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

  run_options.implicit = options.method == "implicit";
  run_options.self_intersections = true;

  std::unique_ptr<IsoDriftProbe> probe;
  if (options.composition_given || run_options.implicit || params_options) {
    isk::ImplicitFieldsOptions field_options;
    field_options.composition = composition;
    if (params_options) field_options = *params_options;
    if (options.grid_precision == "half")
      field_options.grid_precision = isk::GridPrecision::kHalf;
    // Fields are cached on disk (ISK_CACHE_DIR; "off" disables it).
    field_options.cache = true;
    const auto build_start = std::chrono::steady_clock::now();
    auto fields = std::make_shared<const isk::ImplicitFields>(
        isk::samples::buildFieldsWithProgress(rig, field_options,
                                              "isk-skin: building fields",
                                              "isk-skin: warning: "));
    const double build_ms = millisecondsSince(build_start);
    reportFieldCache(*fields);
    if (run_options.implicit) {
      isk::ImplicitSkinnerOptions implicit_options;
      implicit_options.fields = field_options;
      implicit_options.tracking = options.tracking;
      implicit_options.base_skinning = isk::SkinningMethod::kDualQuaternion;
      skinner.enableImplicit(rig, fields, implicit_options);
    }
    probe = std::make_unique<IsoDriftProbe>(rig, fields, build_ms, skinner);
    // The frame's pose again (runFrames does not pass it on); the probe
    // runs outside the frame timings.
    run_options.on_frame = [&](int frame, const isk::Matrix3Xf& positions,
                               const isk::Matrix3Xf&) {
      probe->measure(isk::samples::clipSkinning(rig.skeleton, clip,
                                                run_options.times[frame]),
                     positions);
    };
  }
  // For the tests of what a failed run leaves behind: frame N fails as a
  // write would (after the frames before it were written).
  if (const char* fail_at = std::getenv("ISK_SKIN_FAIL_AT_FRAME")) {
    const int at = std::atoi(fail_at);
    run_options.on_frame = [at, inner = run_options.on_frame](
                               int frame, const isk::Matrix3Xf& positions,
                               const isk::Matrix3Xf& normals) {
      if (inner) inner(frame, positions, normals);
      if (frame == at) {
        throw isk::Error(isk::ErrorCode::kIo,
                         "injected failure (ISK_SKIN_FAIL_AT_FRAME=" +
                             std::to_string(at) + ")");
      }
    };
  }
  // --gltf: keep every frame of the run (see writeGltf below).
  std::vector<isk::Matrix3Xf> gltf_positions, gltf_normals;
  if (!options.gltf.empty()) {
    auto previous = run_options.on_frame;
    run_options.on_frame = [&, previous](int frame,
                                         const isk::Matrix3Xf& positions,
                                         const isk::Matrix3Xf& normals) {
      if (previous) previous(frame, positions, normals);
      gltf_positions.push_back(positions);
      gltf_normals.push_back(normals);
    };
  }
  RunResult result;
  try {
    result = isk::samples::runFrames(rig, clip, skinner, run_options);
  } catch (const isk::Error& error) {
    // The report is the mark of a finished run: none for this one.
    throw isk::Error(error.code(),
                     std::string(error.what()) +
                         (options.report.empty()
                              ? std::string()
                              : "; no report written to " + options.report),
                     error.clStatus());
  }
  if (!options.gltf.empty()) {
    writeGltf(options, rig, clip, skinner, run_options.times,
              std::move(gltf_positions), std::move(gltf_normals));
  }

  if (!options.report.empty()) {
    const fs::path parent = fs::path(options.report).parent_path();
    if (!parent.empty()) fs::create_directories(parent);
    const nlohmann::json report = makeReport(
        options, rig, clip, skinner, load_ms, setup_ms, result, probe.get());
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
  if (!result.self_intersections.empty()) {
    std::cerr << "; self-intersections max "
              << *std::max_element(result.self_intersections.begin(),
                                   result.self_intersections.end());
  }
  if (!result.contact_vertices.empty()) {
    std::cerr << "; contact vertices median "
              << medianCount(result.contact_vertices);
  }
  if (!options.out_dir.empty()) {
    std::cerr << "; wrote " << result.files.size() << " files to "
              << options.out_dir;
  }
  std::cerr << "\n";
  if (probe) {
    std::cerr << "isk-skin: implicit fields (" << probe->describe() << "): ";
    if (probe->measured()) {
      std::cerr << "iso drift mean " << probe->driftMean() << ", max "
                << probe->driftMax() << "; field evaluation "
                << probe->fieldMs() << " ms/frame\n";
    } else {
      std::cerr << "no iso drift to measure\n";
    }
  }
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

// CLI::Range lets NaN through.
const CLI::Validator kFiniteNonNegative(
    [](const std::string& text) -> std::string {
      double value = 0;
      if (!CLI::detail::lexical_cast(text, value) || !std::isfinite(value) ||
          value < 0 || value > 1e9) {
        return "expected a number of at least 0, got '" + text + "'";
      }
      return {};
    },
    "NUMBER >= 0");

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
  app.add_option("--import-timeout", options.import_timeout,
                 "seconds the import may take before it is stopped with an "
                 "error (it runs in a child process; 0: no limit, in this "
                 "process)")
      ->check(kFiniteNonNegative)
      ->capture_default_str();
  app.add_option("--import-memory", options.import_memory_mib,
                 "MiB of memory the import may take before it is stopped with "
                 "an error (0: no limit)")
      ->check(kFiniteNonNegative)
      ->capture_default_str();
  app.add_option("--format", options.format, "frame file format: obj or ply")
      ->check(CLI::IsMember({"obj", "ply"}))
      ->capture_default_str();
  app.add_flag("--overwrite", options.overwrite,
               "write into a non-empty --out folder (replacing the frame "
               "files of an earlier run) and replace an existing --report");
  app.add_option("--params", options.params,
                 "per-joint parameters (JSON, see README.md); default: "
                 "INPUT.isk.json when it exists");
  app.add_option("--save-params", options.save_params,
                 "write the effective per-joint parameters (file + command "
                 "line) to this JSON file");
  app.add_option("--gltf", options.gltf,
                 "animated glTF (.glb) of the frames beside LBS and DQS, "
                 "playable in any glTF viewer");
  CLI::Option* const operator_option =
      app.add_option("--operator", options.default_operator,
                     "composition operator at every joint: union, blend or "
                     "bulge; builds the implicit fields and reports the iso "
                     "drift")
          ->check(CLI::IsMember({"union", "blend", "bulge"}))
          ->capture_default_str();
  // One NAME=OP per occurrence, so that a following INPUT is not taken.
  CLI::Option* const joint_operator_option =
      app.add_option("--joint-operator", options.joint_operators,
                     "NAME=OP: operator OP at the joint NAME (repeatable; "
                     "split at the last '=')")
          ->allow_extra_args(false);
  CLI::Option* const bulge_option =
      app.add_option("--bulge-strength", options.bulge_strength,
                     "bulge strength in [0, 1]")
          ->check(CLI::Range(0.0, 1.0))
          ->capture_default_str();
  CLI::Option* const theta_option =
      app.add_option("--blend-theta", options.blend_theta,
                     "theta of the full blend in radians, [0, pi/4] (0: the "
                     "strongest blend)")
          ->check(CLI::Range(0.0, isk::kThetaUnion))
          ->capture_default_str();
  isk::SurfaceTrackingOptions& tracking = options.tracking;
  std::vector<CLI::Option*> tracking_options = {
      app.add_option("--rounds", tracking.rounds,
                     "implicit: rounds of (projection steps, relaxation)")
          ->check(CLI::Range(0, 1000))
          ->capture_default_str(),
      app.add_option("--sigma", tracking.sigma,
                     "implicit: Newton step factor of eq. 4, (0, 1]; larger is "
                     "faster and less accurate (docs/performance.md)")
          ->check(CLI::Range(1e-6, 1.0))
          ->capture_default_str(),
      app.add_option("--contact-angle", tracking.contact_angle_degrees,
                     "implicit: gradient jump in degrees that stops a "
                     "vertex at a contact")
          ->check(CLI::Range(1e-3, 180.0))
          ->capture_default_str(),
      app.add_option("--smoothing-steps", tracking.smoothing_steps,
                     "implicit: Laplacian steps around contacts (eq. 7)")
          ->check(CLI::Range(0, 1000))
          ->capture_default_str(),
      app.add_flag("!--no-relaxation", tracking.relaxation,
                   "implicit: no tangential relaxation (eq. 5, 6)"),
      app.add_option("--grid-precision", options.grid_precision,
                     "implicit: float, or half (grids rounded to 16-bit "
                     "floats: half the device memory, frames within a small "
                     "fraction of the mesh's size)")
          ->check(CLI::IsMember({"float", "half"}))
          ->capture_default_str()};
  CLI11_PARSE(app, argc, argv);
  for (const CLI::Option* option : tracking_options)
    options.tracking_given = options.tracking_given || option->count() > 0;
  options.operator_given = operator_option->count() > 0;
  options.bulge_strength_given = bulge_option->count() > 0;
  options.blend_theta_given = theta_option->count() > 0;
  options.composition_given =
      operator_option->count() > 0 || joint_operator_option->count() > 0 ||
      options.bulge_strength_given || options.blend_theta_given;

  try {
    return run(options);
  } catch (const isk::Error& error) {
    std::cerr << "isk-skin: error: " << error.what() << "\n";
  } catch (const std::exception& error) {
    std::cerr << "isk-skin: error: " << error.what() << "\n";
  }
  return 1;
}
