// The animated glTF writer (isk/io/gltf_export.hpp) and isk-skin --gltf: the
// .glb is parsed back (GLB chunks + JSON with nlohmann, and with Assimp's
// glTF 2 importer) and each track's base + morph target k is compared with
// frame k as written to OBJ.
#include "isk/io/gltf_export.hpp"

#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "isk/core/error.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using nlohmann::json;

uint32_t readU32(const std::string& bytes, size_t at) {
  uint32_t v = 0;
  for (int i = 3; i >= 0; --i)
    v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
  return v;
}

struct Glb {
  json document;
  std::string bin;
};

// Parses a .glb's header and its two chunks; fails the test on any
// inconsistency of lengths.
Glb parseGlb(const std::string& path) {
  const std::string bytes = test::readFile(path);
  Glb glb;
  EXPECT_GE(bytes.size(), 28u);
  if (bytes.size() < 28) return glb;
  EXPECT_EQ(readU32(bytes, 0), 0x46546C67u);  // glTF
  EXPECT_EQ(readU32(bytes, 4), 2u);
  EXPECT_EQ(readU32(bytes, 8), bytes.size());
  const uint32_t json_length = readU32(bytes, 12);
  EXPECT_EQ(readU32(bytes, 16), 0x4E4F534Au);
  EXPECT_EQ(json_length % 4, 0u);
  glb.document = json::parse(bytes.substr(20, json_length));
  const size_t bin_at = 20 + json_length;
  const uint32_t bin_length = readU32(bytes, bin_at);
  EXPECT_EQ(readU32(bytes, bin_at + 4), 0x004E4942u);
  EXPECT_EQ(bin_at + 8 + bin_length, bytes.size());
  glb.bin = bytes.substr(bin_at + 8, bin_length);
  return glb;
}

// Accessor `index` as floats (FLOAT components only), checked against its
// buffer view and the BIN chunk.
std::vector<float> accessorFloats(const Glb& glb, int index) {
  const json& accessor = glb.document["accessors"][index];
  EXPECT_EQ(accessor["componentType"], 5126);
  const json& view =
      glb.document["bufferViews"][accessor["bufferView"].get<int>()];
  const int components = accessor["type"] == "VEC3" ? 3 : 1;
  const size_t count = accessor["count"].get<size_t>() * components;
  const size_t offset = view["byteOffset"].get<size_t>();
  EXPECT_EQ(offset % 4, 0u);
  EXPECT_EQ(view["byteLength"].get<size_t>(), count * sizeof(float));
  EXPECT_LE(offset + count * sizeof(float), glb.bin.size());
  std::vector<float> out(count);
  if (offset + count * sizeof(float) <= glb.bin.size())
    std::memcpy(out.data(), glb.bin.data() + offset, count * sizeof(float));
  return out;
}

// The "v x y z" lines of an OBJ file.
Matrix3Xf readObjPositions(const std::string& path) {
  std::ifstream in(path);
  std::vector<float> values;
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) != 0) continue;
    std::istringstream s(line.substr(2));
    float x, y, z;
    s >> x >> y >> z;
    values.insert(values.end(), {x, y, z});
  }
  Matrix3Xf m(values.size() / 3, 3);
  for (size_t i = 0; i < values.size(); ++i) m.data()[i] = values[i];
  return m;
}

// Checks the spec's required fields and returns the document.
void checkStructure(const Glb& glb, int tracks, int frames, int vertices) {
  const json& d = glb.document;
  EXPECT_EQ(d["asset"]["version"], "2.0");
  ASSERT_EQ(d["buffers"].size(), 1u);
  EXPECT_EQ(d["buffers"][0]["byteLength"].get<size_t>(), glb.bin.size());
  for (const json& view : d["bufferViews"]) {
    EXPECT_LE(
        view["byteOffset"].get<size_t>() + view["byteLength"].get<size_t>(),
        glb.bin.size());
  }
  ASSERT_EQ(d["meshes"].size(), static_cast<size_t>(tracks));
  ASSERT_EQ(d["nodes"].size(), static_cast<size_t>(tracks));
  EXPECT_EQ(d["scenes"][0]["nodes"].size(), static_cast<size_t>(tracks));
  for (const json& mesh : d["meshes"]) {
    const json& primitive = mesh["primitives"][0];
    const json& position =
        d["accessors"][primitive["attributes"]["POSITION"].get<int>()];
    EXPECT_EQ(position["count"], vertices);
    EXPECT_TRUE(position.contains("min") && position.contains("max"));
    EXPECT_TRUE(primitive["attributes"].contains("NORMAL"));
    ASSERT_EQ(primitive["targets"].size(), static_cast<size_t>(frames));
    for (const json& target : primitive["targets"]) {
      const json& t = d["accessors"][target["POSITION"].get<int>()];
      EXPECT_TRUE(t.contains("min") && t.contains("max"));
      EXPECT_EQ(t["count"], vertices);
    }
    EXPECT_EQ(mesh["weights"].size(), static_cast<size_t>(frames));
  }
  ASSERT_EQ(d["animations"].size(), 1u);
  const json& animation = d["animations"][0];
  EXPECT_EQ(animation["channels"].size(), static_cast<size_t>(tracks));
  for (const json& sampler : animation["samplers"]) {
    EXPECT_EQ(sampler["interpolation"], "STEP");
    const json& input = d["accessors"][sampler["input"].get<int>()];
    EXPECT_EQ(input["count"], frames);
    EXPECT_TRUE(input.contains("min") && input.contains("max"));
    EXPECT_EQ(d["accessors"][sampler["output"].get<int>()]["count"],
              frames * frames);
  }
}

// Frame k of mesh `m`: base + target k.
Matrix3Xf frameOf(const Glb& glb, int m, int k) {
  const json& primitive = glb.document["meshes"][m]["primitives"][0];
  const std::vector<float> base =
      accessorFloats(glb, primitive["attributes"]["POSITION"].get<int>());
  const std::vector<float> delta =
      accessorFloats(glb, primitive["targets"][k]["POSITION"].get<int>());
  Matrix3Xf out(base.size() / 3, 3);
  for (size_t i = 0; i < base.size(); ++i) out.data()[i] = base[i] + delta[i];
  return out;
}

TEST(GltfExportTest, IskSkinGltfMatchesTheObjFramesAndReadsInAssimp) {
  test::ScopedTempDir dir;
  const int frames = 5;
  const std::vector<std::string> args = {
      "builtin:arm",  "--method", "implicit", "--device",     "reference",
      "--frames",     "5",        "--out",    dir / "frames", "--gltf",
      dir / "arm.glb"};
  const test::RunOutput run = test::runProgram(ISK_SKIN_EXE, args);
  ASSERT_EQ(run.exit_code, 0) << test::describeRun("isk-skin", args, run);
  EXPECT_NE(run.output.find("lbs dqs implicit"), std::string::npos)
      << run.output;
  const Glb glb = parseGlb(dir / "arm.glb");
  const Matrix3Xf first = readObjPositions(dir / "frames/frame_0000.obj");
  const int vertices = static_cast<int>(first.rows());
  ASSERT_GT(vertices, 100);
  checkStructure(glb, 3, frames, vertices);
  EXPECT_EQ(glb.document["meshes"][2]["name"], "implicit");
  // Tracks side by side: increasing x offsets.
  EXPECT_LT(glb.document["nodes"][0]["translation"][0].get<float>(),
            glb.document["nodes"][1]["translation"][0].get<float>());
  float diagonal =
      (first.colwise().maxCoeff() - first.colwise().minCoeff()).norm();
  for (int k = 0; k < frames; ++k) {
    char name[64];
    std::snprintf(name, sizeof(name), "frames/frame_%04d.obj", k);
    const Matrix3Xf obj = readObjPositions(dir / name);
    const Matrix3Xf gltf = frameOf(glb, 2, k);
    ASSERT_EQ(gltf.rows(), obj.rows());
    const test::RowMismatch worst = test::largestRowDistance(gltf, obj);
    EXPECT_LE(worst.distance, 1e-5f * diagonal)
        << "frame " << k << " vertex " << worst.row;
  }
  // The frames move: the last differs from the first.
  EXPECT_GT(
      test::largestRowDistance(frameOf(glb, 2, frames - 1), first).distance,
      1e-2f * diagonal);

  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(dir / "arm.glb", 0);
  ASSERT_NE(scene, nullptr) << importer.GetErrorString();
  ASSERT_EQ(scene->mNumMeshes, 3u);
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    EXPECT_EQ(scene->mMeshes[m]->mNumVertices, static_cast<unsigned>(vertices));
    EXPECT_EQ(scene->mMeshes[m]->mNumAnimMeshes, static_cast<unsigned>(frames));
    EXPECT_TRUE(scene->mMeshes[m]->HasNormals());
  }
  ASSERT_EQ(scene->mNumAnimations, 1u);
  EXPECT_EQ(scene->mAnimations[0]->mNumMorphMeshChannels, 3u);
  if (scene->mAnimations[0]->mNumMorphMeshChannels > 0)
    EXPECT_EQ(scene->mAnimations[0]->mMorphMeshChannels[0]->mNumKeys,
              static_cast<unsigned>(frames));
}

TEST(GltfExportTest, IskSkinRefusesToWriteTheGltfOverItsInput) {
  test::ScopedTempDir dir;
  const std::string input = dir / "input.glb";
  const std::vector<std::string> first = {
      "builtin:cylinder", "--frames", "2",  "--device",
      "reference",        "--gltf",   input};
  ASSERT_EQ(test::runProgram(ISK_SKIN_EXE, first).exit_code, 0);
  const std::string before = test::readFile(input);
  const std::vector<std::string> args = {
      input, "--frames", "2", "--device", "reference", "--gltf", input};
  const test::RunOutput run = test::runProgram(ISK_SKIN_EXE, args);
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("is the input file"), std::string::npos)
      << run.output;
  EXPECT_EQ(test::readFile(input), before);
}

TEST(GltfExportTest, WriterChecksItsInputs) {
  test::ScopedTempDir dir;
  TriangleMatrix triangles(1, 3);
  triangles << 0, 1, 2;
  GltfTrack track;
  track.name = "t";
  Matrix3Xf p = Matrix3Xf::Zero(3, 3);
  p(1, 0) = 1;
  p(2, 1) = 1;
  track.positions = {p, p};
  // Two frames, one time.
  EXPECT_THROW(writeAnimatedGltf(dir / "a.glb", triangles, {track}, {0.0}),
               Error);
  // A frame with another vertex count names the track and the frame.
  track.positions[1] = Matrix3Xf::Zero(4, 3);
  try {
    writeAnimatedGltf(dir / "a.glb", triangles, {track}, {0.0, 1.0});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("track 't' frame 1"),
              std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "a.glb"));
  // Equal times are replaced by 30 per second.
  EXPECT_EQ(gltfFrameTimes({0.5, 0.5, 0.5}),
            (std::vector<double>{0, 1 / 30.0, 2 / 30.0}));
  // A valid one-frame file: one target of zeros.
  track.positions = {p};
  track.normals = {Matrix3Xf::Zero(3, 3)};
  track.normals[0].col(2).setOnes();
  writeAnimatedGltf(dir / "b.glb", triangles, {track}, {0.0});
  const Glb glb = parseGlb(dir / "b.glb");
  checkStructure(glb, 1, 1, 3);
  const Matrix3Xf back = frameOf(glb, 0, 0);
  EXPECT_EQ(back, p);
}

// Written like every file the library writes: an old file is replaced
// whole; a folder in the way or a missing folder is kIo naming the path,
// and no temporary file is left.
TEST(GltfExportTest, ReplacesAFileWholeOrFailsNamingThePath) {
  test::ScopedTempDir dir;
  TriangleMatrix triangles(1, 3);
  triangles << 0, 1, 2;
  GltfTrack track;
  track.name = "t";
  Matrix3Xf p = Matrix3Xf::Zero(3, 3);
  p(1, 0) = 1;
  p(2, 1) = 1;
  const Matrix3Xf doubled = 2 * p;
  track.positions = {p, doubled};
  Matrix3Xf n = Matrix3Xf::Zero(3, 3);
  n.col(2).setOnes();
  track.normals = {n, n};
  const std::string path = dir / "a.glb";
  { std::ofstream(path) << "an older, shorter file"; }
  writeAnimatedGltf(path, triangles, {track}, {0.0, 1.0});
  const Glb glb = parseGlb(path);
  checkStructure(glb, 1, 2, 3);
  EXPECT_EQ(frameOf(glb, 0, 1), doubled);

  std::filesystem::create_directories(dir / "folder.glb");
  for (const std::string& target :
       {dir / "folder.glb", (dir.path() / "missing" / "b.glb").string()}) {
    try {
      writeAnimatedGltf(target, triangles, {track}, {0.0, 1.0});
      ADD_FAILURE() << "no error for " << target;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kIo) << e.what();
      EXPECT_NE(std::string(e.what()).find(target), std::string::npos)
          << e.what();
    }
  }
  std::vector<std::string> entries;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path()))
    entries.push_back(entry.path().filename().string());
  std::sort(entries.begin(), entries.end());
  EXPECT_EQ(entries, (std::vector<std::string>{"a.glb", "folder.glb"}));
}

}  // namespace
}  // namespace isk
