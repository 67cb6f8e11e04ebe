#include "isk/skinning/cpu_skinning.hpp"

#include <chrono>
#include <string>

#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"

namespace isk {
CpuSkinning::CpuSkinning(const Mesh& mesh, const SkinWeights& weights,
                         int joint_count)
    : rest_positions_(mesh.positions),
      rest_normals_(mesh.normals),
      triangles_(mesh.triangles),
      weights_(weights),
      joint_count_(joint_count) {
  mesh.validate().throwIfFailed("CpuSkinning mesh");
  weights.validate(mesh.vertexCount(), joint_count)
      .throwIfFailed("CpuSkinning weights");
  adjacency_ = VertexTriangleAdjacency::build(triangles_, mesh.vertexCount());
}

// A built object has at least one vertex (the mesh was validated); a
// moved-from one has none.
void CpuSkinning::checkUsable(const char* what, bool needs_run) const {
  if (rest_positions_.rows() == 0) {
    throw Error(ErrorCode::kInvalidArgument,
                std::string("CpuSkinning::") + what +
                    ": the object was moved from (it holds no mesh)");
  }
  if (needs_run && !has_run_) {
    throw Error(ErrorCode::kInvalidArgument,
                std::string("CpuSkinning::") + what +
                    " before run(): there is no result yet");
  }
}

void CpuSkinning::readPositions(Matrix3Xf& out) const {
  checkUsable("readPositions", true);
  out = positions_;
}

void CpuSkinning::readNormals(Matrix3Xf& out) const {
  checkUsable("readNormals", true);
  out = normals_;
}

void CpuSkinning::run(SkinningMethod method, const TransformList& skinning,
                      bool recompute_normals) {
  checkUsable("run", false);
  if (static_cast<int>(skinning.size()) != joint_count_) {
    throw Error(ErrorCode::kInvalidArgument,
                "CpuSkinning::run: " + std::to_string(skinning.size()) +
                    " joint transforms given for a skeleton of " +
                    std::to_string(joint_count_) + " joints");
  }
  times_ = SkinningStageTimes();
  SkinningJob job;
  job.method = method;
  job.rest_positions = &rest_positions_;
  job.rest_normals = &rest_normals_;
  job.weights = &weights_;
  job.skinning = &skinning;
  job.out_positions = &positions_;
  job.out_normals = recompute_normals ? &skinned_normals_ : &normals_;
  auto start = std::chrono::steady_clock::now();
  job.run();
  has_run_ = true;
  times_.skinning_ms = millisecondsSince(start);
  if (!recompute_normals) return;
  VertexNormalsJob normals;
  normals.positions = &positions_;
  normals.triangles = &triangles_;
  normals.adjacency = &adjacency_;
  normals.fallback_normals = &skinned_normals_;
  normals.out_normals = &normals_;
  start = std::chrono::steady_clock::now();
  normals.run();
  times_.normals_ms = millisecondsSince(start);
}

}  // namespace isk
