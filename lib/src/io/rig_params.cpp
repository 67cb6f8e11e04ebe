#include "isk/io/rig_params.hpp"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "isk/core/error.hpp"
#include "isk/fields/field_composition.hpp"
#include "isk/io/export.hpp"

namespace isk {
namespace {

using nlohmann::json;

constexpr int kVersion = 1;
constexpr int kMaxSamples = 100000;

[[noreturn]] void fail(const std::string& file, const std::string& where,
                       const std::string& why) {
  throw Error(ErrorCode::kInvalidArgument,
              file + ": " + (where.empty() ? "" : where + ": ") + why);
}

std::string keyName(const std::string& key) { return "key '" + key + "'"; }

CompositionOperator readOperator(const json& value, const std::string& file,
                                 const std::string& where) {
  CompositionOperator op;
  if (!value.is_string() ||
      !parseCompositionOperator(value.get<std::string>(), &op))
    fail(file, where,
         "expected \"union\", \"blend\" or \"bulge\", got " + value.dump());
  return op;
}

int readSamples(const json& value, const std::string& file,
                const std::string& where) {
  if (!value.is_number_integer() || value.get<long long>() < 1 ||
      value.get<long long>() > kMaxSamples)
    fail(file, where,
         "expected an integer in [1, " + std::to_string(kMaxSamples) +
             "], got " + value.dump());
  return value.get<int>();
}

double readNumber(const json& value, double lo, double hi,
                  const std::string& file, const std::string& where,
                  const char* range) {
  if (!value.is_number() || !(value.get<double>() >= lo) ||
      !(value.get<double>() <= hi))
    fail(
        file, where,
        std::string("expected a number in ") + range + ", got " + value.dump());
  return value.get<double>();
}

double readStrength(const json& v, const std::string& file,
                    const std::string& where) {
  return readNumber(v, 0, 1, file, where, "[0, 1]");
}
double readTheta(const json& v, const std::string& file,
                 const std::string& where) {
  return readNumber(v, 0, kThetaUnion, file, where, "[0, pi/4]");
}

std::string knownJoints(const Skeleton& skeleton) {
  std::string out;
  const int shown = std::min(skeleton.jointCount(), 8);
  for (int j = 0; j < shown; ++j)
    out += (j ? ", '" : "'") + skeleton.joints[j].name + "'";
  if (skeleton.jointCount() > shown)
    out += " and " + std::to_string(skeleton.jointCount() - shown) + " more";
  return out;
}

}  // namespace

bool JointParams::operator==(const JointParams& o) const {
  return op == o.op && samples == o.samples &&
         bulge_strength == o.bulge_strength && blend_theta == o.blend_theta &&
         theta_curve == o.theta_curve && tracked == o.tracked;
}

bool RigParams::operator==(const RigParams& o) const {
  // The limbs' operator as it acts: unset is the default operator.
  return default_operator == o.default_operator &&
         limb_operator.value_or(default_operator) ==
             o.limb_operator.value_or(o.default_operator) &&
         samples == o.samples && bulge_strength == o.bulge_strength &&
         blend_theta == o.blend_theta && joints == o.joints;
}

RigParams parseRigParams(const std::string& text, const std::string& file,
                         const Skeleton* skeleton) {
  json root;
  try {
    root = json::parse(text);
  } catch (const json::parse_error& e) {
    fail(file, "", std::string("not valid JSON: ") + e.what());
  }
  if (!root.is_object()) fail(file, "", "expected a JSON object at the top");
  RigParams params;
  for (const auto& [key, value] : root.items()) {
    if (key == "format") {
      if (value != "isk-params")
        fail(file, keyName(key),
             "expected \"isk-params\", got " + value.dump());
    } else if (key == "version") {
      if (value != kVersion)
        fail(file, keyName(key),
             "expected " + std::to_string(kVersion) + ", got " + value.dump());
    } else if (key == "defaults") {
      if (!value.is_object()) fail(file, keyName(key), "expected an object");
      for (const auto& [name, v] : value.items()) {
        const std::string where = "defaults: " + keyName(name);
        if (name == "operator") {
          CompositionOptions choice;
          if (!v.is_string() ||
              !parseOperatorChoice(v.get<std::string>(), &choice))
            fail(file, where,
                 "expected \"auto\", \"union\", \"blend\" or \"bulge\", "
                 "got " +
                     v.dump());
          params.default_operator = choice.default_operator;
          params.limb_operator = choice.limb_operator;
        } else if (name == "samples")
          params.samples = readSamples(v, file, where);
        else if (name == "bulge_strength")
          params.bulge_strength = readStrength(v, file, where);
        else if (name == "blend_theta")
          params.blend_theta = readTheta(v, file, where);
        else
          fail(file, where,
               "unknown key (expected operator, samples, bulge_strength or "
               "blend_theta)");
      }
    } else if (key == "joints") {
      if (!value.is_object())
        fail(file, keyName(key), "expected an object of joint names");
      for (const auto& [joint, entries] : value.items()) {
        const std::string at = "joint '" + joint + "'";
        if (skeleton && skeleton->find(joint) < 0)
          fail(file, at,
               "no such joint in the skeleton (joints: " +
                   knownJoints(*skeleton) + ")");
        if (!entries.is_object()) fail(file, at, "expected an object");
        JointParams jp;
        for (const auto& [name, v] : entries.items()) {
          const std::string where = at + ": " + keyName(name);
          if (name == "operator") {
            jp.op = readOperator(v, file, where);
          } else if (name == "samples") {
            jp.samples = readSamples(v, file, where);
          } else if (name == "bulge_strength") {
            jp.bulge_strength = readStrength(v, file, where);
          } else if (name == "blend_theta") {
            jp.blend_theta = readTheta(v, file, where);
          } else if (name == "theta_curve") {
            if (!v.is_array() || v.size() < 2)
              fail(file, where,
                   "expected an array of at least 2 theta samples");
            std::vector<float> curve;
            for (size_t i = 0; i < v.size(); ++i)
              curve.push_back(static_cast<float>(readTheta(
                  v[i], file, where + "[" + std::to_string(i) + "]")));
            jp.theta_curve = curve;
          } else if (name == "tracked") {
            if (!v.is_boolean())
              fail(file, where, "expected true or false, got " + v.dump());
            jp.tracked = v.get<bool>();
          } else {
            fail(file, where,
                 "unknown key (expected operator, samples, bulge_strength, "
                 "blend_theta, theta_curve or tracked)");
          }
        }
        if (jp.theta_curve && (jp.bulge_strength || jp.blend_theta))
          fail(file, at + ": " + keyName("theta_curve"),
               "replaces the controller: drop bulge_strength and "
               "blend_theta");
        // Without an operator of its own the joint takes the default one,
        // or under "auto" the limbs' one if it is a limb joint (known once
        // the fields are built: buildComposition warns if it is not).
        const CompositionOperator op = jp.op.value_or(params.default_operator);
        const bool may_be_limb = !jp.op && params.limb_operator;
        auto takes = [&](CompositionOperator wanted) {
          return op == wanted ||
                 (may_be_limb && *params.limb_operator == wanted);
        };
        const std::string operator_is =
            std::string(" (the joint's operator is ") +
            compositionOperatorName(op) +
            (may_be_limb ? std::string(", or ") +
                               compositionOperatorName(*params.limb_operator) +
                               " if it is a limb joint"
                         : std::string()) +
            ")";
        if (jp.bulge_strength && !takes(CompositionOperator::kBulge))
          fail(file, at + ": " + keyName("bulge_strength"),
               "needs operator bulge" + operator_is);
        if (jp.blend_theta && !takes(CompositionOperator::kBlend))
          fail(file, at + ": " + keyName("blend_theta"),
               "needs operator blend" + operator_is);
        params.joints[joint] = jp;
      }
    } else {
      fail(file, keyName(key),
           "unknown key (expected format, version, defaults or joints)");
    }
  }
  return params;
}

RigParams loadRigParams(const std::string& path, const Skeleton* skeleton) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(ErrorCode::kIo, path + ": cannot open for reading");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw Error(ErrorCode::kIo, path + ": cannot read");
  return parseRigParams(text.str(), path, skeleton);
}

std::string formatRigParams(const RigParams& params) {
  nlohmann::ordered_json root = nlohmann::ordered_json::object();
  root["format"] = "isk-params";
  root["version"] = kVersion;
  CompositionOptions choice;
  choice.default_operator = params.default_operator;
  choice.limb_operator = params.limb_operator;
  root["defaults"] = {{"operator", operatorChoiceName(choice)},
                      {"samples", params.samples},
                      {"bulge_strength", params.bulge_strength},
                      {"blend_theta", params.blend_theta}};
  nlohmann::ordered_json joints = nlohmann::ordered_json::object();
  for (const auto& [name, jp] : params.joints) {
    nlohmann::ordered_json entry = nlohmann::ordered_json::object();
    if (jp.op) entry["operator"] = compositionOperatorName(*jp.op);
    if (jp.samples) entry["samples"] = *jp.samples;
    if (jp.bulge_strength) entry["bulge_strength"] = *jp.bulge_strength;
    if (jp.blend_theta) entry["blend_theta"] = *jp.blend_theta;
    if (jp.theta_curve) entry["theta_curve"] = *jp.theta_curve;
    if (jp.tracked) entry["tracked"] = *jp.tracked;
    joints[name] = entry;
  }
  root["joints"] = joints;
  return root.dump(2) + "\n";
}

void saveRigParams(const std::string& path, const RigParams& params) {
  writeTextFile(path, formatRigParams(params));
}

void applyRigParams(const RigParams& params, ImplicitFieldsOptions* options) {
  CompositionOptions& c = options->composition;
  c.default_operator = params.default_operator;
  c.limb_operator = params.limb_operator;
  c.bulge_strength = params.bulge_strength;
  c.blend_theta = params.blend_theta;
  options->sampling.target_samples = params.samples;
  for (const auto& [name, jp] : params.joints) {
    if (jp.op) c.joint_operators[name] = *jp.op;
    if (jp.samples) options->joint_samples[name] = *jp.samples;
    if (jp.tracked && !*jp.tracked) options->untracked_joints.insert(name);
    if (jp.theta_curve) {
      ThetaController controller;
      controller.theta = *jp.theta_curve;
      c.joint_controllers[name] = controller;
    } else if (jp.bulge_strength) {
      c.joint_controllers[name] = bulgeController(*jp.bulge_strength);
    } else if (jp.blend_theta) {
      c.joint_controllers[name] = blendController(*jp.blend_theta);
    }
  }
}

std::string rigParamsPathFor(const std::string& asset_path) {
  return asset_path + ".isk.json";
}

}  // namespace isk
