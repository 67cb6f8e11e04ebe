// LBS and DQS: OpenCL kernels against the CPU reference on every shared asset
// over its clip and on the procedural rigs; exactness properties of DQS; the
// bind pose reproduces the input; device normals against the reference.
#include "isk/cl/skinning.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "isk/core/dual_quaternion.hpp"
#include "isk/core/error.hpp"
#include "isk/core/vertex_normals.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/skinning/skinning.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using test::clipPoses;

constexpr SkinningMethod kMethods[] = {SkinningMethod::kLinearBlend,
                                       SkinningMethod::kDualQuaternion};

// Tolerances, relative to the bounding-box diagonal (positions) or absolute
// on unit normals. PoCL and the reference both run float math in the same
// order, so differences are a few ulps; GPUs may fuse multiply-adds.
float positionTolerance(const ClContext& context) {
  return context.info().is_gpu ? 2e-5f : 5e-6f;
}
float normalTolerance(const ClContext& context) {
  return context.info().is_gpu ? 2e-4f : 5e-5f;
}

struct Frame {
  Matrix3Xf positions;
  Matrix3Xf normals;
};

Frame skinOnCpu(const Rig& rig, SkinningMethod method,
                const TransformList& pose, bool recompute_normals) {
  CpuSkinning reference(rig.mesh, rig.weights, rig.skeleton.jointCount());
  reference.run(method, pose, recompute_normals);
  return {reference.positions(), reference.normals()};
}

// Runs both paths over the clip and compares every frame, both methods,
// skinned normals and recomputed normals.
void expectDeviceMatchesReference(const Rig& rig, const std::string& name,
                                  int frames) {
  auto context = test::sharedContext();
  ClSkinning device(context, rig.mesh, rig.weights, rig.skeleton.jointCount());
  const float diagonal = rig.boundingBoxDiagonal();
  const auto poses = clipPoses(rig, frames);
  const VertexTriangleAdjacency adjacency = VertexTriangleAdjacency::build(
      rig.mesh.triangles, rig.mesh.vertexCount());
  for (SkinningMethod method : kMethods) {
    for (bool recompute : {false, true}) {
      for (size_t f = 0; f < poses.size(); ++f) {
        const Frame expected = skinOnCpu(rig, method, poses[f], recompute);
        device.run(method, poses[f], recompute);
        Frame actual;
        device.readPositions(actual.positions);
        device.readNormals(actual.normals);
        const auto p =
            test::largestRowDistance(actual.positions, expected.positions);
        ASSERT_LE(p.distance, positionTolerance(*context) * diagonal)
            << name << " " << skinningMethodName(method) << " frame " << f
            << ": first worst vertex " << p.row << " ("
            << rig.mesh.describeVertex(p.row) << ")";
        // Recomputed normals are compared with the reference normals job run
        // on the device's positions: an area-weighted sum can cancel, and a
        // last-bit difference in positions (fused multiply-adds) then shows
        // up magnified in the normal's direction.
        Matrix3Xf expected_normals = expected.normals;
        if (recompute) {
          Matrix3Xf skinned_normals =
              skinOnCpu(rig, method, poses[f], false).normals;
          VertexNormalsJob normals;
          normals.positions = &actual.positions;
          normals.triangles = &rig.mesh.triangles;
          normals.adjacency = &adjacency;
          normals.fallback_normals = &skinned_normals;
          normals.out_normals = &expected_normals;
          normals.run();
        }
        const auto n =
            test::largestRowDistance(actual.normals, expected_normals);
        ASSERT_LE(n.distance, normalTolerance(*context))
            << name << " " << skinningMethodName(method)
            << (recompute ? " recomputed" : " skinned") << " normals, frame "
            << f << ": worst vertex " << n.row;
      }
    }
  }
}

TEST(Skinning, DeviceMatchesReferenceOnProceduralRigs) {
  for (const std::string& name : builtinRigNames()) {
    SCOPED_TRACE(name);
    expectDeviceMatchesReference(makeBuiltinRig(name), "builtin:" + name, 8);
  }
}

TEST(Skinning, DeviceMatchesReferenceOnEverySharedAssetOverItsClip) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("the asset comparisons");
  for (const std::string& file : test::assetNames()) {
    SCOPED_TRACE(file);
    expectDeviceMatchesReference(test::loadAsset(file), file, 12);
  }
}

// Unskinning (isk::unskinPoints, ClSkinning::enqueueUnskinPoints) inverts
// skinning: the skinned rest mesh goes back to the rest mesh; the device's
// unskinning and its skinning of other points than the rest mesh
// (enqueueSkinPoints) equal the reference's, both methods, over the clip.
void expectUnskinningInvertsSkinning(const Rig& rig, const std::string& name,
                                     int frames) {
  auto context = test::sharedContext();
  ClSkinning device(context, rig.mesh, rig.weights, rig.skeleton.jointCount());
  const float diagonal = rig.boundingBoxDiagonal();
  const int n = rig.mesh.vertexCount();
  const size_t bytes = 3 * sizeof(float) * static_cast<size_t>(n);
  cl::Buffer posed(context->context(), CL_MEM_READ_WRITE, bytes);
  cl::Buffer out(context->context(), CL_MEM_READ_WRITE, bytes);
  // Points off the rest mesh: each vertex moved along its normal.
  const Matrix3Xf points =
      rig.mesh.positions + 0.01f * diagonal * rig.mesh.normals;
  for (SkinningMethod method : kMethods) {
    for (const TransformList& pose : clipPoses(rig, frames)) {
      const Frame skinned = skinOnCpu(rig, method, pose, false);
      Matrix3Xf rest;
      unskinPoints(method, rig.weights, pose, skinned.positions, rest);
      const auto back = test::largestRowDistance(rest, rig.mesh.positions);
      ASSERT_LE(back.distance, 1e-5f * diagonal)
          << name << " " << skinningMethodName(method) << ": vertex "
          << back.row << " (" << rig.mesh.describeVertex(back.row) << ")";

      device.run(method, pose, false);
      context->queue().enqueueWriteBuffer(posed, CL_TRUE, 0, bytes,
                                          skinned.positions.data());
      device.enqueueUnskinPoints(posed, out);
      Matrix3Xf device_rest(n, 3);
      context->queue().enqueueReadBuffer(out, CL_TRUE, 0, bytes,
                                         device_rest.data());
      const auto unskin = test::largestRowDistance(device_rest, rest);
      ASSERT_LE(unskin.distance, positionTolerance(*context) * diagonal)
          << name << " " << skinningMethodName(method) << " unskinning: vertex "
          << unskin.row;

      Matrix3Xf expected, unused;
      const SkinningJob job{method,       &points, &rig.mesh.normals,
                            &rig.weights, &pose,   &expected,
                            &unused};
      job.run();
      context->queue().enqueueWriteBuffer(posed, CL_TRUE, 0, bytes,
                                          points.data());
      device.enqueueSkinPoints(posed, out);
      Matrix3Xf device_points(n, 3);
      context->queue().enqueueReadBuffer(out, CL_TRUE, 0, bytes,
                                         device_points.data());
      const auto skin = test::largestRowDistance(device_points, expected);
      ASSERT_LE(skin.distance, positionTolerance(*context) * diagonal)
          << name << " " << skinningMethodName(method)
          << " skinning of points: vertex " << skin.row;
    }
  }
}

TEST(Skinning, UnskinningInvertsSkinningOnProceduralRigs) {
  for (const std::string& name : builtinRigNames()) {
    SCOPED_TRACE(name);
    expectUnskinningInvertsSkinning(makeBuiltinRig(name), "builtin:" + name, 6);
  }
}

TEST(Skinning, UnskinningInvertsSkinningOnEverySharedAsset) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("the asset unskinnings");
  for (const std::string& file : test::assetNames()) {
    SCOPED_TRACE(file);
    expectUnskinningInvertsSkinning(test::loadAsset(file), file, 6);
  }
}

TEST(Skinning, UnskinningNeedsAFrameAndWholeBuffers) {
  const Rig rig = makeBuiltinRig("arm");
  auto context = test::sharedContext();
  ClSkinning device(context, rig.mesh, rig.weights, rig.skeleton.jointCount());
  const size_t bytes = 3 * sizeof(float) * rig.mesh.vertexCount();
  cl::Buffer whole(context->context(), CL_MEM_READ_WRITE, bytes);
  cl::Buffer short_buffer(context->context(), CL_MEM_READ_WRITE, bytes / 2);
  EXPECT_THROW(device.enqueueUnskinPoints(whole, whole), Error);
  device.run(SkinningMethod::kDualQuaternion, bindPoseSkinning(rig.skeleton));
  try {
    device.enqueueSkinPoints(whole, short_buffer);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("fewer than"), std::string::npos)
        << e.what();
  }
  Matrix3Xf rest;
  EXPECT_THROW(unskinPoints(SkinningMethod::kDualQuaternion, rig.weights,
                            TransformList(1), rig.mesh.positions, rest),
               Error);
}

// The bind pose gives identity skinning transforms: both methods, both paths
// give back the input exactly (up to float rounding).
void expectBindPoseReproducesInput(const Rig& rig, const std::string& name) {
  auto context = test::sharedContext();
  ClSkinning device(context, rig.mesh, rig.weights, rig.skeleton.jointCount());
  const TransformList pose = bindPoseSkinning(rig.skeleton);
  const float tolerance = 1e-6f * rig.boundingBoxDiagonal();
  for (SkinningMethod method : kMethods) {
    const Frame cpu = skinOnCpu(rig, method, pose, false);
    device.run(method, pose, false);
    Frame gpu;
    device.readPositions(gpu.positions);
    device.readNormals(gpu.normals);
    for (const Frame* frame : std::initializer_list<const Frame*>{&cpu, &gpu}) {
      const auto p =
          test::largestRowDistance(frame->positions, rig.mesh.positions);
      EXPECT_LE(p.distance, tolerance)
          << name << " " << skinningMethodName(method) << ": vertex " << p.row
          << " moved";
      const auto n = test::largestRowDistance(frame->normals, rig.mesh.normals);
      EXPECT_LE(n.distance, 1e-5f)
          << name << ": normal of vertex " << n.row << " changed";
    }
  }
}

TEST(Skinning, BindPoseReproducesInputOnProceduralRigs) {
  for (const std::string& name : builtinRigNames()) {
    expectBindPoseReproducesInput(makeBuiltinRig(name), "builtin:" + name);
  }
}

TEST(Skinning, BindPoseReproducesInputOnSharedAssets) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("the asset bind poses");
  for (const std::string& file : test::assetNames()) {
    expectBindPoseReproducesInput(test::loadAsset(file), file);
  }
}

// One rigid motion applied to every joint: DQS (and LBS) must move the mesh
// rigidly, exactly as the transform does, whatever the weights.
void expectRigidMotionIsExact(const Rig& rig, const std::string& name) {
  const Eigen::Affine3f motion =
      Eigen::Translation3f(0.3f, -1.2f, 2.5f) *
      Eigen::AngleAxisf(2.6f, Eigen::Vector3f(1.f, 2.f, -0.5f).normalized());
  const TransformList pose(rig.skeleton.joints.size(), motion);
  Matrix3Xf expected =
      (rig.mesh.positions * motion.linear().transpose()).rowwise() +
      motion.translation().transpose();
  auto context = test::sharedContext();
  ClSkinning device(context, rig.mesh, rig.weights, rig.skeleton.jointCount());
  const float tolerance =
      1e-5f * (rig.boundingBoxDiagonal() + motion.translation().norm());
  for (SkinningMethod method : kMethods) {
    const Frame cpu = skinOnCpu(rig, method, pose, false);
    device.run(method, pose, false);
    Frame gpu;
    device.readPositions(gpu.positions);
    for (const Frame* frame : std::initializer_list<const Frame*>{&cpu, &gpu}) {
      const auto p = test::largestRowDistance(frame->positions, expected);
      EXPECT_LE(p.distance, tolerance)
          << name << " " << skinningMethodName(method) << ": vertex " << p.row;
    }
  }
}

TEST(Skinning, SingleRigidMotionIsExact) {
  expectRigidMotionIsExact(makeBuiltinRig("arm"), "builtin:arm");
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("CesiumMan");
  expectRigidMotionIsExact(test::loadAsset("CesiumMan.glb"), "CesiumMan.glb");
}

// A single-bone vertex under DQS follows its bone exactly.
TEST(Skinning, DualQuaternionOfSingleBoneVertexIsExact) {
  Rig rig = makeCylinderRig();
  TransformList pose = bindPoseSkinning(rig.skeleton);
  const Eigen::Affine3f bend =
      Eigen::Translation3f(4.f, 0.f, 0.f) *
      Eigen::AngleAxisf(2.0f, Eigen::Vector3f::UnitZ()) *
      Eigen::Translation3f(-4.f, 0.f, 0.f);
  pose[1] = bend;
  const Frame frame =
      skinOnCpu(rig, SkinningMethod::kDualQuaternion, pose, false);
  int checked = 0;
  for (int v = 0; v < rig.mesh.vertexCount(); ++v) {
    if (rig.weights.influenceCount(v) != 1) continue;
    const Eigen::Vector3f rest = rig.mesh.positions.row(v).transpose();
    const bool on_bone1 = rig.weights.joints[rig.weights.offsets[v]] == 1;
    const Eigen::Vector3f expected =
        on_bone1 ? Eigen::Vector3f(bend * rest) : rest;
    ASSERT_LE((frame.positions.row(v).transpose() - expected).norm(), 1e-5f)
        << "vertex " << v;
    ++checked;
  }
  EXPECT_GT(checked, rig.mesh.vertexCount() / 2);
}

// Two joints rotating about one axis by 0 and 190 degrees, a vertex weighted
// half and half: with the pivot-based antipodality fix the blend takes the
// short way (-85 degrees), not the long one (+95).
TEST(Skinning, DualQuaternionBlendTakesTheShortWayAroundAntipodes) {
  Rig rig;
  rig.mesh.positions.resize(3, 3);
  rig.mesh.positions << 1, 0, 0, 0, 1, 0, 0, 0, 1;
  rig.mesh.normals = rig.mesh.positions;
  rig.mesh.triangles.resize(1, 3);
  rig.mesh.triangles << 0, 1, 2;
  for (int j = 0; j < 2; ++j) {
    Joint joint;
    joint.name = "j" + std::to_string(j);
    joint.parent = j - 1;
    joint.rest_local = Eigen::Affine3f::Identity();
    joint.inverse_bind = Eigen::Affine3f::Identity();
    rig.skeleton.joints.push_back(joint);
  }
  rig.weights = SkinWeights::fromLists(
      {{{0, 0.5f}, {1, 0.5f}}, {{0, 0.5f}, {1, 0.5f}}, {{0, 0.5f}, {1, 0.5f}}});
  rig.weights.sortByWeight();
  ASSERT_TRUE(rig.validate()) << rig.validate().reason();
  const float kDegree = 3.14159265f / 180.f;
  TransformList pose = bindPoseSkinning(rig.skeleton);
  pose[1] = Eigen::AngleAxisf(190.f * kDegree, Eigen::Vector3f::UnitZ());
  const Eigen::Vector3f expected =
      Eigen::AngleAxisf(-85.f * kDegree, Eigen::Vector3f::UnitZ()) *
      Eigen::Vector3f::UnitX();
  const Frame cpu =
      skinOnCpu(rig, SkinningMethod::kDualQuaternion, pose, false);
  EXPECT_LE((cpu.positions.row(0).transpose() - expected).norm(), 1e-5f)
      << "got " << cpu.positions.row(0);
  ClSkinning device(test::sharedContext(), rig.mesh, rig.weights, 2);
  device.run(SkinningMethod::kDualQuaternion, pose, false);
  Frame gpu;
  device.readPositions(gpu.positions);
  EXPECT_LE((gpu.positions.row(0).transpose() - expected).norm(), 1e-5f)
      << "got " << gpu.positions.row(0);
}

TEST(Skinning, DualQuaternionPreservesVolumeBetterThanLinearBlendOnTwist) {
  // A 150 degree twist of the second bone: LBS collapses the joint (the
  // candy-wrapper effect), DQS does not.
  Rig rig = makeCylinderRig();
  TransformList pose = bindPoseSkinning(rig.skeleton);
  pose[1] = Eigen::AngleAxisf(2.6f, Eigen::Vector3f::UnitX());
  const double rest = enclosedVolume(rig.mesh.positions, rig.mesh.triangles);
  const double lbs = enclosedVolume(
      skinOnCpu(rig, SkinningMethod::kLinearBlend, pose, false).positions,
      rig.mesh.triangles);
  const double dqs = enclosedVolume(
      skinOnCpu(rig, SkinningMethod::kDualQuaternion, pose, false).positions,
      rig.mesh.triangles);
  EXPECT_GT(rest, 0.0);
  EXPECT_LT(lbs / rest, 0.97);
  EXPECT_NEAR(dqs / rest, 1.0, 0.01);
}

TEST(Skinning, ValidateReportsBadInputs) {
  Rig rig = makeCylinderRig();
  TransformList pose = bindPoseSkinning(rig.skeleton);
  Matrix3Xf positions, normals;
  SkinningJob job;
  EXPECT_FALSE(job.validate());
  job.rest_positions = &rig.mesh.positions;
  job.rest_normals = &rig.mesh.normals;
  job.weights = &rig.weights;
  job.skinning = &pose;
  job.out_positions = &positions;
  job.out_normals = &normals;
  EXPECT_TRUE(job.validate()) << job.validate().reason();
  TransformList short_pose(1, Eigen::Affine3f::Identity());
  job.skinning = &short_pose;
  EXPECT_FALSE(job.validate());
  EXPECT_NE(job.validate().reason().find("transforms were given"),
            std::string::npos);
  EXPECT_THROW(job.run(), Error);
  TransformList nan_pose = pose;
  nan_pose[0].matrix()(0, 0) = std::nanf("");
  job.skinning = &nan_pose;
  EXPECT_FALSE(job.validate());
  // Both backends reject a pose of the wrong size with a reason too.
  CpuSkinning reference(rig.mesh, rig.weights, rig.skeleton.jointCount());
  EXPECT_THROW(reference.run(SkinningMethod::kLinearBlend, short_pose), Error);
  ClSkinning device(test::sharedContext(), rig.mesh, rig.weights,
                    rig.skeleton.jointCount());
  try {
    device.run(SkinningMethod::kDualQuaternion, short_pose);
    FAIL() << "a pose of the wrong size was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("1 joint transforms given"),
              std::string::npos);
  }
}

TEST(VertexNormals, ReferenceGivesOutwardUnitNormalsOnClosedRig) {
  Rig rig = makeCylinderRig();
  const Frame frame = skinOnCpu(rig, SkinningMethod::kDualQuaternion,
                                bindPoseSkinning(rig.skeleton), true);
  for (int v = 0; v < rig.mesh.vertexCount(); ++v) {
    ASSERT_NEAR(frame.normals.row(v).norm(), 1.f, 1e-5f) << "vertex " << v;
    // Side vertices: the normal points away from the axis.
    const Eigen::Vector3f p = rig.mesh.positions.row(v).transpose();
    if (p.x() > 0.5f && p.x() < 7.5f) {
      const Eigen::Vector3f radial(0.f, p.y(), p.z());
      ASSERT_GT(frame.normals.row(v).dot(radial.normalized().transpose()),
                0.99f)
          << "vertex " << v;
    }
  }
}

TEST(VertexNormals, IsolatedAndDegenerateVerticesTakeTheFallback) {
  Matrix3Xf positions(5, 3);
  positions << 0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 2, 2, 3, 3, 3;
  TriangleMatrix triangles(2, 3);
  triangles << 0, 1, 2, 3, 3, 4;  // second triangle is degenerate
  Matrix3Xf fallback = Matrix3Xf::Zero(5, 3);
  fallback.col(0).setOnes();
  const auto adjacency = VertexTriangleAdjacency::build(triangles, 5);
  Matrix3Xf out;
  VertexNormalsJob job{&positions, &triangles, &adjacency, &fallback, &out};
  job.run();
  EXPECT_NEAR(out(0, 2), 1.f, 1e-6f);
  EXPECT_EQ(out.row(3), fallback.row(3));
  EXPECT_EQ(out.row(4), fallback.row(4));
}

// Area weighting and winding on a fan whose vertex 0 is in every triangle
// (one of them, 2 -> 3 -> 0, folded down out of the plane) and whose
// vertex 5 is in none: each vertex's normal is the sum of the cross
// products (b - a) x (c - a) of its triangles, normalized, on both paths
// (the kernels take each triangle's product once, then sum per vertex).
TEST(VertexNormals, EachVertexSumsItsTrianglesCrossProductsOnBothPaths) {
  Mesh mesh;
  mesh.positions.resize(6, 3);
  mesh.positions << 0, 0, 0, 2, 0, 0, 0, 1, 0, -1, 0, -1, 0, -3, 0, 5, 5, 5;
  mesh.normals.resize(6, 3);
  mesh.normals.setZero();
  mesh.normals.col(0).setOnes();  // the fallback of vertex 5
  mesh.triangles.resize(4, 3);
  mesh.triangles << 0, 1, 2, 2, 3, 0, 3, 4, 0, 4, 1, 0;
  const auto adjacency = VertexTriangleAdjacency::build(mesh.triangles, 6);
  ASSERT_EQ(adjacency.offsets[1] - adjacency.offsets[0], 4u);  // vertex 0
  ASSERT_EQ(adjacency.offsets[6], adjacency.offsets[5]);       // vertex 5
  Matrix3Xf expected(6, 3);
  for (int v = 0; v < 6; ++v) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int t = 0; t < 4; ++t) {
      if ((mesh.triangles.row(t).array() != v).all()) continue;
      const Eigen::Vector3d a =
          mesh.positions.row(mesh.triangles(t, 0)).transpose().cast<double>();
      const Eigen::Vector3d b =
          mesh.positions.row(mesh.triangles(t, 1)).transpose().cast<double>();
      const Eigen::Vector3d c =
          mesh.positions.row(mesh.triangles(t, 2)).transpose().cast<double>();
      sum += (b - a).cross(c - a);
    }
    if (v == 5)
      expected.row(v) = mesh.normals.row(5);
    else
      expected.row(v) = sum.normalized().cast<float>().transpose();
  }
  // Vertex 0: (0, 0, 2) + (-1, 0, 1) + (-3, 0, 3) + (0, 0, 6), the folded
  // triangles tilting it towards -x.
  EXPECT_NEAR(expected(0, 0), -4.f / std::sqrt(160.f), 1e-6f);
  EXPECT_NEAR(expected(0, 2), 12.f / std::sqrt(160.f), 1e-6f);
  Matrix3Xf reference;
  VertexNormalsJob job{&mesh.positions, &mesh.triangles, &adjacency,
                       &mesh.normals, &reference};
  job.run();
  const SkinWeights weights = SkinWeights::fromLists(
      std::vector<std::vector<std::pair<int, float>>>(6, {{0, 1.f}}));
  ClSkinning device(test::sharedContext(), mesh, weights, 1);
  device.run(SkinningMethod::kDualQuaternion,
             {Eigen::Affine3f(Eigen::Affine3f::Identity())}, true);
  Matrix3Xf device_normals;
  device.readNormals(device_normals);
  for (int v = 0; v < 6; ++v) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(reference(v, k), expected(v, k), 1e-6f)
          << "reference, vertex " << v << ", axis " << k;
      EXPECT_NEAR(device_normals(v, k), expected(v, k), 1e-6f)
          << "device, vertex " << v << ", axis " << k;
    }
  }
}

// A triangle whose cross product passes FLT_MAX (a joint scaled by 1e20):
// the sum is (0, 0, inf), which normalizes to NaN; both paths must take the
// fallback instead. NVIDIA's OpenCL contracts the cross product into fused
// multiply-adds and got inf where plain products give NaN, which the old
// length test let through.
TEST(VertexNormals, OverflowingCrossProductsTakeTheFallbackOnBothPaths) {
  Mesh mesh;
  mesh.positions.resize(3, 3);
  mesh.positions << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  mesh.normals.resize(3, 3);
  mesh.normals << 0, 0, 1, 0, 0, 1, 0, 0, 1;
  mesh.triangles.resize(1, 3);
  mesh.triangles << 0, 1, 2;
  const SkinWeights weights =
      SkinWeights::fromLists({{{0, 1.f}}, {{0, 1.f}}, {{0, 1.f}}});
  const TransformList pose = {Eigen::Affine3f(Eigen::Scaling(1e20f))};
  CpuSkinning reference(mesh, weights, 1);
  ClSkinning device(test::sharedContext(), mesh, weights, 1);
  for (const bool recompute : {false, true}) {
    reference.run(SkinningMethod::kLinearBlend, pose, recompute);
    device.run(SkinningMethod::kLinearBlend, pose, recompute);
    Matrix3Xf device_normals;
    device.readNormals(device_normals);
    const char* what = recompute ? "recomputed" : "skinned";
    for (int v = 0; v < 3; ++v) {
      EXPECT_EQ(reference.normals().row(v), mesh.normals.row(v))
          << "reference, " << what << ", vertex " << v;
      EXPECT_EQ(device_normals.row(v), mesh.normals.row(v))
          << "device, " << what << ", vertex " << v;
    }
  }
  // The normals job alone on positions whose cross product is (0, 0, inf).
  Matrix3Xf positions(3, 3);
  positions << 0, 0, 0, 1e20f, 0, 0, 0, 1e20f, 0;
  const auto adjacency = VertexTriangleAdjacency::build(mesh.triangles, 3);
  Matrix3Xf out;
  VertexNormalsJob job{&positions, &mesh.triangles, &adjacency, &mesh.normals,
                       &out};
  job.run();
  for (int v = 0; v < 3; ++v)
    EXPECT_EQ(out.row(v), mesh.normals.row(v)) << "normals job, vertex " << v;
}

}  // namespace
}  // namespace isk
