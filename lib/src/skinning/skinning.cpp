#include "isk/skinning/skinning.hpp"

#include <cfloat>
#include <cmath>
#include <string>

#include "isk/core/dual_quaternion.hpp"
#include "isk/core/error.hpp"

namespace isk {
namespace {

using Vec3 = Eigen::Vector3f;
using Vec4 = Eigen::Vector4f;

// Same operation order as quat_rotate in kernels/skinning.cl.
Vec3 quatRotate(const Vec4& q, const Vec3& v) {
  const Vec3 u = q.head<3>();
  const Vec3 t = 2.f * u.cross(v);
  return v + q.w() * t + u.cross(t);
}

// The blended 3x4 matrix of vertex v's influences (LBS), as rows.
struct BlendedRows {
  Vec4 r0 = Vec4::Zero(), r1 = Vec4::Zero(), r2 = Vec4::Zero();
};
BlendedRows blendRows(const SkinWeights& w, const std::vector<float>& packed,
                      int v) {
  BlendedRows b;
  for (uint32_t i = w.offsets[v]; i < w.offsets[v + 1]; ++i) {
    const float* m = &packed[12 * w.joints[i]];
    b.r0 += w.weights[i] * Vec4(m[0], m[1], m[2], m[3]);
    b.r1 += w.weights[i] * Vec4(m[4], m[5], m[6], m[7]);
    b.r2 += w.weights[i] * Vec4(m[8], m[9], m[10], m[11]);
  }
  return b;
}

void skinLinearBlend(const SkinningJob& job, const std::vector<float>& packed) {
  const int n = static_cast<int>(job.rest_positions->rows());
  for (int v = 0; v < n; ++v) {
    const auto [r0, r1, r2] = blendRows(*job.weights, packed, v);
    const Vec4 p(job.rest_positions->coeff(v, 0),
                 job.rest_positions->coeff(v, 1),
                 job.rest_positions->coeff(v, 2), 1.f);
    job.out_positions->row(v) = Vec3(r0.dot(p), r1.dot(p), r2.dot(p));
    const Vec3 nrm = job.rest_normals->row(v).transpose();
    const Vec3 a = r0.head<3>(), b = r1.head<3>(), c = r2.head<3>();
    Vec3 m(b.cross(c).dot(nrm), c.cross(a).dot(nrm), a.cross(b).dot(nrm));
    const float len = std::sqrt(m.dot(m));
    m = len > FLT_MIN && std::isfinite(len) ? Vec3(m / len) : nrm;
    job.out_normals->row(v) = m;
  }
}

// Vertex v's blended unit dual quaternion (DQS): its rotation `real` and
// translation `t`.
struct BlendedRigid {
  Vec4 real;
  Vec3 t;
};
BlendedRigid blendDualQuaternion(const SkinWeights& w,
                                 const std::vector<float>& packed, int v) {
  auto real_of = [&](uint32_t j) {
    return Vec4(Eigen::Map<const Vec4>(&packed[8 * j]));
  };
  auto dual_of = [&](uint32_t j) {
    return Vec4(Eigen::Map<const Vec4>(&packed[8 * j + 4]));
  };
  const uint32_t begin = w.offsets[v], end = w.offsets[v + 1];
  const Vec4 pivot = real_of(w.joints[begin]);
  Vec4 real = Vec4::Zero(), dual = Vec4::Zero();
  for (uint32_t i = begin; i < end; ++i) {
    const Vec4 qr = real_of(w.joints[i]);
    const float weight = qr.dot(pivot) < 0.f ? -w.weights[i] : w.weights[i];
    real += weight * qr;
    dual += weight * dual_of(w.joints[i]);
  }
  const float norm = std::sqrt(real.dot(real));
  real /= norm;
  dual /= norm;
  const Vec3 rv = real.head<3>(), dv = dual.head<3>();
  return {real, 2.f * (real.w() * dv - dual.w() * rv + rv.cross(dv))};
}

void skinDualQuaternion(const SkinningJob& job,
                        const std::vector<float>& packed) {
  const int n = static_cast<int>(job.rest_positions->rows());
  for (int v = 0; v < n; ++v) {
    const BlendedRigid b = blendDualQuaternion(*job.weights, packed, v);
    const Vec3 p = job.rest_positions->row(v).transpose();
    job.out_positions->row(v) = quatRotate(b.real, p) + b.t;
    job.out_normals->row(v) =
        quatRotate(b.real, job.rest_normals->row(v).transpose());
  }
}

}  // namespace

const char* skinningMethodName(SkinningMethod method) {
  return method == SkinningMethod::kLinearBlend ? "lbs" : "dqs";
}

std::vector<float> packJointTransforms(SkinningMethod method,
                                       const TransformList& skinning) {
  std::vector<float> packed;
  if (method == SkinningMethod::kLinearBlend) {
    packed.resize(12 * skinning.size());
    for (size_t j = 0; j < skinning.size(); ++j) {
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c)
          packed[12 * j + 4 * r + c] = skinning[j].matrix()(r, c);
      }
    }
  } else {
    packed.resize(8 * skinning.size());
    for (size_t j = 0; j < skinning.size(); ++j) {
      packDualQuaternion(DualQuaternion::fromTransform(skinning[j]),
                         &packed[8 * j]);
    }
  }
  return packed;
}

Validation SkinningJob::validate() const {
  if (!rest_positions || !rest_normals || !weights || !skinning ||
      !out_positions || !out_normals) {
    return Validation::fail(
        "an input or output of the skinning job is not set");
  }
  const int n = static_cast<int>(rest_positions->rows());
  if (rest_normals->rows() != n) {
    return Validation::fail("rest normals have " +
                            std::to_string(rest_normals->rows()) +
                            " rows for " + std::to_string(n) + " vertices");
  }
  // Only what run() relies on: a full weights check per frame would cost as
  // much as skinning; Rig::validate() does it once.
  if (weights->offsets.empty() || weights->vertexCount() != n ||
      weights->offsets.back() != weights->joints.size() ||
      weights->weights.size() != weights->joints.size()) {
    return Validation::fail("skin weights have " +
                            std::to_string(weights->vertexCount()) +
                            " rows for " + std::to_string(n) + " vertices");
  }
  for (int v = 0; v < n; ++v) {
    if (weights->offsets[v + 1] <= weights->offsets[v]) {
      return Validation::fail("vertex " + std::to_string(v) +
                              " has no skin weight");
    }
  }
  for (uint32_t joint : weights->joints) {
    if (joint >= skinning->size()) {
      return Validation::fail(
          "a vertex is weighted to joint " + std::to_string(joint) + " but " +
          std::to_string(skinning->size()) + " transforms were given");
    }
  }
  for (size_t j = 0; j < skinning->size(); ++j) {
    if (!(*skinning)[j].matrix().allFinite()) {
      return Validation::fail("skinning transform of joint " +
                              std::to_string(j) + " is not finite");
    }
  }
  return Validation::ok();
}

void SkinningJob::run() const {
  validate().throwIfFailed("SkinningJob");
  out_positions->resize(rest_positions->rows(), 3);
  out_normals->resize(rest_positions->rows(), 3);
  const std::vector<float> packed = packJointTransforms(method, *skinning);
  if (method == SkinningMethod::kLinearBlend) {
    skinLinearBlend(*this, packed);
  } else {
    skinDualQuaternion(*this, packed);
  }
}

void unskinPoints(SkinningMethod method, const SkinWeights& weights,
                  const TransformList& skinning, const Matrix3Xf& posed,
                  Matrix3Xf& rest) {
  Matrix3Xf unused;
  const SkinningJob job{method,    &posed,  &posed, &weights,
                        &skinning, &unused, &unused};
  job.validate().throwIfFailed("unskinPoints");
  const std::vector<float> packed = packJointTransforms(method, skinning);
  const int n = static_cast<int>(posed.rows());
  Matrix3Xf out(n, 3);
  for (int v = 0; v < n; ++v) {
    const Vec3 x = posed.row(v).transpose();
    if (method == SkinningMethod::kLinearBlend) {
      // Same operation order as unskin_lbs: the inverse by the cofactors.
      const auto [r0, r1, r2] = blendRows(weights, packed, v);
      const Vec3 a = r0.head<3>(), b = r1.head<3>(), c = r2.head<3>();
      const Vec3 y = x - Vec3(r0.w(), r1.w(), r2.w());
      const Vec3 bc = b.cross(c), ca = c.cross(a), ab = a.cross(b);
      const float det = a.dot(bc);
      out.row(v) = std::fabs(det) > FLT_MIN && std::isfinite(det)
                       ? Vec3((y.x() * bc + y.y() * ca + y.z() * ab) / det)
                       : x;
    } else {
      const BlendedRigid b = blendDualQuaternion(weights, packed, v);
      const Vec4 inverse(-b.real.x(), -b.real.y(), -b.real.z(), b.real.w());
      out.row(v) = quatRotate(inverse, x - b.t);
    }
  }
  rest = std::move(out);
}

}  // namespace isk
