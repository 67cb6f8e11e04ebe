#include "skin_options.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "isk/core/error.hpp"
#include "isk/fields/composition_operator.hpp"
#include "isk/io/rig_params.hpp"
#include "skin_targets.hpp"

namespace isk::samples::skin {

namespace {

// CLI::Range lets NaN through.
CLI::Validator finiteNonNegative() {
  return CLI::Validator(
      [](const std::string& text) -> std::string {
        double value = 0;
        if (!CLI::detail::lexical_cast(text, value) || !std::isfinite(value) ||
            value < 0 || value > 1e9) {
          return "expected a number of at least 0, got '" + text + "'";
        }
        return {};
      },
      "NUMBER >= 0");
}

// INPUT, the clip and frames, the device and the output files.
void addRunOptions(CLI::App& app, Options& options) {
  app.add_option("INPUT", options.input,
                 "asset file (glTF, FBX, COLLADA, .x, ...) or builtin:NAME; "
                 "builtin:list lists the names")
      ->required();
  app.add_option("--clip", options.clip,
                 "clip name or index (default: clip 0; a procedural bend "
                 "when the rig has none); 'rest' for the bind pose, "
                 "'bend[:DEGREES]' for every joint bent to DEGREES (default "
                 "90) on any rig");
  app.add_option("--frames", options.frames,
                 "frames sampled uniformly over the clip (default: 30 per "
                 "second, plus one)")
      ->check(CLI::Range(1, 10000000));
  app.add_option("--frame-range", options.frame_range,
                 "FIRST:LAST: write and measure only these frames (from 0, "
                 "both included) of the clip's --frames; the files keep "
                 "their numbers, so ranges run apart make one sequence");
  app.add_option("--warm-up", options.warm_up,
                 "frames skinned unwritten before --frame-range's FIRST "
                 "(default: every frame from 0 with --tracking history, so "
                 "that the range equals the whole run's frames; none "
                 "otherwise, each frame depending on its pose alone)")
      ->check(CLI::Range(0, 10000000));
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
      ->check(finiteNonNegative())
      ->capture_default_str();
  app.add_option("--import-memory", options.import_memory_mib,
                 "MiB of memory the import may take before it is stopped with "
                 "an error (0: no limit)")
      ->check(finiteNonNegative())
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
  app.add_option("--untracked-joint", options.untracked_joints,
                 "implicit: PATTERN ('*', '?'): the parts of the joints it "
                 "names stay where skinning puts them (thin parts the fields "
                 "cannot hold, e.g. 'wing*'; repeatable)")
      ->allow_extra_args(false);
  app.add_option("--gltf", options.gltf,
                 "animated glTF (.glb) of the frames beside LBS and DQS, "
                 "playable in any glTF viewer");
}

// The composition operators and their controllers.
struct CompositionFlags {
  CLI::Option* op;
  CLI::Option* joint_operator;
  CLI::Option* bulge_strength;
  CLI::Option* blend_theta;
};

CompositionFlags addCompositionOptions(CLI::App& app, Options& options) {
  CompositionFlags flags;
  flags.op =
      app.add_option("--operator", options.default_operator,
                     "composition operator: auto (the union, with the "
                     "gradient-based blend at the joints of mirrored limbs: "
                     "shoulders, elbows, knees...), or union, blend or bulge "
                     "at every joint; builds the implicit fields and reports "
                     "the iso drift")
          ->check(CLI::IsMember({"auto", "union", "blend", "bulge"}))
          ->capture_default_str();
  // One NAME=OP per occurrence, so that a following INPUT is not taken.
  flags.joint_operator =
      app.add_option("--joint-operator", options.joint_operators,
                     "NAME=OP: operator OP at the joint NAME (repeatable; "
                     "split at the last '=')")
          ->allow_extra_args(false);
  flags.bulge_strength =
      app.add_option("--bulge-strength", options.bulge_strength,
                     "bulge strength in [0, 1]")
          ->check(CLI::Range(0.0, 1.0))
          ->capture_default_str();
  flags.blend_theta =
      app.add_option("--blend-theta", options.blend_theta,
                     "theta of the full blend in radians, [0, pi/4] (0: the "
                     "strongest blend)")
          ->check(CLI::Range(0.0, kThetaUnion))
          ->capture_default_str();
  return flags;
}

// The surface tracking of --method implicit.
std::vector<CLI::Option*> addTrackingOptions(CLI::App& app, Options& options) {
  SurfaceTrackingOptions& tracking = options.tracking;
  return {
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
      app.add_option("--crease-steps", tracking.crease_steps,
                     "implicit: tangential Laplacian steps of the vertices "
                     "piled in a crease between parts (0: none)")
          ->check(CLI::Range(0, 1000))
          ->capture_default_str(),
      app.add_flag("!--ungated-creases", tracking.crease_gate,
                   "implicit: spread every crease between parts (by default "
                   "only those whose rings the march crushed or pushed out "
                   "of their skinned layout)"),
      app.add_flag("!--no-dislocation-guard", tracking.dislocation_guard,
                   "implicit: track every vertex (by default the skin "
                   "blended between two joints the skeleton does not link "
                   "stays on skinning when the pose moves them apart)"),
      app.add_flag("!--no-relaxation", tracking.relaxation,
                   "implicit: no tangential relaxation (eq. 5, 6)"),
      app.add_flag("!--paper-relaxation", tracking.skinned_ring_relaxation,
                   "implicit: relax towards the ring's centroid as eq. 5 "
                   "writes it (by default the skinned ring's own in-plane "
                   "offset is taken out of it)"),
      app.add_option("--contact-entry", tracking.contact_entry,
                     "implicit: how far (field units) another part's field "
                     "must exceed a vertex's own before it marches to the "
                     "contact surface")
          ->check(CLI::Range(1e-6, 0.999))
          ->capture_default_str(),
      app.add_option("--contact-home-slack", tracking.contact_home_slack,
                     "implicit: how far (field units) below the vertex's "
                     "part's surface value the other part's field may be "
                     "and the vertex still start the march to a contact "
                     "(1: no such test)")
          ->check(CLI::Range(0.0, 1.0))
          ->capture_default_str(),
      app.add_option("--contact-home-reach", tracking.contact_home_reach,
                     "implicit: how far (field units) below its part's "
                     "surface value the vertex's own part's field may be for "
                     "it to start the march to a contact; further, it stops "
                     "where skinning put it (1: no such test)")
          ->check(CLI::Range(0.0, 1.0))
          ->capture_default_str(),
      app.add_option("--rest-crease-angle", tracking.rest_crease_degrees,
                     "implicit: a vertex lying at rest on the surface of a "
                     "part the skeleton does not link to its own does not "
                     "march to a contact while the two joints have turned by "
                     "less than this (degrees) relative to each other: the "
                     "crease shifts (0: off)")
          ->check(CLI::Range(0.0, 180.0))
          ->capture_default_str(),
      app.add_option("--blend-contact-angle", tracking.blend_contact_degrees,
                     "implicit: the joint angle (degrees) from which the two "
                     "fields of a blend meet in contact")
          ->check(CLI::Range(0.0, 180.0))
          ->capture_default_str(),
      app.add_option("--volume-restore", tracking.volume_restore,
                     "implicit: the largest fraction of a vertex's inward "
                     "move from skinning given back where a closed part "
                     "lost volume, [0, 3] (0: off; above 1 the skin is pushed "
                     "past skinning's surface there, but not near another "
                     "piece of the mesh)")
          ->check(CLI::Range(0.0, 3.0))
          ->capture_default_str(),
      app.add_option("--contact-bulge", tracking.contact_bulge,
                     "implicit: where a closed part misses more volume than "
                     "its inward moves give back, the largest push out of "
                     "the band around its contacts, in mean edge lengths, "
                     "[0, 10] (0: off)")
          ->check(CLI::Range(0.0, 10.0))
          ->capture_default_str(),
      app.add_option("--contact-bulge-radius", tracking.contact_bulge_radius,
                     "implicit: the reach of the contact bulge's band, a "
                     "fraction of the diagonal along the mesh, (0, 1]")
          ->check(CLI::Range(1e-6, 1.0))
          ->capture_default_str(),
      app.add_option("--contact-bulge-steps", tracking.contact_bulge_steps,
                     "implicit: the rings the contact bulge's band grows "
                     "over at most (0: no bulge)")
          ->check(CLI::Range(0, 1000))
          ->capture_default_str(),
      app.add_option("--contact-bulge-clearance",
                     tracking.contact_bulge_clearance,
                     "implicit: how far out the contact bulge probes for "
                     "another part before pushing a vertex, in largest "
                     "pushes, [0, 10] (0: no probe)")
          ->check(CLI::Range(0.0, 10.0))
          ->capture_default_str(),
      app.add_option("--strain-limit", tracking.strain_limit,
                     "implicit: how much two neighbours' offsets from DQS "
                     "may differ, as a fraction of their rest distance")
          ->check(CLI::Range(0.0, 100.0))
          ->capture_default_str(),
      app.add_option("--strain-limit-steps", tracking.strain_limit_steps,
                     "implicit: steps of the strain limit (0: no limit)")
          ->check(CLI::Range(0, 1000))
          ->capture_default_str(),
      app.add_option("--restore-again-steps", tracking.restore_again_steps,
                     "implicit: after the strain limit, the volume "
                     "restoration runs again (the limit takes back part of "
                     "what it pushed out), followed by this many more steps "
                     "of the limit (0: no second restoration)")
          ->check(CLI::Range(0, 1000))
          ->capture_default_str(),
      app.add_flag("!--no-fold-guard", tracking.fold_guard,
                   "implicit: no fold guard (the strain limit is the same "
                   "around triangles that folded over)"),
      app.add_option("--fold-strain-limit", tracking.fold_strain_limit,
                     "implicit: the strain limit on the edges near a triangle "
                     "that folded over (0: their offsets are averaged)")
          ->check(CLI::Range(0.0, 100.0))
          ->capture_default_str(),
      app.add_option("--fold-rings", tracking.fold_rings,
                     "implicit: how many rings around a folded triangle's "
                     "corners take the fold strain limit")
          ->check(CLI::Range(0, 16))
          ->capture_default_str(),
      app.add_option("--fold-check-steps", tracking.fold_check_steps,
                     "implicit: steps of the strain limit between two "
                     "checks for folded triangles")
          ->check(CLI::Range(1, 1000))
          ->capture_default_str(),
      app.add_option("--tilt-guard", tracking.tilt_guard_degrees,
                     "implicit: with the fold guard, the strain limit also "
                     "evens out triangles turned more than this from their "
                     "skinned normal: spikes and crumples (degrees; 0: off)")
          ->check(CLI::Range(0.0, 179.0))
          ->capture_default_str(),
      app.add_option("--tilt-strain-limit", tracking.tilt_strain_limit,
                     "implicit: the strain limit on the edges near a "
                     "triangle the tilt guard finds")
          ->check(CLI::Range(0.0, 100.0))
          ->capture_default_str(),
      app.add_option("--tracking", options.tracking_mode,
                     "implicit: 2013 (each frame marches from dual "
                     "quaternion skinning, the paper) or history (from the "
                     "last frame's result moved by the skinning's motion)")
          ->check(CLI::IsMember({"2013", "history"}))
          ->capture_default_str(),
      app.add_option("--history-reset-angle", options.history_reset_degrees,
                     "implicit, --tracking history: a frame in which a "
                     "joint turned by more than this many degrees since the "
                     "last starts from skinning")
          ->check(CLI::Range(0.0, 180.0))
          ->capture_default_str(),
      app.add_option("--history-keep", tracking.history_keep,
                     "implicit, --tracking history: the share of its offset "
                     "from skinning a vertex at a contact keeps from the last "
                     "frame, [0, 1]")
          ->check(CLI::Range(0.0, 1.0))
          ->capture_default_str(),
      app.add_option("--grid-precision", options.grid_precision,
                     "implicit: float, or half (grids rounded to 16-bit "
                     "floats: half the device memory, frames within a small "
                     "fraction of the mesh's size)")
          ->check(CLI::IsMember({"float", "half"}))
          ->capture_default_str(),
      app.add_option("--rigid-pieces", options.rigid_pieces,
                     "implicit: pieces of the mesh bound wholly to one joint "
                     "(a robot's plates) stay where skinning puts them: "
                     "auto (when they hold half the mesh or more), rigid, "
                     "or tracked (the paper)")
          ->check(CLI::IsMember({"auto", "rigid", "tracked"}))
          ->capture_default_str(),
      app.add_flag("!--no-layers", options.skin_only,
                   "implicit: fit the layers around the skin (clothes, "
                   "found by bone_partition.hpp's rule) with it, instead of "
                   "leaving them out of the fit to follow the skin's field")};
}

// The parameter file of the run: --params, else <INPUT>.isk.json beside a
// file input (said on `log`); empty for none.
std::string paramsFile(const Options& options, std::ostream& log) {
  if (!options.params.empty()) return options.params;
  const std::string beside = paramsFileBeside(options.input);
  if (!beside.empty()) {
    log << "isk-skin: parameters from " << beside
        << " (found next to the asset; --params FILE to choose another)\n";
  }
  return beside;
}

// The command line wins over the file, option by option.
void applyCommandLine(const Options& options, const Skeleton& skeleton,
                      RigParams& params) {
  const CompositionOptions cli = parseCompositionOptions(options);
  if (options.operator_given) {
    params.default_operator = cli.default_operator;
    params.limb_operator = cli.limb_operator;
  }
  if (options.bulge_strength_given) params.bulge_strength = cli.bulge_strength;
  if (options.blend_theta_given) params.blend_theta = cli.blend_theta;
  for (const auto& [name, op] : cli.joint_operators) {
    if (skeleton.find(name) < 0) continue;  // reported by the validation
    params.joints[name].op = op;
  }
  for (const std::string& pattern : options.untracked_joints) {
    bool matched = false;
    for (const Joint& joint : skeleton.joints) {
      if (!jointNameMatches(pattern, joint.name)) continue;
      params.joints[joint.name].tracked = false;
      matched = true;
    }
    if (!matched) {
      std::string known;
      const int shown = std::min(skeleton.jointCount(), 8);
      for (int j = 0; j < shown; ++j)
        known += (j ? ", '" : "'") + skeleton.joints[j].name + "'";
      if (skeleton.jointCount() > shown)
        known +=
            " and " + std::to_string(skeleton.jointCount() - shown) + " more";
      throw Error(ErrorCode::kInvalidArgument,
                  options.input + ": --untracked-joint '" + pattern +
                      "': no joint matches (joints: " + known + ")");
    }
  }
}

// --save-params: checks that what is written reads back (a joint key that
// no longer fits its operator after a command-line change is an error
// here), then writes it.
void saveParams(const Options& options, const Skeleton& skeleton,
                const RigParams& params, std::ostream& log) {
  checkSaveParamsTarget(options);
  parseRigParams(formatRigParams(params), options.save_params, &skeleton);
  createParentFolder(options.save_params);
  saveRigParams(options.save_params, params);
  log << "isk-skin: wrote the parameters to " << options.save_params << "\n";
}

}  // namespace

void addOptions(CLI::App& app, Options& options) {
  addRunOptions(app, options);
  const CompositionFlags composition = addCompositionOptions(app, options);
  const std::vector<CLI::Option*> tracking = addTrackingOptions(app, options);
  app.callback([&options, composition, tracking] {
    for (const CLI::Option* option : tracking)
      options.tracking_given = options.tracking_given || option->count() > 0;
    options.operator_given = composition.op->count() > 0;
    options.bulge_strength_given = composition.bulge_strength->count() > 0;
    options.blend_theta_given = composition.blend_theta->count() > 0;
    options.composition_given =
        options.operator_given || composition.joint_operator->count() > 0 ||
        options.bulge_strength_given || options.blend_theta_given;
  });
}

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

CompositionOptions parseCompositionOptions(const Options& options) {
  CompositionOptions composition;
  if (!parseOperatorChoice(options.default_operator, &composition)) {
    throw Error(ErrorCode::kInvalidArgument,
                "--operator '" + options.default_operator +
                    "': expected auto, union, blend or bulge");
  }
  // CLI11's range checks let NaN through.
  if (!(options.bulge_strength >= 0 && options.bulge_strength <= 1)) {
    throw Error(ErrorCode::kInvalidArgument,
                "--bulge-strength " + std::to_string(options.bulge_strength) +
                    ": expected a value in [0, 1]");
  }
  if (!(options.blend_theta >= 0 && options.blend_theta <= kThetaUnion)) {
    throw Error(ErrorCode::kInvalidArgument,
                "--blend-theta " + std::to_string(options.blend_theta) +
                    ": expected radians in [0, pi/4]");
  }
  composition.bulge_strength = options.bulge_strength;
  composition.blend_theta = options.blend_theta;
  for (const std::string& arg : options.joint_operators) {
    const std::string where = "--joint-operator '" + arg + "': ";
    const size_t equals = arg.rfind('=');
    if (equals == std::string::npos) {
      throw Error(ErrorCode::kInvalidArgument,
                  where + "expected NAME=OP (OP: union, blend or bulge)");
    }
    const std::string name = arg.substr(0, equals);
    const std::string op_name = arg.substr(equals + 1);
    if (name.empty()) {
      throw Error(ErrorCode::kInvalidArgument,
                  where + "the joint name before '=' is empty");
    }
    CompositionOperator op;
    if (!parseCompositionOperator(op_name, &op)) {
      throw Error(ErrorCode::kInvalidArgument,
                  where + "unknown operator '" + op_name +
                      "' (expected union, blend or bulge)");
    }
    // Two different choices for one joint are a mistake, not "last wins".
    const auto [it, inserted] = composition.joint_operators.emplace(name, op);
    if (!inserted && it->second != op) {
      throw Error(ErrorCode::kInvalidArgument,
                  where + "joint '" + name + "' already has operator " +
                      compositionOperatorName(it->second));
    }
  }
  return composition;
}

void checkTrackingOptions(const Options& options) {
  if (const Validation valid = options.tracking.validate(); !valid) {
    throw Error(ErrorCode::kInvalidArgument,
                "surface tracking: " + valid.reason());
  }
}

std::string trackingOptionsWarning(const Options& options) {
  if (!options.tracking_given || options.method == "implicit") return {};
  return "isk-skin: warning: the tracking options have no effect without "
         "--method implicit";
}

std::vector<std::string> unusedControllerWarnings(const Options& options,
                                                  const Composition& built) {
  std::vector<std::string> warnings;
  if (options.bulge_strength_given &&
      !built.uses(CompositionOperator::kBulge)) {
    warnings.push_back(
        "isk-skin: warning: --bulge-strength has no effect: no joint uses "
        "bulge");
  }
  if (options.blend_theta_given && !built.uses(CompositionOperator::kBlend)) {
    warnings.push_back(
        "isk-skin: warning: --blend-theta has no effect: no joint uses "
        "blend");
  }
  return warnings;
}

void checkJointOperators(const Options& options, const Skeleton& skeleton,
                         const CompositionOptions& composition) {
  if (!options.composition_given) return;
  if (const Validation valid =
          validateCompositionOptions(skeleton, composition);
      !valid) {
    throw Error(ErrorCode::kInvalidArgument,
                options.input + ": --joint-operator: " + valid.reason());
  }
}

SkinningMethod skinningMethod(const Options& options) {
  return options.method == "lbs" ? SkinningMethod::kLinearBlend
                                 : SkinningMethod::kDualQuaternion;
}

MeshFormat frameFormat(const Options& options) {
  return options.format == "ply" ? MeshFormat::kPly : MeshFormat::kObj;
}

ImportOptions importOptions(const Options& options) {
  ImportOptions import_options;
  import_options.time_limit_seconds = options.import_timeout;
  import_options.memory_limit_bytes =
      static_cast<uint64_t>(options.import_memory_mib * kMiB);
  return import_options;
}

int frameCount(const Options& options, const AnimationClip& clip) {
  if (options.frames > 0) return options.frames;
  const int frames = defaultFrameCount(clip);
  if (frames > kMaxDefaultFrames) {
    throw Error(ErrorCode::kInvalidArgument,
                options.input + ": clip '" + clip.name + "' lasts " +
                    std::to_string(clip.duration) + " s, " +
                    std::to_string(frames) +
                    " frames at 30 per second; pass --frames N");
  }
  return frames;
}

FrameRange frameRange(const Options& options, int frames) {
  FrameRange range{0, frames - 1, 0};
  if (!options.frame_range.empty()) {
    const std::string& spec = options.frame_range;
    const size_t colon = spec.find(':');
    auto number = [&](const std::string& text, int* value) {
      if (text.empty() || text.size() > 9 ||
          text.find_first_not_of("0123456789") != std::string::npos)
        return false;
      *value = std::stoi(text);
      return true;
    };
    if (colon == std::string::npos ||
        !number(spec.substr(0, colon), &range.first) ||
        !number(spec.substr(colon + 1), &range.last)) {
      throw Error(ErrorCode::kInvalidArgument,
                  "--frame-range '" + spec +
                      "': expected FIRST:LAST, two frame numbers from 0 "
                      "(e.g. 10:19)");
    }
    if (range.first > range.last || range.last >= frames) {
      throw Error(ErrorCode::kInvalidArgument,
                  "--frame-range " + spec + ": the run has " +
                      std::to_string(frames) + " frame" +
                      (frames == 1 ? "" : "s") + " (0 to " +
                      std::to_string(frames - 1) +
                      "); FIRST must be at most LAST and LAST at most " +
                      std::to_string(frames - 1));
    }
  }
  const bool history =
      options.method == "implicit" && options.tracking_mode == "history";
  const int warm_up =
      options.warm_up >= 0 ? options.warm_up : (history ? range.first : 0);
  range.warm_up_from = std::max(0, range.first - warm_up);
  return range;
}

bool jointNameMatches(const std::string& pattern, const std::string& name) {
  // Greedy match with one backtrack point: the last '*' seen.
  size_t p = 0, n = 0, star = std::string::npos, resume = 0;
  while (n < name.size()) {
    if (p < pattern.size() && (pattern[p] == '?' || pattern[p] == name[n])) {
      ++p;
      ++n;
    } else if (p < pattern.size() && pattern[p] == '*') {
      star = p++;
      resume = n;
    } else if (star != std::string::npos) {
      p = star + 1;
      n = ++resume;
    } else {
      return false;
    }
  }
  while (p < pattern.size() && pattern[p] == '*') ++p;
  return p == pattern.size();
}

std::optional<ImplicitFieldsOptions> loadParams(const Options& options,
                                                const Rig& rig,
                                                std::ostream& log) {
  const std::string path = paramsFile(options, log);
  if (path.empty() && options.save_params.empty() &&
      options.untracked_joints.empty())
    return std::nullopt;
  RigParams params;
  if (!path.empty()) {
    params = loadRigParams(path, &rig.skeleton);
    if (!options.params.empty())
      log << "isk-skin: parameters from " << path << "\n";
  }
  applyCommandLine(options, rig.skeleton, params);
  if (!options.save_params.empty())
    saveParams(options, rig.skeleton, params, log);
  ImplicitFieldsOptions field_options;
  applyRigParams(params, &field_options);
  return field_options;
}

bool needsFields(const Options& options,
                 const std::optional<ImplicitFieldsOptions>& params) {
  return options.composition_given || options.method == "implicit" ||
         params.has_value();
}

ImplicitFieldsOptions fieldOptions(
    const Options& options, const CompositionOptions& composition,
    const std::optional<ImplicitFieldsOptions>& params) {
  ImplicitFieldsOptions field_options;
  field_options.composition = composition;
  if (params) field_options = *params;
  if (options.grid_precision == "half")
    field_options.grid_precision = GridPrecision::kHalf;
  if (!options.skin_only) field_options.sampling.skin_only = false;
  parseRigidPieces(options.rigid_pieces, &field_options.rigid_pieces);
  // Fields are cached on disk (ISK_CACHE_DIR; "off" disables it).
  field_options.cache = true;
  return field_options;
}

ImplicitSkinnerOptions implicitOptions(const Options& options,
                                       const ImplicitFieldsOptions& fields) {
  ImplicitSkinnerOptions implicit_options;
  implicit_options.fields = fields;
  implicit_options.tracking = options.tracking;
  implicit_options.base_skinning = SkinningMethod::kDualQuaternion;
  implicit_options.tracking_mode = options.tracking_mode == "history"
                                       ? TrackingMode::kHistory
                                       : TrackingMode::k2013;
  implicit_options.history_reset_degrees = options.history_reset_degrees;
  return implicit_options;
}

}  // namespace isk::samples::skin
