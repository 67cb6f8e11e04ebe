// Surface orientation (isk/core/surface_orientation.hpp): closed surfaces
// wound inside out are found per welded component, open sheets keep their
// winding; on hand-made meshes, the procedural rigs turned inside out, and
// the assets.
#include "isk/core/surface_orientation.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

// A unit cube at `origin`, its 12 triangles counter-clockwise seen from
// outside; seam copies of each corner per face, as importers split them.
void appendCube(Mesh* mesh, const Eigen::Vector3f& origin) {
  static const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                  {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  const int first = mesh->vertexCount();
  const int first_triangle = mesh->triangleCount();
  mesh->positions.conservativeResize(first + 24, 3);
  mesh->triangles.conservativeResize(first_triangle + 12, 3);
  for (int f = 0; f < 6; ++f) {
    for (int k = 0; k < 4; ++k) {
      const int c = faces[f][k];
      mesh->positions.row(first + 4 * f + k) =
          (origin + Eigen::Vector3f(c & 1, (c >> 1) & 1, (c >> 2) & 1))
              .transpose();
    }
    const int q = first + 4 * f;
    mesh->triangles.row(first_triangle + 2 * f) << q, q + 1, q + 2;
    mesh->triangles.row(first_triangle + 2 * f + 1) << q, q + 2, q + 3;
  }
  mesh->normals.setZero(mesh->vertexCount(), 3);
}

void flipTriangles(Mesh* mesh, int first, int count) {
  for (int t = first; t < first + count; ++t)
    std::swap(mesh->triangles(t, 1), mesh->triangles(t, 2));
}

TEST(SurfaceOrientation, ClosedCubeWoundOutwardKeepsItsWinding) {
  Mesh mesh;
  appendCube(&mesh, Eigen::Vector3f::Zero());
  const SurfaceOrientation o = SurfaceOrientation::of(mesh);
  EXPECT_EQ(o.component_count, 1);  // the seam copies are welded
  EXPECT_TRUE(o.inside_out.empty());
  for (int8_t s : o.triangle_sign) EXPECT_EQ(s, 1);
}

TEST(SurfaceOrientation, OnlyTheComponentWoundInsideOutIsTurned) {
  Mesh mesh;
  appendCube(&mesh, Eigen::Vector3f::Zero());
  appendCube(&mesh, Eigen::Vector3f(3, 0, 0));
  flipTriangles(&mesh, 12, 12);
  const SurfaceOrientation o = SurfaceOrientation::of(mesh);
  EXPECT_EQ(o.component_count, 2);
  ASSERT_EQ(o.inside_out.size(), 1u);
  EXPECT_EQ(o.inside_out[0].triangle_count, 12);
  EXPECT_GE(o.inside_out[0].vertex, 24);  // a vertex of the second cube
  EXPECT_NEAR(o.inside_out[0].signed_volume, -1.0, 1e-6);
  for (int t = 0; t < mesh.triangleCount(); ++t)
    EXPECT_EQ(o.triangle_sign[t], t < 12 ? 1 : -1) << "triangle " << t;
}

TEST(SurfaceOrientation, OpenSheetKeepsItsWindingEitherWay) {
  // A cube without its top face: open, but closed enough to have an inside
  // (its vector area is one face of five); a single face is a sheet.
  for (bool flipped : {false, true}) {
    SCOPED_TRACE(flipped ? "flipped" : "as built");
    Mesh box;
    appendCube(&box, Eigen::Vector3f::Zero());
    box.triangles.conservativeResize(10, 3);  // top face (z = 1) left out
    if (flipped) flipTriangles(&box, 0, 10);
    EXPECT_EQ(SurfaceOrientation::of(box).inside_out.size(), flipped ? 1u : 0u);
    Mesh sheet;
    appendCube(&sheet, Eigen::Vector3f::Zero());
    sheet.triangles.conservativeResize(2, 3);
    if (flipped) flipTriangles(&sheet, 0, 2);
    const SurfaceOrientation o = SurfaceOrientation::of(sheet);
    EXPECT_TRUE(o.inside_out.empty());
    for (int8_t s : o.triangle_sign) EXPECT_EQ(s, 1);
  }
}

TEST(SurfaceOrientation, ProceduralRigsTurnedInsideOutAreFound) {
  for (const std::string& name : builtinRigNames()) {
    SCOPED_TRACE(name);
    Mesh mesh = makeBuiltinRig(name).mesh;
    const SurfaceOrientation as_built = SurfaceOrientation::of(mesh);
    EXPECT_TRUE(as_built.inside_out.empty());
    flipTriangles(&mesh, 0, mesh.triangleCount());
    const SurfaceOrientation o = SurfaceOrientation::of(mesh);
    EXPECT_EQ(o.component_count, as_built.component_count);
    ASSERT_EQ(static_cast<int>(o.inside_out.size()), o.component_count);
    for (int8_t s : o.triangle_sign) ASSERT_EQ(s, -1);
  }
}

// The shared assets as their files wind them: animation_with_skeleton.fbx is
// one closed surface wound inside out (its signed volume is negative); every
// other asset's closed surfaces face outwards. Turned the other way round,
// what was inside out faces outwards and most triangles are inside out.
TEST(SurfaceOrientation, OnAssets) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("the orientation of the assets");
  for (const std::string& name : test::assetNames()) {
    SCOPED_TRACE(name);
    Mesh mesh = test::loadAsset(name).mesh;
    const SurfaceOrientation o = SurfaceOrientation::of(mesh);
    if (name == "animation_with_skeleton.fbx") {
      ASSERT_EQ(o.inside_out.size(), 1u);
      EXPECT_EQ(o.inside_out[0].triangle_count, mesh.triangleCount());
    } else {
      EXPECT_TRUE(o.inside_out.empty())
          << o.inside_out.size() << " components, the first through "
          << mesh.describeVertex(o.inside_out[0].vertex);
    }
    int turned = 0;
    for (int8_t s : o.triangle_sign) turned += s < 0;
    flipTriangles(&mesh, 0, mesh.triangleCount());
    const SurfaceOrientation flipped = SurfaceOrientation::of(mesh);
    int flipped_turned = 0;
    for (int8_t s : flipped.triangle_sign) flipped_turned += s < 0;
    std::cout << "[ orient   ] " << name << ": " << o.component_count
              << " components, " << turned << " triangles inside out as "
              << "read, " << flipped_turned << " turned inside out\n";
    EXPECT_EQ(flipped.component_count, o.component_count);
    for (int t = 0; t < mesh.triangleCount(); ++t)
      if (o.triangle_sign[t] < 0) ASSERT_EQ(flipped.triangle_sign[t], 1);
    // Only quad_skin.glb is a sheet, with no inside either way.
    if (name == "quad_skin.glb")
      EXPECT_EQ(turned + flipped_turned, 0);
    else
      EXPECT_GT(turned + flipped_turned, mesh.triangleCount() / 2);
  }
}

}  // namespace
}  // namespace isk
