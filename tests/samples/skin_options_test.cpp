// isk-skin's host-only preparation (samples/common/skin_options.hpp and
// skin_targets.hpp), without a device: the command line into Options and
// which groups were given, the operator and tracking checks with their
// warnings, the frame count and its refusal, the field options, the
// per-joint parameter files, and the refused output targets.
#include "skin_options.hpp"

#include <gtest/gtest.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <set>
#include <sstream>
#include <string>

#include "isk/core/error.hpp"
#include "isk/io/rig_params.hpp"
#include "isk/rig/animation.hpp"
#include "isk/tools/procedural.hpp"
#include "skin_targets.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

namespace fs = std::filesystem;
using samples::skin::Options;
using test::ScopedTempDir;

// Options as isk-skin reads `command_line` (INPUT and options, no program
// name). Throws what CLI11 throws for a bad command line.
Options parse(const std::string& command_line) {
  Options options;
  CLI::App app;
  samples::skin::addOptions(app, options);
  app.parse(command_line, /*program_name_included=*/false);
  return options;
}

// Expects `work` to throw isk::Error with `code` and a message holding
// `part`.
void expectError(const std::function<void()>& work, ErrorCode code,
                 const std::string& part) {
  try {
    work();
    ADD_FAILURE() << "no isk::Error; expected one holding '" << part << "'";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos)
        << "'" << e.what() << "' lacks '" << part << "'";
  }
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

AnimationClip clipOf(double duration) {
  AnimationClip clip;
  clip.name = "walk";
  clip.duration = duration;
  return clip;
}

TEST(IskSkinOptions, CommandLineFillsTheOptions) {
  const Options options = parse(
      "builtin:arm --method implicit --frames 7 --device opencl:1 --out o "
      "--report r.json --format ply --overwrite --rounds 3 --no-relaxation "
      "--grid-precision half --import-timeout 5 --import-memory 64 "
      "--restore-again-steps 4");
  EXPECT_EQ(options.input, "builtin:arm");
  EXPECT_EQ(options.method, "implicit");
  EXPECT_EQ(options.frames, 7);
  EXPECT_EQ(options.device, "opencl:1");
  EXPECT_EQ(options.out_dir, "o");
  EXPECT_EQ(options.report, "r.json");
  EXPECT_EQ(options.format, "ply");
  EXPECT_TRUE(options.overwrite);
  EXPECT_EQ(options.tracking.rounds, 3);
  EXPECT_FALSE(options.tracking.relaxation);
  EXPECT_EQ(options.tracking.restore_again_steps, 4);
  EXPECT_EQ(options.grid_precision, "half");
  EXPECT_EQ(options.import_timeout, 5);
  EXPECT_EQ(options.import_memory_mib, 64);
  EXPECT_TRUE(options.tracking_given);
  EXPECT_FALSE(options.composition_given);
  EXPECT_FALSE(options.operator_given);
}

TEST(IskSkinOptions, DefaultsAreThoseOfTheReadme) {
  const Options options = parse("character.glb");
  EXPECT_EQ(options.method, "dqs");
  EXPECT_EQ(options.device, "auto");
  EXPECT_EQ(options.format, "obj");
  EXPECT_EQ(options.frames, 0);
  EXPECT_EQ(options.import_timeout, samples::kImportTimeLimitSeconds);
  EXPECT_TRUE(options.tracking.relaxation);
  EXPECT_FALSE(options.tracking_given);
  EXPECT_FALSE(options.composition_given);
}

TEST(IskSkinOptions, EachCompositionOptionCountsAsGiven) {
  const Options bulge = parse("builtin:arm --bulge-strength 0.5");
  EXPECT_TRUE(bulge.composition_given);
  EXPECT_TRUE(bulge.bulge_strength_given);
  EXPECT_FALSE(bulge.blend_theta_given);
  EXPECT_FALSE(bulge.operator_given);
  EXPECT_EQ(bulge.bulge_strength, 0.5);

  const Options joint = parse("--joint-operator elbow=blend builtin:arm");
  EXPECT_TRUE(joint.composition_given);
  EXPECT_FALSE(joint.operator_given);
  ASSERT_EQ(joint.joint_operators.size(), 1u);
  EXPECT_EQ(joint.joint_operators[0], "elbow=blend");
  // One NAME=OP per occurrence: the INPUT after it stays the INPUT.
  EXPECT_EQ(joint.input, "builtin:arm");

  const Options op = parse("builtin:arm --operator union");
  EXPECT_TRUE(op.composition_given);
  EXPECT_TRUE(op.operator_given);
}

TEST(IskSkinOptions, BadValuesAreRefusedByTheParser) {
  EXPECT_THROW(parse("builtin:arm --device gpu2"), CLI::ValidationError);
  EXPECT_THROW(parse("builtin:arm --method fancy"), CLI::ValidationError);
  EXPECT_THROW(parse("builtin:arm --import-timeout nan"), CLI::ValidationError);
  EXPECT_THROW(parse("builtin:arm --import-memory 2e9"), CLI::ValidationError);
  EXPECT_THROW(parse("builtin:arm --bulge-strength 2"), CLI::ValidationError);
  EXPECT_THROW(parse("builtin:arm --frames 0"), CLI::ValidationError);
  EXPECT_THROW(parse("--method lbs"), CLI::RequiredError);
}

TEST(IskSkinOptions, DeviceNamesAreTheDocumentedOnes) {
  for (const char* ok :
       {"auto", "reference", "gpu", "cpu", "opencl:0", "opencl:12"}) {
    EXPECT_EQ(samples::skin::checkDevice(ok), "") << ok;
  }
  for (const char* bad : {"", "opencl:", "opencl:1a", "opencl:-1", "GPU"}) {
    EXPECT_NE(samples::skin::checkDevice(bad).find("expected auto, reference"),
              std::string::npos)
        << bad;
  }
}

TEST(IskSkinOptions, JointOperatorsSplitAtTheLastEquals) {
  Options options;
  options.default_operator = "blend";
  options.joint_operators = {"mixamorig:Left=Arm=bulge", "elbow=union",
                             "elbow=union"};
  const CompositionOptions composition =
      samples::skin::parseCompositionOptions(options);
  EXPECT_EQ(composition.default_operator, CompositionOperator::kBlend);
  ASSERT_EQ(composition.joint_operators.size(), 2u);
  EXPECT_EQ(composition.joint_operators.at("mixamorig:Left=Arm"),
            CompositionOperator::kBulge);
  EXPECT_EQ(composition.joint_operators.at("elbow"),
            CompositionOperator::kUnion);
}

TEST(IskSkinOptions, OperatorAutoIsTheDefault) {
  // --operator auto (the default): the union, the blend at the limbs;
  // --operator union: the union at every joint.
  Options options;
  EXPECT_EQ(options.default_operator, "auto");
  CompositionOptions composition =
      samples::skin::parseCompositionOptions(options);
  EXPECT_EQ(composition.default_operator, CompositionOperator::kUnion);
  EXPECT_EQ(composition.limb_operator, CompositionOperator::kBlend);
  options.default_operator = "union";
  composition = samples::skin::parseCompositionOptions(options);
  EXPECT_EQ(composition.default_operator, CompositionOperator::kUnion);
  EXPECT_FALSE(composition.limb_operator.has_value());
  options.default_operator = "smooth";
  expectError([&] { samples::skin::parseCompositionOptions(options); },
              ErrorCode::kInvalidArgument,
              "--operator 'smooth': expected auto, union, blend or bulge");
}

TEST(IskSkinOptions, BadOperatorChoicesNameTheArgument) {
  auto parseWith = [](const std::vector<std::string>& joint_operators) {
    Options options;
    options.joint_operators = joint_operators;
    samples::skin::parseCompositionOptions(options);
  };
  expectError([&] { parseWith({"elbow"}); }, ErrorCode::kInvalidArgument,
              "--joint-operator 'elbow': expected NAME=OP");
  expectError([&] { parseWith({"=blend"}); }, ErrorCode::kInvalidArgument,
              "the joint name before '=' is empty");
  expectError([&] { parseWith({"elbow=smooth"}); }, ErrorCode::kInvalidArgument,
              "unknown operator 'smooth'");
  expectError(
      [&] {
        parseWith({"elbow=blend", "elbow=bulge"});
      },
      ErrorCode::kInvalidArgument, "joint 'elbow' already has operator blend");

  Options nan_strength;
  nan_strength.bulge_strength = std::numeric_limits<double>::quiet_NaN();
  expectError([&] { samples::skin::parseCompositionOptions(nan_strength); },
              ErrorCode::kInvalidArgument, "--bulge-strength nan");
  Options theta;
  theta.blend_theta = 1;
  expectError([&] { samples::skin::parseCompositionOptions(theta); },
              ErrorCode::kInvalidArgument, "expected radians in [0, pi/4]");
}

TEST(IskSkinOptions, TrackingOptionsAreCheckedAndWarnedAbout) {
  Options options;
  options.tracking.sigma = -1;
  expectError([&] { samples::skin::checkTrackingOptions(options); },
              ErrorCode::kInvalidArgument, "surface tracking: ");

  Options given;
  given.tracking_given = true;
  EXPECT_NE(samples::skin::trackingOptionsWarning(given).find(
                "no effect without --method implicit"),
            std::string::npos);
  given.method = "implicit";
  EXPECT_EQ(samples::skin::trackingOptionsWarning(given), "");
  EXPECT_EQ(samples::skin::trackingOptionsWarning(Options{}), "");
}

TEST(IskSkinOptions, UnusedControllersAreWarnedAbout) {
  Options options;
  options.bulge_strength_given = true;
  options.blend_theta_given = true;
  // The composition as built: two pairs, the first blended.
  Composition built;
  built.pairs.resize(2);
  built.pairs[0].op = CompositionOperator::kBlend;
  built.blended_pairs = {0};
  EXPECT_EQ(samples::skin::unusedControllerWarnings(options, built),
            std::vector<std::string>{
                "isk-skin: warning: --bulge-strength has no effect: no joint "
                "uses bulge"});
  built.pairs[0].op = CompositionOperator::kUnion;  // union everywhere
  built.blended_pairs.clear();
  const std::vector<std::string> both =
      samples::skin::unusedControllerWarnings(options, built);
  ASSERT_EQ(both.size(), 2u);
  EXPECT_EQ(both[0],
            "isk-skin: warning: --bulge-strength has no effect: no joint "
            "uses bulge");
  EXPECT_EQ(both[1],
            "isk-skin: warning: --blend-theta has no effect: no joint uses "
            "blend");
  built.pairs[0].op = CompositionOperator::kBulge;
  built.pairs[1].op = CompositionOperator::kBlend;
  built.blended_pairs = {0, 1};
  EXPECT_TRUE(samples::skin::unusedControllerWarnings(options, built).empty());
  options.bulge_strength_given = options.blend_theta_given = false;
  built.blended_pairs.clear();
  EXPECT_TRUE(samples::skin::unusedControllerWarnings(options, built).empty());
}

TEST(IskSkinOptions, UnknownJointIsAnErrorOnlyWhenOperatorsWereGiven) {
  const Rig rig = makeBuiltinRig("arm");
  Options options;
  options.input = "builtin:arm";
  CompositionOptions composition;
  composition.joint_operators["knee"] = CompositionOperator::kBlend;
  EXPECT_NO_THROW(
      samples::skin::checkJointOperators(options, rig.skeleton, composition));
  options.composition_given = true;
  expectError(
      [&] {
        samples::skin::checkJointOperators(options, rig.skeleton, composition);
      },
      ErrorCode::kInvalidArgument, "builtin:arm: --joint-operator: ");
  composition.joint_operators = {{"elbow", CompositionOperator::kBlend}};
  EXPECT_NO_THROW(
      samples::skin::checkJointOperators(options, rig.skeleton, composition));
}

TEST(IskSkinOptions, MethodFormatAndImportLimitsFollowTheOptions) {
  Options options;
  EXPECT_EQ(samples::skin::skinningMethod(options),
            SkinningMethod::kDualQuaternion);
  EXPECT_EQ(samples::skin::frameFormat(options), MeshFormat::kObj);
  options.method = "lbs";
  options.format = "ply";
  EXPECT_EQ(samples::skin::skinningMethod(options),
            SkinningMethod::kLinearBlend);
  EXPECT_EQ(samples::skin::frameFormat(options), MeshFormat::kPly);
  options.method = "implicit";  // starts from DQS
  EXPECT_EQ(samples::skin::skinningMethod(options),
            SkinningMethod::kDualQuaternion);

  options.import_timeout = 2.5;
  options.import_memory_mib = 3;
  const ImportOptions import = samples::skin::importOptions(options);
  EXPECT_EQ(import.time_limit_seconds, 2.5);
  EXPECT_EQ(import.memory_limit_bytes, 3u * 1024 * 1024);
}

TEST(IskSkinOptions, FrameCountIsThirtyPerSecondUnlessGiven) {
  Options options;
  options.input = "walk.glb";
  EXPECT_EQ(samples::skin::frameCount(options, clipOf(2)), 61);
  EXPECT_EQ(samples::skin::frameCount(options, clipOf(0)), 1);
  options.frames = 4;
  EXPECT_EQ(samples::skin::frameCount(options, clipOf(2)), 4);
}

TEST(IskSkinOptions, AnEndlessClipNeedsFrames) {
  Options options;
  options.input = "walk.glb";
  // An hour of animation is the most the default may ask for.
  EXPECT_EQ(samples::skin::frameCount(options, clipOf(3600)),
            samples::skin::kMaxDefaultFrames);
  expectError([&] { samples::skin::frameCount(options, clipOf(3601)); },
              ErrorCode::kInvalidArgument,
              "walk.glb: clip 'walk' lasts 3601.000000 s, 108031 frames at 30 "
              "per second; pass --frames N");
  options.frames = 10;
  EXPECT_EQ(samples::skin::frameCount(options, clipOf(1e9)), 10);
}

TEST(IskSkinOptions, FieldsAreBuiltForImplicitOperatorsOrParameters) {
  Options options;
  EXPECT_FALSE(samples::skin::needsFields(options, std::nullopt));
  EXPECT_TRUE(samples::skin::needsFields(options, ImplicitFieldsOptions{}));
  options.composition_given = true;
  EXPECT_TRUE(samples::skin::needsFields(options, std::nullopt));
  Options implicit;
  implicit.method = "implicit";
  EXPECT_TRUE(samples::skin::needsFields(implicit, std::nullopt));
}

TEST(IskSkinOptions, FieldOptionsTakeTheParametersOverTheCommandLine) {
  Options options;
  CompositionOptions composition;
  composition.default_operator = CompositionOperator::kBulge;
  const ImplicitFieldsOptions from_cli =
      samples::skin::fieldOptions(options, composition, std::nullopt);
  EXPECT_EQ(from_cli.composition.default_operator, CompositionOperator::kBulge);
  EXPECT_TRUE(from_cli.cache);
  EXPECT_EQ(from_cli.grid_precision, GridPrecision::kFloat);

  ImplicitFieldsOptions params;
  params.composition.default_operator = CompositionOperator::kBlend;
  params.cache = false;
  options.grid_precision = "half";
  const ImplicitFieldsOptions from_params =
      samples::skin::fieldOptions(options, composition, params);
  EXPECT_EQ(from_params.composition.default_operator,
            CompositionOperator::kBlend);
  EXPECT_TRUE(from_params.cache);
  EXPECT_EQ(from_params.grid_precision, GridPrecision::kHalf);

  options.tracking.rounds = 5;
  const ImplicitSkinnerOptions implicit =
      samples::skin::implicitOptions(options, from_params);
  EXPECT_EQ(implicit.tracking.rounds, 5);
  EXPECT_EQ(implicit.base_skinning, SkinningMethod::kDualQuaternion);
  EXPECT_EQ(implicit.fields.grid_precision, GridPrecision::kHalf);
}

TEST(IskSkinOptions, NoParametersWithoutAFileOrSaveParams) {
  const Rig rig = makeBuiltinRig("arm");
  Options options;
  options.input = "builtin:arm";
  std::ostringstream log;
  EXPECT_FALSE(samples::skin::loadParams(options, rig, log).has_value());
  EXPECT_EQ(log.str(), "");
}

TEST(IskSkinOptions, CommandLineOperatorsWinOverTheParameterFile) {
  const ScopedTempDir dir;
  const Rig rig = makeBuiltinRig("arm");
  const std::string params = dir / "arm.isk.json";
  writeText(params,
            R"({"format": "isk-params", "version": 1,
                "defaults": {"operator": "blend"},
                "joints": {"wrist": {"operator": "bulge"}}})");
  Options options;
  options.input = "builtin:arm";
  options.params = params;
  std::ostringstream log;
  const std::optional<ImplicitFieldsOptions> from_file =
      samples::skin::loadParams(options, rig, log);
  ASSERT_TRUE(from_file.has_value());
  EXPECT_EQ(from_file->composition.default_operator,
            CompositionOperator::kBlend);
  EXPECT_EQ(from_file->composition.joint_operators.at("wrist"),
            CompositionOperator::kBulge);
  EXPECT_EQ(log.str(), "isk-skin: parameters from " + params + "\n");

  options.default_operator = "union";
  options.operator_given = true;
  options.joint_operators = {"wrist=blend"};
  options.save_params = dir / "saved/effective.json";
  log.str("");
  const std::optional<ImplicitFieldsOptions> merged =
      samples::skin::loadParams(options, rig, log);
  ASSERT_TRUE(merged.has_value());
  EXPECT_EQ(merged->composition.default_operator, CompositionOperator::kUnion);
  EXPECT_EQ(merged->composition.joint_operators.at("wrist"),
            CompositionOperator::kBlend);
  EXPECT_NE(log.str().find("isk-skin: wrote the parameters to " +
                           options.save_params),
            std::string::npos)
      << log.str();
  const RigParams saved = loadRigParams(options.save_params, &rig.skeleton);
  EXPECT_EQ(saved.default_operator, CompositionOperator::kUnion);
  EXPECT_EQ(saved.joints.at("wrist").op.value_or(CompositionOperator::kUnion),
            CompositionOperator::kBlend);
}

TEST(IskSkinOptions, JointNamePatterns) {
  using samples::skin::jointNameMatches;
  EXPECT_TRUE(jointNameMatches("wrist", "wrist"));
  EXPECT_FALSE(jointNameMatches("wrist", "wrist_l"));
  EXPECT_TRUE(jointNameMatches("wing*", "wing_feather_4_0_l"));
  EXPECT_TRUE(jointNameMatches("wing*", "wing"));
  EXPECT_FALSE(jointNameMatches("wing*", "left_wing"));
  EXPECT_TRUE(jointNameMatches("*wing*", "left_wing_2"));
  EXPECT_TRUE(jointNameMatches("*_l", "wing_3_l"));
  EXPECT_FALSE(jointNameMatches("*_l", "wing_3_r"));
  EXPECT_TRUE(jointNameMatches("wing_?_l", "wing_3_l"));
  EXPECT_FALSE(jointNameMatches("wing_?_l", "wing_10_l"));
  EXPECT_TRUE(jointNameMatches("a*b*c", "aXXbYbZc"));
  EXPECT_FALSE(jointNameMatches("a*b*c", "aXXbYbZ"));
  EXPECT_TRUE(jointNameMatches("*", ""));
  EXPECT_FALSE(jointNameMatches("?", ""));
  EXPECT_TRUE(jointNameMatches("mixamorig:*Hand*", "mixamorig:LeftHandIndex1"));
}

// --untracked-joint: every joint a pattern matches gets "tracked": false
// (in the options and in --save-params); a pattern matching none is an
// error that names it and lists joints.
TEST(IskSkinOptions, UntrackedJointPatternsNameTheJoints) {
  const ScopedTempDir dir;
  const Rig rig = makeBuiltinRig("arm");
  Options options;
  options.input = "builtin:arm";
  options.untracked_joints = {"wri*", "hand_?ip"};
  options.save_params = dir / "saved.json";
  std::ostringstream log;
  const std::optional<ImplicitFieldsOptions> params =
      samples::skin::loadParams(options, rig, log);
  ASSERT_TRUE(params.has_value());
  EXPECT_EQ(params->untracked_joints,
            (std::set<std::string>{"wrist", "hand_tip"}));
  const RigParams saved = loadRigParams(options.save_params, &rig.skeleton);
  EXPECT_EQ(saved.joints.at("wrist").tracked, std::optional<bool>(false));
  EXPECT_EQ(saved.joints.at("hand_tip").tracked, std::optional<bool>(false));
  EXPECT_EQ(saved.joints.count("elbow"), 0u);

  options.save_params.clear();
  options.untracked_joints = {"wrist", "wing*"};
  expectError([&] { samples::skin::loadParams(options, rig, log); },
              ErrorCode::kInvalidArgument,
              "builtin:arm: --untracked-joint 'wing*': no joint matches "
              "(joints: 'shoulder', 'elbow', 'wrist', 'hand_tip')");
}

TEST(IskSkinOptions, TheParameterFileBesideTheAssetIsFoundAndSaid) {
  const ScopedTempDir dir;
  const Rig rig = makeBuiltinRig("arm");
  const std::string asset = dir / "arm.glb";
  writeText(asset, "not read here");
  writeText(rigParamsPathFor(asset),
            R"({"format": "isk-params", "version": 1,
                "defaults": {"operator": "bulge"}})");
  Options options;
  options.input = asset;
  std::ostringstream log;
  const std::optional<ImplicitFieldsOptions> params =
      samples::skin::loadParams(options, rig, log);
  ASSERT_TRUE(params.has_value());
  EXPECT_EQ(params->composition.default_operator, CompositionOperator::kBulge);
  EXPECT_EQ(log.str(), "isk-skin: parameters from " + rigParamsPathFor(asset) +
                           " (found next to the asset; --params FILE to "
                           "choose another)\n");

  options.save_params = asset;
  expectError([&] { samples::skin::loadParams(options, rig, log); },
              ErrorCode::kInvalidArgument,
              "--save-params " + asset + " is the input file");
}

TEST(IskSkinTargets, ReportRefusesWhatItWouldDestroy) {
  const ScopedTempDir dir;
  Options options;
  options.input = dir / "input.glb";
  writeText(options.input, "input");

  options.report = options.input;
  expectError([&] { samples::skin::checkReportTarget(options); },
              ErrorCode::kInvalidArgument, "is the input file");

  options.report = dir.path().string();
  expectError([&] { samples::skin::checkReportTarget(options); },
              ErrorCode::kIo, ": is a folder");

  options.report = dir / "old.json";
  writeText(options.report, "{}");
  expectError([&] { samples::skin::checkReportTarget(options); },
              ErrorCode::kIo, "the file exists; pass --overwrite");
  options.overwrite = true;
  EXPECT_NO_THROW(samples::skin::checkReportTarget(options));

  options.out_dir = dir / "frames";
  options.report = dir / "frames/frame_0002.ply";
  expectError([&] { samples::skin::checkReportTarget(options); },
              ErrorCode::kInvalidArgument,
              "a frame file of --out would replace it");
  options.report = dir / "frames/frame_0002.json";
  EXPECT_NO_THROW(samples::skin::checkReportTarget(options));
  options.report = dir / "frame_0002.obj";  // beside --out, not in it
  EXPECT_NO_THROW(samples::skin::checkReportTarget(options));
}

TEST(IskSkinTargets, GltfAndSaveParamsRefuseTheInput) {
  const ScopedTempDir dir;
  Options options;
  options.input = dir / "input.glb";
  writeText(options.input, "input");
  options.gltf = options.input;
  expectError([&] { samples::skin::checkGltfTarget(options); },
              ErrorCode::kInvalidArgument, "is the input file");
  options.gltf = dir.path().string();
  expectError([&] { samples::skin::checkGltfTarget(options); },
              ErrorCode::kInvalidArgument, "is a folder");
  options.gltf = dir / "out.glb";
  EXPECT_NO_THROW(samples::skin::checkGltfTarget(options));

  options.save_params = options.input;
  expectError([&] { samples::skin::checkSaveParamsTarget(options); },
              ErrorCode::kInvalidArgument, "is the input file");
  // A builtin input is no file: nothing to protect.
  options.input = "builtin:arm";
  options.save_params = "builtin:arm";
  EXPECT_NO_THROW(samples::skin::checkSaveParamsTarget(options));
}

TEST(IskSkinTargets, ParentFolderIsCreated) {
  const ScopedTempDir dir;
  const std::string path = dir / "a/b/report.json";
  samples::skin::createParentFolder(path);
  EXPECT_TRUE(fs::is_directory(dir / "a/b"));
  EXPECT_FALSE(fs::exists(path));
  EXPECT_NO_THROW(samples::skin::createParentFolder("report.json"));
}

}  // namespace
}  // namespace isk
