// Shared helpers of the test suite: assets, a shared OpenCL context,
// comparisons that report the index of the first mismatch (libigl's style),
// and running the sample executables end to end.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "isk/cl/runtime.hpp"
#include "isk/core/types.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/rig/rig.hpp"

namespace isk::test {

// Every asset of the shared data folder that the tests know.
const std::vector<std::string>& allAssetNames();

// The environment variable that narrows the asset tests to some assets: a
// comma-separated list of allAssetNames() entries; unset or empty: all.
// The sanitizer run sets it (run.sh sanitize), since the CPU references
// under ASan make the densest assets the bulk of its time.
inline constexpr const char* kAssetSelectionVariable = "ISK_TEST_ASSETS";
// The assets a list of that form names, in its order; all when the list is
// null or empty. Throws std::invalid_argument naming an unknown entry.
std::vector<std::string> assetSelection(const char* list);

// The assets the asset tests run on: allAssetNames() in its order, less
// those that $ISK_TEST_ASSETS leaves out, each printed as "[ left out ]"
// so that a run says what it did not cover.
std::vector<std::string> assetNames();

// An asset a check leaves out, and why (measured).
struct LeftOutAsset {
  std::string name;
  std::string reason;
};
// assetNames() less those `left_out` names; prints each one left out with
// its reason, so that a run says what a check did not cover.
std::vector<std::string> assetNamesExcept(
    const std::vector<LeftOutAsset>& left_out);

// Loads an asset of the data folder (cached per process; each test copies).
const Rig& loadAsset(const std::string& file);

// A procedural rig by name (builtinRigNames()) or an asset file of
// the data folder (cached per process).
const Rig& rigNamed(const std::string& name);
// The implicit fields of rigNamed(name), built with default options (cached).
const ImplicitFields& implicitFieldsOf(const std::string& name);

// A rig of a test's own with its fields (default options), for the
// procedural characters a test file builds once and shares.
struct RigWithFields {
  Rig rig;
  std::shared_ptr<const ImplicitFields> fields;
};
RigWithFields withDefaultFields(Rig rig);

// True when the data folder exists. When it does not, asset tests call
// GTEST_SKIP with a message naming the folder and what was skipped.
bool haveAssets();
std::string missingAssetsMessage(const std::string& what);

// One context for the whole test process (programs are built once): the
// device ClContext::create("") picks (PoCL in CI).
std::shared_ptr<ClContext> sharedContext();

// #V by 3 positions and #F by 3 triangles of hand-built meshes.
Matrix3Xf positionsOf(const std::vector<Eigen::Vector3f>& points);
TriangleMatrix trianglesOf(const std::vector<Eigen::Vector3i>& corners);

// Largest row distance between a and b, and the row where it occurs.
struct RowMismatch {
  float distance = 0.f;
  int row = -1;
};
RowMismatch largestRowDistance(const Matrix3Xf& a, const Matrix3Xf& b);

// A fresh folder under the system's temporary folder, removed with its
// content when the object dies.
class ScopedTempDir {
 public:
  ScopedTempDir();
  ~ScopedTempDir();
  ScopedTempDir(const ScopedTempDir&) = delete;
  ScopedTempDir& operator=(const ScopedTempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  // Path of `name` inside the folder.
  std::string file(const std::string& name) const {
    return (path_ / name).string();
  }
  std::string operator/(const std::string& name) const { return file(name); }

 private:
  std::filesystem::path path_;
};

// Sets (or, with a null value, unsets) an environment variable for one
// scope; the old value comes back when the object dies.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value);
  ~ScopedEnv();
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  std::string name_;
  std::optional<std::string> old_;
};

// A program's exit code and its stdout and stderr together.
struct RunOutput {
  int exit_code = -1;  // -1 when it did not exit normally
  std::string output;
};

// `arg` single-quoted for the shell.
std::string shellQuote(const std::string& arg);

// Runs `program` with `args` (each quoted) through the shell; `environment`
// is prepended to the command ("NAME=value ...").
RunOutput runProgram(const std::string& program,
                     const std::vector<std::string>& args,
                     const std::string& environment = "");

// "NAME ARGS...\nexit N, output:\n..." for failure messages.
std::string describeRun(const std::string& name,
                        const std::vector<std::string>& args,
                        const RunOutput& run);

// The whole file (binary); empty when it cannot be read.
std::string readFile(const std::string& path);

// A COLLADA file of one triangle without a skeleton; `indices` is its <p>
// list ("0 1 2"). Assimp 5.2 hangs on a list holding a non-number ("0 x 2").
std::string colladaTriangle(const std::string& indices);

// Width and height from a PNG's signature and IHDR chunk; unset (0) when
// the bytes are not a PNG.
struct PngHeader {
  bool valid = false;
  uint32_t width = 0, height = 0;
};
PngHeader parsePngHeader(const std::string& bytes);

// The body rows of the markdown table whose header line starts with
// `header`, as trimmed cells; empty when there is no such table.
std::vector<std::vector<std::string>> tableRows(const std::string& text,
                                                const std::string& header);

// The number a cell spells; NaN when it is not entirely a number.
double number(const std::string& cell);

// A PNG decoded to 8-bit RGB (stb_image), top row first. Empty (width 0)
// when the bytes do not decode; the decoders then add a test failure naming
// `what` and stb_image's reason.
struct DecodedPng {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;  // width * height * 3
  bool valid() const { return width > 0; }
  const uint8_t* at(int x, int y) const {
    return &rgb[(static_cast<size_t>(y) * width + x) * 3];
  }
};
DecodedPng decodePng(const std::string& bytes, const std::string& what);
DecodedPng decodePngFile(const std::string& path);

// Skinning transforms that bend `rig` at `joint` by `degrees` about `axis`
// through the joint's bind position: the joint and everything below it
// turn rigidly.
TransformList bendAt(const Rig& rig, int joint, double degrees,
                     const Eigen::Vector3f& axis = Eigen::Vector3f::UnitZ());

// Skinning transforms of every joint bent by `degrees`: the last pose of
// isk-skin's `--clip bend:DEGREES` (isk::makeBendClip).
TransformList everyJointBent(const Rig& rig, double degrees);

// `frames` skinning poses spread over the rig's first clip, from its start
// to its end (a 1.5 rad bend of every joint when the rig has none).
std::vector<TransformList> clipPoses(const Rig& rig, int frames);

}  // namespace isk::test
