// isk::countSelfIntersections against CGAL, whose definition it follows
// (self_intersection.hpp), on the mesh welded by vertex group:
//   (a) where the welded mesh, degenerate faces dropped, is a polygon mesh
//       (CGAL::Polygon_mesh_processing::is_polygon_soup_a_polygon_mesh):
//       CGAL::Polygon_mesh_processing::self_intersections on a
//       CGAL::Surface_mesh, the same pairs exactly;
//   (b) always: a per-pair reference written with CGAL's predicates
//       (Exact_predicates_inexact_constructions_kernel: do_intersect of
//       triangles and of a triangle and a segment, coplanar,
//       coplanar_orientation) following do_faces_intersect's rules by the
//       number of shared welded vertices, on the candidate pairs of
//       CGAL::box_self_intersection_d, so non-manifold welded meshes are
//       covered too; and the degenerate faces counted with CGAL::collinear.
// Inputs: the hand-built cases of self_intersection_test.cpp, cylinders
// snapped to a coarse grid (coplanar, touching and degenerate triangles by
// the hundred), the procedural rigs bent 120 to 150 degrees with LBS and
// DQS, and every asset of the data folder at rest, at a mid-clip frame (the
// procedural bend when it has no clip) with LBS and DQS through the CPU
// reference skinning, and with one vertex pushed far along and against its
// normal (a spike). Welded with coincidentVertexGroups of the rest positions.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/box_intersection_d.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "data_folder.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tools/procedural.hpp"
#include "isk/tools/self_intersection.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using test::positionsOf;
using test::trianglesOf;

namespace PMP = CGAL::Polygon_mesh_processing;
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Pairs = std::vector<std::pair<int, int>>;

// The welded soup: one point per welded vertex that a triangle uses, the
// non-degenerate triangles as faces of those points.
struct WeldedSoup {
  std::vector<Point> points;
  std::vector<std::vector<std::size_t>> faces;
  std::vector<int> triangle_of_face;  // index into the input triangles
  int degenerate = 0;                 // triangles with collinear corners
};

WeldedSoup weld(const Matrix3Xf& positions, const TriangleMatrix& triangles,
                const std::vector<int>* groups) {
  WeldedSoup soup;
  std::vector<std::size_t> point_of_vertex(positions.rows(), SIZE_MAX);
  for (int f = 0; f < triangles.rows(); ++f) {
    std::vector<std::size_t> face(3);
    for (int c = 0; c < 3; ++c) {
      const int v = groups ? (*groups)[triangles(f, c)] : triangles(f, c);
      if (point_of_vertex[v] == SIZE_MAX) {
        point_of_vertex[v] = soup.points.size();
        soup.points.emplace_back(positions(v, 0), positions(v, 1),
                                 positions(v, 2));
      }
      face[c] = point_of_vertex[v];
    }
    if (CGAL::collinear(soup.points[face[0]], soup.points[face[1]],
                        soup.points[face[2]])) {
      ++soup.degenerate;
      continue;
    }
    soup.faces.push_back(face);
    soup.triangle_of_face.push_back(f);
  }
  return soup;
}

// (a) CGAL's own count on a Surface_mesh; unset when the welded soup is not
// a polygon mesh.
std::optional<Pairs> surfaceMeshPairs(const WeldedSoup& soup) {
  if (!PMP::is_polygon_soup_a_polygon_mesh(soup.faces)) return std::nullopt;
  using Mesh = CGAL::Surface_mesh<Point>;
  Mesh mesh;
  PMP::polygon_soup_to_polygon_mesh(soup.points, soup.faces, mesh);
  // Faces are added in the soup's order.
  EXPECT_EQ(mesh.number_of_faces(), soup.faces.size());
  std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> found;
  PMP::self_intersections(mesh, std::back_inserter(found));
  Pairs pairs;
  for (const auto& [f, g] : found) {
    const int a = soup.triangle_of_face[static_cast<std::size_t>(f)];
    const int b = soup.triangle_of_face[static_cast<std::size_t>(g)];
    EXPECT_NE(a, b) << "a degenerate face reached CGAL";
    pairs.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

// (b) do_faces_intersect's rules with CGAL's predicates, by the number of
// welded vertices faces f and g share.
bool referenceMeet(const WeldedSoup& soup, std::size_t f, std::size_t g) {
  const std::vector<std::size_t>& a = soup.faces[f];
  const std::vector<std::size_t>& b = soup.faces[g];
  auto pa = [&](int i) { return soup.points[a[(i + 3) % 3]]; };
  auto pb = [&](int i) { return soup.points[b[(i + 3) % 3]]; };
  int shared = 0, ia[3], ib[3];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (a[i] == b[j]) {
        ia[shared] = i;
        ib[shared] = j;
        ++shared;
      }
    }
  }
  const Kernel::Triangle_3 ta(pa(0), pa(1), pa(2)), tb(pb(0), pb(1), pb(2));
  switch (shared) {
    case 0:
      return CGAL::do_intersect(ta, tb);
    case 1:
      return CGAL::do_intersect(
                 ta, Kernel::Segment_3(pb(ib[0] + 1), pb(ib[0] + 2))) ||
             CGAL::do_intersect(
                 tb, Kernel::Segment_3(pa(ia[0] + 1), pa(ia[0] + 2)));
    case 2: {
      const Point& u = pa(ia[0]);
      const Point& v = pa(ia[1]);
      const Point& r = pa(3 - ia[0] - ia[1]);
      const Point& s = pb(3 - ib[0] - ib[1]);
      return CGAL::coplanar(u, v, r, s) &&
             CGAL::coplanar_orientation(u, v, r, s) == CGAL::POSITIVE;
    }
    default:
      return true;
  }
}

Pairs referencePairs(const WeldedSoup& soup) {
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, std::size_t>;
  std::vector<Box> boxes;
  boxes.reserve(soup.faces.size());
  for (std::size_t f = 0; f < soup.faces.size(); ++f) {
    const auto& face = soup.faces[f];
    boxes.emplace_back(soup.points[face[0]].bbox() +
                           soup.points[face[1]].bbox() +
                           soup.points[face[2]].bbox(),
                       f);
  }
  Pairs pairs;
  CGAL::box_self_intersection_d(
      boxes.begin(), boxes.end(), [&](const Box& x, const Box& y) {
        if (!referenceMeet(soup, x.info(), y.info())) return;
        const int a = soup.triangle_of_face[x.info()];
        const int b = soup.triangle_of_face[y.info()];
        pairs.emplace_back(std::min(a, b), std::max(a, b));
      });
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

// "" when equal, else the first pair only one side has.
std::string firstDifference(const Pairs& ours, const Pairs& theirs) {
  Pairs only_ours, only_theirs;
  std::set_difference(ours.begin(), ours.end(), theirs.begin(), theirs.end(),
                      std::back_inserter(only_ours));
  std::set_difference(theirs.begin(), theirs.end(), ours.begin(), ours.end(),
                      std::back_inserter(only_theirs));
  if (only_ours.empty() && only_theirs.empty() && ours.size() == theirs.size())
    return "";
  auto name = [](const Pairs& p) {
    return p.empty()
               ? std::string("none")
               : std::to_string(p[0].first) + "-" + std::to_string(p[0].second);
  };
  return std::to_string(only_ours.size()) + " pairs only ours (first " +
         name(only_ours) + "), " + std::to_string(only_theirs.size()) +
         " only CGAL's (first " + name(only_theirs) + ")";
}

struct Comparison {
  int ours = 0, reference = 0, degenerate = 0;
  std::optional<int> surface_mesh;  // unset: not a polygon mesh
};

// Compares ours with (a) and (b) on one frame; `what` names it.
Comparison compareWithCgal(const Matrix3Xf& positions,
                           const TriangleMatrix& triangles,
                           const std::vector<int>* groups,
                           const std::string& what) {
  Comparison result;
  Pairs ours;
  int degenerate = -1;
  result.ours =
      countSelfIntersections(positions, triangles, groups, &ours, &degenerate);
  EXPECT_EQ(result.ours, static_cast<int>(ours.size())) << what;
  const WeldedSoup soup = weld(positions, triangles, groups);
  EXPECT_EQ(degenerate, soup.degenerate) << what << ": degenerate triangles";
  result.degenerate = soup.degenerate;
  const Pairs reference = referencePairs(soup);
  result.reference = static_cast<int>(reference.size());
  EXPECT_EQ(firstDifference(ours, reference), "")
      << what << ": ours " << ours.size() << ", CGAL predicates "
      << reference.size();
  if (const std::optional<Pairs> mesh = surfaceMeshPairs(soup)) {
    result.surface_mesh = static_cast<int>(mesh->size());
    EXPECT_EQ(firstDifference(ours, *mesh), "")
        << what << ": ours " << ours.size() << ", CGAL Surface_mesh "
        << mesh->size();
  }
  return result;
}

std::string describe(const Comparison& c) {
  return "ours " + std::to_string(c.ours) + ", CGAL predicates " +
         std::to_string(c.reference) + ", CGAL Surface_mesh " +
         (c.surface_mesh ? std::to_string(*c.surface_mesh)
                         : std::string("skipped (not a polygon mesh)")) +
         "; degenerate " + std::to_string(c.degenerate);
}

// The adjacency classes of self_intersection_test.cpp, with CGAL's answer.
TEST(SelfIntersectionCgal, HandBuiltCasesMatchCgal) {
  struct Case {
    std::string name;
    std::vector<Eigen::Vector3f> points;
    std::vector<Eigen::Vector3i> triangles;
    int expected;
  };
  const Eigen::Vector3f o(0, 0, 0), x(2, 0, 0), y(0, 2, 0);
  const float lift = std::nextafter(0.f, 1.f);
  std::vector<Case> cases = {
      {"edge, folded flat",
       {o, x, {1, 2, 0}, {1, 1, 0}},
       {{0, 1, 2}, {1, 0, 3}},
       1},
      {"edge, flat unfolded",
       {o, x, {1, 2, 0}, {1, -2, 0}},
       {{0, 1, 2}, {1, 0, 3}},
       0},
      {"edge, sharp fold",
       {o, x, {1, 2, 0}, {1, 1, lift}},
       {{0, 1, 2}, {1, 0, 3}},
       0},
      {"vertex, pierced",
       {o, x, y, {1, 0.5f, 1}, {1, 0.5f, -1}},
       {{0, 1, 2}, {0, 3, 4}},
       1},
      {"vertex, apart",
       {o, x, y, {1, -1, 1}, {1, -1, -1}},
       {{0, 1, 2}, {0, 3, 4}},
       0},
      {"vertex, coplanar inside",
       {o, x, y, {1, 0.5f, 0}, {0.5f, 1, 0}},
       {{0, 1, 2}, {0, 3, 4}},
       1},
      {"vertex, coplanar long",
       {o, x, y, {4, 2, 0}, {2, 4, 0}},
       {{0, 1, 2}, {0, 3, 4}},
       1},
      {"doubled face", {o, x, y}, {{0, 1, 2}, {0, 2, 1}}, 1},
      {"doubled face, same orientation", {o, x, y}, {{0, 1, 2}, {1, 2, 0}}, 1},
  };
  // The flipped fan: flat, then not flat.
  std::vector<Eigen::Vector3f> fan_points = {
      {0, 0, 0},  {-1, -0.5f, 0}, {1, 2, 0}, {-1, 2, 0},
      {-2, 0, 0}, {-1, -2, 0},    {1, -2, 0}};
  std::vector<Eigen::Vector3i> fan;
  for (int k = 0; k < 6; ++k) fan.emplace_back(0, k + 1, (k + 1) % 6 + 1);
  cases.push_back({"flipped flat fan", fan_points, fan, 5});
  fan_points[2] = {1, 2, 1};
  fan_points[1] = {-2, -1, -1};
  cases.push_back({"flipped fan through a neighbour", fan_points, fan, 1});
  for (const Case& c : cases) {
    const Comparison result = compareWithCgal(
        positionsOf(c.points), trianglesOf(c.triangles), nullptr, c.name);
    EXPECT_EQ(result.ours, c.expected) << c.name;
  }
}

// Cylinders jittered and snapped to a coarse grid: exactly coplanar
// neighbours, vertices on edges, coincident points (welded or not) and
// degenerate triangles are everywhere, the cases an inexact test gets wrong.
TEST(SelfIntersectionCgal, GridSnappedCylindersMatchCgal) {
  int total = 0, degenerate = 0, with_surface_mesh = 0;
  for (int m = 0; m < 24; ++m) {
    CylinderRigOptions options;
    options.rings = 4 + m % 5;
    options.segments = 5 + m % 7;
    options.length = 4.f;
    options.radius = 2.f;
    Mesh mesh = makeCylinderRig(options).mesh;
    std::mt19937 random(500 + m);
    std::uniform_int_distribution<int> step(-1, 1);
    const float grid = m % 2 ? 1.f : 0.5f;
    for (int v = 0; v < mesh.positions.rows(); ++v) {
      for (int k = 0; k < 3; ++k) {
        mesh.positions(v, k) =
            grid * (std::round(mesh.positions(v, k) / grid) +
                    static_cast<float>((m % 3) ? step(random) : 0));
      }
    }
    const std::vector<int> groups = coincidentVertexGroups(mesh.positions);
    for (const std::vector<int>* g :
         {static_cast<const std::vector<int>*>(nullptr), &groups}) {
      const Comparison c =
          compareWithCgal(mesh.positions, mesh.triangles, g,
                          "snapped cylinder " + std::to_string(m) +
                              (g ? " welded" : " unwelded"));
      total += c.ours;
      degenerate += c.degenerate;
      with_surface_mesh += c.surface_mesh ? 1 : 0;
    }
  }
  std::cout << "[ snapped cylinders ] " << total << " pairs, " << degenerate
            << " degenerate triangles; " << with_surface_mesh
            << " of 48 meshes also through CGAL's Surface_mesh\n";
  EXPECT_GT(total, 100);
  EXPECT_GT(degenerate, 10);
}

// The pose at the end of a bend of every joint by `degrees`.
TransformList bentPose(const Rig& rig, double degrees) {
  const AnimationClip bend = makeBendClip(
      rig.skeleton, static_cast<float>(degrees * 3.14159265358979 / 180), 1.0);
  return skinningTransforms(
      rig.skeleton,
      globalTransforms(rig.skeleton, bend.sampleLocal(rig.skeleton, 1.0)));
}

Matrix3Xf skinned(const Rig& rig, SkinningMethod method,
                  const TransformList& pose) {
  CpuSkinning skinning(rig.mesh, rig.weights, rig.skeleton.jointCount());
  skinning.run(method, pose, false);
  return skinning.positions();
}

TEST(SelfIntersectionCgal, BentProceduralRigsMatchCgal) {
  CylinderRigOptions small;
  small.rings = 24;
  small.segments = 16;
  std::vector<std::pair<std::string, Rig>> rigs = {
      {"cylinder 24x16", makeCylinderRig(small)}};
  for (const std::string& name : builtinRigNames())
    rigs.emplace_back(name, makeBuiltinRig(name));
  for (const auto& [name, rig] : rigs) {
    const std::vector<int> groups = coincidentVertexGroups(rig.mesh.positions);
    int folded = 0;
    for (double degrees : {120.0, 135.0, 150.0}) {
      const TransformList pose = bentPose(rig, degrees);
      for (SkinningMethod method :
           {SkinningMethod::kLinearBlend, SkinningMethod::kDualQuaternion}) {
        const std::string what =
            name + " bent " + std::to_string(static_cast<int>(degrees)) +
            (method == SkinningMethod::kLinearBlend ? " LBS" : " DQS");
        const Comparison c = compareWithCgal(skinned(rig, method, pose),
                                             rig.mesh.triangles, &groups, what);
        std::cout << "[ " << what << " ] " << describe(c) << "\n";
        EXPECT_TRUE(c.surface_mesh.has_value()) << what;
        folded += c.ours;
      }
    }
    EXPECT_GT(folded, 0) << name << " never folds";
  }
}

// Every rigged model in the data folder, by name.
std::vector<std::string> dataFolderAssets() {
  std::vector<std::string> names;
  for (const auto& entry :
       std::filesystem::directory_iterator(samples::dataFolder())) {
    const std::string ext = entry.path().extension().string();
    if (ext == ".glb" || ext == ".gltf" || ext == ".dae" || ext == ".x" ||
        ext == ".fbx")
      names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

// Rest positions with the welded vertex of triangle #F/2's first corner
// moved by `distance` along its normal (the vertex normal, else the
// triangle's).
Matrix3Xf spiked(const Mesh& mesh, const std::vector<int>& groups,
                 float distance) {
  Matrix3Xf positions = mesh.positions;
  const int f = mesh.triangleCount() / 2;
  const int v = groups[mesh.triangles(f, 0)];
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();
  if (mesh.normals.rows() == mesh.positions.rows())
    normal = mesh.normals.row(v).transpose();
  if (!normal.allFinite() || normal.norm() < 0.5f) {
    const Eigen::Vector3f a = mesh.positions.row(mesh.triangles(f, 0));
    const Eigen::Vector3f b = mesh.positions.row(mesh.triangles(f, 1));
    const Eigen::Vector3f c = mesh.positions.row(mesh.triangles(f, 2));
    normal = (b - a).cross(c - a).normalized();
  }
  for (int u = 0; u < mesh.vertexCount(); ++u) {
    if (groups[u] == v)
      positions.row(u) += distance * normal.normalized().transpose();
  }
  return positions;
}

TEST(SelfIntersectionCgal, EverySharedAssetMatchesCgal) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage(
        "the CGAL self-intersection comparisons on the assets");
  const std::vector<std::string> assets = dataFolderAssets();
  EXPECT_FALSE(assets.empty());
  for (const std::string& file : assets) {
    SCOPED_TRACE(file);
    const auto start = std::chrono::steady_clock::now();
    const Rig& rig = test::loadAsset(file);
    const Mesh& mesh = rig.mesh;
    const std::vector<int> groups = coincidentVertexGroups(mesh.positions);
    const bool has_clip = !rig.clips.empty();
    const AnimationClip clip =
        has_clip ? rig.clips.front() : makeBendClip(rig.skeleton, 1.5f);
    const double t = clip.start + 0.5 * clip.duration;
    const TransformList pose = skinningTransforms(
        rig.skeleton,
        globalTransforms(rig.skeleton, clip.sampleLocal(rig.skeleton, t)));
    const float diagonal = rig.boundingBoxDiagonal();
    const std::string frame = has_clip ? "mid-clip" : "mid-bend";
    const std::vector<std::pair<std::string, Matrix3Xf>> frames = {
        {"rest", mesh.positions},
        {frame + " LBS", skinned(rig, SkinningMethod::kLinearBlend, pose)},
        {frame + " DQS", skinned(rig, SkinningMethod::kDualQuaternion, pose)},
        {"spike out", spiked(mesh, groups, 0.5f * diagonal)},
        {"spike in", spiked(mesh, groups, -0.5f * diagonal)}};
    Pairs rest_pairs;
    countSelfIntersections(mesh.positions, mesh.triangles, &groups,
                           &rest_pairs);
    size_t spike_new = 0;
    for (const auto& [name, positions] : frames) {
      const std::string what = file + " " + name;
      const Comparison c =
          compareWithCgal(positions, mesh.triangles, &groups, what);
      Pairs pairs;
      countSelfIntersections(positions, mesh.triangles, &groups, &pairs);
      const size_t fresh = newSelfIntersections(pairs, rest_pairs).size();
      if (name.rfind("spike", 0) == 0) spike_new += fresh;
      std::cout << "[ " << what << " ] " << describe(c) << "; new against rest "
                << fresh << "\n";
      RecordProperty(what, describe(c));
      if (!c.surface_mesh) {
        // Said, not silent: (b) still compared every pair.
        std::cout << "[ " << what
                  << " ] CGAL Surface_mesh comparison skipped: the welded "
                     "mesh is not a polygon mesh\n";
      }
    }
    // A spike through a closed skin crosses something (or folds over).
    if (mesh.triangleCount() > 100) {
      EXPECT_GT(spike_new, 0u) << "neither spike is counted";
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
            .count();
    std::cout << "[ " << file << " ] " << mesh.vertexCount() << " vertices, "
              << mesh.triangleCount() << " triangles: " << seconds << " s\n";
  }
}

}  // namespace
}  // namespace isk
