// Offline field construction (section 4.1): partition, Poisson-disk sampling,
// HRBF fits, 32^3 baking and iso values, per model, on 1 thread and on every
// hardware thread. Counters give each stage's milliseconds, the number of
// fields and the baked fields' memory.
//
// Field evaluation at the skinned vertices of a clip frame (what surface
// tracking does once per vertex and step): the single-thread CPU reference
// against the OpenCL kernel with the grids in a buffer and in a 3D image;
// points already on the device, composed value + gradient left there.
// FieldEval composes with the union of all fields; FieldCompose with the
// blend or the bulge at every joint (Appendix A, operator tables, one pair
// per joint on top of the union). The counter fields_per_point is the broad
// phase's average number of fields sampled per point (of `fields`).
//
//   FieldBuild/<model>/threads:<n>        (subdivided models: all threads only)
//   FieldEval/reference/<model>, FieldEval/opencl-<buffer|image>:<d>/<model>
//   FieldCompose/<blend|bulge>/<backend as FieldEval>/<model>
//
//   isk_bench --benchmark_filter='FieldBuild'
//   isk_bench --benchmark_filter='FieldEval|FieldCompose'
#include <benchmark/benchmark.h>

#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <thread>

#include "bench_support.hpp"
#include "isk/cl/field_evaluation.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/skinning/cpu_skinning.hpp"

namespace isk::bench {
namespace {

void buildFields(benchmark::State& state, const Model& model, int threads) {
  const Rig& rig = rigOf(model);
  ImplicitFieldsOptions options;
  options.threads = threads;
  ImplicitFieldsTimes sum;
  int64_t runs = 0;
  size_t bytes = 0;
  int fields = 0;
  for (auto _ : state) {
    const ImplicitFields built = buildImplicitFields(rig, options);
    benchmark::DoNotOptimize(built.iso_values.data());
    sum.partition_ms += built.times.partition_ms;
    sum.sampling_ms += built.times.sampling_ms;
    sum.fitting_ms += built.times.fitting_ms;
    sum.baking_ms += built.times.baking_ms;
    sum.operators_ms += built.times.operators_ms;
    sum.iso_ms += built.times.iso_ms;
    bytes = built.grids.bytes();
    fields = built.grids.fieldCount();
    ++runs;
  }
  const double n = static_cast<double>(std::max<int64_t>(runs, 1));
  state.counters["vertices"] = rig.mesh.vertexCount();
  state.counters["joints"] = rig.skeleton.skinJointCount();
  state.counters["fields"] = fields;
  state.counters["field_MiB"] = bytes / (1024.0 * 1024.0);
  state.counters["partition_ms"] = sum.partition_ms / n;
  state.counters["sampling_ms"] = sum.sampling_ms / n;
  state.counters["fitting_ms"] = sum.fitting_ms / n;
  state.counters["baking_ms"] = sum.baking_ms / n;
  state.counters["operators_ms"] = sum.operators_ms / n;
  state.counters["iso_ms"] = sum.iso_ms / n;
  state.SetLabel(std::to_string(threads) + " thread(s)");
}

const ImplicitFields& fieldsOf(const Model& model) {
  static std::map<std::string, std::unique_ptr<ImplicitFields>> cache;
  auto& slot = cache[model.name];
  if (!slot)
    slot = std::make_unique<ImplicitFields>(buildImplicitFields(rigOf(model)));
  return *slot;
}

// Skinned (DQS) positions of a few frames of the first clip, with their pose.
struct PosedFrames {
  std::vector<TransformList> poses;
  std::vector<Matrix3Xf> positions;
};
const PosedFrames& framesOf(const Model& model) {
  static std::map<std::string, std::unique_ptr<PosedFrames>> cache;
  auto& slot = cache[model.name];
  if (!slot) {
    const Rig& rig = rigOf(model);
    slot = std::make_unique<PosedFrames>();
    CpuSkinning skinning(rig.mesh, rig.weights, rig.skeleton.jointCount());
    for (int frame = 0; frame < 8; ++frame) {
      slot->poses.push_back(poseAt(rig, frame * 4));
      skinning.run(SkinningMethod::kDualQuaternion, slot->poses.back(), false);
      slot->positions.push_back(skinning.positions());
    }
  }
  return *slot;
}

// The composition of `op` at every joint for the model's fields (cached).
const Composition& compositionOf(const Model& model, CompositionOperator op) {
  static std::map<std::pair<std::string, int>, std::unique_ptr<Composition>>
      cache;
  auto& slot = cache[{model.name, static_cast<int>(op)}];
  if (!slot) {
    CompositionOptions options;
    options.default_operator = op;
    slot = std::make_unique<Composition>(buildComposition(
        rigOf(model).skeleton, fieldsOf(model).grids, options));
  }
  return *slot;
}

// Average number of fields whose posed bounding sphere holds a point.
double fieldsPerPoint(const FieldGridSet& grids, const TransformList& pose,
                      const Matrix3Xf& points) {
  const std::vector<Eigen::Vector4f> spheres =
      posedFieldSpheres(grids, fieldTransforms(grids, pose));
  double count = 0;
  for (Eigen::Index p = 0; p < points.rows(); ++p)
    for (const Eigen::Vector4f& s : spheres)
      count += (points.row(p).transpose() - s.head<3>()).squaredNorm() <= s[3];
  return count / std::max<Eigen::Index>(points.rows(), 1);
}

void evaluateReference(benchmark::State& state, const Model& model,
                       CompositionOperator op) {
  const ImplicitFields& fields = fieldsOf(model);
  const PosedFrames& frames = framesOf(model);
  Matrix4Xf composed;
  FieldEvaluationJob job;
  job.fields = &fields.grids;
  job.out_composed = &composed;
  if (op != CompositionOperator::kUnion)
    job.composition = &compositionOf(model, op);
  size_t frame = 0;
  for (auto _ : state) {
    job.skinning = &frames.poses[frame % frames.poses.size()];
    job.points = &frames.positions[frame % frames.poses.size()];
    job.run();
    benchmark::DoNotOptimize(composed.data());
    ++frame;
  }
  state.counters["points"] = rigOf(model).mesh.vertexCount();
  state.counters["fields"] = fields.grids.fieldCount();
  state.counters["fields_per_point"] =
      fieldsPerPoint(fields.grids, frames.poses[0], frames.positions[0]);
  state.counters["pairs"] =
      job.composition ? job.composition->blended_pairs.size() : 0;
  state.SetLabel("CPU reference, 1 thread");
}

void evaluateOpenCl(benchmark::State& state, const Model& model, int device,
                    FieldStorage storage, CompositionOperator op) {
  const ImplicitFields& fields = fieldsOf(model);
  const PosedFrames& frames = framesOf(model);
  const Rig& rig = rigOf(model);
  ClFieldEvaluation evaluation(
      context(device), fields.grids, rig.skeleton.jointCount(), storage,
      op == CompositionOperator::kUnion ? nullptr : &compositionOf(model, op));
  if (evaluation.storage() != storage) {
    state.SkipWithError(
        ("storage not available: " + evaluation.storageReason()).c_str());
    return;
  }
  // The points stay on the device, as the skinning kernel leaves them.
  std::vector<cl::Buffer> points;
  for (const Matrix3Xf& p : frames.positions)
    points.emplace_back(context(device)->context(),
                        CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                        p.size() * sizeof(float), const_cast<float*>(p.data()));
  // PoCL compiles a kernel at its first launch: keep that out of the loop.
  evaluation.evaluate(frames.poses[0], points[0], rig.mesh.vertexCount());
  double kernel = 0, upload = 0;
  size_t frame = 0;
  for (auto _ : state) {
    const size_t f = frame % frames.poses.size();
    evaluation.evaluate(frames.poses[f], points[f], rig.mesh.vertexCount());
    kernel += evaluation.lastKernelMs();
    upload += evaluation.lastUploadMs();
    ++frame;
  }
  const double n = static_cast<double>(std::max<size_t>(frame, 1));
  state.counters["points"] = rig.mesh.vertexCount();
  state.counters["fields"] = fields.grids.fieldCount();
  state.counters["kernel_ms"] = kernel / n;
  state.counters["pose_upload_ms"] = upload / n;
  state.counters["field_MiB"] = evaluation.fieldBytes() / (1024.0 * 1024.0);
  state.counters["operator_MiB"] =
      evaluation.operatorBytes() / (1024.0 * 1024.0);
  state.counters["pairs"] = evaluation.pairCount();
  state.SetLabel(devices()[device].describe());
}

}  // namespace

void registerFieldBenchmarks() {
  const int all =
      static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  for (const Model& model : models()) {
    if (!available(model)) continue;
    for (int threads : {1, all}) {
      if (threads == all && all == 1) continue;
      // One run of a subdivided model takes seconds: all threads only.
      if (model.subdivision_levels > 0 && threads != all) continue;
      registerGuarded(
          ("FieldBuild/" + model.name + "/threads:" + std::to_string(threads))
              .c_str(),
          buildFields, model, threads)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
  for (const CompositionOperator op :
       {CompositionOperator::kUnion, CompositionOperator::kBlend,
        CompositionOperator::kBulge}) {
    const std::string group =
        op == CompositionOperator::kUnion
            ? std::string("FieldEval/")
            : std::string("FieldCompose/") + compositionOperatorName(op) + "/";
    for (const Model& model : models()) {
      if (!available(model)) continue;
      registerGuarded((group + "reference/" + model.name).c_str(),
                      evaluateReference, model, op)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
      for (const ClDeviceInfo& device : devices())
        for (FieldStorage storage :
             {FieldStorage::kBuffer, FieldStorage::kImage})
          registerGuarded(
              (group +
               onDevice(std::string("opencl-") + fieldStorageName(storage),
                        device.index) +
               "/" + model.name)
                  .c_str(),
              evaluateOpenCl, model, device.index, storage, op)
              ->Unit(benchmark::kMillisecond)
              ->UseRealTime();
    }
  }
}

}  // namespace isk::bench
