// API misuse (issue 7, Reliability): wrong array sizes, poses with the wrong
// joint count or non-finite transforms, objects used after a move, results
// asked for before any frame and tracking stages called before begin() are
// refused with isk::Error(kInvalidArgument) naming what is wrong -- never
// undefined behaviour. Each case runs on the CPU reference and on OpenCL.
#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "isk/cl/field_evaluation.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/core/error.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/implicit_crowd.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/skinning/skinning.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"
#include "tracking/tracking_test_access.hpp"

namespace isk {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

struct Misuse {
  std::string name;
  std::function<void()> call;
  std::vector<std::string> named;  // in the message
};

// Every case throws isk::Error(kInvalidArgument) with each `named` string;
// failures name the case.
void expectAllRefused(const std::vector<Misuse>& cases) {
  for (const Misuse& misuse : cases) {
    try {
      misuse.call();
      ADD_FAILURE() << misuse.name << ": no error";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument)
          << misuse.name << ": " << errorCodeName(e.code()) << ": " << e.what();
      for (const std::string& s : misuse.named) {
        EXPECT_NE(std::string(e.what()).find(s), std::string::npos)
            << misuse.name << ": '" << s << "' not in: " << e.what();
      }
    } catch (const std::exception& e) {
      ADD_FAILURE() << misuse.name << ": not an isk::Error: " << e.what();
    }
  }
}

// A small cylinder (2 bones) and its fields, coarse for speed.
struct Small {
  Rig rig;
  ImplicitSkinnerOptions options;
  std::shared_ptr<const ImplicitFields> fields;
};

const Small& small() {
  static const Small s = [] {
    Small out;
    CylinderRigOptions cylinder;
    cylinder.rings = 16;
    cylinder.segments = 10;
    out.rig = makeCylinderRig(cylinder);
    out.options.fields.grid_resolution = 16;
    out.fields = std::make_shared<const ImplicitFields>(
        buildImplicitFields(out.rig, out.options.fields));
    return out;
  }();
  return s;
}

// Poses of the wrong length, and one with a NaN.
std::vector<std::pair<std::string, TransformList>> badPoses(const Rig& rig) {
  const TransformList bind = bindPoseSkinning(rig.skeleton);
  TransformList shorter = bind, longer = bind, nan = bind;
  shorter.pop_back();
  longer.push_back(Eigen::Affine3f::Identity());
  nan[1].matrix()(0, 3) = kNaN;
  return {{"empty pose", {}},
          {"one joint short", shorter},
          {"one joint too many", longer},
          {"NaN transform", nan}};
}

TEST(ApiMisuse, PosesOfTheWrongSizeOrNotFiniteAreRefused) {
  const Small& s = small();
  const Rig& rig = s.rig;
  const int joints = rig.skeleton.jointCount();
  CpuSkinning cpu(rig.mesh, rig.weights, joints);
  ClSkinning cl(test::sharedContext(), rig.mesh, rig.weights, joints);
  CpuImplicitSkinner cpu_implicit(rig, s.fields, s.options);
  ImplicitSkinner cl_implicit(test::sharedContext(), rig, s.fields, s.options);
  ClFieldEvaluation evaluation(test::sharedContext(), s.fields->grids, joints,
                               FieldStorage::kAuto, &s.fields->composition);
  std::vector<Misuse> cases;
  for (const auto& [what, pose] : badPoses(rig)) {
    const std::vector<std::string> named =
        what == "NaN transform"
            ? std::vector<std::string>{"not finite"}
            : std::vector<std::string>{std::to_string(pose.size()),
                                       std::to_string(joints) + " joints"};
    for (const SkinningMethod method :
         {SkinningMethod::kLinearBlend, SkinningMethod::kDualQuaternion}) {
      const std::string m = skinningMethodName(method);
      cases.push_back({"CpuSkinning::run " + m + ", " + what,
                       [&, pose = pose, method] { cpu.run(method, pose); },
                       named});
      cases.push_back({"ClSkinning::run " + m + ", " + what,
                       [&, pose = pose, method] { cl.run(method, pose); },
                       named});
    }
    cases.push_back({"CpuImplicitSkinner::run, " + what,
                     [&, pose = pose] { cpu_implicit.run(pose); }, named});
    cases.push_back({"ImplicitSkinner::run, " + what,
                     [&, pose = pose] { cl_implicit.run(pose); }, named});
    cases.push_back({"ClFieldEvaluation::evaluate, " + what,
                     [&, pose = pose] {
                       Matrix4Xf out;
                       evaluation.evaluate(pose, rig.mesh.positions, out);
                     },
                     {}});
  }
  expectAllRefused(cases);

  // After all that, a good pose still works.
  Matrix3Xf positions;
  const TransformList bend = test::bendAt(rig, 1, 60.0);
  cl_implicit.run(bend);
  cl_implicit.readPositions(positions);
  EXPECT_EQ(positions.rows(), rig.mesh.vertexCount());
  EXPECT_TRUE(positions.allFinite());
}

TEST(ApiMisuse, ArraysOfTheWrongSizeAreRefused) {
  const Small& s = small();
  const Rig& rig = s.rig;
  const int joints = rig.skeleton.jointCount();
  const Rig other = makeBuiltinRig("finger");
  Matrix3Xf out_positions, out_normals;
  const TransformList bind = bindPoseSkinning(rig.skeleton);
  SkinningJob job;
  job.rest_positions = &rig.mesh.positions;
  job.rest_normals = &rig.mesh.normals;
  job.weights = &rig.weights;
  job.skinning = &bind;
  job.out_positions = &out_positions;
  job.out_normals = &out_normals;
  const Matrix3Xf fewer_normals = rig.mesh.normals.topRows(5);
  const SkinWeights empty_weights;
  const Matrix3Xf no_positions;
  auto context = test::sharedContext();
  const std::vector<Misuse> cases = {
      {"CpuSkinning with another rig's weights",
       [&] { CpuSkinning(rig.mesh, other.weights, joints); },
       {"rows for"}},
      {"ClSkinning with another rig's weights",
       [&] { ClSkinning(context, rig.mesh, other.weights, joints); },
       {"rows for"}},
      {"ClSkinning with fewer joints than the weights use",
       [&] { ClSkinning(context, rig.mesh, rig.weights, 1); },
       {"joint 1"}},
      {"ClSkinning without context",
       [&] { ClSkinning(nullptr, rig.mesh, rig.weights, joints); },
       {"no context"}},
      {"SkinningJob without outputs",
       [&] {
         SkinningJob j = job;
         j.out_normals = nullptr;
         j.run();
       },
       {"not set"}},
      {"SkinningJob with 5 rest normals",
       [&] {
         SkinningJob j = job;
         j.rest_normals = &fewer_normals;
         j.run();
       },
       {"5 rows"}},
      {"SkinningJob with empty weights and no vertex",
       [&] {
         SkinningJob j = job;
         j.rest_positions = &no_positions;
         j.rest_normals = &no_positions;
         j.weights = &empty_weights;
         j.run();
       },
       {"skin weights"}},
      {"implicit skinner with another rig's fields",
       [&] { CpuImplicitSkinner(other, s.fields, s.options); },
       {"another rig"}},
      {"OpenCL implicit skinner with another rig's fields",
       [&] { ImplicitSkinner(context, other, s.fields, s.options); },
       {"another rig"}},
      {"implicit skinner with unbuilt fields",
       [&] {
         CpuImplicitSkinner(rig, std::make_shared<const ImplicitFields>(),
                            s.options);
       },
       {"0 iso values"}},
      {"implicit skinner with no fields",
       [&] { ImplicitSkinner(context, rig, nullptr, s.options); },
       {"no fields"}},
      {"implicit skinner without context",
       [&] { ImplicitSkinner(nullptr, rig, s.fields, s.options); },
       {"no context"}},
      {"fields with a grid of 1 node",
       [&] {
         ImplicitFieldsOptions options;
         options.grid_resolution = 1;
         buildImplicitFields(rig, options);
       },
       {"grid_resolution"}},
      {"field evaluation for fewer joints than the fields",
       [&] { ClFieldEvaluation(context, s.fields->grids, 1); },
       {}},
      {"device points buffer too small",
       [&] {
         ClFieldEvaluation evaluation(context, s.fields->grids, joints);
         const cl::Buffer points(context->context(), CL_MEM_READ_WRITE,
                                 3 * sizeof(float) * 4);
         evaluation.evaluate(bind, points, 5);
       },
       {"5"}},
  };
  expectAllRefused(cases);
}

TEST(ApiMisuse, MovedFromObjectsAreRefusedAndTheMovedToOnesWork) {
  const Small& s = small();
  const Rig& rig = s.rig;
  const int joints = rig.skeleton.jointCount();
  const TransformList bend = test::bendAt(rig, 1, 45.0);
  Matrix3Xf positions;

  CpuSkinning cpu(rig.mesh, rig.weights, joints);
  ClSkinning cl(test::sharedContext(), rig.mesh, rig.weights, joints);
  CpuImplicitSkinner cpu_implicit(rig, s.fields, s.options);
  ImplicitSkinner cl_implicit(test::sharedContext(), rig, s.fields, s.options);
  CpuSkinning cpu_to = std::move(cpu);
  ClSkinning cl_to = std::move(cl);
  CpuImplicitSkinner cpu_implicit_to = std::move(cpu_implicit);
  ImplicitSkinner cl_implicit_to = std::move(cl_implicit);

  const SkinningMethod dqs = SkinningMethod::kDualQuaternion;
  const std::vector<std::string> moved = {"moved from"};
  expectAllRefused({
      {"CpuSkinning::run", [&] { cpu.run(dqs, bend); }, moved},
      {"CpuSkinning::readPositions", [&] { cpu.readPositions(positions); },
       moved},
      {"ClSkinning::run", [&] { cl.run(dqs, bend); }, moved},
      {"ClSkinning::readNormals", [&] { cl.readNormals(positions); }, moved},
      {"CpuImplicitSkinner::run", [&] { cpu_implicit.run(bend); }, moved},
      {"CpuImplicitSkinner::positions", [&] { (void)cpu_implicit.positions(); },
       moved},
      {"CpuImplicitSkinner::vertexCount",
       [&] { (void)cpu_implicit.vertexCount(); }, moved},
      {"ImplicitSkinner::run", [&] { cl_implicit.run(bend); }, moved},
      {"ImplicitSkinner::readPositions",
       [&] { cl_implicit.readPositions(positions); }, moved},
      {"ImplicitSkinner::contactCount",
       [&] { (void)cl_implicit.contactCount(); }, moved},
      {"ImplicitSkinner::anchor", [&] { (void)cl_implicit.anchor(); }, moved},
      {"CpuImplicitSkinner::anchor", [&] { (void)cpu_implicit.anchor(); },
       moved},
      {"ImplicitSkinner::positionsBuffer",
       [&] { (void)cl_implicit.positionsBuffer(); }, moved},
      {"ImplicitSkinner::fields", [&] { (void)cl_implicit.fields(); }, moved},
      {"ImplicitSkinner::tracking", [&] { (void)cl_implicit.tracking(); },
       moved},
  });

  // The moved-to objects give the same frame as fresh ones would.
  const int n = rig.mesh.vertexCount();
  cpu_to.run(dqs, bend);
  cpu_to.readPositions(positions);
  EXPECT_EQ(positions.rows(), n);
  const Matrix3Xf cpu_positions = positions;
  cl_to.run(dqs, bend);
  cl_to.readPositions(positions);
  const test::RowMismatch skinning =
      test::largestRowDistance(positions, cpu_positions);
  EXPECT_LT(skinning.distance, 1e-4f) << "vertex " << skinning.row;
  cpu_implicit_to.run(bend);
  cl_implicit_to.run(bend);
  cl_implicit_to.readPositions(positions);
  const test::RowMismatch implicit =
      test::largestRowDistance(positions, cpu_implicit_to.positions());
  EXPECT_LT(implicit.distance, 1e-2f * rig.boundingBoxDiagonal())
      << "vertex " << implicit.row;
}

TEST(ApiMisuse, ResultsBeforeTheFirstFrameAndStagesBeforeBeginAreRefused) {
  const Small& s = small();
  const Rig& rig = s.rig;
  const int joints = rig.skeleton.jointCount();
  CpuSkinning cpu(rig.mesh, rig.weights, joints);
  ClSkinning cl(test::sharedContext(), rig.mesh, rig.weights, joints);
  CpuImplicitSkinner cpu_implicit(rig, s.fields, s.options);
  ImplicitSkinner cl_implicit(test::sharedContext(), rig, s.fields, s.options);
  Matrix3Xf out;
  const int n = rig.mesh.vertexCount();
  const Matrix3Xf positions = rig.mesh.positions;
  const std::vector<TrackState> states(n, TrackState::kMarching);
  const Matrix4Xf gradients = Matrix4Xf::Zero(n, 4);
  const std::vector<std::string> before_run = {"before run()"};
  const std::vector<std::string> before_begin = {"before begin()"};
  expectAllRefused({
      {"CpuSkinning::readPositions", [&] { cpu.readPositions(out); },
       before_run},
      {"CpuSkinning::readNormals", [&] { cpu.readNormals(out); }, before_run},
      {"ClSkinning::readPositions", [&] { cl.readPositions(out); }, before_run},
      {"ClSkinning::readNormals", [&] { cl.readNormals(out); }, before_run},
      {"CpuImplicitSkinner::readPositions",
       [&] { cpu_implicit.readPositions(out); }, before_run},
      {"CpuImplicitSkinner::contactCount",
       [&] { (void)cpu_implicit.contactCount(); }, before_run},
      {"ImplicitSkinner::readPositions",
       [&] { cl_implicit.readPositions(out); }, before_run},
      {"ImplicitSkinner::readNormals", [&] { cl_implicit.readNormals(out); },
       before_run},
      {"ImplicitSkinner::contactCount",
       [&] { (void)cl_implicit.contactCount(); }, before_run},
      {"CpuSurfaceTracking::project",
       [&] { cpu_implicit.tracking().project(2); }, before_begin},
      {"CpuSurfaceTracking::relax", [&] { cpu_implicit.tracking().relax(); },
       before_begin},
      {"CpuSurfaceTracking::smooth", [&] { cpu_implicit.tracking().smooth(); },
       before_begin},
      {"CpuSurfaceTracking::limitStrain",
       [&] { cpu_implicit.tracking().limitStrain(); }, before_begin},
      {"CpuSurfaceTracking::restoreVolumeAgain",
       [&] { cpu_implicit.tracking().restoreVolumeAgain(); }, before_begin},
      {"CpuSurfaceTracking::finish", [&] { cpu_implicit.tracking().finish(); },
       before_begin},
      {"CpuSurfaceTracking::translate",
       [&] { cpu_implicit.tracking().translate(Eigen::Vector3f::Ones()); },
       before_begin},
      {"CpuSurfaceTracking::setState",
       [&] {
         detail::TrackingTestAccess::setState(cpu_implicit.tracking(),
                                              positions, states, gradients);
       },
       before_begin},
      {"ClSurfaceTracking::project", [&] { cl_implicit.tracking().project(2); },
       before_begin},
      {"ClSurfaceTracking::relax", [&] { cl_implicit.tracking().relax(); },
       before_begin},
      {"ClSurfaceTracking::smooth", [&] { cl_implicit.tracking().smooth(); },
       before_begin},
      {"ClSurfaceTracking::limitStrain",
       [&] { cl_implicit.tracking().limitStrain(); }, before_begin},
      {"ClSurfaceTracking::restoreVolumeAgain",
       [&] { cl_implicit.tracking().restoreVolumeAgain(); }, before_begin},
      {"ClSurfaceTracking::finish", [&] { cl_implicit.tracking().finish(); },
       before_begin},
      {"ClSurfaceTracking::translate",
       [&] { cl_implicit.tracking().translate(Eigen::Vector3f::Ones()); },
       before_begin},
      {"ClSurfaceTracking::setState",
       [&] {
         detail::TrackingTestAccess::setState(cl_implicit.tracking(), positions,
                                              states, gradients);
       },
       before_begin},
      {"ClSurfaceTracking::readPositions",
       [&] { cl_implicit.tracking().readPositions(out); }, before_begin},
      {"ClSurfaceTracking::contactCount",
       [&] { (void)cl_implicit.tracking().contactCount(); }, before_begin},
  });

  // Then one frame makes every read valid.
  const TransformList bind = bindPoseSkinning(rig.skeleton);
  cl_implicit.run(bind);
  cl_implicit.readPositions(out);
  EXPECT_EQ(out.rows(), n);
  EXPECT_GE(cl_implicit.contactCount(), 0);
  cpu_implicit.run(bind);
  EXPECT_EQ(cpu_implicit.positions().rows(), n);
  cl.run(SkinningMethod::kLinearBlend, bind);
  cl.readNormals(out);
  EXPECT_TRUE(out.allFinite());
}

}  // namespace
}  // namespace isk

namespace isk {
namespace {

// Finite poses that are not rigid: a joint scaled to nothing, to almost
// nothing, squashed along one axis, or moved very far. Each call either
// refuses the pose (isk::Error kInvalidArgument naming the joint) or gives
// finite positions and normals.
TEST(ApiMisuse, DegeneratePosesGiveFiniteOutputOrNameTheJoint) {
  const Small& s = small();
  const Rig& rig = s.rig;
  const int joints = rig.skeleton.jointCount();
  const int n = rig.mesh.vertexCount();
  CpuSkinning cpu(rig.mesh, rig.weights, joints);
  ClSkinning cl(test::sharedContext(), rig.mesh, rig.weights, joints);
  CpuImplicitSkinner cpu_implicit(rig, s.fields, s.options);
  ImplicitSkinner cl_implicit(test::sharedContext(), rig, s.fields, s.options);
  ImplicitCrowd crowd(test::sharedContext(), rig, s.fields, 2, s.options);
  const TransformList bend = test::bendAt(rig, 1, 60.0);
  const std::vector<std::pair<std::string, Eigen::Affine3f>> spoilers = {
      {"scale 0", Eigen::Affine3f(Eigen::Scaling(0.f))},
      {"scale 1e-20", Eigen::Affine3f(Eigen::Scaling(1e-20f))},
      {"scale 1e20", Eigen::Affine3f(Eigen::Scaling(1e20f))},
      {"squashed along y", Eigen::Affine3f(Eigen::Scaling(1.f, 0.f, 1.f))},
      {"moved by 1e30", Eigen::Affine3f(Eigen::Translation3f(1e30f, 0.f, 0.f))},
  };
  Matrix3Xf positions, normals;
  for (const auto& [what, spoiler] : spoilers) {
    TransformList pose = bend;
    pose[1] = pose[1] * spoiler;
    auto check = [&](const std::string& who, const std::function<void()>& run,
                     const std::function<void()>& read) {
      try {
        run();
      } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument)
            << who << ", " << what << ": " << e.what();
        EXPECT_NE(std::string(e.what()).find("joint 1"), std::string::npos)
            << who << ", " << what << ": " << e.what();
        return;
      }
      read();
      ASSERT_EQ(positions.rows(), n) << who << ", " << what;
      for (int v = 0; v < n; ++v) {
        ASSERT_TRUE(positions.row(v).allFinite())
            << who << ", " << what << ": vertex " << v << " position";
        ASSERT_TRUE(normals.row(v).allFinite())
            << who << ", " << what << ": vertex " << v << " normal";
      }
    };
    for (const SkinningMethod method :
         {SkinningMethod::kLinearBlend, SkinningMethod::kDualQuaternion}) {
      const std::string m = skinningMethodName(method);
      check(
          "CpuSkinning " + m, [&] { cpu.run(method, pose); },
          [&] {
            cpu.readPositions(positions);
            cpu.readNormals(normals);
          });
      check(
          "ClSkinning " + m, [&] { cl.run(method, pose); },
          [&] {
            cl.readPositions(positions);
            cl.readNormals(normals);
          });
    }
    check(
        "CpuImplicitSkinner", [&] { cpu_implicit.run(pose); },
        [&] {
          cpu_implicit.readPositions(positions);
          cpu_implicit.readNormals(normals);
        });
    check(
        "ImplicitSkinner", [&] { cl_implicit.run(pose); },
        [&] {
          cl_implicit.readPositions(positions);
          cl_implicit.readNormals(normals);
        });
    // A crowd whose second instance has the pose: the same, for both
    // instances' rows (the crowd's broad phase sorts boxes by their bounds).
    check(
        "ImplicitCrowd",
        [&] {
          crowd.run({bend, pose});
        },
        [&] {
          Matrix3Xf all_positions, all_normals;
          crowd.readPositions(all_positions);
          crowd.readNormals(all_normals);
          ASSERT_EQ(all_positions.rows(), 2 * n);
          ASSERT_TRUE(all_positions.topRows(n).allFinite() &&
                      all_normals.topRows(n).allFinite())
              << what << ": the first instance";
          positions = all_positions.bottomRows(n);
          normals = all_normals.bottomRows(n);
        });
  }
}

}  // namespace
}  // namespace isk
