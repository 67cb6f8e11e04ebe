// Tests of isk::writeMesh (OBJ, PLY) and of the mesh metrics.
#include "isk/io/export.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>
#include <string>

#include "isk/core/error.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using test::ScopedTempDir;

namespace fs = std::filesystem;

struct ParsedMesh {
  Matrix3Xf positions;
  Matrix3Xf normals;
  TriangleMatrix triangles;
  bool has_normals = false;
};

// Reads the subset of OBJ that writeMesh produces; fails the test on a face
// whose position and normal indices differ.
ParsedMesh readObj(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in) << path;
  std::vector<Eigen::RowVector3f> v, vn;
  std::vector<Eigen::Matrix<int32_t, 1, 3>> f;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string tag;
    s >> tag;
    if (tag == "v" || tag == "vn") {
      Eigen::RowVector3f p;
      s >> p.x() >> p.y() >> p.z();
      (tag == "v" ? v : vn).push_back(p);
    } else if (tag == "f") {
      Eigen::Matrix<int32_t, 1, 3> t;
      for (int c = 0; c < 3; ++c) {
        std::string corner;
        s >> corner;
        const size_t slash = corner.find("//");
        const int position = std::stoi(corner.substr(0, slash));
        if (slash != std::string::npos) {
          EXPECT_EQ(std::stoi(corner.substr(slash + 2)), position) << line;
        }
        t[c] = position - 1;
      }
      f.push_back(t);
    }
  }
  ParsedMesh mesh;
  mesh.positions.resize(v.size(), 3);
  for (size_t i = 0; i < v.size(); ++i) mesh.positions.row(i) = v[i];
  mesh.has_normals = !vn.empty();
  mesh.normals.resize(vn.size(), 3);
  for (size_t i = 0; i < vn.size(); ++i) mesh.normals.row(i) = vn[i];
  mesh.triangles.resize(f.size(), 3);
  for (size_t i = 0; i < f.size(); ++i) mesh.triangles.row(i) = f[i];
  return mesh;
}

// Reads the binary little-endian PLY that writeMesh produces (x86 hosts are
// little endian, so the bytes are copied as they are).
ParsedMesh readPly(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in) << path;
  std::string line;
  int vertices = 0, faces = 0, vertex_properties = 0;
  std::getline(in, line);
  EXPECT_EQ(line, "ply");
  std::getline(in, line);
  EXPECT_EQ(line, "format binary_little_endian 1.0");
  std::string element;
  while (std::getline(in, line) && line != "end_header") {
    std::istringstream s(line);
    std::string word;
    s >> word;
    if (word == "element") {
      s >> element;
      s >> (element == "vertex" ? vertices : faces);
    } else if (word == "property" && element == "vertex") {
      EXPECT_EQ(line.rfind("property float ", 0), 0u) << line;
      ++vertex_properties;
    } else if (word == "property") {
      EXPECT_EQ(line, "property list uchar int vertex_indices");
    }
  }
  ParsedMesh mesh;
  mesh.has_normals = vertex_properties == 6;
  EXPECT_TRUE(vertex_properties == 3 || vertex_properties == 6);
  mesh.positions.resize(vertices, 3);
  mesh.normals.resize(mesh.has_normals ? vertices : 0, 3);
  for (int v = 0; v < vertices; ++v) {
    float values[6];
    in.read(reinterpret_cast<char*>(values), 4 * vertex_properties);
    for (int c = 0; c < 3; ++c) mesh.positions(v, c) = values[c];
    if (mesh.has_normals) {
      for (int c = 0; c < 3; ++c) mesh.normals(v, c) = values[3 + c];
    }
  }
  mesh.triangles.resize(faces, 3);
  for (int f = 0; f < faces; ++f) {
    unsigned char count = 0;
    in.read(reinterpret_cast<char*>(&count), 1);
    EXPECT_EQ(count, 3);
    int32_t indices[3];
    in.read(reinterpret_cast<char*>(indices), sizeof(indices));
    for (int c = 0; c < 3; ++c) mesh.triangles(f, c) = indices[c];
  }
  EXPECT_TRUE(in) << "truncated " << path;
  EXPECT_EQ(in.peek(), std::char_traits<char>::eof()) << "trailing bytes";
  return mesh;
}

// Five vertices and three triangles on the edge (0, 1): a non-manifold fan
// that a halfedge structure would reject. Coordinates that need all 9
// significant digits check that the text round-trips exactly.
struct FanMesh {
  Matrix3Xf positions;
  Matrix3Xf normals;
  TriangleMatrix triangles;
};

FanMesh makeFan() {
  FanMesh mesh;
  mesh.positions.resize(5, 3);
  mesh.positions << 0.f, 0.f, 0.f,      //
      1.f, 0.f, 0.f,                    //
      0.5f, 1.f / 3.f, 0.f,             //
      0.5f, -0.1234567f, 1e-7f,         //
      0.5f, 3.14159274f, -123456.789f;  //
  mesh.normals.resize(5, 3);
  mesh.normals << 0.f, 0.f, 1.f,      //
      0.f, 0.f, 1.f,                  //
      0.f, 0.6f, 0.8f,                //
      0.f, -1.f, 0.f,                 //
      0.f, 0.70710678f, 0.70710678f;  //
  mesh.triangles.resize(3, 3);
  mesh.triangles << 0, 1, 2,  //
      1, 0, 3,                //
      0, 1, 4;
  return mesh;
}

TEST(ExportTest, ObjRoundTripKeepsVertexOrderAndNonManifoldTriangles) {
  ScopedTempDir dir;
  const FanMesh fan = makeFan();
  const std::string path = (dir.path() / "fan.obj").string();
  writeMesh(path, MeshFormat::kObj, fan.positions, &fan.normals, fan.triangles);
  const ParsedMesh read = readObj(path);
  EXPECT_EQ(read.positions, fan.positions);  // bit-exact round trip
  ASSERT_TRUE(read.has_normals);
  EXPECT_EQ(read.normals, fan.normals);
  EXPECT_EQ(read.triangles, fan.triangles);
}

TEST(ExportTest, ObjWithoutNormalsWritesPlainFaces) {
  ScopedTempDir dir;
  const FanMesh fan = makeFan();
  const std::string path = (dir.path() / "fan.obj").string();
  writeMesh(path, MeshFormat::kObj, fan.positions, nullptr, fan.triangles);
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)),
                         std::istreambuf_iterator<char>());
  EXPECT_EQ(text.find("vn"), std::string::npos);
  EXPECT_NE(text.find("\nf 1 2 3\n"), std::string::npos) << text;
  const ParsedMesh read = readObj(path);
  EXPECT_FALSE(read.has_normals);
  EXPECT_EQ(read.positions, fan.positions);
  EXPECT_EQ(read.triangles, fan.triangles);
}

TEST(ExportTest, PlyRoundTripKeepsVertexOrderAndNonManifoldTriangles) {
  ScopedTempDir dir;
  const FanMesh fan = makeFan();
  const std::string path = (dir.path() / "fan.ply").string();
  writeMesh(path, MeshFormat::kPly, fan.positions, &fan.normals, fan.triangles);
  const ParsedMesh read = readPly(path);
  EXPECT_EQ(read.positions, fan.positions);
  ASSERT_TRUE(read.has_normals);
  EXPECT_EQ(read.normals, fan.normals);
  EXPECT_EQ(read.triangles, fan.triangles);

  writeMesh(path, MeshFormat::kPly, fan.positions, nullptr, fan.triangles);
  const ParsedMesh without_normals = readPly(path);
  EXPECT_FALSE(without_normals.has_normals);
  EXPECT_EQ(without_normals.positions, fan.positions);
  EXPECT_EQ(without_normals.triangles, fan.triangles);
}

TEST(ExportTest, ReplacesAnExistingFile) {
  ScopedTempDir dir;
  const FanMesh fan = makeFan();
  const std::string path = (dir.path() / "fan.obj").string();
  std::ofstream(path) << "old content that is longer than nothing\n";
  writeMesh(path, MeshFormat::kObj, fan.positions, &fan.normals, fan.triangles);
  EXPECT_EQ(readObj(path).triangles, fan.triangles);
}

std::vector<std::string> folderEntries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());  // listing order is unspecified
  return names;
}

TEST(ExportTest, MissingFolderThrowsIoNamingThePath) {
  ScopedTempDir dir;
  const FanMesh fan = makeFan();
  const std::string path = (dir.path() / "no_such_folder" / "fan.obj").string();
  try {
    writeMesh(path, MeshFormat::kObj, fan.positions, &fan.normals,
              fan.triangles);
    FAIL() << "expected isk::Error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kIo);
    EXPECT_NE(std::string(error.what()).find(path), std::string::npos)
        << error.what();
  }
  EXPECT_TRUE(folderEntries(dir.path()).empty());
}

// The target is a folder: the write is refused (only a regular file is ever
// replaced) and no temporary file is left behind (permissions cannot make a
// path unwritable when the tests run as root; this failure happens for
// everyone).
TEST(ExportTest, FailedRenameThrowsIoAndLeavesNoTemporaryFile) {
  ScopedTempDir dir;
  const FanMesh fan = makeFan();
  const fs::path target = dir.path() / "taken.ply";
  fs::create_directories(target / "inside");
  for (MeshFormat format : {MeshFormat::kObj, MeshFormat::kPly}) {
    try {
      writeMesh(target.string(), format, fan.positions, &fan.normals,
                fan.triangles);
      FAIL() << "expected isk::Error";
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), ErrorCode::kIo);
      EXPECT_NE(std::string(error.what()).find(target.string()),
                std::string::npos)
          << error.what();
    }
    EXPECT_EQ(folderEntries(dir.path()), std::vector<std::string>{"taken.ply"});
  }
}

// A link under the target's name is neither followed nor replaced.
TEST(ExportTest, NeverReplacesALink) {
  ScopedTempDir dir;
  const FanMesh fan = makeFan();
  { std::ofstream(dir.path() / "mine.obj") << "mine\n"; }
  fs::create_symlink(dir.path() / "mine.obj", dir.path() / "fan.obj");
  const std::string path = dir.file("fan.obj");
  try {
    writeMesh(path, MeshFormat::kObj, fan.positions, &fan.normals,
              fan.triangles);
    FAIL() << "expected isk::Error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kIo);
    EXPECT_NE(std::string(error.what()).find(path), std::string::npos)
        << error.what();
  }
  EXPECT_THROW(writeTextFile(path, "x"), Error);
  EXPECT_TRUE(fs::is_symlink(path));
  std::ifstream in(dir.path() / "mine.obj");
  std::string text;
  std::getline(in, text);
  EXPECT_EQ(text, "mine");
  EXPECT_EQ(folderEntries(dir.path()),
            (std::vector<std::string>{"fan.obj", "mine.obj"}));
}

// Larger than the writer's 1 MiB buffer: written in several chunks, whole.
TEST(ExportTest, LargeMeshesAreWrittenWhole) {
  ScopedTempDir dir;
  const int vertices = 60000;  // about 2 MiB of OBJ text
  Matrix3Xf positions(vertices, 3);
  for (int v = 0; v < vertices; ++v)
    positions.row(v) << 0.001f * v, -0.5f * v, 1.f / (v + 1);
  TriangleMatrix triangles(vertices - 2, 3);
  for (int f = 0; f < vertices - 2; ++f) triangles.row(f) << f, f + 1, f + 2;
  const std::string path = dir.file("large.obj");
  writeMesh(path, MeshFormat::kObj, positions, nullptr, triangles);
  EXPECT_GT(fs::file_size(path), 2u << 20);
  const ParsedMesh read = readObj(path);
  EXPECT_EQ(read.positions, positions);
  EXPECT_EQ(read.triangles, triangles);
  EXPECT_EQ(folderEntries(dir.path()), std::vector<std::string>{"large.obj"});
}

TEST(ExportTest, TextFilesAreWrittenWholeOrNotAtAll) {
  ScopedTempDir dir;
  const std::string path = dir.file("report.json");
  writeTextFile(path, "{\"a\": 1}\n");
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)),
                   std::istreambuf_iterator<char>());
  EXPECT_EQ(text, "{\"a\": 1}\n");
  EXPECT_EQ(folderEntries(dir.path()), std::vector<std::string>{"report.json"});
  // A folder in the way: kIo naming the path, and no temporary left behind.
  fs::create_directories(dir.path() / "taken.json" / "inside");
  EXPECT_THROW(writeTextFile(dir.file("taken.json"), "x"), Error);
  EXPECT_EQ(folderEntries(dir.path()),
            (std::vector<std::string>{"report.json", "taken.json"}));
}

TEST(ExportTest, RejectsMismatchedShapes) {
  ScopedTempDir dir;
  const FanMesh fan = makeFan();
  const std::string path = (dir.path() / "fan.obj").string();
  const Matrix3Xf too_few_normals = fan.normals.topRows(2);
  EXPECT_THROW(writeMesh(path, MeshFormat::kObj, fan.positions,
                         &too_few_normals, fan.triangles),
               Error);
  TriangleMatrix out_of_range = fan.triangles;
  out_of_range(2, 1) = 5;
  EXPECT_THROW(
      writeMesh(path, MeshFormat::kObj, fan.positions, nullptr, out_of_range),
      Error);
  EXPECT_TRUE(folderEntries(dir.path()).empty());
}

// Unit cube [0,1]^3, 12 triangles, counter-clockwise seen from outside.
void makeCube(Matrix3Xf& positions, TriangleMatrix& triangles) {
  positions.resize(8, 3);
  for (int v = 0; v < 8; ++v) {
    positions.row(v) << float(v & 1), float((v >> 1) & 1), float((v >> 2) & 1);
  }
  triangles.resize(12, 3);
  triangles << 0, 2, 1, 1, 2, 3,  // z = 0, normal -z
      4, 5, 6, 5, 7, 6,           // z = 1, normal +z
      0, 1, 4, 1, 5, 4,           // y = 0, normal -y
      2, 6, 3, 3, 6, 7,           // y = 1, normal +y
      0, 4, 2, 2, 4, 6,           // x = 0, normal -x
      1, 3, 5, 3, 7, 5;           // x = 1, normal +x
}

TEST(MeshMetricsTest, UnitCubeVolumeIsOneAndScalesWithTheCube) {
  Matrix3Xf positions;
  TriangleMatrix triangles;
  makeCube(positions, triangles);
  EXPECT_NEAR(enclosedVolume(positions, triangles), 1.0, 1e-12);

  const float s = 2.5f;
  const Matrix3Xf scaled = positions * s;
  EXPECT_NEAR(enclosedVolume(scaled, triangles), double(s) * s * s, 1e-9);

  // Closed mesh: independent of where it sits.
  Matrix3Xf moved = positions;
  moved.rowwise() += Eigen::RowVector3f(10.f, -3.f, 7.f);
  EXPECT_NEAR(enclosedVolume(moved, triangles), 1.0, 1e-5);

  // Flipped orientation flips the sign.
  TriangleMatrix flipped = triangles;
  flipped.col(1).swap(flipped.col(2));
  EXPECT_NEAR(enclosedVolume(positions, flipped), -1.0, 1e-12);
}

TEST(MeshMetricsTest, BoundingBoxDiagonal) {
  Matrix3Xf positions;
  TriangleMatrix triangles;
  makeCube(positions, triangles);
  EXPECT_FLOAT_EQ(boundingBoxDiagonal(positions), std::sqrt(3.f));
  EXPECT_FLOAT_EQ(boundingBoxDiagonal(positions * 2.f), 2.f * std::sqrt(3.f));
  EXPECT_EQ(boundingBoxDiagonal(Matrix3Xf(0, 3)), 0.f);
}

TEST(MeshMetricsTest, MaxVertexDistance) {
  Matrix3Xf a;
  TriangleMatrix triangles;
  makeCube(a, triangles);
  Matrix3Xf b = a;
  EXPECT_EQ(maxVertexDistance(a, b), 0.f);
  b(5, 1) += 0.25f;
  b(2, 0) -= 0.5f;
  EXPECT_FLOAT_EQ(maxVertexDistance(a, b), 0.5f);
  b(3, 2) = std::nanf("");
  EXPECT_TRUE(std::isnan(maxVertexDistance(a, b)));

  try {
    maxVertexDistance(a, a.topRows(7));
    FAIL() << "expected isk::Error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
  }
}

}  // namespace
}  // namespace isk
