#include "skin_runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <regex>
#include <sstream>

#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"
#include "isk/fields/bone_partition.hpp"
#include "isk/io/import.hpp"
#include "isk/io/rig_params.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "isk/tools/procedural.hpp"
#include "isk/tools/self_intersection.hpp"

namespace isk::samples {
namespace fs = std::filesystem;

namespace {

constexpr const char* kBuiltinPrefix = "builtin:";
constexpr double kPi = 3.14159265358979323846;

bool parseIndex(const std::string& text, int* index) {
  if (text.empty() || text.size() > 9) return false;
  for (char c : text) {
    if (c < '0' || c > '9') return false;
  }
  *index = std::stoi(text);
  return true;
}

std::string describeClips(const Rig& rig) {
  if (rig.clips.empty()) return "none";
  std::ostringstream out;
  for (size_t i = 0; i < rig.clips.size(); ++i) {
    out << (i ? ", " : "") << i << ": \"" << rig.clips[i].name << "\" ("
        << rig.clips[i].duration << " s)";
  }
  return out.str();
}

// Names our own frame files (and their temporaries), so --overwrite never
// removes anything else.
bool isFrameFileName(const std::string& name) {
  static const std::regex pattern(R"(frame_[0-9]+\.(obj|ply)(\.tmp-[0-9]+)?)");
  return std::regex_match(name, pattern);
}

// Throws isk::Error(kInternal) naming the first vertex whose skinned
// position or normal is not finite: such a frame is never written.
void checkFiniteFrame(const Mesh& mesh, const Matrix3Xf& positions,
                      const Matrix3Xf& normals) {
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    const char* what =
        !positions.row(v).allFinite() ? "position"
        : (normals.rows() == positions.rows() && !normals.row(v).allFinite())
            ? "normal"
            : nullptr;
    if (what) {
      throw Error(ErrorCode::kInternal,
                  mesh.describeVertex(static_cast<int>(v)) +
                      " has a non-finite skinned " + what);
    }
  }
}

// The message of a failed frame: what failed, and what is on disk.
std::string describeFailedFrame(int frame, int frames, const std::string& why,
                                const RunOptions& options,
                                const std::vector<std::string>& written) {
  std::ostringstream out;
  out << "frame " << options.first_frame + frame;
  if (options.first_frame > 0) {
    out << " (of the range " << options.first_frame << " to "
        << options.first_frame + frames - 1 << ")";
  } else {
    out << " of " << frames;
  }
  out << " failed: " << why;
  if (options.out_dir.empty()) return out.str();
  if (written.empty()) {
    out << "; no frame file was written to " << options.out_dir;
  } else {
    out << "; the run is incomplete: frames " << options.first_frame << " to "
        << options.first_frame + static_cast<int>(written.size()) - 1
        << " were written to " << options.out_dir << " ("
        << fs::path(written.front()).filename().string() << " to "
        << fs::path(written.back()).filename().string() << ", "
        << written.size() << " of " << frames << " files)";
  }
  return out.str();
}

}  // namespace

bool samePath(const std::string& a, const std::string& b) {
  std::error_code ec;
  const bool same = fs::equivalent(a, b, ec);
  return !ec && same;
}

bool isBuiltinInput(const std::string& input) {
  return input.rfind(kBuiltinPrefix, 0) == 0;
}

std::string paramsFileBeside(const std::string& input) {
  if (isBuiltinInput(input)) return {};
  const std::string beside = rigParamsPathFor(input);
  std::error_code ec;
  return fs::is_regular_file(beside, ec) ? beside : std::string();
}

Rig loadRig(const std::string& input, ImportOptions options) {
  const std::string prefix = kBuiltinPrefix;
  if (isBuiltinInput(input)) {
    return makeBuiltinRig(input.substr(prefix.size()));
  }
  // Progress on stderr: one update per stage and per tenth, so a large file
  // shows it is alive without flooding a log.
  std::string last_stage;
  int last_tenth = -1;
  bool printed = false;
  options.progress = [&](const char* stage, float fraction) {
    const int tenth = static_cast<int>(fraction * 10.f);
    if (stage == last_stage && tenth == last_tenth) return;
    last_stage = stage;
    last_tenth = tenth;
    std::fprintf(stderr, "\rloading %s: %-10s %3d%%", input.c_str(), stage,
                 tenth * 10);
    printed = true;
  };
  Rig rig;
  try {
    rig = importRig(input, options);
  } catch (...) {
    if (printed) std::fprintf(stderr, "\n");
    throw;
  }
  if (printed) std::fprintf(stderr, "\n");
  return rig;
}

std::optional<AnimationClip> proceduralClip(const Skeleton& skeleton,
                                            const std::string& spec) {
  if (spec == "rest") {
    AnimationClip rest;  // no channel: every joint at its rest transform
    rest.name = "rest";
    return rest;
  }
  if (spec != "bend" && spec.rfind("bend:", 0) != 0) return std::nullopt;
  double degrees = 90;
  const bool has_angle = spec.size() >= 5;  // "bend:..."
  if (has_angle) {
    const std::string value = spec.substr(5);
    char* end = nullptr;
    degrees = std::strtod(value.c_str(), &end);
    if (value.empty() || *end != '\0' || !std::isfinite(degrees) ||
        degrees < 0 || degrees > 180) {
      throw Error(ErrorCode::kInvalidArgument,
                  "clip '" + spec +
                      "': the bend's angle must be a number of degrees from "
                      "0 to 180 (bend:DEGREES)");
    }
  }
  AnimationClip bend =
      makeBendClip(skeleton, static_cast<float>(degrees * kPi / 180), 1.0);
  bend.name = has_angle ? spec : "bend:90";
  return bend;
}

AnimationClip selectClip(const Rig& rig, const std::string& spec,
                         std::string* note) {
  // The rig's own clip of that name first: nothing the asset holds is hidden.
  if (rig.findClip(spec) < 0) {
    if (std::optional<AnimationClip> clip = proceduralClip(rig.skeleton, spec))
      return *clip;
  }
  if (rig.clips.empty()) {
    if (!spec.empty()) {
      throw Error(ErrorCode::kInvalidArgument,
                  "clip '" + spec + "': " + rig.source +
                      " has no animation clip (leave --clip out to use a "
                      "procedural bend)");
    }
    if (note) {
      *note = rig.source +
              " has no animation clip: using a 90-degree bend of every "
              "joint over 1 s";
    }
    return makeBendClip(rig.skeleton, static_cast<float>(kPi / 2), 1.0);
  }
  if (spec.empty()) return rig.clips[0];
  if (const int by_name = rig.findClip(spec); by_name >= 0) {
    return rig.clips[by_name];
  }
  int index = -1;
  if (parseIndex(spec, &index) && index < static_cast<int>(rig.clips.size())) {
    return rig.clips[index];
  }
  throw Error(ErrorCode::kInvalidArgument,
              "no clip '" + spec + "' in " + rig.source +
                  "; available clips: " + describeClips(rig));
}

int defaultFrameCount(const AnimationClip& clip) {
  if (!std::isfinite(clip.duration) || clip.duration <= 0) return 1;
  // A corrupt key time can make a clip last for ages: no int overflow.
  const double frames = std::floor(clip.duration * 30.0) + 1;
  return frames >= std::numeric_limits<int>::max()
             ? std::numeric_limits<int>::max()
             : static_cast<int>(frames);
}

std::vector<double> frameTimes(const AnimationClip& clip, int frames) {
  if (frames < 1) {
    throw Error(
        ErrorCode::kInvalidArgument,
        "frame count must be at least 1, got " + std::to_string(frames));
  }
  std::vector<double> times(frames, clip.start);
  for (int i = 1; i < frames; ++i) {
    times[i] = clip.start + i * clip.duration / (frames - 1);
  }
  return times;
}

std::string frameFileName(int frame, MeshFormat format) {
  char name[64];
  std::snprintf(name, sizeof(name), "frame_%04d.%s", frame,
                format == MeshFormat::kObj ? "obj" : "ply");
  return name;
}

void prepareOutputFolder(const std::string& dir, bool overwrite,
                         const std::string& protected_path) {
  std::error_code ec;
  const fs::path folder(dir);
  if (fs::exists(folder, ec) && !fs::is_directory(folder, ec)) {
    throw Error(ErrorCode::kIo, dir + ": exists and is not a folder");
  }
  if (!fs::exists(folder, ec)) {
    fs::create_directories(folder, ec);
    if (ec) {
      throw Error(ErrorCode::kIo,
                  dir + ": cannot create the folder: " + ec.message());
    }
    return;
  }

  std::vector<fs::path> frame_files;
  std::vector<std::string> entries;  // every name, for the refusal
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    entries.push_back(name);
    if (!isFrameFileName(name)) continue;
    // The input is never removed nor replaced, --overwrite or not.
    if (!protected_path.empty() &&
        samePath(entry.path().string(), protected_path)) {
      throw Error(ErrorCode::kIo,
                  dir + ": the input " + protected_path +
                      " has a frame file's name in this folder; choose "
                      "another --out folder");
    }
    frame_files.push_back(entry.path());
  }
  if (ec) {
    throw Error(ErrorCode::kIo,
                dir + ": cannot list the folder: " + ec.message());
  }
  // Anything already there (an earlier run's frames, the input, the user's
  // files) could be mistaken for this run's output or lost: refused unless
  // asked for.
  if (!entries.empty() && !overwrite) {
    std::sort(entries.begin(), entries.end());
    std::string listed;
    for (size_t i = 0; i < entries.size() && i < 3; ++i) {
      listed += (i ? ", '" : "'") + entries[i] + "'";
    }
    if (entries.size() > 3) listed += ", ...";
    throw Error(ErrorCode::kIo,
                dir + ": the folder is not empty (" +
                    std::to_string(entries.size()) +
                    (entries.size() == 1 ? " entry: " : " entries: ") + listed +
                    "); pass --overwrite to write into it (only its "
                    "frame_NNNN files are replaced) or choose another --out "
                    "folder");
  }
  for (const fs::path& file : frame_files) {
    fs::remove(file, ec);
    if (ec) {
      throw Error(ErrorCode::kIo,
                  file.string() + ": cannot remove: " + ec.message());
    }
  }
}

FrameSkinner::FrameSkinner(const Rig& rig, const std::string& device) {
  if (device == "reference") {
    reference_ = std::make_unique<CpuSkinning>(rig.mesh, rig.weights,
                                               rig.skeleton.jointCount());
    return;
  }
  context_ = ClContext::create(device == "auto" ? "" : device);
  device_ = std::make_unique<ClSkinning>(context_, rig.mesh, rig.weights,
                                         rig.skeleton.jointCount());
}

const ClDeviceInfo* FrameSkinner::deviceInfo() const {
  return device_ ? &device_->context().info() : nullptr;
}

std::string FrameSkinner::describe() const {
  return device_ ? device_->context().info().describe()
                 : std::string("reference (CPU)");
}

void FrameSkinner::skin(SkinningMethod method, const TransformList& skinning,
                        Matrix3Xf& positions, Matrix3Xf& normals) {
  if (device_) {
    device_->run(method, skinning, /*recompute_normals=*/true);
    device_->readPositions(positions);
    device_->readNormals(normals);
  } else {
    reference_->run(method, skinning, /*recompute_normals=*/true);
    reference_->readPositions(positions);
    reference_->readNormals(normals);
  }
  const SkinningStageTimes& t = lastTimes();
  stages_ = {{"upload", t.upload_ms},
             {"skinning", t.skinning_ms},
             {"normals", t.normals_ms},
             {"readback", t.readback_ms}};
}

void FrameSkinner::enableImplicit(const Rig& rig,
                                  std::shared_ptr<const ImplicitFields> fields,
                                  const ImplicitSkinnerOptions& options) {
  if (device_) {
    implicit_device_ = std::make_unique<ImplicitSkinner>(
        context_, rig, std::move(fields), options);
  } else {
    implicit_reference_ =
        std::make_unique<CpuImplicitSkinner>(rig, std::move(fields), options);
  }
}

void FrameSkinner::skinImplicit(const TransformList& skinning,
                                Matrix3Xf& positions, Matrix3Xf& normals) {
  if (!hasImplicit())
    throw Error(ErrorCode::kInternal,
                "FrameSkinner::skinImplicit before enableImplicit");
  const ImplicitStageTimes* t = nullptr;
  if (implicit_device_) {
    implicit_device_->run(skinning);
    implicit_device_->readPositions(positions);
    implicit_device_->readNormals(normals);
    t = &implicit_device_->lastTimes();
  } else {
    implicit_reference_->run(skinning);
    implicit_reference_->readPositions(positions);
    implicit_reference_->readNormals(normals);
    t = &implicit_reference_->lastTimes();
  }
  stages_ = {{"upload", t->upload_ms},
             {"skinning", t->skinning_ms},
             {"projection", t->tracking.projection_ms},
             {"relaxation", t->tracking.relaxation_ms},
             {"smoothing", t->tracking.smoothing_ms},
             {"volume", t->tracking.volume_ms},
             {"strain_limit", t->tracking.strain_limit_ms},
             {"normals", t->tracking.normals_ms},
             {"readback", t->readback_ms}};
}

int FrameSkinner::lastContactCount() {
  if (implicit_device_) return implicit_device_->contactCount();
  if (implicit_reference_) return implicit_reference_->contactCount();
  return 0;
}

void FrameSkinner::lastTrackStates(std::vector<TrackState>& out) {
  if (implicit_device_) {
    implicit_device_->tracking().readStates(out);
  } else if (implicit_reference_) {
    out = implicit_reference_->tracking().states();
  } else {
    out.clear();
  }
}

const TrackingMesh* FrameSkinner::trackingMesh() const {
  if (implicit_device_) return &implicit_device_->trackingMesh();
  if (implicit_reference_) return &implicit_reference_->trackingMesh();
  return nullptr;
}

TimeSummary summarize(std::vector<double> values) {
  TimeSummary summary;
  if (values.empty()) return summary;
  std::sort(values.begin(), values.end());
  const size_t n = values.size();
  summary.median =
      n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
  const size_t rank = static_cast<size_t>(std::ceil(0.95 * n));
  summary.p95 = values[std::max<size_t>(rank, 1) - 1];
  summary.min = values.front();
  return summary;
}

double medianCount(const std::vector<int>& counts) {
  return summarize(std::vector<double>(counts.begin(), counts.end())).median;
}

int changedStates(const std::vector<TrackState>& before,
                  const std::vector<TrackState>& after) {
  if (before.size() != after.size())
    throw Error(ErrorCode::kInvalidArgument,
                "changedStates: " + std::to_string(before.size()) + " and " +
                    std::to_string(after.size()) + " states");
  int changed = 0;
  for (size_t v = 0; v < before.size(); ++v) changed += before[v] != after[v];
  return changed;
}

std::optional<StateChangeSummary> summarizeStateChanges(
    const std::vector<std::optional<int>>& changes) {
  StateChangeSummary summary;
  int frames = 0;
  for (const std::optional<int>& c : changes) {
    if (!c) continue;
    summary.mean += *c;
    summary.max = std::max(summary.max, *c);
    ++frames;
  }
  if (frames == 0) return std::nullopt;
  summary.mean /= frames;
  return summary;
}

CountTotals countTotals(const std::vector<int>& counts) {
  CountTotals totals;
  for (const int count : counts) {
    totals.max = std::max(totals.max, count);
    totals.total += count;
  }
  return totals;
}

void placeSideBySide(std::vector<GltfTrack>& tracks) {
  std::vector<Matrix3Xf> all_frames;
  for (const GltfTrack& track : tracks)
    all_frames.insert(all_frames.end(), track.positions.begin(),
                      track.positions.end());
  const float spacing = gltfTrackSpacing(all_frames);
  const float middle = (tracks.size() - 1) / 2.f;
  for (size_t i = 0; i < tracks.size(); ++i)
    tracks[i].offset = {spacing * (i - middle), 0, 0};
}

RunResult runFrames(const Rig& rig, const AnimationClip& clip,
                    FrameSkinner& skinner, const RunOptions& options) {
  const Mesh& mesh = rig.mesh;
  const Skeleton& skeleton = rig.skeleton;
  RunResult result;
  result.frames = static_cast<int>(options.times.size());
  result.first_frame = options.first_frame;
  result.warm_up_frames = static_cast<int>(options.warm_up_times.size());

  Matrix3Xf positions, normals;
  auto skinFrame = [&](const TransformList& skinning) {
    if (options.implicit) {
      skinner.skinImplicit(skinning, positions, normals);
    } else {
      skinner.skin(options.method, skinning, positions, normals);
    }
  };
  skinFrame(bindPoseSkinning(skeleton));
  const double diagonal = rig.boundingBoxDiagonal();
  const double rest_distance = maxVertexDistance(positions, mesh.positions);
  result.rest_pose_error =
      diagonal > 0 ? rest_distance / diagonal : rest_distance;

  // A flat or open mesh can enclose (almost) nothing; ratios against that
  // would be noise, so they are left unset.
  result.rest_volume = enclosedVolume(mesh.positions, mesh.triangles);
  const bool volume_meaningful =
      diagonal > 0 &&
      std::abs(result.rest_volume) > 1e-6 * diagonal * diagonal * diagonal;

  std::vector<std::vector<double>> stage_ms;
  // The quality is measured on the mesh welded at its seams (copies that
  // touch along edges without sharing an index), against DQS of the same
  // pose skinned on the CPU reference (unless the frame is DQS).
  std::optional<SkinQuality> quality;
  std::optional<CpuSkinning> dqs_reference;
  const bool frames_are_dqs =
      !options.implicit && options.method == SkinningMethod::kDualQuaternion;
  if (options.quality) {
    // Per bone's part: where on the character the frames depart from DQS.
    SkinQualityOptions quality_options;
    quality_options.vertex_parts = partitionMesh(rig).vertex_joint;
    quality.emplace(mesh,
                    skinner.trackingMesh()
                        ? skinner.trackingMesh()->rings.representative
                        : coincidentVertexGroups(mesh.positions),
                    quality_options);
    result.rest_self_intersections =
        static_cast<int>(quality->restPairs().size());
    if (!frames_are_dqs) {
      dqs_reference.emplace(mesh, rig.weights, skeleton.jointCount());
    }
  }
  std::vector<TrackState> states, last_states;
  std::vector<uint8_t> contacts;
  // Ends the progress line before an error message goes out.
  struct ProgressLine {
    bool active;
    ~ProgressLine() {
      if (active) std::cerr << "\n";
    }
  } progress_line{options.progress};
  auto poseAt = [&](double time) {
    return skinningTransforms(
        skeleton, globalTransforms(skeleton, clip.sampleLocal(skeleton, time)));
  };
  const int warm_up_frames = result.warm_up_frames;
  for (int i = 0; i < warm_up_frames; ++i) {
    const int frame = options.first_frame - warm_up_frames + i;
    try {
      skinFrame(poseAt(options.warm_up_times[i]));
      checkFiniteFrame(mesh, positions, normals);
    } catch (const std::exception& e) {
      const Error* error = dynamic_cast<const Error*>(&e);
      throw Error(error ? error->code() : ErrorCode::kInternal,
                  "warm-up frame " + std::to_string(frame) +
                      " failed: " + e.what() + "; no frame file was written",
                  error ? error->clStatus() : 0);
    }
    if (options.progress) {
      std::cerr << "\r[warm-up frame " << (i + 1) << "/" << warm_up_frames
                << "]" << std::flush;
    }
  }
  auto runFrame = [&](int i) {
    const TransformList skinning = poseAt(options.times[i]);

    const auto start = std::chrono::steady_clock::now();
    skinFrame(skinning);
    result.frame_ms.push_back(millisecondsSince(start));
    checkFiniteFrame(mesh, positions, normals);
    const StageTimes& stages = skinner.lastStages();
    stage_ms.resize(stages.size());
    for (size_t s = 0; s < stages.size(); ++s)
      stage_ms[s].push_back(stages[s].second);
    if (options.implicit)
      result.contact_vertices.push_back(skinner.lastContactCount());
    if (quality) {
      if (dqs_reference) {
        dqs_reference->run(SkinningMethod::kDualQuaternion, skinning,
                           /*recompute_normals=*/false);
      }
      int lost = 0;
      if (options.implicit) {
        skinner.lastTrackStates(states);
        contacts.assign(states.size(), 0);
        for (size_t v = 0; v < states.size(); ++v) {
          contacts[v] = states[v] == TrackState::kContact ||
                        states[v] == TrackState::kCrease;
          lost += states[v] == TrackState::kLost;
        }
        result.state_changes.push_back(
            last_states.size() == states.size()
                ? std::optional<int>(changedStates(last_states, states))
                : std::nullopt);
        last_states = states;
      }
      result.quality.push_back(quality->measure(
          positions, dqs_reference ? &dqs_reference->positions() : nullptr,
          options.implicit ? &contacts : nullptr, lost));
      result.self_intersections.push_back(
          result.quality.back().new_self_intersections);
    }

    if (volume_meaningful) {
      const double ratio =
          enclosedVolume(positions, mesh.triangles) / result.rest_volume;
      result.volume_ratio_min =
          i == 0 ? ratio : std::min(*result.volume_ratio_min, ratio);
      result.volume_ratio_max =
          i == 0 ? ratio : std::max(*result.volume_ratio_max, ratio);
    }
    if (options.on_frame) options.on_frame(i, positions, normals);
    if (!options.out_dir.empty()) {
      const std::string path =
          (fs::path(options.out_dir) /
           frameFileName(options.first_frame + i, options.format))
              .string();
      writeMesh(path, options.format, positions, &normals, mesh.triangles);
      result.files.push_back(path);
    }
  };
  for (int i = 0; i < result.frames; ++i) {
    try {
      runFrame(i);
    } catch (const std::exception& e) {
      const Error* error = dynamic_cast<const Error*>(&e);
      throw Error(error ? error->code() : ErrorCode::kInternal,
                  describeFailedFrame(i, result.frames, e.what(), options,
                                      result.files),
                  error ? error->clStatus() : 0);
    }
    if (options.progress) {
      std::cerr << "\r[frame " << (i + 1) << "/" << result.frames << "]"
                << std::flush;
    }
  }

  result.frame = summarize(result.frame_ms);
  const StageTimes& names = skinner.lastStages();
  for (size_t s = 0; s < names.size() && s < stage_ms.size(); ++s)
    result.stage_median.emplace_back(names[s].first,
                                     summarize(stage_ms[s]).median);
  return result;
}

}  // namespace isk::samples
