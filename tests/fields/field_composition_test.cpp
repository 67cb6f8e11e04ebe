// The global field of a character (isk/fields/field_composition.hpp, eq. 3):
// joint pairs and their operators, the composed gradient, the blend's union at
// aligned bones, the bulge strength, the broad phase, and the OpenCL
// composition against the CPU reference on procedural rigs and assets.
#include "isk/fields/field_composition.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "isk/cl/field_evaluation.hpp"
#include "isk/core/error.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using test::bendAt;

using test::rigNamed;

constexpr double kPi = 3.14159265358979323846;

ImplicitFields fieldsWith(const Rig& rig, CompositionOptions composition) {
  ImplicitFieldsOptions options;
  options.composition = std::move(composition);
  return buildImplicitFields(rig, options);
}

CompositionOptions everywhere(CompositionOperator op) {
  CompositionOptions options;
  options.default_operator = op;
  return options;
}

// A constant theta(alpha): the composed field's gradient is then exactly
// the chain rule (theta does not vary from point to point).
ThetaController constantController(float theta) {
  ThetaController c;
  c.theta.assign(kControllerSamples, theta);
  return c;
}

// Points in a cube of side 2 * half around `centre`, the same every run.
Matrix3Xf pointsAround(const Eigen::Vector3f& centre, float half, int count,
                       unsigned seed = 3) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(-1.f, 1.f);
  Matrix3Xf points(count, 3);
  for (int p = 0; p < count; ++p)
    for (int a = 0; a < 3; ++a) points(p, a) = centre[a] + half * unit(rng);
  return points;
}

// The composition of the analytic fields at a posed point (double).
Eigen::Vector4d exactComposed(const ImplicitFields& fields,
                              const TransformList& skinning,
                              const Eigen::Vector3d& x) {
  std::vector<Eigen::Vector4d> samples(fields.fields.size());
  for (size_t i = 0; i < fields.fields.size(); ++i) {
    const Eigen::Affine3d to_bind =
        skinning[fields.fields[i].joint].cast<double>().inverse(Eigen::Affine);
    double value = 0;
    Eigen::Vector3d gradient;
    fields.fields[i].evaluate(to_bind * x, value, gradient);
    samples[i] << value, to_bind.linear().transpose() * gradient;
  }
  return composeExact(
      fields.composition, samples,
      pairJointAngles(fields.composition, fields.grids, skinning));
}

double angleDegrees(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) *
         180 / kPi;
}

// --- pairs and options
// --------------------------------------------------------

TEST(FieldComposition, PairsFollowTheSkeletonAndTheChoices) {
  const Rig& rig = rigNamed("arm");
  CompositionOptions options;
  options.joint_operators["elbow"] = CompositionOperator::kBlend;
  options.joint_operators["shoulder"] = CompositionOperator::kBulge;
  const ImplicitFields fields = fieldsWith(rig, options);
  const Composition& c = fields.composition;
  const FieldGridSet& grids = fields.grids;
  const int shoulder = rig.skeleton.find("shoulder");
  const int elbow = rig.skeleton.find("elbow");
  const int wrist = rig.skeleton.find("wrist");
  ASSERT_EQ(c.pairs.size(), 2u);
  EXPECT_EQ(c.pairs[0].joint, elbow);
  EXPECT_EQ(c.pairs[0].field_a, grids.field_of_joint[shoulder]);
  EXPECT_EQ(c.pairs[0].field_b, grids.field_of_joint[elbow]);
  EXPECT_EQ(c.pairs[0].op, CompositionOperator::kBlend);
  EXPECT_EQ(c.pairs[1].joint, wrist);
  EXPECT_EQ(c.pairs[1].op, CompositionOperator::kUnion);
  EXPECT_EQ(c.operatorAt(elbow), CompositionOperator::kBlend);
  EXPECT_EQ(c.operatorAt(wrist), CompositionOperator::kUnion);
  // The shoulder has no pair, so its bulge is used nowhere.
  EXPECT_TRUE(c.uses(CompositionOperator::kBlend));
  EXPECT_TRUE(c.uses(CompositionOperator::kUnion));
  EXPECT_FALSE(c.uses(CompositionOperator::kBulge));
  ASSERT_EQ(c.blended_pairs, std::vector<int>{0});
  ASSERT_EQ(c.tables.size(), 1u);
  EXPECT_EQ(c.tables[0]->op, CompositionOperator::kBlend);
  EXPECT_EQ(c.tableBytes(), 128u * 128 * 128 * 16);
  EXPECT_EQ(describeComposition(c, rig.skeleton),
            "blend at 'elbow'; union elsewhere");
  // The shoulder starts the chain: nothing to pair, a warning says so.
  ASSERT_FALSE(c.warnings.empty());
  EXPECT_NE(c.warnings[0].find("'shoulder'"), std::string::npos)
      << c.warnings[0];
  EXPECT_NE(
      std::find(fields.warnings.begin(), fields.warnings.end(), c.warnings[0]),
      fields.warnings.end());
  // Union everywhere: no pair is evaluated, no table is baked.
  const Composition plain = buildComposition(rig.skeleton, grids);
  EXPECT_TRUE(plain.blended_pairs.empty());
  EXPECT_TRUE(plain.tables.empty());
  EXPECT_FALSE(plain.uses(CompositionOperator::kBlend));
  EXPECT_FALSE(plain.uses(CompositionOperator::kBulge));
  EXPECT_EQ(describeComposition(plain, rig.skeleton), "union at every joint");
}

void expectRejected(const CompositionOptions& options,
                    const std::string& needle) {
  const Rig& rig = rigNamed("arm");
  const FieldGridSet& grids = test::implicitFieldsOf("arm").grids;
  try {
    buildComposition(rig.skeleton, grids, options);
    ADD_FAILURE() << "accepted; expected an error naming " << needle;
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
        << e.what();
  }
  // buildImplicitFields checks them before any fitting.
  ImplicitFieldsOptions build;
  build.composition = options;
  EXPECT_THROW(buildImplicitFields(rig, build), Error);
}

TEST(FieldComposition, RejectsBadOptionsNamingThem) {
  CompositionOptions options;
  options.joint_operators["elbw"] = CompositionOperator::kBlend;
  expectRejected(options, "'elbw'");
  options = {};
  options.joint_controllers["nobody"] = blendController();
  expectRejected(options, "'nobody'");
  options = {};
  options.bulge_strength = 1.5;
  expectRejected(options, "bulge_strength");
  options = {};
  options.blend_theta = -0.1;
  expectRejected(options, "blend_theta");
  options = {};
  options.table_resolution = 1;
  expectRejected(options, "table_resolution");
  options = {};
  options.joint_controllers["elbow"] = constantController(1.0f);
  expectRejected(options, "outside [0, pi/4]");
  options = {};
  options.joint_controllers["elbow"].theta = {0.1f};
  expectRejected(options, "at least 2");
}

TEST(FieldComposition, UsesACustomControllerResampled) {
  const Rig& rig = rigNamed("arm");
  CompositionOptions options = everywhere(CompositionOperator::kBlend);
  ThetaController two;
  two.theta = {0.f, static_cast<float>(kThetaUnion)};  // a ramp over alpha
  options.joint_controllers["elbow"] = two;
  const Composition c = buildComposition(
      rig.skeleton, test::implicitFieldsOf("arm").grids, options);
  const ThetaController& used = c.controllers[c.pairs[0].controller];
  ASSERT_EQ(used.theta.size(), static_cast<size_t>(kControllerSamples));
  EXPECT_NEAR(used.at(static_cast<float>(kPi / 2)), kThetaUnion / 2, 1e-6);
  // The wrist keeps the default blend controller.
  EXPECT_NEAR(c.controllers[c.pairs[1].controller].at(0.f), kThetaUnion, 1e-6);
}

// --- the composed field ----------------------------------------------------

// What the composed gradient looks like against central differences of
// the composed value (analytic fields, operators solved directly) at random
// points around the bent joint of the cylinder, where the pair's operator
// is active (its value above the union's). Points on a crease (the max's,
// the blend's C = 0.5), where the forward and backward slopes differ, have
// no gradient to compare and are left out.
struct GradientCheck {
  int active = 0, checked = 0;
  double worst_relative = 0;         // |fd - gradient| / |gradient|
  std::vector<double> fd_angles;     // degrees, sorted
  double baked_value = 0;            // largest |baked - exact| value
  std::vector<double> baked_angles;  // baked vs exact gradient, sorted
};

GradientCheck checkComposedGradient(CompositionOperator op,
                                    bool constant_theta) {
  const Rig& rig = rigNamed("cylinder");
  const int joint = rig.skeleton.find("bone1");
  const TransformList skinning = bendAt(rig, joint, 60);
  const Eigen::Vector3f centre =
      rig.skeleton.bindGlobals()[joint].translation();
  const Matrix3Xf points = pointsAround(centre, 1.6f, 3000);
  CompositionOptions options = everywhere(op);
  if (constant_theta)
    options.joint_controllers["bone1"] = constantController(0.25f);
  const ImplicitFields fields = fieldsWith(rig, options);
  const Matrix4Xf baked = evaluateComposedField(fields.grids, skinning, points,
                                                &fields.composition);
  const Matrix4Xf plain =
      evaluateComposedField(fields.grids, skinning, points, nullptr);
  GradientCheck out;
  const double h = 1e-5;
  for (Eigen::Index p = 0; p < points.rows(); ++p) {
    if (op != CompositionOperator::kUnion &&
        !(baked(p, 0) > plain(p, 0) + 1e-4))
      continue;
    const Eigen::Vector3d x = points.row(p).transpose().cast<double>();
    const Eigen::Vector4d f = exactComposed(fields, skinning, x);
    if (!(f[0] > 0.05 && f[0] < 0.95)) continue;
    ++out.active;
    out.baked_value = std::max(out.baked_value, std::abs(baked(p, 0) - f[0]));
    out.baked_angles.push_back(angleDegrees(
        baked.row(p).tail<3>().transpose().cast<double>(), f.tail<3>()));
    Eigen::Vector3d fd;
    bool crease = false;
    for (int a = 0; a < 3; ++a) {
      Eigen::Vector3d step = Eigen::Vector3d::Zero();
      step[a] = h;
      const double forward = exactComposed(fields, skinning, x + step)[0];
      const double backward = exactComposed(fields, skinning, x - step)[0];
      fd[a] = (forward - backward) / (2 * h);
      crease |= std::abs((forward - f[0]) - (f[0] - backward)) / h >
                1e-3 * f.tail<3>().norm();
    }
    if (crease) continue;
    ++out.checked;
    out.worst_relative = std::max(
        out.worst_relative, (fd - f.tail<3>()).norm() / f.tail<3>().norm());
    out.fd_angles.push_back(angleDegrees(fd, f.tail<3>()));
  }
  std::sort(out.fd_angles.begin(), out.fd_angles.end());
  std::sort(out.baked_angles.begin(), out.baked_angles.end());
  return out;
}

double percentile(const std::vector<double>& sorted, int percent) {
  return sorted.empty() ? 0 : sorted[sorted.size() * percent / 100];
}

// With a constant controller theta does not vary from point to point and
// the composed gradient is exactly the chain rule through the operator's
// partials: it matches the finite differences to 1e-5. The baked
// composition (grids and tables) follows the exact one.
TEST(FieldComposition, ComposedGradientMatchesFiniteDifferences) {
  for (CompositionOperator op :
       {CompositionOperator::kUnion, CompositionOperator::kBlend,
        CompositionOperator::kBulge}) {
    SCOPED_TRACE(compositionOperatorName(op));
    const GradientCheck c = checkComposedGradient(op, true);
    EXPECT_GT(c.active, 300);
    EXPECT_GT(c.checked, c.active / 2);
    EXPECT_LT(c.worst_relative, 1e-5);
    EXPECT_LT(c.baked_value, 0.03);
    EXPECT_LT(percentile(c.baked_angles, 95), 10.0);
  }
}

// With the Figure 7 controllers theta follows the gradients' angle, and the
// paper's gradient, dg/df1 grad f1 + dg/df2 grad f2, leaves out
// dg/dtheta grad theta: the direction stays close to the true gradient
// (measured where the operator is active: 95% of points within 6.8 degrees
// for the blend, 2.6 for the bulge; at most 13).
TEST(FieldComposition, Figure7GradientStaysCloseToFiniteDifferences) {
  for (CompositionOperator op :
       {CompositionOperator::kBlend, CompositionOperator::kBulge}) {
    SCOPED_TRACE(compositionOperatorName(op));
    const GradientCheck c = checkComposedGradient(op, false);
    EXPECT_GT(c.checked, 300);
    EXPECT_LT(percentile(c.fd_angles, 95), 10.0);
    EXPECT_LT(c.fd_angles.back(), 20.0);
  }
}

// The number of points where the composed field is at least 0.5: a
// measure of the volume the composed surface encloses near the joint.
int insideCount(const ImplicitFields& fields, const TransformList& skinning,
                const Matrix3Xf& points) {
  const Matrix4Xf f = evaluateComposedField(fields.grids, skinning, points,
                                            &fields.composition);
  return static_cast<int>((f.col(0).array() >= 0.5f).count());
}

// A joint at its bind rotation is a union under the blend (theta(0) =
// theta_u, alpha capped by the joint's rotation): the straight cylinder and
// arm, at rest or turned as a whole, have the union's field around their
// joint, so its surface shows no bulge there. Bent by 45 degrees, the
// blend fills the fold (the check would catch a blend that does nothing).
TEST(FieldComposition, StraightLimbBlendIsAUnion) {
  for (const char* name : {"cylinder", "arm"}) {
    SCOPED_TRACE(name);
    const Rig& rig = rigNamed(name);
    const int joint =
        rig.skeleton.joints.size() > 2 && rig.skeleton.find("elbow") >= 0
            ? rig.skeleton.find("elbow")
            : rig.skeleton.find("bone1");
    ASSERT_GE(joint, 0);
    const ImplicitFields blend =
        fieldsWith(rig, everywhere(CompositionOperator::kBlend));
    const ImplicitFields plain =
        fieldsWith(rig, everywhere(CompositionOperator::kUnion));
    const Eigen::Vector3f centre =
        rig.skeleton.bindGlobals()[joint].translation();
    const Matrix3Xf points = pointsAround(centre, 1.5f, 6000);
    TransformList turned(rig.skeleton.jointCount(),
                         Eigen::Affine3f(Eigen::AngleAxisf(
                             0.7f, Eigen::Vector3f(1, 2, 3).normalized())));
    for (const TransformList& straight :
         {TransformList(rig.skeleton.jointCount(), Eigen::Affine3f::Identity()),
          turned}) {
      const Matrix3Xf moved =
          (points * straight[0].linear().transpose()).rowwise() +
          straight[0].translation().transpose();
      const Matrix4Xf a = evaluateComposedField(blend.grids, straight, moved,
                                                &blend.composition);
      const Matrix4Xf b = evaluateComposedField(plain.grids, straight, moved,
                                                &plain.composition);
      EXPECT_GT(a.col(0).maxCoeff(), 0.5f);
      float largest = 0;
      Eigen::Index where = 0;
      (a - b).cwiseAbs().rowwise().maxCoeff().maxCoeff(&where);
      largest = (a - b).row(where).cwiseAbs().maxCoeff();
      // Equal up to the table's float interpolation of G = x.
      EXPECT_LE(largest, 1e-6f) << "first at point " << where << ": blend "
                                << a.row(where) << ", union " << b.row(where);
    }
    const TransformList bent = bendAt(rig, joint, 45);
    const int fill = insideCount(blend, bent, points);
    const int crease = insideCount(plain, bent, points);
    EXPECT_GT(fill, crease + crease / 200)
        << "blend " << fill << ", union " << crease;
  }
}

// The bulge strength really changes the shape: bent by 90 degrees, the
// composed surface encloses more the stronger the bulge; strength 0 is the
// union exactly.
TEST(FieldComposition, BulgeStrengthChangesTheShape) {
  const Rig& rig = rigNamed("cylinder");
  const int joint = rig.skeleton.find("bone1");
  const TransformList bent = bendAt(rig, joint, 90);
  const Matrix3Xf points = pointsAround(
      rig.skeleton.bindGlobals()[joint].translation(), 1.5f, 20000);
  std::vector<int> inside;
  for (double strength : {0.0, 0.5, 1.0}) {
    CompositionOptions options = everywhere(CompositionOperator::kBulge);
    options.bulge_strength = strength;
    inside.push_back(insideCount(fieldsWith(rig, options), bent, points));
  }
  const int plain = insideCount(
      fieldsWith(rig, everywhere(CompositionOperator::kUnion)), bent, points);
  EXPECT_EQ(inside[0], plain);
  EXPECT_GT(inside[1], plain + plain / 200) << inside[1] << " vs " << plain;
  EXPECT_GT(inside[2], inside[1] + plain / 200)
      << inside[2] << " vs " << inside[1];
}

// Broad phase: a field's posed bounding sphere holds its whole support box
// for rigid poses and for the scaled transforms LBS may give, so skipping
// the fields whose sphere misses a point changes no result.
TEST(FieldComposition, BoundingSpheresHoldTheSupportBoxes) {
  const Rig& rig = rigNamed("arm");
  const FieldGridSet& grids = test::implicitFieldsOf("arm").grids;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> unit(-1.f, 1.f);
  for (int trial = 0; trial < 50; ++trial) {
    TransformList skinning(rig.skeleton.jointCount());
    for (Eigen::Affine3f& t : skinning) {
      t = Eigen::Translation3f(5 * unit(rng), 5 * unit(rng), 5 * unit(rng)) *
          Eigen::AngleAxisf(
              3 * unit(rng),
              Eigen::Vector3f(unit(rng), unit(rng), 1).normalized()) *
          Eigen::Scaling(1.f + 0.5f * unit(rng) * (trial % 2));
    }
    const std::vector<Eigen::Affine3f> to_bone =
        fieldTransforms(grids, skinning);
    const std::vector<Eigen::Vector4f> spheres =
        posedFieldSpheres(grids, to_bone);
    for (int i = 0; i < grids.fieldCount(); ++i) {
      const FieldGrid& g = grids.grids[i];
      const Eigen::Affine3f to_model = to_bone[i].inverse(Eigen::Affine);
      for (int corner = 0; corner < 8; ++corner) {
        const Eigen::Vector3f local(
            (corner & 1) ? g.box_max.x() : g.box_min.x(),
            (corner & 2) ? g.box_max.y() : g.box_min.y(),
            (corner & 4) ? g.box_max.z() : g.box_min.z());
        const Eigen::Vector3f x = to_model * local;
        EXPECT_LE((x - spheres[i].head<3>()).squaredNorm(), spheres[i][3])
            << "trial " << trial << ", field " << i << ", corner " << corner;
      }
    }
  }
}

}  // namespace
}  // namespace isk
