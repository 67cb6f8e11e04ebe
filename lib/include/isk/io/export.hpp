// Writing deformed frames as OBJ (text) or PLY (binary little endian).
//
// The writers are ours rather than OpenMesh's: OpenMesh's halfedge mesh drops
// non-manifold triangles ("complex edge") on insertion, and an export must
// keep every triangle and the input vertex order. Files are written to a
// temporary name beside the target and renamed when complete, so a failure
// never leaves a partial file under the final name; only a regular file is
// ever replaced, and the target's folder must exist.
#pragma once

#include <string>

#include "isk/core/types.hpp"

namespace isk {

// OBJ: text, "v x y z", "vn", "f a//a b//b c//c" (1-based). PLY: binary
// little endian, float x y z (nx ny nz), uchar-counted int triangles.
enum class MeshFormat { kObj, kPly };

// Throws isk::Error(kIo) naming the path when it cannot be written.
// `positions` and `normals` #V by 3, `triangles` #F by 3 (0-based, written
// as the format wants); `normals` may be null (no normals written).
void writeMesh(const std::string& path, MeshFormat format,
               const Matrix3Xf& positions, const Matrix3Xf* normals,
               const TriangleMatrix& triangles);

// Writes `text` (any bytes) to `path` the same way (temporary file, then
// rename). Throws isk::Error(kIo) naming the path.
void writeTextFile(const std::string& path, const std::string& text);

}  // namespace isk
