#include "isk/cl/skinning.hpp"

#include <chrono>
#include <string>

#include "cl/device_buffers.hpp"
#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"
#include "isk/core/vertex_normals.hpp"

namespace isk {
namespace {

using detail::roundUp;

template <typename T>
cl::Buffer uploadReadOnly(const ClContext& context, const std::vector<T>& data,
                          const char* what) {
  return detail::uploadReadOnly(context, data,
                                std::string("ClSkinning ") + what);
}

// Enqueues `kernel` over the vertices: the vertex count, then `buffers` as
// its arguments in order.
template <typename... Buffers>
void launchPerVertex(const ClContext& context, int vertex_count,
                     cl::Kernel& kernel, const Buffers&... buffers) {
  kernel.setArg(0, static_cast<cl_uint>(vertex_count));
  cl_uint index = 1;
  (kernel.setArg(index++, buffers), ...);
  context.queue().enqueueNDRangeKernel(
      kernel, cl::NullRange,
      cl::NDRange(roundUp(std::max(vertex_count, 1), 64)), cl::NullRange);
}

}  // namespace

ClSkinning::ClSkinning(std::shared_ptr<ClContext> context, const Mesh& mesh,
                       const SkinWeights& weights, int joint_count)
    : context_(std::move(context)),
      vertex_count_(mesh.vertexCount()),
      joint_count_(joint_count) {
  if (!context_)
    throw Error(ErrorCode::kInvalidArgument, "ClSkinning: no context");
  mesh.validate().throwIfFailed("ClSkinning mesh");
  weights.validate(vertex_count_, joint_count)
      .throwIfFailed("ClSkinning weights");
  const VertexTriangleAdjacency adjacency =
      VertexTriangleAdjacency::build(mesh.triangles, vertex_count_);
  try {
    cl::Program skinning = context_->program("skinning");
    cl::Program normals = context_->program("normals");
    lbs_kernel_ = cl::Kernel(skinning, "skin_lbs");
    dqs_kernel_ = cl::Kernel(skinning, "skin_dqs");
    unskin_lbs_kernel_ = cl::Kernel(skinning, "unskin_lbs");
    unskin_dqs_kernel_ = cl::Kernel(skinning, "unskin_dqs");
    triangle_normals_kernel_ = cl::Kernel(normals, "triangle_normals");
    normals_kernel_ = cl::Kernel(normals, "vertex_normals");
    const float* p = mesh.positions.data();
    const float* n = mesh.normals.data();
    const size_t floats = 3 * static_cast<size_t>(vertex_count_);
    const ClContext& c = *context_;
    rest_positions_ =
        uploadReadOnly(c, std::vector<float>(p, p + floats), "rest positions");
    rest_normals_ =
        uploadReadOnly(c, std::vector<float>(n, n + floats), "rest normals");
    influence_offsets_ =
        uploadReadOnly(c, weights.offsets, "influence offsets");
    influence_joints_ = uploadReadOnly(c, weights.joints, "influence joints");
    influence_weights_ =
        uploadReadOnly(c, weights.weights, "influence weights");
    adjacency_offsets_ =
        uploadReadOnly(c, adjacency.offsets, "adjacency offsets");
    adjacency_triangles_ =
        uploadReadOnly(c, adjacency.triangles, "adjacency triangles");
    triangle_count_ = static_cast<int>(mesh.triangles.rows());
    const int* t = mesh.triangles.data();  // row-major: corners in order
    triangles_ = uploadReadOnly(
        c, std::vector<int>(t, t + 3 * static_cast<size_t>(triangle_count_)),
        "triangles");
    triangle_normals_ = c.createBuffer(
        CL_MEM_READ_WRITE,
        3 * sizeof(float) * static_cast<size_t>(std::max(triangle_count_, 1)),
        nullptr, "ClSkinning triangle normals");
    // Large enough for either layout (LBS 12 floats per joint, DQS 8).
    joint_transforms_ = c.createBuffer(
        CL_MEM_READ_ONLY, 12 * sizeof(float) * std::max(joint_count, 1),
        nullptr, "ClSkinning joint transforms");
    const size_t bytes = floats * sizeof(float);
    skinned_normals_ = c.createBuffer(CL_MEM_READ_WRITE, bytes, nullptr,
                                      "ClSkinning skinned normals");
    out_positions_ = c.createBuffer(CL_MEM_READ_WRITE, bytes, nullptr,
                                    "ClSkinning positions");
    out_normals_ =
        c.createBuffer(CL_MEM_READ_WRITE, bytes, nullptr, "ClSkinning normals");
  } catch (const cl::Error& e) {
    throwClError(
        e, "ClSkinning: uploading the mesh to " + context_->info().describe());
  }
}

void ClSkinning::run(SkinningMethod method, const TransformList& skinning,
                     bool recompute_normals) {
  enqueue(method, skinning, recompute_normals);
  collectTimes();
}

void ClSkinning::checkUsable(const char* what, bool needs_run) const {
  if (!context_) {
    throw Error(ErrorCode::kInvalidArgument,
                std::string("ClSkinning::") + what +
                    ": the object was moved from (it holds no mesh)");
  }
  if (needs_run && !has_run_) {
    throw Error(ErrorCode::kInvalidArgument,
                std::string("ClSkinning::") + what +
                    " before run(): there is no result yet");
  }
}

void ClSkinning::collectTimes() {
  if (!pending_) return;
  pending_ = false;
  try {
    (pending_normals_ ? normals_event_ : skin_event_).wait();
    times_.upload_ms = eventMilliseconds(upload_event_);
    times_.skinning_ms = eventMilliseconds(skin_event_);
    times_.normals_ms = pending_normals_
                            ? eventMilliseconds(triangle_normals_event_) +
                                  eventMilliseconds(normals_event_)
                            : 0.0;
  } catch (const cl::Error& e) {
    throwClError(e, "ClSkinning: waiting for the skinning on " +
                        context_->info().describe());
  }
}

void ClSkinning::enqueue(SkinningMethod method, const TransformList& skinning,
                         bool recompute_normals) {
  checkUsable("run", false);
  collectTimes();  // a frame still pending reads staging_'s old contents
  if (static_cast<int>(skinning.size()) != joint_count_) {
    throw Error(ErrorCode::kInvalidArgument,
                "ClSkinning::run: " + std::to_string(skinning.size()) +
                    " joint transforms given for a skeleton of " +
                    std::to_string(joint_count_) + " joints");
  }
  for (size_t j = 0; j < skinning.size(); ++j) {
    if (!skinning[j].matrix().allFinite()) {
      throw Error(ErrorCode::kInvalidArgument,
                  "ClSkinning::run: the transform of joint " +
                      std::to_string(j) + " is not finite");
    }
  }
  // Kept in a member: the non-blocking write reads it until the queue is done.
  staging_ = packJointTransforms(method, skinning);
  method_ = method;
  const cl::CommandQueue& queue = context_->queue();
  const bool profiling = context_->profilingEnabled();
  const cl::NDRange global(roundUp(std::max(vertex_count_, 1), 64));
  const cl_uint n = static_cast<cl_uint>(vertex_count_);
  times_ = SkinningStageTimes();
  try {
    auto start = std::chrono::steady_clock::now();
    cl::Event upload, skin, triangle_normals, normals;
    // Without profiling, each stage is waited for and timed on the host;
    // with it, the queue runs unbroken and the events give the times.
    queue.enqueueWriteBuffer(joint_transforms_, profiling ? CL_FALSE : CL_TRUE,
                             0, staging_.size() * sizeof(float),
                             staging_.data(), nullptr, &upload);
    if (!profiling) times_.upload_ms = millisecondsSince(start);

    cl::Kernel& kernel =
        method == SkinningMethod::kLinearBlend ? lbs_kernel_ : dqs_kernel_;
    const cl::Buffer& normals_target =
        recompute_normals ? skinned_normals_ : out_normals_;
    kernel.setArg(0, n);
    kernel.setArg(1, rest_positions_);
    kernel.setArg(2, rest_normals_);
    kernel.setArg(3, influence_offsets_);
    kernel.setArg(4, influence_joints_);
    kernel.setArg(5, influence_weights_);
    kernel.setArg(6, joint_transforms_);
    kernel.setArg(7, out_positions_);
    kernel.setArg(8, normals_target);
    start = std::chrono::steady_clock::now();
    queue.enqueueNDRangeKernel(kernel, cl::NullRange, global, cl::NullRange,
                               nullptr, &skin);
    if (!profiling) {
      skin.wait();
      times_.skinning_ms = millisecondsSince(start);
    }
    if (recompute_normals) {
      triangle_normals_kernel_.setArg(0, static_cast<cl_uint>(triangle_count_));
      triangle_normals_kernel_.setArg(1, out_positions_);
      triangle_normals_kernel_.setArg(2, triangles_);
      triangle_normals_kernel_.setArg(3, triangle_normals_);
      normals_kernel_.setArg(0, n);
      normals_kernel_.setArg(1, triangle_normals_);
      normals_kernel_.setArg(2, adjacency_offsets_);
      normals_kernel_.setArg(3, adjacency_triangles_);
      normals_kernel_.setArg(4, skinned_normals_);
      normals_kernel_.setArg(5, out_normals_);
      start = std::chrono::steady_clock::now();
      queue.enqueueNDRangeKernel(
          triangle_normals_kernel_, cl::NullRange,
          cl::NDRange(roundUp(std::max(triangle_count_, 1), 64)), cl::NullRange,
          nullptr, &triangle_normals);
      queue.enqueueNDRangeKernel(normals_kernel_, cl::NullRange, global,
                                 cl::NullRange, nullptr, &normals);
      if (!profiling) {
        normals.wait();
        times_.normals_ms = millisecondsSince(start);
      }
    }
    if (profiling) {
      upload_event_ = upload;
      skin_event_ = skin;
      triangle_normals_event_ = triangle_normals;
      normals_event_ = normals;
      pending_ = true;
      pending_normals_ = recompute_normals;
    }
    has_run_ = true;
  } catch (const cl::Error& e) {
    throwClError(e, std::string("ClSkinning::run (") +
                        skinningMethodName(method) + ") on " +
                        context_->info().describe());
  }
}

void ClSkinning::checkVertexBuffer(const cl::Buffer& buffer,
                                   const char* what) const {
  const size_t needed = 3 * static_cast<size_t>(vertex_count_) * sizeof(float);
  if (buffer.getInfo<CL_MEM_SIZE>() < needed)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("ClSkinning::") + what +
                    ": a buffer holds fewer than " +
                    std::to_string(vertex_count_) + " vertices");
}

void ClSkinning::enqueueSkinPoints(const cl::Buffer& rest_points,
                                   const cl::Buffer& out) {
  checkUsable("enqueueSkinPoints", true);
  try {
    checkVertexBuffer(rest_points, "enqueueSkinPoints");
    checkVertexBuffer(out, "enqueueSkinPoints");
    if (point_normals_() == nullptr)
      point_normals_ = context_->createBuffer(
          CL_MEM_READ_WRITE, 3 * sizeof(float) * vertex_count_, nullptr,
          "ClSkinning point normals");
    launchPerVertex(
        *context_, vertex_count_,
        method_ == SkinningMethod::kLinearBlend ? lbs_kernel_ : dqs_kernel_,
        rest_points, rest_normals_, influence_offsets_, influence_joints_,
        influence_weights_, joint_transforms_, out, point_normals_);
  } catch (const cl::Error& e) {
    throwClError(
        e, "ClSkinning::enqueueSkinPoints on " + context_->info().describe());
  }
}

void ClSkinning::enqueueUnskinPoints(const cl::Buffer& posed,
                                     const cl::Buffer& out_rest) {
  checkUsable("enqueueUnskinPoints", true);
  try {
    checkVertexBuffer(posed, "enqueueUnskinPoints");
    checkVertexBuffer(out_rest, "enqueueUnskinPoints");
    launchPerVertex(*context_, vertex_count_,
                    method_ == SkinningMethod::kLinearBlend
                        ? unskin_lbs_kernel_
                        : unskin_dqs_kernel_,
                    posed, influence_offsets_, influence_joints_,
                    influence_weights_, joint_transforms_, out_rest);
  } catch (const cl::Error& e) {
    throwClError(
        e, "ClSkinning::enqueueUnskinPoints on " + context_->info().describe());
  }
}

void ClSkinning::readPositions(Matrix3Xf& out) {
  times_.readback_ms += readBuffer(out_positions_, out, "readPositions");
}

void ClSkinning::readNormals(Matrix3Xf& out) {
  times_.readback_ms += readBuffer(out_normals_, out, "readNormals");
}

double ClSkinning::readBuffer(const cl::Buffer& buffer, Matrix3Xf& out,
                              const char* what) {
  checkUsable(what, true);
  out.resize(vertex_count_, 3);
  try {
    cl::Event read;
    const auto start = std::chrono::steady_clock::now();
    context_->queue().enqueueReadBuffer(buffer, CL_TRUE, 0,
                                        out.size() * sizeof(float), out.data(),
                                        nullptr, &read);
    return context_->profilingEnabled() ? eventMilliseconds(read)
                                        : millisecondsSince(start);
  } catch (const cl::Error& e) {
    throwClError(e, std::string("ClSkinning::") + what);
  }
}

}  // namespace isk
