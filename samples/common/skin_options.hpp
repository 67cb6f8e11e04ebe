// isk-skin's command line: its options (CLI11), the checks made before any
// work, and what the options choose (method, frame count, field options,
// per-joint parameters). Host only: nothing here needs an OpenCL device.
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "isk/fields/field_composition.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/io/export.hpp"
#include "isk/io/import.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/rig.hpp"
#include "isk/skinning/skinning.hpp"
#include "isk/tracking/surface_tracking.hpp"
#include "skin_runner.hpp"

namespace isk::samples::skin {

struct Options {
  std::string input;
  std::string clip;
  int frames = 0;  // 0: 30 per second of the clip
  // --frame-range FIRST:LAST of those frames (empty: all) and --warm-up
  // (-1: every frame before FIRST with --tracking history, none otherwise).
  std::string frame_range;
  int warm_up = -1;
  std::string method = "dqs";
  std::string device = "auto";
  std::string out_dir;
  std::string report;
  std::string format = "obj";
  bool overwrite = false;

  // The import runs in a child process that is stopped after this many
  // seconds (0: in this process, no limit) or past this much memory (MiB,
  // 0: none): some corrupt files make Assimp hang.
  double import_timeout = kImportTimeLimitSeconds;
  double import_memory_mib = 0;

  // Composition operators (the implicit fields are built only when one of
  // these options is given: `composition_given`).
  std::string default_operator = "auto";
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
  // --untracked-joint: joint name patterns ('*', '?') whose parts stay on
  // skinning, as given.
  std::vector<std::string> untracked_joints;

  // Surface tracking (--method implicit); defaults are the paper's.
  SurfaceTrackingOptions tracking;
  // implicit, --tracking: "2013" or "history" (TrackingMode), and
  // --history-reset-angle.
  std::string tracking_mode = "2013";
  float history_reset_degrees = 30.f;
  std::string grid_precision = "float";  // implicit: "float" or "half"
  // implicit, --rigid-pieces: "auto", "rigid" or "tracked" (RigidPieces).
  std::string rigid_pieces = "auto";
  bool skin_only = true;  // implicit: layers left out of the fit (--no-layers)
  bool tracking_given = false;
};

constexpr double kMiB = 1024.0 * 1024.0;
// The most frames the default (30 per second of the clip) may ask for: an
// hour of animation.
constexpr int kMaxDefaultFrames = 108001;

// Declares isk-skin's options on `app`, read into `options`; once
// app.parse() has succeeded, the *_given fields say which groups of options
// the command line held.
void addOptions(CLI::App& app, Options& options);

// --device: empty for auto, reference, gpu, cpu and opencl:N (N a device
// index), else why the value is refused.
std::string checkDevice(const std::string& value);

// The operator choices of the command line. Joint names may hold '=', ' ' or
// ':' (mixamorig:LeftForeArm), so NAME=OP splits at the last '='. Throws
// isk::Error(kInvalidArgument) naming the bad argument.
CompositionOptions parseCompositionOptions(const Options& options);

// Throws isk::Error(kInvalidArgument) for tracking options out of range.
void checkTrackingOptions(const Options& options);
// The warning for tracking options given without --method implicit (which
// ignores them); empty when there is nothing to say.
std::string trackingOptionsWarning(const Options& options);

// A controller option without a joint of its operator changes nothing: one
// warning per such option, to be said rather than passed over in silence.
// `built` is the composition of the rig's fields (buildComposition), so that
// the auto choice counts only the limb joints the rig has.
std::vector<std::string> unusedControllerWarnings(const Options& options,
                                                  const Composition& built);

// The joint names of --joint-operator against the rig's skeleton (only when
// operators were given). Throws isk::Error(kInvalidArgument) naming the input.
void checkJointOperators(const Options& options, const Skeleton& skeleton,
                         const CompositionOptions& composition);

SkinningMethod skinningMethod(const Options& options);  // lbs, else dqs
MeshFormat frameFormat(const Options& options);
// The import's limits: --import-timeout and --import-memory.
ImportOptions importOptions(const Options& options);

// The frames of the run: --frames, else 30 per second of the clip. A clip
// of absurd length (a corrupt key time) would run for ever at 30 per
// second: past kMaxDefaultFrames that is an isk::Error(kInvalidArgument)
// asking for --frames.
int frameCount(const Options& options, const AnimationClip& clip);

// The frames of the run that are written and measured, FIRST to LAST of
// the clip's `frames` (--frame-range), and the first frame skinned before
// them unwritten (--warm-up): by default frame 0 in the history mode, whose
// frames each start from the one before, so that the range is the whole
// run's frames bit for bit; FIRST in the 2013 mode, whose frames depend on
// their pose alone. Throws isk::Error(kInvalidArgument) naming the option.
struct FrameRange {
  int first = 0;
  int last = 0;
  int warm_up_from = 0;
};
FrameRange frameRange(const Options& options, int frames);

// Whether `name` matches `pattern`, where '*' stands for any run of
// characters and '?' for one (--untracked-joint).
bool jointNameMatches(const std::string& pattern, const std::string& name);

// The parameters of --params FILE.json (or, without it, of
// <INPUT>.isk.json when that file exists: said on `log`) with the command
// line's operator options and untracked joints on top, as field options;
// written to --save-params. Unset when neither a file, --save-params nor
// --untracked-joint is in play. A --untracked-joint pattern that matches no
// joint is an error naming it.
// Throws isk::Error naming the file, the joint and the key.
std::optional<ImplicitFieldsOptions> loadParams(const Options& options,
                                                const Rig& rig,
                                                std::ostream& log);

// The run builds implicit fields: for --method implicit, an operator option
// or per-joint parameters.
bool needsFields(const Options& options,
                 const std::optional<ImplicitFieldsOptions>& params);
// The fields' build options: the parameters when there are some, else the
// command line's operators; the grid precision; the on-disk cache.
ImplicitFieldsOptions fieldOptions(
    const Options& options, const CompositionOptions& composition,
    const std::optional<ImplicitFieldsOptions>& params);
// Implicit skinning with `fields` and the command line's tracking, from DQS.
ImplicitSkinnerOptions implicitOptions(const Options& options,
                                       const ImplicitFieldsOptions& fields);

}  // namespace isk::samples::skin
