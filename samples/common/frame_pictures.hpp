// isk-frame-pictures' host-only parts: reading back the OBJ frames isk-skin
// writes, and where a frame looks worst (the close-up's target and its
// direction of view), so that QUALITY.md can show each asset's worst frame
// with the methods side by side.
#pragma once

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "isk/core/types.hpp"
#include "mesh_render.hpp"

namespace isk::samples {

// A triangle mesh read back from an OBJ file: #V by 3 positions, #F by 3
// triangles (0-based).
struct ObjMesh {
  Matrix3Xf positions;
  TriangleMatrix triangles;
};

// Reads the "v" and "f" lines of `path` (faces of three corners, "a",
// "a/b", "a//c" or "a/b/c", 1-based or negative); other lines are skipped.
// Throws isk::Error(kIo) naming the file and line for a file that cannot be
// read, a malformed line, a face that is not a triangle or an index out of
// range.
ObjMesh readObjMesh(const std::string& path);

// Where the picture of `frame` looks: at the densest cluster of the
// triangles of `pairs` (intersecting pairs new against the rest pose), else
// at the vertex farthest from `reference` (the same mesh in another frame,
// e.g. DQS; skipped when null or of another size), seen from outside along
// the mean normal there. `half_height` frames a close-up of `close_fraction`
// of the rest diagonal `diagonal`. `reason` says which of the two it is.
struct FocusView {
  RenderView view;
  std::string reason;
};
FocusView worstPlaceView(const ObjMesh& frame,
                         const std::vector<std::pair<int, int>>& pairs,
                         const Matrix3Xf* reference, float diagonal,
                         float close_fraction = 0.12f);

// Panels stacked top to bottom on white, kPanelGap apart, each centred;
// throws isk::Error(kInvalidArgument) for none.
Image stackVertically(const std::vector<Image>& rows);

}  // namespace isk::samples
