// Implicit skinning per frame (Vaillant et al. 2013, surface tracking of
// section 5) against DQS on the same device and against the single-thread
// CPU reference, on the shared assets and on CesiumMan and human-addon
// subdivided (the paper's Table 1 has a 31,750-vertex hand and the
// 172,974-vertex Armadillo); and a scaling series on procedural cylinders.
//
// Implicit/<model>/opencl:<d>: a frame = pose from the clip -> ImplicitSkinner
// ::run (upload, DQS, projection and relaxation rounds, smoothing, normals)
// -> read back positions and normals, on OpenCL device d. Counters give the
// per-stage times (OpenCL profiling events; readback is host wall time)
// averaged over iterations, the vertices stopped at a contact (and at a
// crease, and lost) per frame, counted with the timer paused, and the
// start-up: setup_ms (the skinner's construction from built fields: tracking
// mesh, uploads, program builds) and first_frame_ms (the first frame, where
// PoCL compiles each kernel).
// Implicit/<model>/dqs:<d>: the same frame with isk::ClSkinning (DQS, normals
// recomputed, reads) on the same device, so that implicit / DQS is a ratio
// measured in one process.
// Implicit/<model>/paired:<d>: the two frames above in turn, for an
// implicit / DQS ratio of frames timed side by side.
// Implicit/<model>/reference: isk::CpuImplicitSkinner (1 thread).
//
// Scaling/vertices/<target>/{implicit,dqs,paired}:<d>: a 4-bone cylinder (bones
// of length 3, radius 1) with about 2.5k, 10k, 40k and 160k vertices;
// Scaling/joints/<bones>/{implicit,dqs,paired}:<d>: cylinders of 2 to 32 bones
// with about 40k vertices. Every inner joint is bent 30 to 50 degrees,
// alternately up and down (bench_support.hpp, zigzagPose). Same frame and
// counters as Implicit/.
//
// The fields (the library's default operators) are built once per model,
// outside the timing; PoCL compiles a kernel at its first launch, so one
// frame runs before the timed loop. Frames are independent (tracking starts
// from the skinned pose every frame), so the timed frames step through the
// clip by the golden ratio: the few frames of a large model's run are spread
// over the whole clip, and the backends see the same sequence.
//
// Crowd/<model>/x<n>:<d>: n instances of the model, each at its own pose
// of the clip and apart from the others, skinned by one isk::ImplicitCrowd
// (every stage one launch over all instances) and by n ImplicitSkinners (one
// per instance, the same fields), the two frames in turn: counters crowd_ms
// and separate_ms (wall time of the whole crowd's frame with its read-backs,
// means over the iterations) and separate_over_crowd, their ratio (above 1:
// the crowd pays). Crowd/mixed/x<n>:<d>: n instances of each of those
// models (the assets present and the built-in arm) in one crowd of
// characters of different sizes, against one ImplicitSkinner per instance.
//
//   isk_bench --benchmark_filter='^Implicit/'
//   isk_bench --benchmark_filter='^Levers/'
//   isk_bench --benchmark_filter='^Scaling/'
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "bench_support.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/implicit_crowd.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "tracking/tracking_tuning.hpp"

namespace isk::bench {
namespace {

// Minimum time per benchmark: on 2 CPU cores the Implicit family takes about
// 2.5 minutes (CesiumMan-x64: about 8 to 15 frames per backend, the 113k
// human-addon-x16 3 to 7), the Scaling family about 1 minute.
constexpr double kMinTimeS = 2.0;
constexpr double kScalingMinTimeS = 1.0;

// What one implicit benchmark skins: a rig, its fields and its i-th pose.
struct Case {
  std::string name;  // cache key of the fields
  std::function<const Rig&()> rig;
  std::function<TransformList(const Rig&, int64_t)> pose;
};

Case modelCase(const Model& model) {
  return {"model:" + model.name,
          [model]() -> const Rig& { return rigOf(model); },
          [](const Rig& rig, int64_t i) {
            return poseAt(
                rig, static_cast<int64_t>(spread(i) * clipFrameCount(rig)));
          }};
}

Case scalingCase(int vertices, int bones) {
  return {
      "cylinder:" + std::to_string(vertices) + ":" + std::to_string(bones),
      [vertices, bones]() -> const Rig& { return scalingRig(vertices, bones); },
      [](const Rig& rig, int64_t i) { return zigzagPose(rig, i); }};
}

std::shared_ptr<const ImplicitFields> implicitFieldsOf(const Case& c) {
  static std::map<std::string, std::shared_ptr<const ImplicitFields>> cache;
  auto& slot = cache[c.name];
  if (!slot)
    slot = std::make_shared<const ImplicitFields>(
        buildImplicitFields(c.rig(), {}));
  return slot;
}

// The fields composed with the union at every joint (the paper's default,
// `--operator union`; the library's default blends at the limb joints).
std::shared_ptr<const ImplicitFields> unionFieldsOf(const Case& c) {
  static std::map<std::string, std::shared_ptr<const ImplicitFields>> cache;
  auto& slot = cache[c.name];
  if (!slot) {
    ImplicitFieldsOptions options;
    options.composition.limb_operator.reset();
    slot = std::make_shared<const ImplicitFields>(
        buildImplicitFields(c.rig(), options));
  }
  return slot;
}

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now() - start)
      .count();
}

struct StageSums {
  double upload = 0, skinning = 0, projection = 0, relaxation = 0,
         smoothing = 0, volume = 0, strain_limit = 0, normals = 0, readback = 0;
  void add(const ImplicitStageTimes& t) {
    upload += t.upload_ms;
    skinning += t.skinning_ms;
    projection += t.tracking.projection_ms;
    relaxation += t.tracking.relaxation_ms;
    smoothing += t.tracking.smoothing_ms;
    volume += t.tracking.volume_ms;
    strain_limit += t.tracking.strain_limit_ms;
    normals += t.tracking.normals_ms;
    readback += t.readback_ms;
  }
};

struct CountSums {
  double contact = 0, crease = 0, lost = 0;
  int tracked = 0;
  void add(const TrackingCounts& c, int vertices) {
    contact += c.contact;
    crease += c.crease;
    lost += c.lost;
    tracked = vertices - c.untracked;
  }
};

void setCounters(benchmark::State& state, const Rig& rig, int64_t frames,
                 const StageSums& t, const CountSums& c) {
  const double n = static_cast<double>(std::max<int64_t>(frames, 1));
  state.counters["vertices"] = rig.mesh.vertexCount();
  state.counters["joints"] = rig.skeleton.skinJointCount();
  state.counters["tracked"] = c.tracked;
  state.counters["contact"] = c.contact / n;
  state.counters["crease"] = c.crease / n;
  state.counters["lost"] = c.lost / n;
  state.counters["upload_ms"] = t.upload / n;
  state.counters["skinning_ms"] = t.skinning / n;
  state.counters["projection_ms"] = t.projection / n;
  state.counters["relaxation_ms"] = t.relaxation / n;
  state.counters["smoothing_ms"] = t.smoothing / n;
  state.counters["volume_ms"] = t.volume / n;
  state.counters["strain_limit_ms"] = t.strain_limit / n;
  state.counters["normals_ms"] = t.normals / n;
  state.counters["readback_ms"] = t.readback / n;
  state.counters["fps"] = benchmark::Counter(static_cast<double>(frames),
                                             benchmark::Counter::kIsRate);
}

void implicitOpenCl(benchmark::State& state, const Case& c, int device) {
  const ImplicitSkinnerOptions options;
  const Rig& rig = c.rig();
  const std::shared_ptr<const ImplicitFields> fields = implicitFieldsOf(c);
  auto start = std::chrono::steady_clock::now();
  ImplicitSkinner skinner(context(device), rig, fields, options);
  const double setup_ms = msSince(start);
  start = std::chrono::steady_clock::now();
  skinner.run(c.pose(rig, 0));  // PoCL compiles at the first launch
  const double first_frame_ms = msSince(start);
  Matrix3Xf positions, normals;
  std::vector<TrackState> states;
  StageSums times;
  CountSums counts;
  int64_t frame = 0;
  for (auto _ : state) {
    skinner.run(c.pose(rig, frame++));
    skinner.readPositions(positions);
    skinner.readNormals(normals);
    benchmark::DoNotOptimize(positions.data());
    benchmark::DoNotOptimize(normals.data());
    times.add(skinner.lastTimes());
    state.PauseTiming();
    skinner.tracking().readStates(states);
    counts.add(countStates(states), skinner.vertexCount());
    state.ResumeTiming();
  }
  setCounters(state, rig, frame, times, counts);
  state.counters["setup_ms"] = setup_ms;
  state.counters["first_frame_ms"] = first_frame_ms;
  state.SetLabel(devices()[device].describe());
}

// Two frames of one pose in turn, run_frame(true) and run_frame(false),
// which goes first alternating with `frame` so that neither gains from the
// other's warm caches or from the machine's drift; adds each frame's wall
// time to true_ms or false_ms.
template <class Frame>
void framesInTurn(int64_t frame, const Frame& run_frame, double& true_ms,
                  double& false_ms) {
  for (int k = 0; k < 2; ++k) {
    const bool which = (k == 0) == (frame % 2 == 0);
    const auto start = std::chrono::steady_clock::now();
    run_frame(which);
    (which ? true_ms : false_ms) += msSince(start);
  }
}

// Levers/<model>/<lever>:<d>: the implicit frame with one speed switch of
// SurfaceTrackingOptions off (the result is the same, tests check it):
// 'all' has every switch on, as Implicit/ runs it. Each iteration runs the
// same pose on a second skinner with every switch on, the two frames in
// turn (which goes first alternates): on a shared machine whose speed
// drifts by tens of percent within minutes, only frames timed side by side
// give a ratio that holds. Counters: frame_ms and all_frame_ms (host wall
// time of one frame with its read-back, means over the iterations) and
// frame_over_all, their ratio; the stage counters are the lever's frames'.
// 'half-grids', 'sigma-<s>', 'no-fold-guard', 'no-tilt-guard',
// 'no-restore-again', 'union-operator' and 'history-tracking' change the
// result on purpose
// (half-precision grids; eq. 4's step size sigma instead of the paper's
// 0.35, a speed / accuracy trade-off the paper leaves to the user; the
// strain limit without its fold guard, or without its tilt guard, what the
// guard costs; no second volume restoration after the strain limit, what
// it costs; the union at every joint instead of the
// default's blend at the limb joints, what the blend costs; each frame
// started from the last, what the history mode costs): how far, the
// counters
// mean_moved, max_moved (distance of a vertex from its place in the paired
// frame, over the rest mesh's bounding-box diagonal; means over vertices and
// frames, largest over both) and moved_beyond_1e-3 (the fraction of vertices
// farther than 1e-3 of the diagonal), taken with the timer paused. They are
// 0 for the switches that keep the result.
void implicitLever(benchmark::State& state, const Case& c, int device,
                   const std::string& lever) {
  ImplicitSkinnerOptions options;
  detail::TrackingTuning tuning;
  if (lever == "no-neighbourhoods") tuning.field_neighbourhoods = false;
  if (lever == "no-march-order") tuning.march_order = false;
  if (lever == "no-occupied-cells") tuning.occupied_cells = false;
  if (lever == "no-value-bounds") tuning.value_bounds = false;
  if (lever == "no-lane-tests") tuning.lane_tests = false;
  if (lever == "no-active-vertices") tuning.active_vertices = false;
  if (lever == "no-pair-bounds") tuning.pair_bounds = false;
  if (lever == "no-neighbourhood-cells")
    tuning.neighbourhood_cells = 1;  // the whole box
  options.tracking = detail::withTuning(options.tracking, tuning);
  if (lever.rfind("sigma-", 0) == 0)
    options.tracking.sigma = std::stof(lever.substr(6));
  if (lever == "no-fold-guard") options.tracking.fold_guard = false;
  if (lever == "no-tilt-guard") options.tracking.tilt_guard_degrees = 0.f;
  if (lever == "no-restore-again") options.tracking.restore_again_steps = 0;
  if (lever.rfind("strain-limit-steps-", 0) == 0)
    options.tracking.strain_limit_steps = std::stoi(lever.substr(19));
  if (lever == "history-tracking")
    options.tracking_mode = TrackingMode::kHistory;
  const Rig& rig = c.rig();
  const std::shared_ptr<const ImplicitFields> fields = implicitFieldsOf(c);
  std::shared_ptr<const ImplicitFields> switched_fields = fields;
  if (lever == "half-grids") {  // the same fields, rounded to halves
    auto half = std::make_shared<ImplicitFields>(*fields);
    useHalfPrecisionGrids(*half, rig);
    switched_fields = half;
  }
  if (lever == "union-operator") switched_fields = unionFieldsOf(c);
  ImplicitSkinner switched(context(device), rig, switched_fields, options);
  ImplicitSkinner all(context(device), rig, fields, ImplicitSkinnerOptions());
  switched.run(c.pose(rig, 0));  // PoCL compiles at the first launch
  all.run(c.pose(rig, 0));
  Matrix3Xf switched_positions, all_positions, normals;
  StageSums times;
  CountSums counts;
  std::vector<TrackState> states;
  double switched_ms = 0, all_ms = 0;
  const double diagonal = boundingBoxDiagonal(rig.mesh.positions);
  double moved_sum = 0, moved_max = 0, moved_beyond = 0;
  int64_t frame = 0;
  for (auto _ : state) {
    const TransformList pose = c.pose(rig, frame);
    framesInTurn(
        frame,
        [&](bool lever_frame) {
          ImplicitSkinner& skinner = lever_frame ? switched : all;
          Matrix3Xf& positions =
              lever_frame ? switched_positions : all_positions;
          skinner.run(pose);
          skinner.readPositions(positions);
          skinner.readNormals(normals);
          benchmark::DoNotOptimize(positions.data());
          benchmark::DoNotOptimize(normals.data());
        },
        switched_ms, all_ms);
    times.add(switched.lastTimes());
    ++frame;
    state.PauseTiming();
    switched.tracking().readStates(states);
    counts.add(countStates(states), switched.vertexCount());
    for (Eigen::Index v = 0; v < switched_positions.rows(); ++v) {
      const double moved =
          (switched_positions.row(v) - all_positions.row(v)).norm() / diagonal;
      moved_sum += moved;
      moved_max = std::max(moved_max, moved);
      moved_beyond += moved > 1e-3 ? 1 : 0;
    }
    state.ResumeTiming();
  }
  setCounters(state, rig, frame, times, counts);
  const double n = static_cast<double>(std::max<int64_t>(frame, 1));
  state.counters["frame_ms"] = switched_ms / n;
  state.counters["all_frame_ms"] = all_ms / n;
  state.counters["frame_over_all"] = all_ms > 0 ? switched_ms / all_ms : 0;
  const double samples = n * std::max<double>(switched.vertexCount(), 1);
  state.counters["mean_moved"] = moved_sum / samples;
  state.counters["max_moved"] = moved_max;
  state.counters["moved_beyond_1e-3"] = moved_beyond / samples;
  state.SetLabel(devices()[device].describe());
}

void dqsOpenCl(benchmark::State& state, const Case& c, int device) {
  const Rig& rig = c.rig();
  ClSkinning skinning(context(device), rig.mesh, rig.weights,
                      rig.skeleton.jointCount());
  Matrix3Xf positions, normals;
  skinning.run(SkinningMethod::kDualQuaternion, c.pose(rig, 0), true);
  StageSums times;
  int64_t frame = 0;
  for (auto _ : state) {
    skinning.run(SkinningMethod::kDualQuaternion, c.pose(rig, frame++), true);
    skinning.readPositions(positions);
    skinning.readNormals(normals);
    benchmark::DoNotOptimize(positions.data());
    benchmark::DoNotOptimize(normals.data());
    const SkinningStageTimes& t = skinning.lastTimes();
    times.upload += t.upload_ms;
    times.skinning += t.skinning_ms;
    times.normals += t.normals_ms;
    times.readback += t.readback_ms;
  }
  setCounters(state, rig, frame, times, CountSums{});
  state.SetLabel(devices()[device].describe());
}

// Implicit/<model>/paired:<d>: an implicit frame (as opencl:<d>) and a DQS
// frame (as dqs:<d>) of the same pose in turn, which goes first
// alternating, so that implicit / DQS comes from frames timed side by side:
// the separate benchmarks run minutes apart on a shared machine whose speed
// drifts, so their ratio moves between runs of the same code. Counters:
// implicit_ms and dqs_ms (wall time of one frame with its read-backs, means
// over the iterations) and implicit_over_dqs, their ratio.
void implicitPairedWithDqs(benchmark::State& state, const Case& c, int device) {
  const Rig& rig = c.rig();
  ImplicitSkinner implicit(context(device), rig, implicitFieldsOf(c),
                           ImplicitSkinnerOptions());
  ClSkinning dqs(context(device), rig.mesh, rig.weights,
                 rig.skeleton.jointCount());
  implicit.run(c.pose(rig, 0));  // PoCL compiles at the first launch
  dqs.run(SkinningMethod::kDualQuaternion, c.pose(rig, 0), true);
  Matrix3Xf positions, normals;
  double implicit_ms = 0, dqs_ms = 0;
  int64_t frame = 0;
  for (auto _ : state) {
    const TransformList pose = c.pose(rig, frame);
    framesInTurn(
        frame,
        [&](bool implicit_frame) {
          if (implicit_frame) {
            implicit.run(pose);
            implicit.readPositions(positions);
            implicit.readNormals(normals);
          } else {
            dqs.run(SkinningMethod::kDualQuaternion, pose, true);
            dqs.readPositions(positions);
            dqs.readNormals(normals);
          }
          benchmark::DoNotOptimize(positions.data());
          benchmark::DoNotOptimize(normals.data());
        },
        implicit_ms, dqs_ms);
    ++frame;
  }
  const double n = static_cast<double>(std::max<int64_t>(frame, 1));
  state.counters["vertices"] = rig.mesh.vertexCount();
  state.counters["joints"] = rig.skeleton.skinJointCount();
  state.counters["implicit_ms"] = implicit_ms / n;
  state.counters["dqs_ms"] = dqs_ms / n;
  state.counters["implicit_over_dqs"] = dqs_ms > 0 ? implicit_ms / dqs_ms : 0;
  state.SetLabel(devices()[device].describe());
}

void implicitReference(benchmark::State& state, const Case& c) {
  const Rig& rig = c.rig();
  const std::shared_ptr<const ImplicitFields> fields = implicitFieldsOf(c);
  const auto start = std::chrono::steady_clock::now();
  CpuImplicitSkinner skinner(rig, fields);
  const double setup_ms = msSince(start);
  StageSums times;
  CountSums counts;
  int64_t frame = 0;
  for (auto _ : state) {
    skinner.run(c.pose(rig, frame++));
    benchmark::DoNotOptimize(skinner.positions().data());
    benchmark::DoNotOptimize(skinner.normals().data());
    times.add(skinner.lastTimes());
    counts.add(countStates(skinner.tracking().states()), skinner.vertexCount());
  }
  setCounters(state, rig, frame, times, counts);
  state.counters["setup_ms"] = setup_ms;
  state.SetLabel("CPU reference, 1 thread");
}

// Crowd/<model>/x<n>:<d> and Crowd/mixed/x<n>:<d> (see the top of this
// file): `instances` instances of each case's character.
void crowdAgainstSeparate(benchmark::State& state,
                          const std::vector<Case>& cases, int device,
                          int instances) {
  std::vector<CrowdCharacter> characters;
  std::vector<ImplicitSkinner> separate;
  std::vector<int> case_of;  // per instance
  float apart = 0;
  double vertices = 0, joints = 0;
  for (size_t k = 0; k < cases.size(); ++k) {
    const Rig& rig = cases[k].rig();
    const std::shared_ptr<const ImplicitFields> fields =
        implicitFieldsOf(cases[k]);
    characters.push_back({&rig, fields, instances});
    for (int i = 0; i < instances; ++i) {
      separate.emplace_back(context(device), rig, fields);
      case_of.push_back(static_cast<int>(k));
    }
    // Instances 2 of the largest diagonals apart.
    apart = std::max(apart, 2.f * boundingBoxDiagonal(rig.mesh.positions));
    vertices += static_cast<double>(rig.mesh.vertexCount()) * instances;
    joints += rig.skeleton.skinJointCount();
  }
  ImplicitCrowd crowd(context(device), characters);
  const int total = static_cast<int>(case_of.size());
  // Instance i at its own place on a square grid.
  const int side = static_cast<int>(std::ceil(std::sqrt(total)));
  auto poses = [&](int64_t frame) {
    std::vector<TransformList> out;
    for (int i = 0; i < total; ++i) {
      const Case& c = cases[case_of[i]];
      TransformList pose = c.pose(c.rig(), frame * total + i);
      const Eigen::Vector3f at(apart * (i % side), 0.f, apart * (i / side));
      for (Eigen::Affine3f& t : pose) t.pretranslate(at);
      out.push_back(std::move(pose));
    }
    return out;
  };
  Matrix3Xf positions, normals;
  auto crowd_frame = [&](const std::vector<TransformList>& p) {
    crowd.run(p);
    crowd.readPositions(positions);
    crowd.readNormals(normals);
    benchmark::DoNotOptimize(positions.data());
    benchmark::DoNotOptimize(normals.data());
  };
  auto separate_frame = [&](const std::vector<TransformList>& p) {
    for (int i = 0; i < total; ++i) {
      separate[i].run(p[i]);
      separate[i].readPositions(positions);
      separate[i].readNormals(normals);
      benchmark::DoNotOptimize(positions.data());
      benchmark::DoNotOptimize(normals.data());
    }
  };
  crowd_frame(poses(0));  // PoCL compiles at the first launch
  separate_frame(poses(0));
  double crowd_ms = 0, separate_ms = 0;
  StageSums times;
  int64_t frame = 0;
  for (auto _ : state) {
    const std::vector<TransformList> p = poses(frame);
    framesInTurn(
        frame,
        [&](bool crowd_turn) {
          if (crowd_turn)
            crowd_frame(p);
          else
            separate_frame(p);
        },
        crowd_ms, separate_ms);
    times.add(crowd.lastTimes());
    ++frame;
  }
  const double n = static_cast<double>(std::max<int64_t>(frame, 1));
  state.counters["vertices"] = vertices;
  state.counters["joints"] = joints;  // of one instance of each character
  state.counters["instances"] = total;
  state.counters["characters"] = static_cast<double>(cases.size());
  state.counters["crowd_ms"] = crowd_ms / n;
  state.counters["separate_ms"] = separate_ms / n;
  state.counters["separate_over_crowd"] =
      crowd_ms > 0 ? separate_ms / crowd_ms : 0;
  state.counters["projection_ms"] = times.projection / n;
  state.counters["smoothing_ms"] = times.smoothing / n;
  state.SetLabel(devices()[device].describe());
}

void registerCase(const std::string& prefix, const Case& c, bool reference,
                  const std::string& implicit_backend, double min_time) {
  for (const ClDeviceInfo& device : devices()) {
    registerGuarded((prefix + onDevice(implicit_backend, device.index)).c_str(),
                    implicitOpenCl, c, device.index)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->MinTime(min_time);
    registerGuarded((prefix + onDevice("dqs", device.index)).c_str(), dqsOpenCl,
                    c, device.index)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->MinTime(min_time);
    registerGuarded((prefix + onDevice("paired", device.index)).c_str(),
                    implicitPairedWithDqs, c, device.index)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->MinTime(min_time);
  }
  if (reference)
    registerGuarded((prefix + "reference").c_str(), implicitReference, c)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->MinTime(min_time);
}

}  // namespace

void registerImplicitBenchmarks() {
  for (const Model& model : models()) {
    if (!available(model)) continue;
    registerCase("Implicit/" + model.name + "/", modelCase(model), true,
                 "opencl", kMinTimeS);
  }
  // The speed switches, on the 53-field human, the coarse fox (blend pairs
  // at most of its joints) and the 38k- and 152k-vertex models.
  for (const Model& model : models()) {
    if (!available(model) ||
        (model.name != "human-addon" && model.name != "fox" &&
         model.name != "CesiumMan-x16" && model.name != "CesiumMan-x64"))
      continue;
    for (const ClDeviceInfo& device : devices())
      for (const char* lever :
           {"all", "no-neighbourhoods", "no-neighbourhood-cells",
            "no-march-order", "no-occupied-cells", "no-value-bounds",
            "no-lane-tests", "no-active-vertices", "no-pair-bounds",
            "half-grids", "sigma-0.5", "sigma-0.7", "sigma-1", "no-fold-guard",
            "no-tilt-guard", "strain-limit-steps-16", "no-restore-again",
            "union-operator", "history-tracking"})
        registerGuarded(
            ("Levers/" + model.name + "/" + onDevice(lever, device.index))
                .c_str(),
            implicitLever, modelCase(model), device.index, std::string(lever))
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime()
            ->MinTime(kMinTimeS);
  }
  // Crowds of the models up to the 7.8k-vertex human: where a frame is a
  // few milliseconds, launches and waits are a large part of it.
  std::vector<Case> crowd_models;
  for (const Model& model : models()) {
    if (!available(model) || model.subdivision_levels > 0) continue;
    crowd_models.push_back(modelCase(model));
    for (const ClDeviceInfo& device : devices())
      for (const int instances : {4, 16})
        registerGuarded(
            ("Crowd/" + model.name + "/" +
             onDevice("x" + std::to_string(instances), device.index))
                .c_str(),
            crowdAgainstSeparate, std::vector<Case>{modelCase(model)},
            device.index, instances)
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime()
            ->MinTime(kScalingMinTimeS);
  }
  // Every one of those models in one crowd: characters of different sizes.
  if (crowd_models.size() > 1)
    for (const ClDeviceInfo& device : devices())
      for (const int instances : {1, 4})
        registerGuarded(
            ("Crowd/mixed/" +
             onDevice("x" + std::to_string(instances), device.index))
                .c_str(),
            crowdAgainstSeparate, crowd_models, device.index, instances)
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime()
            ->MinTime(kScalingMinTimeS);
  constexpr int kFixedBones = 4, kFixedVertices = 40000;
  const std::pair<int, const char*> sizes[] = {
      {2500, "2.5k"}, {10000, "10k"}, {40000, "40k"}, {160000, "160k"}};
  for (const auto& [vertices, label] : sizes)
    registerCase(std::string("Scaling/vertices/") + label + "/",
                 scalingCase(vertices, kFixedBones), false, "implicit",
                 kScalingMinTimeS);
  for (int bones : {2, 4, 8, 16, 32})
    registerCase("Scaling/joints/" + std::to_string(bones) + "/",
                 scalingCase(kFixedVertices, bones), false, "implicit",
                 kScalingMinTimeS);
}

}  // namespace isk::bench
