// The joints of mirrored limbs (isk/fields/limb_joints.hpp) and the default
// composition that blends there (CompositionOptions::limb_operator): on a
// hand-built figure, on the procedural rigs and on the assets.
#include "isk/fields/limb_joints.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "isk/fields/field_composition.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

// A skeleton built joint by joint at bind positions (model space).
struct Figure {
  Skeleton skeleton;
  std::vector<Eigen::Vector3f> at;

  int add(const std::string& name, int parent, const Eigen::Vector3f& p) {
    Joint joint;
    joint.name = name;
    joint.parent = parent;
    const Eigen::Vector3f from =
        parent >= 0 ? at[parent] : Eigen::Vector3f::Zero().eval();
    joint.rest_local = Eigen::Translation3f(p - from);
    joint.inverse_bind = Eigen::Translation3f(-p);
    joint.is_skin_joint = true;
    skeleton.joints.push_back(joint);
    at.push_back(p);
    return skeleton.jointCount() - 1;
  }
  // A chain of `names` from `parent`, each joint `step` further.
  int chain(int parent, const std::vector<std::string>& names,
            const Eigen::Vector3f& step) {
    int j = parent;
    for (const std::string& name : names) j = add(name, j, at[j] + step);
    return j;
  }
};

// Pelvis -> chest -> neck -> head; clavicles, arms down to a wrist with three
// fingers; legs from the pelvis down to a ball. `left_arm_scale` stretches
// the left arm's bones.
Figure humanFigure(float left_arm_scale = 1.f) {
  Figure f;
  const int pelvis = f.add("pelvis", -1, {0, 1, 0});
  const int chest = f.add("chest", pelvis, {0, 1.4f, 0});
  f.chain(chest, {"neck", "head"}, {0, 0.15f, 0});
  for (const char* side : {"l", "r"}) {
    const float s = side[0] == 'l' ? 1.f : -1.f;
    const float k = side[0] == 'l' ? left_arm_scale : 1.f;
    const std::string x = std::string("_") + side;
    const int clavicle = f.add("clavicle" + x, chest, {s * 0.1f, 1.4f, 0});
    const int wrist =
        f.chain(clavicle, {"upperarm" + x, "lowerarm" + x, "hand" + x},
                {s * 0.25f * k, 0, 0});
    for (const char* finger : {"index", "middle", "ring"})
      f.chain(
          wrist,
          {finger + std::string("_01") + x, finger + std::string("_02") + x},
          {s * 0.03f, 0, 0});
    const int thigh = f.add("thigh" + x, pelvis, {s * 0.1f, 0.95f, 0});
    f.chain(thigh, {"calf" + x, "foot" + x, "ball" + x}, {0, -0.3f, 0});
  }
  return f;
}

std::vector<int> everyJointHasAField(const Skeleton& skeleton) {
  std::vector<int> fields(skeleton.jointCount());
  for (int j = 0; j < skeleton.jointCount(); ++j) fields[j] = j;
  return fields;
}

std::set<std::string> names(const Skeleton& skeleton,
                            const std::vector<int>& joints) {
  std::set<std::string> out;
  for (int j : joints) out.insert(skeleton.joints[j].name);
  return out;
}

TEST(LimbJoints, MirroredLimbsDownToTheirFirstBranch) {
  const Figure f = humanFigure();
  const std::vector<int> limbs =
      limbJoints(f.skeleton, everyJointHasAField(f.skeleton));
  EXPECT_TRUE(std::is_sorted(limbs.begin(), limbs.end()));
  // Not the clavicles (they meet the chest), nor the neck and head (no
  // mirror), nor the fingers (three alike, past the hand's branch).
  EXPECT_EQ(
      names(f.skeleton, limbs),
      (std::set<std::string>{"upperarm_l", "lowerarm_l", "hand_l", "upperarm_r",
                             "lowerarm_r", "hand_r", "calf_l", "foot_l",
                             "ball_l", "calf_r", "foot_r", "ball_r"}));
}

TEST(LimbJoints, JointsWithoutAFieldAreSkipped) {
  // Without fields on the clavicles and the thighs, the upper arms and the
  // calves hang from the chest and the pelvis: they start the limbs.
  const Figure f = humanFigure();
  std::vector<int> fields = everyJointHasAField(f.skeleton);
  for (const char* name : {"clavicle_l", "clavicle_r", "thigh_l", "thigh_r"})
    fields[f.skeleton.find(name)] = -1;
  EXPECT_EQ(
      names(f.skeleton, limbJoints(f.skeleton, fields)),
      (std::set<std::string>{"lowerarm_l", "hand_l", "lowerarm_r", "hand_r",
                             "foot_l", "ball_l", "foot_r", "ball_r"}));
  // A size mismatch finds none.
  fields.pop_back();
  EXPECT_TRUE(limbJoints(f.skeleton, fields).empty());
}

TEST(LimbJoints, LimbsOfDifferentLengthsAreNotMirrored) {
  // Within the tolerance the arms still mirror each other; past it, only
  // the legs do.
  const std::set<std::string> legs = {"calf_l", "foot_l", "ball_l",
                                      "calf_r", "foot_r", "ball_r"};
  const Figure close = humanFigure(1.1f);
  EXPECT_EQ(
      names(close.skeleton,
            limbJoints(close.skeleton, everyJointHasAField(close.skeleton)))
          .size(),
      12u);
  const Figure far = humanFigure(1.3f);
  EXPECT_EQ(names(far.skeleton,
                  limbJoints(far.skeleton, everyJointHasAField(far.skeleton))),
            legs);
}

TEST(LimbJoints, NoneOnTheProceduralRigs) {
  // One limb each: nothing mirrors it, so the default composition is the
  // union everywhere, as before.
  for (const std::string& name : builtinRigNames()) {
    const ImplicitFields& fields = test::implicitFieldsOf(name);
    EXPECT_TRUE(
        limbJoints(test::rigNamed(name).skeleton, fields.grids.field_of_joint)
            .empty())
        << name;
    EXPECT_TRUE(fields.composition.blended_pairs.empty()) << name;
  }
}

// The hand-built figure's composition: only field_of_joint is read.
Composition figureComposition(const Figure& f,
                              const CompositionOptions& options) {
  FieldGridSet grids;
  grids.field_of_joint = everyJointHasAField(f.skeleton);
  return buildComposition(f.skeleton, grids, options);
}

TEST(LimbJoints, TheDefaultCompositionBlendsAtTheLimbs) {
  const Figure f = humanFigure();
  const std::set<std::string> limbs = names(
      f.skeleton, limbJoints(f.skeleton, everyJointHasAField(f.skeleton)));
  CompositionOptions options;
  options.joint_operators["hand_l"] = CompositionOperator::kBulge;
  const Composition c = figureComposition(f, options);
  for (int j = 0; j < f.skeleton.jointCount(); ++j) {
    const std::string& name = f.skeleton.joints[j].name;
    const CompositionOperator expected =
        name == "hand_l"    ? CompositionOperator::kBulge
        : limbs.count(name) ? CompositionOperator::kBlend
                            : CompositionOperator::kUnion;
    EXPECT_EQ(c.operatorAt(j), expected) << name;
  }
  EXPECT_EQ(c.blended_pairs.size(), limbs.size());
  // Named choices: "union" is the union at every joint (the paper's
  // default), "auto" the default above.
  CompositionOptions choice;
  ASSERT_TRUE(parseOperatorChoice("union", &choice));
  EXPECT_FALSE(choice.limb_operator.has_value());
  EXPECT_EQ(operatorChoiceName(choice), "union");
  EXPECT_TRUE(figureComposition(f, choice).blended_pairs.empty());
  ASSERT_TRUE(parseOperatorChoice("bulge", &choice));
  EXPECT_EQ(figureComposition(f, choice).blended_pairs.size(),
            figureComposition(f, choice).pairs.size());
  ASSERT_TRUE(parseOperatorChoice("auto", &choice));
  EXPECT_EQ(choice.default_operator, CompositionOperator::kUnion);
  EXPECT_EQ(choice.limb_operator, CompositionOperator::kBlend);
  EXPECT_EQ(operatorChoiceName(choice), "auto");
  EXPECT_EQ(operatorChoiceName(CompositionOptions{}), "auto");
  EXPECT_FALSE(parseOperatorChoice("smooth", &choice));
  choice.limb_operator = CompositionOperator::kBulge;
  EXPECT_EQ(operatorChoiceName(choice), "union, bulge at the limbs");
}

TEST(LimbJoints, AControllerShapesALimbJointAndIsWarnedAboutElsewhere) {
  // A parameter file's blend_theta on joints left to the auto choice: the
  // elbow is a limb joint and takes it; the neck composes with the union,
  // which no controller shapes: a warning says so.
  const Figure f = humanFigure();
  CompositionOptions options;
  options.joint_controllers["lowerarm_l"] = blendController(0.3f);
  options.joint_controllers["neck"] = blendController(0.3f);
  const Composition c = figureComposition(f, options);
  const Composition plain = figureComposition(f, CompositionOptions{});
  auto controllerAt = [&](const Composition& comp, const char* name) {
    for (const int k : comp.blended_pairs)
      if (comp.pairs[k].joint == f.skeleton.find(name))
        return comp.controllers[comp.pairs[k].controller].theta;
    return std::vector<float>{};
  };
  ASSERT_FALSE(controllerAt(c, "lowerarm_l").empty());
  EXPECT_NE(controllerAt(c, "lowerarm_l"), controllerAt(plain, "lowerarm_l"));
  EXPECT_EQ(controllerAt(c, "lowerarm_r"), controllerAt(plain, "lowerarm_r"));
  EXPECT_EQ(c.operatorAt(f.skeleton.find("neck")), CompositionOperator::kUnion);
  ASSERT_EQ(c.warnings.size(), 1u);
  EXPECT_EQ(c.warnings[0],
            "joint 'neck': its controller has no effect: the joint composes "
            "with the union (it is not a limb joint)");
  EXPECT_TRUE(plain.warnings.empty());
  // The union everywhere: the elbow's controller is unused too.
  CompositionOptions all_union = options;
  ASSERT_TRUE(parseOperatorChoice("union", &all_union));
  const Composition u = figureComposition(f, all_union);
  ASSERT_EQ(u.warnings.size(), 2u);
  EXPECT_EQ(u.warnings[0],
            "joint 'lowerarm_l': its controller has no effect: the joint "
            "composes with the union");
}

TEST(LimbJoints, OnTheAssets) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("the assets' limb joints");
  // The limbs found, and the default composition blending exactly there.
  const std::map<std::string, std::set<std::string>> expected = {
      {"human-addon-animations.glb",
       {"upperarm_l", "lowerarm_l", "hand_l", "upperarm_r", "lowerarm_r",
        "hand_r", "calf_l", "foot_l", "ball_l", "calf_r", "foot_r", "ball_r"}},
      {"CesiumMan.glb",
       {"Skeleton_arm_joint_L__3_", "Skeleton_arm_joint_L__2_",
        "Skeleton_arm_joint_R__2_", "Skeleton_arm_joint_R__3_", "leg_joint_L_2",
        "leg_joint_L_3", "leg_joint_L_5", "leg_joint_R_2", "leg_joint_R_3",
        "leg_joint_R_5"}},
      {"anim_test.x", {}},
      {"RiggedSimple.dae", {}},
  };
  for (const auto& [file, limbs] : expected) {
    const Rig& rig = test::rigNamed(file);
    const ImplicitFields& fields = test::implicitFieldsOf(file);
    const std::vector<int> found =
        limbJoints(rig.skeleton, fields.grids.field_of_joint);
    EXPECT_EQ(names(rig.skeleton, found), limbs) << file;
    std::set<std::string> blended;
    for (int k : fields.composition.blended_pairs) {
      const FieldPair& pair = fields.composition.pairs[k];
      EXPECT_EQ(pair.op, CompositionOperator::kBlend) << file;
      blended.insert(rig.skeleton.joints[pair.joint].name);
    }
    EXPECT_EQ(blended, limbs) << file;
  }
  // Every leg joint of the quadrupeds below the shoulder and the hip, and
  // no joint of their spines, heads, jaws or tails.
  for (const char* file : {"horse-animations.glb", "fox-animations.glb"}) {
    const Rig& rig = test::rigNamed(file);
    const std::set<std::string> found =
        names(rig.skeleton,
              limbJoints(rig.skeleton,
                         test::implicitFieldsOf(file).grids.field_of_joint));
    EXPECT_GE(found.size(), 8u) << file;
    for (const std::string& name : found) {
      std::string lower = name;
      std::transform(lower.begin(), lower.end(), lower.begin(), ::tolower);
      EXPECT_TRUE(lower.find("leg") != std::string::npos ||
                  lower.find("ear") != std::string::npos ||
                  lower.find("humerus") != std::string::npos)
          << file << ": " << name;
    }
  }
}

}  // namespace
}  // namespace isk
