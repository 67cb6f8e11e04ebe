// isk-skin: skins a rig over an animation clip, writes the frames and a JSON
// report of timings and quality. With composition operators chosen
// (--operator, --joint-operator, ...), it also builds the rig's implicit
// fields and measures each frame's iso drift in the composed field. See
// README.md for the options. The options and their checks, the refused
// targets and the report are in samples/common/skin_options, skin_targets
// and skin_report.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "field_pictures.hpp"
#include "isk/cl/field_evaluation.hpp"
#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"
#include "isk/fields/field_composition.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/io/export.hpp"
#include "isk/io/gltf_export.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/procedural.hpp"
#include "skin_options.hpp"
#include "skin_report.hpp"
#include "skin_runner.hpp"
#include "skin_targets.hpp"

namespace {

namespace skin = isk::samples::skin;
using isk::samples::FrameSkinner;
using isk::samples::RunResult;
using skin::Options;

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
      upload_ms_ = isk::millisecondsSince(upload_start);
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
    field_ms_.push_back(isk::millisecondsSince(start));
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

  // What was measured so far.
  skin::IsoDrift drift() const {
    skin::IsoDrift drift;
    drift.build_ms = build_ms_;
    drift.upload_ms = upload_ms_;
    if (device_) {
      drift.evaluation = std::string("opencl (") +
                         isk::fieldStorageName(device_->storage()) + ")";
    }
    drift.tracked_vertices = tracked_.size();
    if (!drift_mean_.empty()) {
      drift.mean = isk::samples::summarize(drift_mean_).median;
      drift.max = *std::max_element(drift_max_.begin(), drift_max_.end());
      drift.field_ms = isk::samples::summarize(field_ms_).median;
    }
    return drift;
  }
  std::string describe() const {
    return isk::describeComposition(fields_.composition, rig_.skeleton);
  }
  nlohmann::json report() const {
    return skin::implicitFieldsSection(fields_, rig_.skeleton, drift());
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

// One track of the --gltf file: `method`'s frames at `times`, skinned again.
isk::GltfTrack skinTrack(const char* name, isk::SkinningMethod method,
                         const isk::Rig& rig, const isk::AnimationClip& clip,
                         FrameSkinner& skinner,
                         const std::vector<double>& times) {
  isk::GltfTrack track;
  track.name = name;
  for (const double t : times) {
    isk::Matrix3Xf p, n;
    skinner.skin(method, isk::samples::clipSkinning(rig.skeleton, clip, t), p,
                 n);
    track.positions.push_back(std::move(p));
    track.normals.push_back(std::move(n));
  }
  return track;
}

// The run's frames (`positions`, `normals`) as a track named `name`.
isk::GltfTrack runTrack(const char* name, std::vector<isk::Matrix3Xf> positions,
                        std::vector<isk::Matrix3Xf> normals) {
  isk::GltfTrack track;
  track.name = name;
  track.positions = std::move(positions);
  track.normals = std::move(normals);
  return track;
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
  for (const char* name : {"lbs", "dqs"}) {
    if (options.method == name) {
      tracks.push_back(
          runTrack(name, std::move(positions), std::move(normals)));
    } else {
      const isk::SkinningMethod method =
          name == std::string("lbs") ? isk::SkinningMethod::kLinearBlend
                                     : isk::SkinningMethod::kDualQuaternion;
      tracks.push_back(skinTrack(name, method, rig, clip, skinner, times));
    }
  }
  if (options.method == "implicit") {
    tracks.push_back(
        runTrack("implicit", std::move(positions), std::move(normals)));
  }
  isk::samples::placeSideBySide(tracks);
  skin::createParentFolder(options.gltf);
  isk::writeAnimatedGltf(options.gltf, rig.mesh.triangles, tracks,
                         isk::gltfFrameTimes(times));
  std::cerr << "isk-skin: wrote " << options.gltf << " (" << times.size()
            << " frames; " << tracks.size() << " meshes side by side:";
  for (const isk::GltfTrack& track : tracks) std::cerr << " " << track.name;
  std::cerr << ")\n";
}

// Checks everything the command line decides before the rig is loaded:
// the operators, the tracking and the --gltf target (the input is never
// written: checked before it is even loaded). Returns the operators.
isk::CompositionOptions checkBeforeLoading(const Options& options) {
  const isk::CompositionOptions composition =
      skin::parseCompositionOptions(options);
  skin::checkTrackingOptions(options);
  if (const std::string warning = skin::trackingOptionsWarning(options);
      !warning.empty()) {
    std::cerr << warning << "\n";
  }
  if (!options.gltf.empty()) skin::checkGltfTarget(options);
  return composition;
}

// The rig of INPUT, its warnings said; `load_ms` is the time it took.
isk::Rig loadInputRig(const Options& options, double& load_ms) {
  const auto load_start = std::chrono::steady_clock::now();
  isk::Rig rig =
      isk::samples::loadRig(options.input, skin::importOptions(options));
  load_ms = isk::millisecondsSince(load_start);
  for (const std::string& warning : rig.warnings) {
    std::cerr << "warning: " << warning << "\n";
  }
  return rig;
}

// The clip of --clip, its note said.
isk::AnimationClip chooseClip(const Options& options, const isk::Rig& rig) {
  std::string clip_note;
  isk::AnimationClip clip =
      isk::samples::selectClip(rig, options.clip, &clip_note);
  if (!clip_note.empty()) std::cerr << "isk-skin: " << clip_note << "\n";
  return clip;
}

// Refuses the targets that would destroy something and readies --out:
// checked before any work, so that a refused run writes nothing.
void prepareTargets(const Options& options) {
  if (!options.report.empty()) skin::checkReportTarget(options);
  if (!options.out_dir.empty()) {
    isk::samples::prepareOutputFolder(
        options.out_dir, options.overwrite,
        isk::samples::isBuiltinInput(options.input) ? "" : options.input);
  }
}

isk::samples::RunOptions frameLoopOptions(const Options& options,
                                          const isk::AnimationClip& clip,
                                          int frames,
                                          const skin::FrameRange& range) {
  isk::samples::RunOptions run_options;
  run_options.method = skin::skinningMethod(options);
  const std::vector<double> times = isk::samples::frameTimes(clip, frames);
  run_options.times.assign(times.begin() + range.first,
                           times.begin() + range.last + 1);
  run_options.warm_up_times.assign(times.begin() + range.warm_up_from,
                                   times.begin() + range.first);
  run_options.first_frame = range.first;
  run_options.out_dir = options.out_dir;
  run_options.format = skin::frameFormat(options);
  run_options.progress = frames > 5;
  run_options.implicit = options.method == "implicit";
  run_options.quality = true;
  return run_options;
}

// Builds the rig's fields (and warns about the controller options no joint of
// the built composition uses, unless a parameter file set them), gives them
// to the skinner for --method implicit and measures the iso drift after each
// frame (outside the frame timings).
std::unique_ptr<IsoDriftProbe> addImplicitFields(
    const Options& options, const isk::Rig& rig, const isk::AnimationClip& clip,
    const isk::ImplicitFieldsOptions& field_options, bool from_params,
    FrameSkinner& skinner, isk::samples::RunOptions& run_options) {
  const auto build_start = std::chrono::steady_clock::now();
  auto fields = std::make_shared<const isk::ImplicitFields>(
      isk::samples::buildFieldsWithProgress(rig, field_options,
                                            "isk-skin: building fields",
                                            "isk-skin: warning: "));
  const double build_ms = isk::millisecondsSince(build_start);
  reportFieldCache(*fields);
  // A parameter file checks its own controllers against its operators.
  if (!from_params) {
    for (const std::string& warning :
         skin::unusedControllerWarnings(options, fields->composition)) {
      std::cerr << warning << "\n";
    }
  }
  if (run_options.implicit) {
    skinner.enableImplicit(rig, fields,
                           skin::implicitOptions(options, field_options));
  }
  auto probe = std::make_unique<IsoDriftProbe>(rig, fields, build_ms, skinner);
  // The frame's pose again (runFrames does not pass it on).
  run_options.on_frame = [&rig, &clip, &run_options, probe = probe.get()](
                             int frame, const isk::Matrix3Xf& positions,
                             const isk::Matrix3Xf&) {
    probe->measure(isk::samples::clipSkinning(rig.skeleton, clip,
                                              run_options.times[frame]),
                   positions);
  };
  return probe;
}

// For the tests of what a failed run leaves behind: with
// ISK_SKIN_FAIL_AT_FRAME=N, frame N fails as a write would (after the
// frames before it were written).
void injectFailureForTests(isk::samples::RunOptions& run_options) {
  const char* fail_at = std::getenv("ISK_SKIN_FAIL_AT_FRAME");
  if (!fail_at) return;
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

// Every frame of the run, kept for --gltf.
struct KeptFrames {
  std::vector<isk::Matrix3Xf> positions, normals;
};

void keepFrames(KeptFrames& kept, isk::samples::RunOptions& run_options) {
  run_options.on_frame = [&kept, previous = run_options.on_frame](
                             int frame, const isk::Matrix3Xf& positions,
                             const isk::Matrix3Xf& normals) {
    if (previous) previous(frame, positions, normals);
    kept.positions.push_back(positions);
    kept.normals.push_back(normals);
  };
}

// runFrames; a failed run's error also says that no report was written.
RunResult runFramesOrSayNoReport(const Options& options, const isk::Rig& rig,
                                 const isk::AnimationClip& clip,
                                 FrameSkinner& skinner,
                                 const isk::samples::RunOptions& run_options) {
  try {
    return isk::samples::runFrames(rig, clip, skinner, run_options);
  } catch (const isk::Error& error) {
    // The report is the mark of a finished run: none for this one.
    throw isk::Error(error.code(),
                     std::string(error.what()) +
                         (options.report.empty()
                              ? std::string()
                              : "; no report written to " + options.report),
                     error.clStatus());
  }
}

void writeReport(const Options& options, const isk::Rig& rig,
                 const isk::AnimationClip& clip, const FrameSkinner& skinner,
                 const skin::PrecomputeTimes& precompute,
                 const RunResult& result, const IsoDriftProbe* probe) {
  skin::createParentFolder(options.report);
  const std::optional<nlohmann::json> implicit_fields =
      probe ? std::optional<nlohmann::json>(probe->report()) : std::nullopt;
  const nlohmann::json report = skin::makeReport(
      options, rig, clip.name, {skinner.deviceInfo(), skinner.trackingMesh()},
      precompute, result, implicit_fields ? &*implicit_fields : nullptr);
  isk::writeTextFile(options.report, report.dump(2) + "\n");
}

// Prints the names of the procedural rigs, one "builtin:NAME" a line.
int listBuiltinRigs() {
  for (const std::string& name : isk::builtinRigNames()) {
    std::cout << "builtin:" << name << "\n";
  }
  return 0;
}

// The per-joint parameters of the run (skin::loadParams), once the joint
// names of the command line are checked against the rig.
std::optional<isk::ImplicitFieldsOptions> parametersOf(
    const Options& options, const isk::Rig& rig,
    const isk::CompositionOptions& composition) {
  skin::checkJointOperators(options, rig.skeleton, composition);
  return skin::loadParams(options, rig, std::cerr);
}

// The skinner of --device; `setup_ms` is the time its build and upload took.
std::unique_ptr<FrameSkinner> makeSkinner(const Options& options,
                                          const isk::Rig& rig,
                                          double& setup_ms) {
  const auto setup_start = std::chrono::steady_clock::now();
  auto skinner = std::make_unique<FrameSkinner>(rig, options.device);
  setup_ms = isk::millisecondsSince(setup_start);
  return skinner;
}

// The summary lines of the run on stderr.
void sayHowItWent(const Options& options, const isk::Rig& rig,
                  const isk::AnimationClip& clip, const FrameSkinner& skinner,
                  const RunResult& result, const IsoDriftProbe* probe) {
  std::cerr << skin::formatRunSummary(options, clip.name, skinner.describe(),
                                      result);
  if (options.method == "implicit") {
    std::cerr << skin::formatPartsSummary(result, rig.skeleton);
    std::cerr << skin::formatPairPartsSummary(result, rig.skeleton);
  }
  if (probe) {
    std::cerr << skin::formatIsoDriftSummary(probe->describe(), probe->drift());
  }
}

int run(const Options& options) {
  if (options.input == "builtin:list") return listBuiltinRigs();
  const isk::CompositionOptions composition = checkBeforeLoading(options);
  skin::PrecomputeTimes precompute;
  const isk::Rig rig = loadInputRig(options, precompute.load_ms);
  const std::optional<isk::ImplicitFieldsOptions> params =
      parametersOf(options, rig, composition);
  const isk::AnimationClip clip = chooseClip(options, rig);
  const int frames = skin::frameCount(options, clip);
  const skin::FrameRange range = skin::frameRange(options, frames);
  prepareTargets(options);
  const std::unique_ptr<FrameSkinner> skinner =
      makeSkinner(options, rig, precompute.setup_ms);

  isk::samples::RunOptions run_options =
      frameLoopOptions(options, clip, frames, range);
  std::unique_ptr<IsoDriftProbe> probe;
  if (skin::needsFields(options, params)) {
    probe = addImplicitFields(options, rig, clip,
                              skin::fieldOptions(options, composition, params),
                              params.has_value(), *skinner, run_options);
  }
  injectFailureForTests(run_options);
  KeptFrames kept;
  if (!options.gltf.empty()) keepFrames(kept, run_options);
  const RunResult result =
      runFramesOrSayNoReport(options, rig, clip, *skinner, run_options);
  if (!options.gltf.empty()) {
    writeGltf(options, rig, clip, *skinner, run_options.times,
              std::move(kept.positions), std::move(kept.normals));
  }
  if (!options.report.empty()) {
    writeReport(options, rig, clip, *skinner, precompute, result, probe.get());
  }
  sayHowItWent(options, rig, clip, *skinner, result, probe.get());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  CLI::App app{
      "Skins a rig (asset file or builtin:NAME) over an animation clip on an "
      "OpenCL device or the CPU reference; writes frames and a JSON report."};
  skin::addOptions(app, options);
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
