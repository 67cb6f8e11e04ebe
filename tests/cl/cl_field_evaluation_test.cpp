// Baked implicit fields on the OpenCL device (kernels/fields/) against the
// CPU reference FieldEvaluationJob, through both storages (image atlas and
// buffer), on the procedural rigs and every shared asset, at the bind pose
// and at a frame of the rig's first clip; points are the skinned vertices
// plus random points around them. Also: exact zeros outside every box, input
// validation, the automatic choice of storage, and the device-buffer path
// fed by ClSkinning's positions.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>

#include "field_pictures.hpp"
#include "isk/cl/field_evaluation.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/core/error.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/skinning.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

constexpr FieldStorage kStorages[] = {FieldStorage::kImage,
                                      FieldStorage::kBuffer};

// Tolerances: value absolute (fields lie in [0, 1]), gradient relative to the
// largest gradient norm of the field compared. Both storages interpolate in
// the kernel in the reference's order of operations (the image path reads
// texels unfiltered); GPUs may fuse multiply-adds.
struct Tolerance {
  float value;
  float gradient;
};

Tolerance tolerance(const ClContext& context, FieldStorage storage) {
  (void)storage;
  if (!context.info().is_gpu) return {1e-5f, 1e-4f};
  return {1e-4f, 1e-3f};
}

std::string rigLabel(const std::string& name) {
  return name.find('.') == std::string::npos ? "builtin:" + name : name;
}

const Rig& rigOf(const std::string& name) {
  if (name.find('.') != std::string::npos) return test::loadAsset(name);
  static std::mutex mutex;
  static std::map<std::string, Rig> cache;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = cache.find(name);
  if (it == cache.end()) it = cache.emplace(name, makeBuiltinRig(name)).first;
  return it->second;
}

// The baked fields of a rig, built once per process.
const FieldGridSet& fieldsOf(const std::string& name) {
  static std::mutex mutex;
  static std::map<std::string, FieldGridSet> cache;
  const Rig& rig = rigOf(name);
  std::lock_guard<std::mutex> lock(mutex);
  auto it = cache.find(name);
  if (it == cache.end())
    it = cache.emplace(name, buildImplicitFields(rig).grids).first;
  return it->second;
}

struct Pose {
  std::string label;
  TransformList skinning;
};

// The bind pose and, when the rig has a clip, a frame 60% into its first.
std::vector<Pose> posesOf(const Rig& rig) {
  std::vector<Pose> poses = {{"bind pose", bindPoseSkinning(rig.skeleton)}};
  if (!rig.clips.empty()) {
    const AnimationClip& clip = rig.clips.front();
    const double t = clip.start + 0.6 * clip.duration;
    poses.push_back({"clip '" + clip.name + "' at " + std::to_string(t) + " s",
                     skinningTransforms(
                         rig.skeleton,
                         globalTransforms(rig.skeleton,
                                          clip.sampleLocal(rig.skeleton, t)))});
  }
  return poses;
}

// The DQS-skinned vertices, then `random_count` uniform points in their
// bounding box grown by 20%.
Matrix3Xf pointsOf(const Rig& rig, const TransformList& skinning,
                   int random_count) {
  const Matrix3Xf positions = samples::dqsPositions(rig, skinning);
  const Eigen::Vector3f lo = positions.colwise().minCoeff().transpose();
  const Eigen::Vector3f hi = positions.colwise().maxCoeff().transpose();
  const Eigen::Vector3f centre = 0.5f * (lo + hi);
  const Eigen::Vector3f half = 0.6f * (hi - lo);
  Matrix3Xf points(positions.rows() + random_count, 3);
  points.topRows(positions.rows()) = positions;
  std::mt19937 random(12345);
  std::uniform_real_distribution<float> unit(-1.f, 1.f);
  for (int r = 0; r < random_count; ++r)
    for (int a = 0; a < 3; ++a)
      points(positions.rows() + r, a) = centre[a] + half[a] * unit(random);
  return points;
}

// Largest gradient norm of each field at this pose: the grid's largest node
// gradient norm times the largest stretch of the model -> bone transform.
std::vector<float> gradientScales(const FieldGridSet& fields,
                                  const TransformList& skinning) {
  const std::vector<Eigen::Affine3f> to_bone =
      fieldTransforms(fields, skinning);
  std::vector<float> scales;
  for (size_t i = 0; i < fields.grids.size(); ++i) {
    const std::vector<float>& nodes = fields.grids[i].nodes;
    float largest = 0.f;
    for (size_t k = 0; k < nodes.size(); k += 4)
      largest = std::max(
          largest,
          Eigen::Vector3f(nodes[k + 1], nodes[k + 2], nodes[k + 3]).norm());
    const float stretch = Eigen::JacobiSVD<Eigen::Matrix3f>(to_bone[i].linear())
                              .singularValues()(0);
    // A flat field (no gradient anywhere) still gets a meaningful bound.
    scales.push_back(std::max(largest * stretch, 1e-6f));
  }
  return scales;
}

struct Worst {
  float value = 0.f;     // largest absolute value difference
  float gradient = 0.f;  // largest gradient difference over its scale
};

std::string row(const Matrix4Xf& m, Eigen::Index r) {
  std::ostringstream text;
  text << "(" << m.row(r) << ")";
  return text.str();
}

// Compares one evaluation; returns the largest differences or fails naming
// the first mismatching point (and field).
std::optional<Worst> compare(const FieldGridSet& fields,
                             const TransformList& skinning,
                             const Matrix4Xf& expected_composed,
                             const Matrix4Xf& expected_per_field,
                             const Matrix4Xf& actual_composed,
                             const Matrix4Xf& actual_per_field,
                             const Tolerance& tol, const std::string& what) {
  const int field_count = fields.fieldCount();
  const Eigen::Index point_count = expected_composed.rows();
  EXPECT_EQ(actual_composed.rows(), point_count) << what;
  EXPECT_EQ(actual_per_field.rows(), point_count * field_count) << what;
  if (actual_composed.rows() != point_count ||
      actual_per_field.rows() != point_count * field_count)
    return std::nullopt;
  const std::vector<float> scales = gradientScales(fields, skinning);
  const float largest_scale =
      scales.empty() ? 1.f : *std::max_element(scales.begin(), scales.end());
  Worst worst;
  for (Eigen::Index p = 0; p < point_count; ++p) {
    for (int i = 0; i < field_count; ++i) {
      const Eigen::Index r = p * field_count + i;
      const float dv =
          std::abs(actual_per_field(r, 0) - expected_per_field(r, 0));
      const float dg = (actual_per_field.row(r).tail<3>() -
                        expected_per_field.row(r).tail<3>())
                           .norm() /
                       scales[i];
      if (!(dv <= tol.value) || !(dg <= tol.gradient)) {
        ADD_FAILURE() << what << ": first mismatch at point " << p << ", field "
                      << i << " (joint " << fields.grids[i].joint
                      << "): device " << row(actual_per_field, r)
                      << ", reference " << row(expected_per_field, r)
                      << "; value difference " << dv << " (tolerance "
                      << tol.value << "), gradient difference " << dg
                      << " of the field's largest gradient (tolerance "
                      << tol.gradient << ")";
        return std::nullopt;
      }
      worst.value = std::max(worst.value, dv);
      worst.gradient = std::max(worst.gradient, dg);
    }
    const float dv = std::abs(actual_composed(p, 0) - expected_composed(p, 0));
    // The union takes the gradient of the largest field: where two fields
    // tie within the tolerance either gradient is right.
    float dg =
        (actual_composed.row(p).tail<3>() - expected_composed.row(p).tail<3>())
            .norm() /
        largest_scale;
    if (dg > tol.gradient) {
      const float top = expected_composed(p, 0);
      if (top <= tol.value)
        dg = std::min(dg,
                      actual_composed.row(p).tail<3>().norm() / largest_scale);
      for (int i = 0; i < field_count; ++i) {
        const Eigen::Index r = p * field_count + i;
        if (expected_per_field(r, 0) >= top - tol.value)
          dg = std::min(dg, (actual_composed.row(p).tail<3>() -
                             expected_per_field.row(r).tail<3>())
                                    .norm() /
                                largest_scale);
      }
    }
    if (!(dv <= tol.value) || !(dg <= tol.gradient)) {
      ADD_FAILURE() << what
                    << ": first mismatch of the composed field at point " << p
                    << ": device " << row(actual_composed, p) << ", reference "
                    << row(expected_composed, p) << "; value difference " << dv
                    << ", gradient difference " << dg
                    << " of the largest gradient";
      return std::nullopt;
    }
    worst.value = std::max(worst.value, dv);
    worst.gradient = std::max(worst.gradient, dg);
  }
  return worst;
}

// Both storages against the reference, every pose of the rig, for the
// union of all fields and for the blend and the bulge at every joint
// (operator tables, controllers, pairs); kHalf: on the grids rounded to
// half precision, which the device stores as halves (buffer, or a
// CL_HALF_FLOAT image where the device has them) and samples exactly.
void expectDeviceMatchesReference(
    const std::string& name, GridPrecision precision = GridPrecision::kFloat) {
  const Rig& rig = rigOf(name);
  FieldGridSet half;
  if (precision == GridPrecision::kHalf) {
    half = fieldsOf(name);
    roundGridsToHalf(half);
  }
  const FieldGridSet& fields =
      precision == GridPrecision::kHalf ? half : fieldsOf(name);
  ASSERT_GT(fields.fieldCount(), 0) << rigLabel(name) << " has no field";
  auto context = test::sharedContext();
  for (const CompositionOperator op :
       {CompositionOperator::kUnion, CompositionOperator::kBlend,
        CompositionOperator::kBulge}) {
    CompositionOptions options;
    options.default_operator = op;
    const Composition composition =
        buildComposition(rig.skeleton, fields, options);
    // The union runs without a composition (the union of all fields).
    const Composition* used =
        op == CompositionOperator::kUnion ? nullptr : &composition;
    for (FieldStorage storage : kStorages) {
      ClFieldEvaluation device(context, fields, rig.skeleton.jointCount(),
                               storage, used);
      ASSERT_EQ(device.storage(), storage) << device.storageReason();
      if (precision == GridPrecision::kHalf) {
        const bool halves = storage == FieldStorage::kBuffer ||
                            device.storageReason().find(
                                "CL_HALF_FLOAT image") != std::string::npos;
        const size_t float_bytes =
            storage == FieldStorage::kBuffer
                ? fields.bytes()
                : 16 * static_cast<size_t>(device.atlasTiles()[0]) *
                      device.atlasTiles()[1] * device.atlasTiles()[2] *
                      fields.resolution * fields.resolution * fields.resolution;
        EXPECT_EQ(device.fieldBytes(), halves ? float_bytes / 2 : float_bytes)
            << device.storageReason();
        EXPECT_NE(device.storageReason().find("half-precision"),
                  std::string::npos)
            << device.storageReason();
      }
      EXPECT_EQ(device.pairCount(),
                static_cast<int>(composition.blended_pairs.size()) *
                    (used != nullptr));
      // Device and host acos differ in the last bits; near the blend's
      // C = 0.5 crease its partials vary by about 200 per radian of theta.
      Tolerance tol = tolerance(*context, storage);
      if (used) tol.gradient *= 10;
      for (const Pose& pose : posesOf(rig)) {
        const std::string what = rigLabel(name) + ", " + pose.label + ", " +
                                 compositionOperatorName(op) + ", " +
                                 fieldStorageName(storage) + " storage on " +
                                 context->info().describe();
        const Matrix3Xf points = pointsOf(rig, pose.skinning, 2000);
        Matrix4Xf expected, expected_per_field;
        FieldEvaluationJob job;
        job.fields = &fields;
        job.skinning = &pose.skinning;
        job.points = &points;
        job.composition = used;
        job.out_composed = &expected;
        job.out_per_field = &expected_per_field;
        job.run();
        Matrix4Xf actual, actual_per_field;
        device.evaluate(pose.skinning, points, actual, &actual_per_field);
        const std::optional<Worst> worst =
            compare(fields, pose.skinning, expected, expected_per_field, actual,
                    actual_per_field, tol, what);
        ASSERT_TRUE(worst.has_value());
        // Positive somewhere: the comparison is not of zeros only.
        EXPECT_GT(expected.col(0).maxCoeff(), 0.1f) << what;
        std::printf(
            "[fields] %s: %d points, %d fields, %d pairs, max |value| "
            "difference %.3g, max gradient difference %.3g (relative), "
            "kernel %.3f ms\n",
            what.c_str(), static_cast<int>(points.rows()), fields.fieldCount(),
            device.pairCount(), worst->value, worst->gradient,
            device.lastKernelMs());
      }
    }
  }
}

class ClFieldEvaluationOnRig : public ::testing::TestWithParam<std::string> {};

TEST_P(ClFieldEvaluationOnRig, DeviceMatchesReferenceForBothStorages) {
  const std::string& name = GetParam();
  if (name.find('.') != std::string::npos && !test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("the field comparison on " +
                                               name);
  expectDeviceMatchesReference(name);
}

TEST_P(ClFieldEvaluationOnRig,
       HalfPrecisionGridsMatchReferenceForBothStorages) {
  const std::string& name = GetParam();
  if (name.find('.') != std::string::npos && !test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage(
        "the half-precision field comparison on " + name);
  expectDeviceMatchesReference(name, GridPrecision::kHalf);
}

std::vector<std::string> rigNames() {
  std::vector<std::string> names = builtinRigNames();
  // Every asset: the instances are listed when the suite is built.
  for (const std::string& file : test::allAssetNames()) names.push_back(file);
  return names;
}

std::string testName(const ::testing::TestParamInfo<std::string>& info) {
  std::string name = info.param;
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return name;
}

INSTANTIATE_TEST_SUITE_P(Rigs, ClFieldEvaluationOnRig,
                         ::testing::ValuesIn(rigNames()), testName);

// Far from every support box: exactly zero, value and gradient, per field
// and composed, on both storages.
TEST(ClFieldEvaluation, PointOutsideEveryBoxGivesExactZero) {
  const Rig& rig = rigOf("cylinder");
  const FieldGridSet& fields = fieldsOf("cylinder");
  Matrix3Xf points(3, 3);
  points << 1e3f, 1e3f, 1e3f,  //
      -50.f, 0.f, 0.f,         //
      4.f, 0.f, 40.f;
  for (const Pose& pose : posesOf(rig)) {
    for (FieldStorage storage : kStorages) {
      ClFieldEvaluation device(test::sharedContext(), fields,
                               rig.skeleton.jointCount(), storage);
      Matrix4Xf composed, per_field;
      device.evaluate(pose.skinning, points, composed, &per_field);
      ASSERT_EQ(composed.rows(), 3);
      EXPECT_TRUE((composed.array() == 0.f).all())
          << fieldStorageName(storage) << ", " << pose.label << ":\n"
          << composed;
      EXPECT_TRUE((per_field.array() == 0.f).all())
          << fieldStorageName(storage) << ", " << pose.label << ":\n"
          << per_field;
    }
  }
}

template <typename F>
void expectInvalidArgument(F&& f, const std::string& expected_text) {
  try {
    f();
    ADD_FAILURE() << "no isk::Error; expected one saying '" << expected_text
                  << "'";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
    EXPECT_NE(std::string(e.what()).find(expected_text), std::string::npos)
        << e.what();
  }
}

TEST(ClFieldEvaluation, InvalidInputThrowsWithMessage) {
  const Rig& rig = rigOf("finger");
  const FieldGridSet& fields = fieldsOf("finger");
  const int joints = rig.skeleton.jointCount();
  auto context = test::sharedContext();
  int last_joint = 0;
  for (const FieldGrid& g : fields.grids)
    last_joint = std::max(last_joint, g.joint);
  expectInvalidArgument(
      [&] { (void)ClFieldEvaluation(context, fields, last_joint); },
      "belongs to joint " + std::to_string(last_joint) +
          " but the skeleton has " + std::to_string(last_joint) + " joints");
  expectInvalidArgument(
      [&] { (void)ClFieldEvaluation(nullptr, fields, joints); }, "no context");
  FieldGridSet broken = fields;
  broken.grids[0].nodes.pop_back();
  expectInvalidArgument(
      [&] { (void)ClFieldEvaluation(context, broken, joints); },
      "field 0 holds");
  broken = fields;
  broken.grids.back().nodes[5] = std::nanf("");
  expectInvalidArgument(
      [&] { (void)ClFieldEvaluation(context, broken, joints); },
      "node 1 is not finite");
  broken = fields;  // marked half, but a node is no half
  roundGridsToHalf(broken);
  broken.grids[0].nodes[8] = 0.1f + 1e-6f;
  expectInvalidArgument(
      [&] { (void)ClFieldEvaluation(context, broken, joints); },
      "field 0 node 2 holds 0.100001, not a half-precision value");

  ClFieldEvaluation device(context, fields, joints, FieldStorage::kBuffer);
  Matrix3Xf points = Matrix3Xf::Zero(4, 3);
  Matrix4Xf composed;
  const TransformList short_pose(joints - 1, Eigen::Affine3f::Identity());
  expectInvalidArgument([&] { device.evaluate(short_pose, points, composed); },
                        std::to_string(joints - 1) +
                            " skinning transforms given for a skeleton of " +
                            std::to_string(joints) + " joints");
  TransformList nan_pose = bindPoseSkinning(rig.skeleton);
  nan_pose[1].matrix()(0, 3) = std::nanf("");
  expectInvalidArgument([&] { device.evaluate(nan_pose, points, composed); },
                        "skinning transform 1 is not finite");
  const TransformList pose = bindPoseSkinning(rig.skeleton);
  cl::Buffer small(context->context(), CL_MEM_READ_ONLY, 3 * sizeof(float));
  expectInvalidArgument([&] { device.evaluate(pose, small, 2); },
                        "the points buffer holds 12 bytes");
  device.evaluate(pose, points, composed);
  Matrix4Xf per_field;
  expectInvalidArgument([&] { device.readPerField(per_field); },
                        "did not ask for per-field results");
}

TEST(ClFieldEvaluation, AutoPicksBufferOnCpuDevicesAndHonoursTheEnvironment) {
  const Rig& rig = rigOf("cylinder");
  const FieldGridSet& fields = fieldsOf("cylinder");
  const int joints = rig.skeleton.jointCount();
  auto context = test::sharedContext();
  const bool images = context->device().getInfo<CL_DEVICE_IMAGE_SUPPORT>();
  {
    test::ScopedEnv env("ISK_FIELD_STORAGE", nullptr);
    ClFieldEvaluation automatic(context, fields, joints);
    if (context->info().is_cpu && !context->info().is_gpu)
      EXPECT_EQ(automatic.storage(), FieldStorage::kBuffer)
          << automatic.storageReason();
    else if (context->info().is_gpu && images)
      EXPECT_EQ(automatic.storage(), FieldStorage::kImage)
          << automatic.storageReason();
    EXPECT_FALSE(automatic.storageReason().empty());
    // The data a later kernel binds: one of the two is set.
    EXPECT_EQ(automatic.storage() == FieldStorage::kImage,
              automatic.fieldImage()() != nullptr);
    EXPECT_EQ(automatic.storage() == FieldStorage::kBuffer,
              automatic.fieldBuffer()() != nullptr);
    EXPECT_GE(automatic.bytes(), fields.bytes());
  }
  {
    test::ScopedEnv env("ISK_FIELD_STORAGE", "image");
    ClFieldEvaluation forced(context, fields, joints);
    EXPECT_EQ(forced.storage(),
              images ? FieldStorage::kImage : FieldStorage::kBuffer)
        << forced.storageReason();
    EXPECT_NE(forced.storageReason().find("ISK_FIELD_STORAGE=image"),
              std::string::npos);
    // An explicit storage wins over the environment.
    ClFieldEvaluation buffer(context, fields, joints, FieldStorage::kBuffer);
    EXPECT_EQ(buffer.storage(), FieldStorage::kBuffer);
  }
  {
    test::ScopedEnv env("ISK_FIELD_STORAGE", "buffer");
    EXPECT_EQ(ClFieldEvaluation(context, fields, joints).storage(),
              FieldStorage::kBuffer);
  }
  {
    test::ScopedEnv env("ISK_FIELD_STORAGE", "texture");
    expectInvalidArgument(
        [&] { (void)ClFieldEvaluation(context, fields, joints); },
        "ISK_FIELD_STORAGE='texture'");
  }
  EXPECT_STREQ(fieldStorageName(FieldStorage::kAuto), "auto");
  EXPECT_STREQ(fieldStorageName(FieldStorage::kImage), "image");
  EXPECT_STREQ(fieldStorageName(FieldStorage::kBuffer), "buffer");
}

// The device path takes ClSkinning's positions buffer as it is (packed
// float3) and gives what the host path gives for the read-back positions.
TEST(ClFieldEvaluation, DevicePathTakesSkinnedPositionsBuffer) {
  const Rig& rig = rigOf("arm");
  const FieldGridSet& fields = fieldsOf("arm");
  const int joints = rig.skeleton.jointCount();
  auto context = test::sharedContext();
  ClSkinning skinning(context, rig.mesh, rig.weights, joints);
  const TransformList pose = posesOf(rig).back().skinning;
  skinning.run(SkinningMethod::kDualQuaternion, pose, false);
  Matrix3Xf positions;
  skinning.readPositions(positions);
  for (FieldStorage storage : kStorages) {
    ClFieldEvaluation device(context, fields, joints, storage);
    device.evaluate(pose, skinning.positionsBuffer(), skinning.vertexCount(),
                    true);
    Matrix4Xf composed, per_field;
    device.readComposed(composed);
    device.readPerField(per_field);
    Matrix4Xf host, host_per_field;
    device.evaluate(pose, positions, host, &host_per_field);
    EXPECT_EQ(composed, host) << fieldStorageName(storage);
    EXPECT_EQ(per_field, host_per_field) << fieldStorageName(storage);
    EXPECT_GT(composed.col(0).maxCoeff(), 0.1f);
    EXPECT_GE(device.lastKernelMs(), 0.0);
  }
}

// A later kernel built with the same options reuses the cached program and
// binds the field data through setFieldArgs.
TEST(ClFieldEvaluation, OtherKernelsCanBindTheFieldData) {
  const Rig& rig = rigOf("cylinder");
  auto context = test::sharedContext();
  for (FieldStorage storage : kStorages) {
    ClFieldEvaluation device(context, fieldsOf("cylinder"),
                             rig.skeleton.jointCount(), storage);
    const int programs = context->cachedProgramCount();
    cl::Program program =
        context->program("fields/evaluate", device.buildOptions());
    EXPECT_EQ(context->cachedProgramCount(), programs);
    cl::Kernel kernel(program, "evaluate_fields");
    EXPECT_NO_THROW(device.setFieldArgs(kernel, 2));
    device.setPose(bindPoseSkinning(rig.skeleton));
    EXPECT_GT(device.lastUploadMs(), -1.0);
  }
}

}  // namespace
}  // namespace isk
