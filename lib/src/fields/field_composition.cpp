#include "isk/fields/field_composition.hpp"

#include <algorithm>
#include <cmath>
#include <set>

#include "isk/core/error.hpp"
#include "isk/fields/limb_joints.hpp"

namespace isk {
namespace {

[[noreturn]] void invalid(const std::string& message) {
  throw Error(ErrorCode::kInvalidArgument, "buildComposition: " + message);
}

std::string someJointNames(const Skeleton& skeleton) {
  std::string names;
  const int shown = std::min(skeleton.jointCount(), 8);
  for (int j = 0; j < shown; ++j)
    names += (j ? ", '" : "'") + skeleton.joints[j].name + "'";
  if (skeleton.jointCount() > shown)
    names += ", ... (" + std::to_string(skeleton.jointCount()) + " joints)";
  return names;
}

std::string controllerProblem(const ThetaController& c,
                              const std::string& joint) {
  if (c.theta.size() < 2)
    return "the controller of joint '" + joint + "' has " +
           std::to_string(c.theta.size()) + " samples, at least 2 needed";
  for (size_t i = 0; i < c.theta.size(); ++i)
    if (!(c.theta[i] >= 0 && c.theta[i] <= static_cast<float>(kThetaUnion)))
      return "the controller of joint '" + joint + "' has theta " +
             std::to_string(c.theta[i]) + " at sample " + std::to_string(i) +
             ", outside [0, pi/4]";
  return {};
}

// A valid controller resampled to kControllerSamples.
ThetaController resampled(const ThetaController& c) {
  if (static_cast<int>(c.theta.size()) == kControllerSamples) return c;
  ThetaController out;
  out.theta.resize(kControllerSamples);
  for (int i = 0; i < kControllerSamples; ++i)
    out.theta[i] = c.at(static_cast<float>(3.14159265358979323846 * i /
                                           (kControllerSamples - 1)));
  return out;
}

}  // namespace

CompositionOperator Composition::operatorAt(int joint) const {
  for (const FieldPair& p : pairs)
    if (p.joint == joint) return p.op;
  return CompositionOperator::kUnion;
}

bool Composition::uses(CompositionOperator op) const {
  for (const FieldPair& p : pairs)
    if (p.op == op) return true;
  return false;
}

size_t Composition::tableBytes() const {
  size_t bytes = 0;
  for (const auto& t : tables) bytes += t->bytes();
  return bytes;
}

bool parseOperatorChoice(const std::string& name, CompositionOptions* options) {
  if (name == "auto") {
    options->default_operator = CompositionOperator::kUnion;
    options->limb_operator = CompositionOperator::kBlend;
    return true;
  }
  CompositionOperator op;
  if (!parseCompositionOperator(name, &op)) return false;
  options->default_operator = op;
  options->limb_operator.reset();
  return true;
}

std::string operatorChoiceName(const CompositionOptions& options) {
  const CompositionOperator limb =
      options.limb_operator.value_or(options.default_operator);
  if (limb == options.default_operator)
    return compositionOperatorName(options.default_operator);
  if (options.default_operator == CompositionOperator::kUnion &&
      limb == CompositionOperator::kBlend)
    return "auto";
  return std::string(compositionOperatorName(options.default_operator)) + ", " +
         compositionOperatorName(limb) + " at the limbs";
}

Validation validateCompositionOptions(const Skeleton& skeleton,
                                      const CompositionOptions& options) {
  if (options.table_resolution < 2 || options.table_resolution > 512)
    return Validation::fail("table_resolution " +
                            std::to_string(options.table_resolution) +
                            " is outside 2..512");
  if (!(options.blend_theta >= 0 && options.blend_theta <= kThetaUnion))
    return Validation::fail("blend_theta " +
                            std::to_string(options.blend_theta) +
                            " is outside [0, pi/4]");
  if (!(options.bulge_strength >= 0 && options.bulge_strength <= 1))
    return Validation::fail("bulge_strength " +
                            std::to_string(options.bulge_strength) +
                            " is outside [0, 1]");
  auto unknown = [&](const std::string& name, const char* what) {
    return Validation::fail(std::string(what) + " names joint '" + name +
                            "', which is not in the skeleton (joints: " +
                            someJointNames(skeleton) + ")");
  };
  for (const auto& entry : options.joint_operators)
    if (skeleton.find(entry.first) < 0)
      return unknown(entry.first, "an operator choice");
  for (const auto& [name, c] : options.joint_controllers) {
    if (skeleton.find(name) < 0) return unknown(name, "a controller");
    const std::string problem = controllerProblem(c, name);
    if (!problem.empty()) return Validation::fail(problem);
  }
  return Validation::ok();
}

Composition buildComposition(const Skeleton& skeleton,
                             const FieldGridSet& fields,
                             const CompositionOptions& options,
                             const std::function<void(float)>& progress) {
  validateCompositionOptions(skeleton, options)
      .throwIfFailed("buildComposition");
  if (static_cast<int>(fields.field_of_joint.size()) != skeleton.jointCount())
    invalid("the field set maps " +
            std::to_string(fields.field_of_joint.size()) +
            " joints but the skeleton has " +
            std::to_string(skeleton.jointCount()));

  Composition out;
  out.table_resolution = options.table_resolution;
  std::vector<char> is_limb(skeleton.jointCount(), 0);
  if (options.limb_operator)
    for (int j : limbJoints(skeleton, fields.field_of_joint)) is_limb[j] = 1;
  std::set<std::string> paired;
  for (int j = 0; j < skeleton.jointCount(); ++j) {
    const int field = fields.field_of_joint[j];
    if (field < 0) continue;
    int ancestor = skeleton.joints[j].parent;
    while (ancestor >= 0 && fields.field_of_joint[ancestor] < 0)
      ancestor = skeleton.joints[ancestor].parent;
    if (ancestor < 0) continue;
    const std::string& name = skeleton.joints[j].name;
    FieldPair pair;
    pair.joint = j;
    pair.field_a = fields.field_of_joint[ancestor];
    pair.field_b = field;
    const auto chosen = options.joint_operators.find(name);
    pair.op = chosen != options.joint_operators.end() ? chosen->second
              : is_limb[j]                            ? *options.limb_operator
                           : options.default_operator;
    paired.insert(name);
    if (pair.op != CompositionOperator::kUnion) {
      const auto custom = options.joint_controllers.find(name);
      ThetaController controller;
      if (custom != options.joint_controllers.end())
        controller = resampled(custom->second);
      else if (pair.op == CompositionOperator::kBlend)
        controller = blendController(options.blend_theta);
      else
        controller = bulgeController(options.bulge_strength);
      pair.controller = static_cast<int>(out.controllers.size());
      out.controllers.push_back(std::move(controller));
      out.blended_pairs.push_back(static_cast<int>(out.pairs.size()));
    }
    out.pairs.push_back(pair);
  }
  for (const auto& [name, op] : options.joint_operators)
    if (!paired.count(name))
      out.warnings.push_back("joint '" + name +
                             "': no field on its bone or above it to pair "
                             "with, so its operator (" +
                             compositionOperatorName(op) +
                             ") composes nothing");
  // A controller only shapes a blend or a bulge (a joint left to the auto
  // choice that is not a limb joint takes the union).
  for (const auto& entry : options.joint_controllers) {
    const std::string& name = entry.first;
    const int j = skeleton.find(name);
    if (!paired.count(name)) {
      if (!options.joint_operators.count(name))
        out.warnings.push_back("joint '" + name +
                               "': no field on its bone or above it to pair "
                               "with, so its controller composes nothing");
    } else if (out.operatorAt(j) == CompositionOperator::kUnion)
      out.warnings.push_back("joint '" + name +
                             "': its controller has no effect: the joint "
                             "composes with the union" +
                             (options.limb_operator && !is_limb[j] &&
                                      !options.joint_operators.count(name)
                                  ? " (it is not a limb joint)"
                                  : ""));
  }

  // One table per operator in use, in a fixed order.
  std::vector<CompositionOperator> kinds;
  for (int k : out.blended_pairs)
    if (std::find(kinds.begin(), kinds.end(), out.pairs[k].op) == kinds.end())
      kinds.push_back(out.pairs[k].op);
  std::sort(kinds.begin(), kinds.end());
  for (size_t t = 0; t < kinds.size(); ++t) {
    const auto report = [&](float f) {
      if (progress) progress((t + f) / kinds.size());
    };
    out.tables.push_back(sharedOperatorTable(kinds[t], options.table_resolution,
                                             report, &out.warnings));
  }
  for (int k : out.blended_pairs) {
    FieldPair& p = out.pairs[k];
    p.table = static_cast<int>(std::find(kinds.begin(), kinds.end(), p.op) -
                               kinds.begin());
  }
  if (progress) progress(1.f);
  return out;
}

Eigen::Vector4f fieldBoundingSphere(const FieldGrid& grid) {
  const Eigen::Vector3f centre = 0.5f * (grid.box_min + grid.box_max);
  // Padded so that rounding never rejects a point of the box.
  const float radius = 0.5f * (grid.box_max - grid.box_min).norm() * 1.001f;
  return {centre.x(), centre.y(), centre.z(), radius};
}

std::vector<float> pairJointAngles(const Composition& composition,
                                   const FieldGridSet& fields,
                                   const TransformList& skinning) {
  std::vector<float> angles;
  angles.reserve(composition.blended_pairs.size());
  for (int k : composition.blended_pairs) {
    const FieldPair& pair = composition.pairs[k];
    const Eigen::Quaternionf a(
        skinning[fields.grids[pair.field_a].joint].rotation());
    const Eigen::Quaternionf b(
        skinning[fields.grids[pair.field_b].joint].rotation());
    // The half-angle form stays accurate near 0 (the acos of the trace
    // would turn float rounding into 3e-4 rad at rest).
    const Eigen::Quaternionf relative = a.conjugate() * b;
    angles.push_back(2.f *
                     std::atan2(relative.vec().norm(), std::abs(relative.w())));
  }
  return angles;
}

Eigen::Vector4f composePair(const Composition& composition,
                            const FieldPair& pair, const Eigen::Vector4f& a,
                            const Eigen::Vector4f& b, float joint_angle) {
  const Eigen::Vector3f ga = a.tail<3>(), gb = b.tail<3>();
  const float la = ga.norm(), lb = gb.norm();
  float alpha = 0.f;
  if (la > 0.f && lb > 0.f)
    alpha = std::acos(std::min(1.f, std::max(-1.f, ga.dot(gb) / (la * lb))));
  alpha = std::min(alpha, joint_angle);
  const float theta = composition.controllers[pair.controller].at(alpha);
  float g[3];
  composition.tables[pair.table]->sample(a[0], b[0], theta, g);
  Eigen::Vector4f out;
  out[0] = g[0];
  out.tail<3>() = g[1] * ga + g[2] * gb;
  return out;
}

Eigen::Vector4d composeExact(const Composition& composition,
                             const std::vector<Eigen::Vector4d>& samples,
                             const std::vector<float>& joint_angles) {
  Eigen::Vector4d best = Eigen::Vector4d::Zero();
  for (const Eigen::Vector4d& s : samples)
    if (s[0] > best[0]) best = s;
  for (size_t n = 0; n < composition.blended_pairs.size(); ++n) {
    const FieldPair& pair = composition.pairs[composition.blended_pairs[n]];
    const Eigen::Vector4d& a = samples.at(pair.field_a);
    const Eigen::Vector4d& b = samples.at(pair.field_b);
    if (!(a[0] > 0 && b[0] > 0)) continue;
    const Eigen::Vector3d ga = a.tail<3>(), gb = b.tail<3>();
    double alpha = 0;
    if (ga.norm() > 0 && gb.norm() > 0)
      alpha = std::acos(
          std::clamp(ga.normalized().dot(gb.normalized()), -1.0, 1.0));
    alpha = std::min(alpha, static_cast<double>(joint_angles.at(n)));
    const double theta =
        composition.controllers[pair.controller].at(static_cast<float>(alpha));
    const OperatorValue v = evaluateOperator(pair.op, a[0], b[0], theta);
    if (v.g > best[0]) {
      best[0] = v.g;
      best.tail<3>() = v.dg_df1 * ga + v.dg_df2 * gb;
    }
  }
  return best;
}

std::string describeComposition(const Composition& composition,
                                const Skeleton& skeleton) {
  std::string text;
  for (CompositionOperator op :
       {CompositionOperator::kBlend, CompositionOperator::kBulge}) {
    std::string joints;
    int count = 0;
    for (const FieldPair& p : composition.pairs) {
      if (p.op != op) continue;
      if (count < 6)
        joints += (count ? ", '" : "'") + skeleton.joints[p.joint].name + "'";
      ++count;
    }
    if (count == 0) continue;
    if (count > 6) joints += " and " + std::to_string(count - 6) + " more";
    text += std::string(text.empty() ? "" : "; ") +
            compositionOperatorName(op) + " at " + joints;
  }
  return text.empty() ? "union at every joint" : text + "; union elsewhere";
}

}  // namespace isk
