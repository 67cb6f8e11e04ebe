// The plane isk-field-slices draws the fields in, and the mesh's section
// by it.
//
// The plane runs "along the skeleton": through the centroid of the joint
// positions, spanned by their two principal axes (PCA). When the joints are
// (nearly) collinear -- a chain of bones on one line, like the procedural
// rigs -- the second axis is the direction across the chain in which the
// mesh spreads most (the principal axis of the vertices once the first axis
// is projected out), e.g. the flat side of a hand.
//
// Image frame: u (the first axis) points right, v up; the picture covers the
// mesh's bounding box projected on the plane plus a margin of 10% of its
// longer side on every side, with square pixels.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "isk/core/types.hpp"

namespace isk::samples {

struct SlicePlane {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();   // centroid of the joints
  Eigen::Vector3d u = Eigen::Vector3d::UnitX();       // image right
  Eigen::Vector3d v = Eigen::Vector3d::UnitY();       // image up
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // u x v
  // Plane coordinates covered by the image (margin included).
  double u_min = 0, u_max = 1, v_min = 0, v_max = 1;
  double pixel = 1;  // model units per pixel
  int width = 1, height = 1;
  // True when the joints were (nearly) collinear and the mesh chose v.
  bool collinear_joints = false;
  // How the axes were chosen, one sentence.
  std::string how;

  // Model-space centre of pixel (x, y); y = 0 is the top row.
  Eigen::Vector3d pixelCentre(int x, int y) const;
  // Continuous image coordinates of a model-space point projected on the
  // plane: pixel (x, y) covers [x, x + 1) x [y, y + 1).
  Eigen::Vector2d toImage(const Eigen::Vector3d& p) const;
  // Signed distance of p to the plane (along `normal`).
  double distance(const Eigen::Vector3d& p) const;
};

// Fits the plane to `joints` (model space; at least one) and frames the
// mesh `positions` in an image whose longer side is `size` pixels. Throws
// isk::Error(kInvalidArgument) for an empty or flat-to-a-point mesh.
SlicePlane fitSlicePlane(const std::vector<Eigen::Vector3d>& joints,
                         const Matrix3Xf& positions, int size);

// A segment of the mesh's section, in continuous image coordinates.
struct Segment2 {
  Eigen::Vector2d a, b;
};

// Intersects every triangle with the plane. A vertex exactly on the plane
// counts as being on its positive side, so a section through vertices is
// drawn once and triangles lying in the plane give nothing.
std::vector<Segment2> meshSection(const SlicePlane& plane,
                                  const Matrix3Xf& positions,
                                  const TriangleMatrix& triangles);

}  // namespace isk::samples
