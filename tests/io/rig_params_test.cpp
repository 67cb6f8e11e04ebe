// Per-joint parameters in JSON (isk/io/rig_params.hpp) and isk-skin's
// --params, --save-params and <asset>.isk.json.
#include "isk/io/rig_params.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "data_folder.hpp"
#include "isk/core/error.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

namespace fs = std::filesystem;

void writeText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// A parameter set using every key, on the arm's joint names.
RigParams everyKey(const Skeleton& skeleton) {
  RigParams params;
  params.default_operator = CompositionOperator::kBlend;
  params.samples = 40;
  params.bulge_strength = 0.75;
  params.blend_theta = 0.125;
  JointParams a;
  a.op = CompositionOperator::kBulge;
  a.samples = 80;
  a.bulge_strength = 0.5;
  params.joints[skeleton.joints[1].name] = a;
  JointParams b;
  b.theta_curve = std::vector<float>{0.785398f, 0.3f, 0.1f, 0.3f, 0.785398f};
  b.tracked = false;
  params.joints[skeleton.joints[2].name] = b;
  JointParams c;
  c.tracked = true;  // said, the default
  params.joints[skeleton.joints[3].name] = c;
  return params;
}

// The message of the isk::Error `f` throws ("" when none).
template <typename F>
std::string errorOf(F f) {
  try {
    f();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "no isk::Error";
  return "";
}

TEST(RigParamsTest, RoundTripsThroughAFile) {
  test::ScopedTempDir dir;
  const Rig& rig = test::rigNamed("arm");
  ASSERT_GE(rig.skeleton.jointCount(), 4);
  const RigParams params = everyKey(rig.skeleton);
  saveRigParams(dir / "p.json", params);
  const RigParams back = loadRigParams(dir / "p.json", &rig.skeleton);
  EXPECT_TRUE(back == params) << formatRigParams(back);
  EXPECT_EQ(formatRigParams(back), test::readFile(dir / "p.json"));
  // An empty object is every default.
  EXPECT_TRUE(parseRigParams("{}", "x.json") == RigParams());
}

TEST(RigParamsTest, AutoOperatorBlendsAtTheLimbs) {
  // "auto" (the default) is the union with the blend at the limb joints;
  // "union" is the union at every joint; both written back as read.
  const RigParams plain = RigParams();
  EXPECT_EQ(plain.limb_operator, CompositionOperator::kBlend);
  EXPECT_NE(formatRigParams(plain).find(R"("operator": "auto")"),
            std::string::npos)
      << formatRigParams(plain);
  const RigParams automatic =
      parseRigParams(R"({"defaults": {"operator": "auto"}})", "p.json");
  EXPECT_TRUE(automatic == plain);
  const RigParams unions =
      parseRigParams(R"({"defaults": {"operator": "union"}})", "p.json");
  EXPECT_EQ(unions.default_operator, CompositionOperator::kUnion);
  EXPECT_FALSE(unions.limb_operator.has_value());
  EXPECT_FALSE(unions == plain);
  EXPECT_NE(formatRigParams(unions).find(R"("operator": "union")"),
            std::string::npos);
  ImplicitFieldsOptions options;
  applyRigParams(unions, &options);
  EXPECT_FALSE(options.composition.limb_operator.has_value());
  applyRigParams(automatic, &options);
  EXPECT_EQ(options.composition.limb_operator, CompositionOperator::kBlend);
}

// Saved like every file the library writes: whole or not at all, into a
// folder that exists, over nothing but a regular file.
TEST(RigParamsTest, SaveFailuresAreIoErrorsNamingThePath) {
  test::ScopedTempDir dir;
  const Rig& rig = test::rigNamed("arm");
  const RigParams params = everyKey(rig.skeleton);
  fs::create_directories(dir.path() / "folder.json");
  for (const std::string& path :
       {(dir.path() / "missing" / "p.json").string(), dir / "folder.json"}) {
    try {
      saveRigParams(path, params);
      ADD_FAILURE() << "no isk::Error for " << path;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kIo) << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos)
          << e.what();
    }
  }
  EXPECT_FALSE(fs::exists(dir / "missing"));
  EXPECT_TRUE(fs::is_directory(dir / "folder.json"));
  std::vector<std::string> entries;
  for (const auto& entry : fs::directory_iterator(dir.path()))
    entries.push_back(entry.path().filename().string());
  EXPECT_EQ(entries, std::vector<std::string>{"folder.json"});
}

TEST(RigParamsTest, ApplySetsOperatorsSamplesAndControllers) {
  const Rig& rig = test::rigNamed("arm");
  const RigParams params = everyKey(rig.skeleton);
  ImplicitFieldsOptions options;
  applyRigParams(params, &options);
  const std::string a = rig.skeleton.joints[1].name;
  const std::string b = rig.skeleton.joints[2].name;
  EXPECT_EQ(options.composition.default_operator, CompositionOperator::kBlend);
  EXPECT_EQ(options.composition.blend_theta, 0.125);
  EXPECT_EQ(options.composition.bulge_strength, 0.75);
  EXPECT_EQ(options.sampling.target_samples, 40);
  EXPECT_EQ(options.composition.joint_operators.at(a),
            CompositionOperator::kBulge);
  EXPECT_EQ(options.joint_samples.at(a), 80);
  EXPECT_EQ(options.composition.joint_controllers.at(a).theta,
            bulgeController(0.5).theta);
  EXPECT_EQ(options.composition.joint_controllers.at(b).theta,
            params.joints.at(b).theta_curve.value());
  // "tracked": false, and only it, names an untracked joint.
  EXPECT_EQ(options.untracked_joints, std::set<std::string>{b});
  // The options build: the parameters are valid for the rig.
  const ImplicitFields fields = buildImplicitFields(rig, options);
  EXPECT_EQ(fields.composition.operatorAt(1), CompositionOperator::kBulge);
  EXPECT_FALSE(fields.untracked_vertices.empty());
}

TEST(RigParamsTest, ErrorsNameTheFileTheJointAndTheKey) {
  const Rig& rig = test::rigNamed("arm");
  const Skeleton* s = &rig.skeleton;
  const std::string joint = rig.skeleton.joints[1].name;
  std::string m =
      errorOf([&] { parseRigParams("{\"joints\": ", "bad.json", s); });
  EXPECT_NE(m.find("bad.json"), std::string::npos) << m;
  EXPECT_NE(m.find("not valid JSON"), std::string::npos) << m;

  m = errorOf([&] {
    parseRigParams(R"({"joints": {"nope": {"operator": "blend"}}})", "p.json",
                   s);
  });
  EXPECT_NE(m.find("p.json: joint 'nope'"), std::string::npos) << m;
  EXPECT_NE(m.find("'" + rig.skeleton.joints[0].name + "'"), std::string::npos)
      << m;  // lists known joints

  m = errorOf([&] {
    parseRigParams(R"({"joints": {")" + joint + R"(": {"strength": 1}}})",
                   "p.json", s);
  });
  EXPECT_NE(m.find("joint '" + joint + "': key 'strength'"), std::string::npos)
      << m;
  EXPECT_NE(m.find("unknown key"), std::string::npos) << m;

  m = errorOf([&] {
    parseRigParams(R"({"joints": {")" + joint +
                       R"(": {"operator": "bulge", "bulge_strength": 1.5}}})",
                   "p.json", s);
  });
  EXPECT_NE(m.find("joint '" + joint + "': key 'bulge_strength'"),
            std::string::npos)
      << m;
  EXPECT_NE(m.find("[0, 1]"), std::string::npos) << m;

  m = errorOf([&] {
    parseRigParams(R"({"joints": {")" + joint + R"(": {"samples": 0}}})",
                   "p.json", s);
  });
  EXPECT_NE(m.find("key 'samples'"), std::string::npos) << m;

  m = errorOf([&] {
    parseRigParams(
        R"({"joints": {")" + joint + R"(": {"theta_curve": [0.1, 2.0]}}})",
        "p.json", s);
  });
  EXPECT_NE(m.find("key 'theta_curve'[1]"), std::string::npos) << m;

  m = errorOf([&] {
    parseRigParams(R"({"joints": {")" + joint + R"(": {"tracked": "no"}}})",
                   "p.json", s);
  });
  EXPECT_NE(m.find("joint '" + joint + "': key 'tracked'"), std::string::npos)
      << m;
  EXPECT_NE(m.find("expected true or false"), std::string::npos) << m;

  // A key that does not fit the joint's operator.
  m = errorOf([&] {
    parseRigParams(R"({"defaults": {"operator": "union"}, "joints": {")" +
                       joint + R"(": {"blend_theta": 0.1}}})",
                   "p.json", s);
  });
  EXPECT_NE(m.find("needs operator blend (the joint's operator is union)"),
            std::string::npos)
      << m;
  // Under "auto" (the default) a joint without an operator of its own may be
  // a limb joint, which blends: a blend_theta is taken, a bulge_strength
  // not.
  EXPECT_NO_THROW(parseRigParams(
      R"({"joints": {")" + joint + R"(": {"blend_theta": 0.1}}})", "p.json",
      s));
  m = errorOf([&] {
    parseRigParams(
        R"({"joints": {")" + joint + R"(": {"bulge_strength": 0.5}}})",
        "p.json", s);
  });
  EXPECT_NE(m.find("needs operator bulge (the joint's operator is union, or "
                   "blend if it is a limb joint)"),
            std::string::npos)
      << m;

  m = errorOf([&] {
    parseRigParams(R"({"defaults": {"operator": "max"}})", "p.json", s);
  });
  EXPECT_NE(m.find("defaults: key 'operator'"), std::string::npos) << m;
  m = errorOf([&] { parseRigParams(R"({"version": 2})", "p.json", s); });
  EXPECT_NE(m.find("key 'version'"), std::string::npos) << m;
  m = errorOf([&] { parseRigParams(R"({"extra": 1})", "p.json", s); });
  EXPECT_NE(m.find("key 'extra'"), std::string::npos) << m;

  try {
    loadRigParams("/nonexistent/p.json", s);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kIo);
    EXPECT_NE(std::string(e.what()).find("/nonexistent/p.json"),
              std::string::npos);
  }
}

TEST(RigParamsTest, IskSkinSavesLoadsAndRejectsParams) {
  test::ScopedTempDir dir;
  const Rig& rig = test::rigNamed("arm");
  const std::string joint = rig.skeleton.joints[1].name;
  // The command line's choices are saved as the effective parameters.
  std::vector<std::string> args = {"builtin:arm",
                                   "--frames",
                                   "2",
                                   "--device",
                                   "reference",
                                   "--operator",
                                   "bulge",
                                   "--bulge-strength",
                                   "0.5",
                                   "--joint-operator",
                                   joint + "=blend",
                                   "--save-params",
                                   dir / "saved.json",
                                   "--report",
                                   dir / "a.json"};
  test::RunOutput run = test::runProgram(ISK_SKIN_EXE, args);
  ASSERT_EQ(run.exit_code, 0) << test::describeRun("isk-skin", args, run);
  const RigParams saved = loadRigParams(dir / "saved.json", &rig.skeleton);
  EXPECT_EQ(saved.default_operator, CompositionOperator::kBulge);
  EXPECT_EQ(saved.bulge_strength, 0.5);
  EXPECT_EQ(saved.joints.at(joint).op, CompositionOperator::kBlend);

  // Loaded back, they give the same composition and iso drift.
  args = {"builtin:arm",      "--frames",      "2",
          "--device",         "reference",     "--params",
          dir / "saved.json", "--save-params", dir / "again.json",
          "--report",         dir / "b.json"};
  run = test::runProgram(ISK_SKIN_EXE, args);
  ASSERT_EQ(run.exit_code, 0) << test::describeRun("isk-skin", args, run);
  EXPECT_NE(run.output.find("parameters from"), std::string::npos)
      << run.output;
  EXPECT_EQ(test::readFile(dir / "again.json"),
            test::readFile(dir / "saved.json"));
  const std::string a = test::readFile(dir / "a.json");
  const std::string b = test::readFile(dir / "b.json");
  auto section = [](const std::string& report, const std::string& key) {
    const size_t at = report.find("\"" + key + "\"");
    if (at == std::string::npos) return std::string();
    return report.substr(at, report.find('\n', at) - at);
  };
  EXPECT_FALSE(section(a, "iso_drift").empty()) << a;
  // The drift's mean and max follow the key on the next lines.
  auto drift = [](const std::string& report) {
    const size_t at = report.find("\"iso_drift\"");
    return at == std::string::npos ? std::string() : report.substr(at, 90);
  };
  EXPECT_EQ(drift(a), drift(b));
  EXPECT_EQ(section(a, "composition"), section(b, "composition"));

  // A bad file: exit 1, naming the file, the joint and the key.
  writeText(dir / "bad.json",
            R"({"joints": {")" + joint + R"(": {"samples": -3}}})");
  args = {"builtin:arm", "--frames",      "2", "--device", "reference",
          "--params",    dir / "bad.json"};
  run = test::runProgram(ISK_SKIN_EXE, args);
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find(dir / "bad.json"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("joint '" + joint + "': key 'samples'"),
            std::string::npos)
      << run.output;
}

TEST(RigParamsTest, ParamsPathIsBesideTheAsset) {
  EXPECT_EQ(rigParamsPathFor("/data/CesiumMan.glb"),
            "/data/CesiumMan.glb.isk.json");
}

// <asset>.isk.json is loaded without --params, and isk-skin says so.
TEST(RigParamsTest, IskSkinAutoLoadsTheFileNextToTheAsset) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("the auto-loaded parameters");
  test::ScopedTempDir dir;
  const std::string asset = dir / "RiggedSimple.dae";
  fs::copy_file(fs::path(samples::dataFolder()) / "RiggedSimple.dae", asset);
  RigParams params;
  params.default_operator = CompositionOperator::kBlend;
  saveRigParams(rigParamsPathFor(asset), params);
  const std::vector<std::string> args = {asset,         "--frames",  "2",
                                         "--device",    "reference", "--report",
                                         dir / "r.json"};
  const test::RunOutput run = test::runProgram(ISK_SKIN_EXE, args);
  ASSERT_EQ(run.exit_code, 0) << test::describeRun("isk-skin", args, run);
  EXPECT_NE(run.output.find("parameters from " + rigParamsPathFor(asset)),
            std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find("found next to the asset"), std::string::npos);
  EXPECT_NE(test::readFile(dir / "r.json").find("blend"), std::string::npos);
}

}  // namespace
}  // namespace isk
