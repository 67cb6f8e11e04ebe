// isk-frame-pictures: its OBJ reader against isk::writeMesh and bad files,
// the close-up's target (the new intersecting pairs, else the vertex farthest
// from the reference frame), vertical stacking, and the program end to end
// on frames of a bent cylinder (a PNG, refusals that leave files alone).
#include "frame_pictures.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include "isk/core/error.hpp"
#include "isk/io/export.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "isk/tools/procedural.hpp"
#include "isk/tools/self_intersection.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using test::ScopedTempDir;

Matrix3Xf bentCylinder(const Rig& rig, SkinningMethod method, float angle) {
  const AnimationClip bend = makeBendClip(rig.skeleton, angle, 1.0);
  const TransformList skinning = skinningTransforms(
      rig.skeleton,
      globalTransforms(rig.skeleton, bend.sampleLocal(rig.skeleton, 1.0)));
  CpuSkinning skinner(rig.mesh, rig.weights, rig.skeleton.jointCount());
  skinner.run(method, skinning, false);
  return skinner.positions();
}

TEST(FramePictures, ReadsBackWhatWriteMeshWrites) {
  const Rig rig = makeCylinderRig();
  ScopedTempDir dir;
  const std::string path = dir / "frame.obj";
  writeMesh(path, MeshFormat::kObj, rig.mesh.positions, &rig.mesh.normals,
            rig.mesh.triangles);
  const samples::ObjMesh mesh = samples::readObjMesh(path);
  EXPECT_EQ(mesh.triangles, rig.mesh.triangles);
  ASSERT_EQ(mesh.positions.rows(), rig.mesh.positions.rows());
  EXPECT_LT((mesh.positions - rig.mesh.positions).cwiseAbs().maxCoeff(), 1e-6f);
}

TEST(FramePictures, BadObjFilesNameTheLine) {
  ScopedTempDir dir;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", ":4:"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3 4\n", ":5:"},
      {"v 0 0\n", ":1:"},
      {"v 0 0 0\nf 1 x 1\n", ":2:"},
  };
  for (const auto& [text, where] : cases) {
    const std::string path = dir / "bad.obj";
    std::ofstream(path) << text;
    try {
      samples::readObjMesh(path);
      ADD_FAILURE() << "no error for:\n" << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(path + where), std::string::npos)
          << e.what();
    }
  }
  EXPECT_THROW(samples::readObjMesh(dir / "missing.obj"), Error);
  // Negative (relative) indices and slashes are read.
  const std::string path = dir / "relative.obj";
  std::ofstream(path) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3/1 -2//1 -1/2/3\n";
  const samples::ObjMesh mesh = samples::readObjMesh(path);
  EXPECT_EQ(mesh.triangles.row(0), Eigen::RowVector3i(0, 1, 2));
}

TEST(FramePictures, CloseUpAimsAtTheNewPairsElseTheFarthestVertex) {
  const Rig rig = makeCylinderRig();
  samples::ObjMesh frame{bentCylinder(rig, SkinningMethod::kLinearBlend, 2.4f),
                         rig.mesh.triangles};
  const std::vector<int> groups = coincidentVertexGroups(rig.mesh.positions);
  std::vector<std::pair<int, int>> pairs;
  countSelfIntersections(frame.positions, frame.triangles, &groups, &pairs);
  ASSERT_FALSE(pairs.empty());
  const float diagonal = boundingBoxDiagonal(rig.mesh.positions);
  const samples::FocusView on_pairs =
      samples::worstPlaceView(frame, pairs, nullptr, diagonal);
  // The target lies among the intersecting triangles: near one of them.
  float nearest = 1e30f;
  for (const auto& [a, b] : pairs) {
    for (int k = 0; k < 3; ++k) {
      nearest = std::min(
          nearest, (frame.positions.row(frame.triangles(a, k)).transpose() -
                    on_pairs.view.target)
                       .norm());
    }
  }
  EXPECT_LT(nearest, 0.12f * diagonal);
  EXPECT_NEAR(on_pairs.view.half_height, 0.12f * diagonal, 1e-5f);
  EXPECT_NE(on_pairs.reason.find("new intersecting pairs"), std::string::npos);

  Matrix3Xf reference = frame.positions;
  reference.row(17) += Eigen::RowVector3f(0, 0, 3);
  const samples::FocusView on_vertex =
      samples::worstPlaceView(frame, {}, &reference, diagonal);
  EXPECT_LT(
      (on_vertex.view.target - frame.positions.row(17).transpose()).norm(),
      1e-6f);
  EXPECT_NEAR(on_vertex.view.direction.norm(), 1.f, 1e-5f);
}

TEST(FramePictures, StacksRowsCentred) {
  samples::Image top(10, 4), bottom(6, 3);
  top.set(0, 0, {1, 2, 3});
  bottom.set(0, 0, {4, 5, 6});
  const samples::Image both = samples::stackVertically({top, bottom});
  EXPECT_EQ(both.width, 10);
  EXPECT_EQ(both.height, 4 + 3 + samples::kPanelGap);
  EXPECT_EQ(both.get(0, 0), (samples::Rgb{1, 2, 3}));
  EXPECT_EQ(both.get(2, 4 + samples::kPanelGap), (samples::Rgb{4, 5, 6}));
  EXPECT_THROW(samples::stackVertically({}), Error);
}

TEST(FramePictures, ProgramWritesAPictureAndRefusesToOverwrite) {
  const Rig rig = makeCylinderRig();
  ScopedTempDir dir;
  writeMesh(dir / "rest.obj", MeshFormat::kObj, rig.mesh.positions, nullptr,
            rig.mesh.triangles);
  writeMesh(dir / "lbs.obj", MeshFormat::kObj,
            bentCylinder(rig, SkinningMethod::kLinearBlend, 2.4f), nullptr,
            rig.mesh.triangles);
  writeMesh(dir / "dqs.obj", MeshFormat::kObj,
            bentCylinder(rig, SkinningMethod::kDualQuaternion, 2.4f), nullptr,
            rig.mesh.triangles);
  const std::vector<std::string> args = {"--rest",    dir / "rest.obj",
                                         "--out",     dir / "p.png",
                                         "--frame",   dir / "lbs.obj",
                                         "--caption", "LBS",
                                         "--frame",   dir / "dqs.obj",
                                         "--caption", "DQS",
                                         "--size",    "96",
                                         "--focus",   "0"};
  const test::RunOutput run = test::runProgram(ISK_FRAME_PICTURES_EXE, args);
  ASSERT_EQ(run.exit_code, 0)
      << test::describeRun("isk-frame-pictures", args, run);
  const std::string png = test::readFile(dir / "p.png");
  const test::PngHeader header = test::parsePngHeader(png);
  ASSERT_TRUE(header.valid);
  EXPECT_EQ(header.width, 2u * 96 + samples::kPanelGap);
  // A second run refuses to replace it; a frame of another mesh is refused.
  const test::RunOutput again = test::runProgram(ISK_FRAME_PICTURES_EXE, args);
  EXPECT_NE(again.exit_code, 0);
  EXPECT_NE(again.output.find("--overwrite"), std::string::npos)
      << again.output;
  EXPECT_EQ(test::readFile(dir / "p.png"), png);
  std::ofstream(dir / "other.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const std::vector<std::string> other = {"--rest",  dir / "rest.obj",
                                          "--out",   dir / "q.png",
                                          "--frame", dir / "other.obj"};
  const test::RunOutput refused =
      test::runProgram(ISK_FRAME_PICTURES_EXE, other);
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.output.find("not a frame of"), std::string::npos)
      << refused.output;
}

}  // namespace
}  // namespace isk
