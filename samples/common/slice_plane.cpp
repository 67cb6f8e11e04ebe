#include "slice_plane.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "isk/core/error.hpp"

namespace isk::samples {
namespace {

// Joints whose spread across their main axis is under this fraction of the
// spread along it (ratio of standard deviations) count as collinear.
constexpr double kCollinearRatio = 1e-2;
constexpr double kMarginFraction = 0.1;

// Makes the largest component of `axis` positive (a deterministic sign).
Eigen::Vector3d canonicalSign(const Eigen::Vector3d& axis) {
  Eigen::Index largest = 0;
  axis.cwiseAbs().maxCoeff(&largest);
  return axis[largest] < 0 ? Eigen::Vector3d(-axis) : axis;
}

// Eigenvectors of a symmetric 3x3 matrix, largest eigenvalue first.
struct Principal {
  Eigen::Vector3d axes[3];
  double values[3];
};

Principal principalAxes(const Eigen::Matrix3d& covariance) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  Principal p;
  for (int i = 0; i < 3; ++i) {
    p.axes[i] = solver.eigenvectors().col(2 - i);
    p.values[i] = std::max(0.0, solver.eigenvalues()[2 - i]);
  }
  return p;
}

Eigen::Matrix3d covarianceOf(const std::vector<Eigen::Vector3d>& points,
                             const Eigen::Vector3d& centre) {
  Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) {
    c += (p - centre) * (p - centre).transpose();
  }
  return c / static_cast<double>(std::max<size_t>(1, points.size()));
}

}  // namespace

Eigen::Vector3d SlicePlane::pixelCentre(int x, int y) const {
  return origin + u * (u_min + (x + 0.5) * pixel) +
         v * (v_max - (y + 0.5) * pixel);
}

Eigen::Vector2d SlicePlane::toImage(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d d = p - origin;
  return {(d.dot(u) - u_min) / pixel, (v_max - d.dot(v)) / pixel};
}

double SlicePlane::distance(const Eigen::Vector3d& p) const {
  return (p - origin).dot(normal);
}

SlicePlane fitSlicePlane(const std::vector<Eigen::Vector3d>& joints,
                         const Matrix3Xf& positions, int size) {
  if (positions.rows() == 0) {
    throw Error(ErrorCode::kInvalidArgument,
                "the mesh has no vertex: nothing to slice");
  }
  if (joints.empty()) {
    throw Error(ErrorCode::kInvalidArgument,
                "the skeleton has no joint: no plane along it");
  }
  std::vector<Eigen::Vector3d> vertices(positions.rows());
  Eigen::Vector3d mesh_centre = Eigen::Vector3d::Zero();
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    vertices[i] = positions.row(i).transpose().cast<double>();
    mesh_centre += vertices[i];
  }
  mesh_centre /= static_cast<double>(vertices.size());
  const Eigen::Matrix3d mesh_covariance = covarianceOf(vertices, mesh_centre);

  SlicePlane plane;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& j : joints) centroid += j;
  centroid /= static_cast<double>(joints.size());
  plane.origin = centroid;

  const Principal joint_axes = principalAxes(covarianceOf(joints, centroid));
  const Principal mesh_axes = principalAxes(mesh_covariance);
  const double mesh_spread = std::sqrt(mesh_axes.values[0]);
  if (!(mesh_spread > 0)) {
    throw Error(ErrorCode::kInvalidArgument,
                "the mesh's vertices all lie at one point: nothing to slice");
  }
  const double spread0 = std::sqrt(joint_axes.values[0]);
  const double spread1 = std::sqrt(joint_axes.values[1]);
  if (joints.size() >= 2 && spread0 > 1e-9 * mesh_spread &&
      spread1 > kCollinearRatio * spread0) {
    plane.u = joint_axes.axes[0];
    plane.v = joint_axes.axes[1];
    plane.how = "the two principal axes of the " +
                std::to_string(joints.size()) + " joint positions (PCA)";
  } else {
    plane.collinear_joints = true;
    if (joints.size() >= 2 && spread0 > 1e-9 * mesh_spread) {
      plane.u = joint_axes.axes[0];
      plane.how =
          "the line of the (nearly collinear) joints, and across it "
          "the direction in which the mesh spreads most";
    } else {
      // One joint, or all at one point: the mesh's own main axis.
      plane.u = mesh_axes.axes[0];
      plane.how =
          "the mesh's two principal axes (the joints are at one "
          "point)";
    }
    // The mesh's principal axis once u is projected out.
    const Eigen::Matrix3d across =
        Eigen::Matrix3d::Identity() - plane.u * plane.u.transpose();
    const Principal rest = principalAxes(across * mesh_covariance * across);
    plane.v = rest.axes[0] - rest.axes[0].dot(plane.u) * plane.u;
    if (!(plane.v.norm() > 1e-6)) {
      // No spread across u at all: any perpendicular direction.
      plane.v = plane.u.unitOrthogonal();
    }
    plane.v.normalize();
  }
  // Signs: u from the root joint (joint 0; parents precede children) to the
  // centroid when they differ, else canonical; v canonical.
  plane.u.normalize();
  const double root_along = (centroid - joints.front()).dot(plane.u);
  if (std::abs(root_along) > 1e-6 * mesh_spread) {
    if (root_along < 0) plane.u = -plane.u;
  } else {
    plane.u = canonicalSign(plane.u);
  }
  plane.v = canonicalSign(plane.v);
  plane.normal = plane.u.cross(plane.v).normalized();

  // Extent: the bounding box's corners projected on the plane.
  const Eigen::Vector3d lo =
      positions.colwise().minCoeff().transpose().cast<double>();
  const Eigen::Vector3d hi =
      positions.colwise().maxCoeff().transpose().cast<double>();
  double u_lo = INFINITY, u_hi = -INFINITY, v_lo = INFINITY, v_hi = -INFINITY;
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d p((corner & 1) ? hi.x() : lo.x(),
                            (corner & 2) ? hi.y() : lo.y(),
                            (corner & 4) ? hi.z() : lo.z());
    const Eigen::Vector3d d = p - plane.origin;
    u_lo = std::min(u_lo, d.dot(plane.u));
    u_hi = std::max(u_hi, d.dot(plane.u));
    v_lo = std::min(v_lo, d.dot(plane.v));
    v_hi = std::max(v_hi, d.dot(plane.v));
  }
  const double margin = kMarginFraction * std::max(u_hi - u_lo, v_hi - v_lo);
  plane.u_min = u_lo - margin;
  plane.u_max = u_hi + margin;
  plane.v_min = v_lo - margin;
  plane.v_max = v_hi + margin;
  const double extent_u = plane.u_max - plane.u_min;
  const double extent_v = plane.v_max - plane.v_min;
  plane.pixel = std::max(extent_u, extent_v) / size;
  plane.width =
      std::max(1, static_cast<int>(std::lround(extent_u / plane.pixel)));
  plane.height =
      std::max(1, static_cast<int>(std::lround(extent_v / plane.pixel)));
  // Centre the (rounded) picture on the box.
  const double u_mid = 0.5 * (plane.u_min + plane.u_max);
  const double v_mid = 0.5 * (plane.v_min + plane.v_max);
  plane.u_min = u_mid - 0.5 * plane.width * plane.pixel;
  plane.u_max = u_mid + 0.5 * plane.width * plane.pixel;
  plane.v_min = v_mid - 0.5 * plane.height * plane.pixel;
  plane.v_max = v_mid + 0.5 * plane.height * plane.pixel;
  return plane;
}

std::vector<Segment2> meshSection(const SlicePlane& plane,
                                  const Matrix3Xf& positions,
                                  const TriangleMatrix& triangles) {
  std::vector<double> side(positions.rows());
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    side[i] = plane.distance(positions.row(i).transpose().cast<double>());
  }
  std::vector<Segment2> segments;
  for (Eigen::Index t = 0; t < triangles.rows(); ++t) {
    Eigen::Vector2d ends[2];
    int found = 0;
    for (int e = 0; e < 3; ++e) {
      const int a = triangles(t, e);
      const int b = triangles(t, (e + 1) % 3);
      const bool above_a = side[a] >= 0;
      const bool above_b = side[b] >= 0;
      if (above_a == above_b) continue;
      const double s = side[a] / (side[a] - side[b]);
      const Eigen::Vector3d pa = positions.row(a).transpose().cast<double>();
      const Eigen::Vector3d pb = positions.row(b).transpose().cast<double>();
      if (found < 2) ends[found] = plane.toImage(pa + s * (pb - pa));
      ++found;
    }
    if (found == 2) segments.push_back({ends[0], ends[1]});
  }
  return segments;
}

}  // namespace isk::samples
