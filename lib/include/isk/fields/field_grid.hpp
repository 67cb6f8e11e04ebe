// Baked fields: each bone's f_i sampled on a regular grid of float4
// (value, gradient x y z) over its support box, in the bone's frame
// (Vaillant et al. 2013, section 6: 32^3 textures, trilinear interpolation).
//
// Node (i, j, k) sits at box.min + (i, j, k) * spacing, i fastest in memory
// (the layout of a 3D image). Between nodes the four channels are
// interpolated trilinearly; outside the box the value and the gradient are 0.
// Gradients are analytic (chain rule through t_r), in the bone frame.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "isk/core/types.hpp"
#include "isk/fields/bone_field.hpp"

namespace isk {

// One bone's baked field. Lengths in model units.
struct FieldGrid {
  int joint = -1;       // the field's joint (skeleton index)
  int resolution = 32;  // nodes per axis
  // Bone frame (origin at the joint, x along the bone) to model space at the
  // bind pose.
  Eigen::Isometry3f bone_to_model = Eigen::Isometry3f::Identity();
  Eigen::Vector3f box_min = {0, 0, 0};  // bone frame: the support box
  Eigen::Vector3f box_max = {0, 0, 0};
  // resolution^3 * 4 floats: (value, gradient x y z) per node, node
  // (i, j, k) at floats 4 * (i + N * (j + N * k)).
  std::vector<float> nodes;

  // Distance between neighbouring nodes along x, y and z (bone frame).
  Eigen::Vector3f spacing() const {
    return (box_max - box_min) / static_cast<float>(resolution - 1);
  }
  // Size of `nodes` in bytes.
  size_t bytes() const { return nodes.size() * sizeof(float); }

  // Trilinear sample at a bone-frame point: value and bone-frame gradient
  // (0 outside the box). The kernels' buffer path does exactly this.
  Eigen::Vector4f sampleLocal(const Eigen::Vector3f& local) const;
};

// Bakes `field` at `resolution`^3 nodes over its support box. Throws
// isk::Error(kInvalidArgument) for a resolution below 2.
FieldGrid bakeField(const BoneField& field, int resolution = 32);

// The cells of `grid` that can interpolate to non-zero: one bit per cell,
// (resolution - 1)^3 cells, cell (i, j, k) (nodes i..i+1, j..j+1, k..k+1)
// at bit i + (N - 1) * (j + (N - 1) * k), 32 per word, lowest bit first;
// ceil((N - 1)^3 / 32) words. A bit is set when any of the cell's 8 nodes
// has a non-zero value or gradient component: a sample in a clear cell is
// exactly zero, so the kernels skip its loads (most of a support box lies
// outside the field's compact support).
std::vector<uint32_t> occupiedCells(const FieldGrid& grid);

// The bone-frame box of the cells occupiedCells sets: every sample of
// `grid` outside it is exactly 0 (the support's tight box, within the
// support box). Empty (isEmpty()) when no cell is set.
Eigen::AlignedBox3f occupiedBox(const FieldGrid& grid);

// An upper bound of `grid`'s value in each cell, one byte per cell in
// occupiedCells' order ((resolution - 1)^3 bytes): 0 when the cell's bit in
// occupiedCells is clear (the samples there are zero), else b with every
// value interpolated in the cell (a convex combination of its 8 nodes'
// values) below b / 255, with at least 1 / 255 to spare (b = floor(255 m)
// + 2 for the largest node value m, at most 255; 255: no bound). The
// tracking kernel skips the loads of a field whose bound shows it can
// change nothing at a point (the tracking tuning's value_bounds).
std::vector<uint8_t> cellValueBounds(const FieldGrid& grid);

// Precision of the grid nodes (FieldGridSet::precision).
enum class GridPrecision {
  kFloat,  // 32-bit floats, as baked
  // Every node rounded to the nearest 16-bit IEEE float (roundGridsToHalf):
  // OpenCL devices store halves (half the memory of the field data), the
  // CPU reference samples the same rounded values as floats.
  kHalf,
};

// "float", "half".
const char* gridPrecisionName(GridPrecision precision);

// All baked fields of a character, ready to upload.
struct FieldGridSet {
  std::vector<FieldGrid> grids;     // one per field, in joint order
  std::vector<int> field_of_joint;  // #joints: index into grids, -1 if none
  int resolution = 32;
  // kHalf: every node is a half-precision value (roundGridsToHalf).
  GridPrecision precision = GridPrecision::kFloat;

  int fieldCount() const { return static_cast<int>(grids.size()); }
  // Bytes of every grid's nodes.
  size_t bytes() const;
};

// Rounds every node of every grid to the nearest half-precision value
// (round to nearest even; values below half's smallest subnormal become 0)
// and sets `grids.precision` to kHalf. Throws isk::Error(kInvalidArgument)
// naming the field's joint and the node when a component's magnitude
// exceeds 65504, half's largest value (a gradient that steep means model
// units far too small for half precision); `grids` is unchanged then.
void roundGridsToHalf(FieldGridSet& grids);

}  // namespace isk
