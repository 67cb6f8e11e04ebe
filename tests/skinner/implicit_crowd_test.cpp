// isk::ImplicitCrowd (isk/implicit_crowd.hpp): several instances of one
// character, or of several characters of different sizes, skinned by the
// same launches. Instances apart from each other come out as an
// ImplicitSkinner gives each alone, on procedural rigs (with union, blend
// and bulge joints) and on the assets; overlapping instances stop at each
// other; bad input is a clear error.
#include "isk/implicit_crowd.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "isk/cl/field_evaluation.hpp"
#include "isk/core/error.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

std::shared_ptr<const ImplicitFields> sharedFields(const std::string& name) {
  return std::shared_ptr<const ImplicitFields>(&test::implicitFieldsOf(name),
                                               [](const ImplicitFields*) {});
}

// What an instance alone is compared with: its own ImplicitSkinner
// computing in the scene's coordinates, as the crowd does (anchor_pose off;
// the lone skinner's default computes about the pose's anchor, which the
// crowd's shared scene cannot).
ImplicitSkinnerOptions inSceneCoordinates(ImplicitSkinnerOptions options) {
  options.anchor_pose = false;
  return options;
}

// `pose` moved by `offset` (model units) in the scene.
TransformList placed(const TransformList& pose, const Eigen::Vector3f& offset) {
  TransformList out = pose;
  for (Eigen::Affine3f& t : out) t.pretranslate(offset);
  return out;
}

// Rows [first, first + count) of m.
Matrix3Xf rowsOf(const Matrix3Xf& m, int first, int count) {
  return m.middleRows(first, count);
}

// `instances` instances of rig, each at its own pose of the clip and
// `spacing` diagonals apart along x, skinned by one crowd and each by its
// own ImplicitSkinner on the same device: the same positions and normals,
// vertex by vertex (the same kernels on the same data; 1e-6 of the diagonal
// allows a device that vectorizes the two launches differently).
void checkInstancesApart(const Rig& rig,
                         std::shared_ptr<const ImplicitFields> fields,
                         int instances,
                         const ImplicitSkinnerOptions& options = {}) {
  const auto context = test::sharedContext();
  const float diagonal = rig.boundingBoxDiagonal();
  const std::vector<TransformList> clip = test::clipPoses(rig, instances + 1);
  std::vector<TransformList> poses;
  for (int i = 0; i < instances; ++i)
    poses.push_back(
        placed(clip[i + 1], Eigen::Vector3f(3.f * diagonal * i, 0.f, 0.f)));
  ImplicitCrowd crowd(context, rig, fields, instances, options);
  EXPECT_EQ(crowd.instanceCount(), instances);
  EXPECT_EQ(crowd.vertexCount(), rig.mesh.vertexCount());
  crowd.run(poses);
  Matrix3Xf positions, normals;
  crowd.readPositions(positions);
  crowd.readNormals(normals);
  const int v = rig.mesh.vertexCount();
  ASSERT_EQ(positions.rows(), static_cast<Eigen::Index>(v) * instances);
  ASSERT_EQ(normals.rows(), positions.rows());
  ImplicitSkinner alone(context, rig, fields, inSceneCoordinates(options));
  // The grids are stored once for every instance.
  EXPECT_EQ(crowd.fieldEvaluation().fieldCount(),
            instances * fields->grids.fieldCount());
  EXPECT_EQ(crowd.fieldEvaluation().gridCount(), fields->grids.fieldCount());
  EXPECT_EQ(crowd.fieldEvaluation().fieldBytes(),
            alone.fieldEvaluation().fieldBytes());
  int contacts = 0;
  for (int i = 0; i < instances; ++i) {
    SCOPED_TRACE("instance " + std::to_string(i));
    alone.run(poses[i]);
    Matrix3Xf own_positions, own_normals;
    alone.readPositions(own_positions);
    alone.readNormals(own_normals);
    contacts += alone.contactCount();
    const test::RowMismatch p =
        test::largestRowDistance(rowsOf(positions, i * v, v), own_positions);
    EXPECT_LE(p.distance, 1e-6f * diagonal)
        << "first largest position mismatch at vertex " << p.row;
    const test::RowMismatch n =
        test::largestRowDistance(rowsOf(normals, i * v, v), own_normals);
    EXPECT_LE(n.distance, 1e-5f)
        << "largest normal mismatch at vertex " << n.row;
  }
  EXPECT_EQ(crowd.contactCount(), contacts);
  EXPECT_TRUE(positions.allFinite() && normals.allFinite());
}

TEST(ImplicitCrowd, InstancesApartMatchTheirOwnSkinnerOnProceduralRigs) {
  for (const std::string& name : builtinRigNames()) {
    SCOPED_TRACE(name);
    checkInstancesApart(test::rigNamed(name), sharedFields(name), 3);
  }
}

TEST(ImplicitCrowd, InstancesApartMatchTheirOwnSkinnerWithBlendAndBulge) {
  // Blend and bulge pairs: the crowd's pairs, tables and controllers are
  // the instance's, shifted to its fields and joints.
  for (const CompositionOperator op :
       {CompositionOperator::kBlend, CompositionOperator::kBulge}) {
    SCOPED_TRACE(op == CompositionOperator::kBlend ? "blend" : "bulge");
    const Rig& arm = test::rigNamed("arm");
    ImplicitSkinnerOptions options;
    options.fields.composition.default_operator = op;
    const auto fields = std::make_shared<const ImplicitFields>(
        buildImplicitFields(arm, options.fields));
    ASSERT_FALSE(fields->composition.blended_pairs.empty());
    checkInstancesApart(arm, fields, 2, options);
  }
}

TEST(ImplicitCrowd, InstancesApartMatchTheirOwnSkinnerForEveryStorage) {
  // Images (GPUs) and buffers, float and half grids: each reads the shared
  // grid of its field.
  const Rig& arm = test::rigNamed("arm");
  auto half = std::make_shared<ImplicitFields>(test::implicitFieldsOf("arm"));
  useHalfPrecisionGrids(*half, arm);
  for (const FieldStorage storage :
       {FieldStorage::kImage, FieldStorage::kBuffer})
    for (const bool halves : {false, true}) {
      SCOPED_TRACE(std::string(fieldStorageName(storage)) +
                   (halves ? ", half grids" : ", float grids"));
      ImplicitSkinnerOptions options;
      options.storage = storage;
      checkInstancesApart(arm, halves ? half : sharedFields("arm"), 3, options);
    }
}

TEST(ImplicitCrowd, FieldEvaluationOfInstancesMatchesEachAlone) {
  // The host path of ClFieldEvaluation with instances: instance k's fields
  // at points give what one instance's evaluation gives with its pose.
  const Rig& arm = test::rigNamed("arm");
  const ImplicitFields& fields = test::implicitFieldsOf("arm");
  const auto context = test::sharedContext();
  const int joints = arm.skeleton.jointCount();
  const std::vector<TransformList> clip = test::clipPoses(arm, 3);
  const Eigen::Vector3f offset(10.f, 0.f, 0.f);
  const TransformList second = placed(clip[2], offset);
  TransformList both = clip[1];
  both.insert(both.end(), second.begin(), second.end());
  ClFieldEvaluation crowd(context, fields.grids, joints, FieldStorage::kAuto,
                          &fields.composition, 2);
  ClFieldEvaluation one(context, fields.grids, joints, FieldStorage::kAuto,
                        &fields.composition);
  EXPECT_EQ(crowd.jointCount(), 2 * joints);
  EXPECT_EQ(crowd.pairCount(), 2 * one.pairCount());
  Matrix3Xf points = arm.mesh.positions;
  points.rowwise() += offset.transpose();
  Matrix4Xf composed, per_field, own_composed, own_per_field;
  crowd.evaluate(both, points, composed, &per_field);
  one.evaluate(second, points, own_composed, &own_per_field);
  const int f = fields.grids.fieldCount();
  ASSERT_EQ(per_field.rows(), static_cast<Eigen::Index>(points.rows()) * 2 * f);
  for (Eigen::Index p = 0; p < points.rows(); ++p) {
    ASSERT_EQ(composed.row(p), own_composed.row(p)) << "point " << p;
    for (int i = 0; i < f; ++i) {
      ASSERT_EQ(per_field.row(p * 2 * f + f + i), own_per_field.row(p * f + i))
          << "point " << p << ", field " << i;
      ASSERT_EQ(per_field(p * 2 * f + i, 0), 0.f)  // instance 0 is far
          << "point " << p << ", field " << i;
    }
  }
  EXPECT_GT(composed.col(0).maxCoeff(), 0.5f);
  EXPECT_THROW(ClFieldEvaluation(context, fields.grids, joints,
                                 FieldStorage::kAuto, nullptr, 0),
               Error);
}

TEST(ImplicitCrowd, InstancesApartMatchTheirOwnSkinnerOnAssets) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("crowds of the assets");
  for (const std::string& name : test::assetNames()) {
    SCOPED_TRACE(name);
    checkInstancesApart(test::rigNamed(name), sharedFields(name), 2);
  }
}

TEST(ImplicitCrowd, ReplicatedTrackingMeshShiftsEveryIndex) {
  const Rig& arm = test::rigNamed("arm");
  const TrackingMesh one =
      TrackingMesh::build(arm.mesh, test::implicitFieldsOf("arm"));
  const int joints = arm.skeleton.jointCount();
  const TrackingMesh two = replicateTrackingMesh(one, 2, joints);
  const int v = one.vertexCount();
  ASSERT_EQ(two.vertexCount(), 2 * v);
  EXPECT_EQ(two.field_count, 2 * one.field_count);
  EXPECT_EQ(two.diagonal, one.diagonal);
  EXPECT_EQ(two.trackedCount(), 2 * one.trackedCount());
  ASSERT_EQ(two.march_order.size(), 2 * one.march_order.size());
  for (size_t k = 0; k < one.march_order.size(); ++k)
    ASSERT_EQ(two.march_order[one.march_order.size() + k],
              one.march_order[k] + v)
        << "march slot " << k;
  for (int u = 0; u < v; ++u) {
    ASSERT_EQ(two.rings.representative[v + u], one.rings.representative[u] + v)
        << "vertex " << u;
    ASSERT_EQ(two.home_field[v + u],
              one.home_field[u] < 0 ? -1 : one.home_field[u] + one.field_count)
        << "vertex " << u;
    const uint32_t a = one.rings.offsets[u], b = one.rings.offsets[u + 1];
    ASSERT_EQ(two.rings.offsets[v + u + 1] - two.rings.offsets[v + u], b - a);
    for (uint32_t k = a; k < b; ++k)
      ASSERT_EQ(two.rings.neighbours[two.rings.offsets[v + u] + (k - a)],
                one.rings.neighbours[k] + v)
          << "vertex " << u;
  }
  for (int t = 0; t < one.triangles.rows(); ++t)
    ASSERT_TRUE((two.triangles.row(one.triangles.rows() + t).array() ==
                 one.triangles.row(t).array() + v)
                    .all())
        << "triangle " << t;
  for (size_t k = 0; k < one.partner_pairs.size(); ++k) {
    const auto& a = one.partner_pairs[k];
    const auto& b = two.partner_pairs[one.partner_pairs.size() + k];
    EXPECT_EQ(b.field_a, a.field_a + one.field_count);
    EXPECT_EQ(b.joint_b, a.joint_b + joints);
  }
  EXPECT_THROW(replicateTrackingMesh(one, 0, joints), Error);
}

// The volume restoration's near flags (VolumeGroups::near_other: the
// sleeved arm's skin and sleeve are near each other) follow each copy.
TEST(ImplicitCrowd, ReplicatedTrackingMeshKeepsEachCopysNearFlags) {
  const Rig& arm = test::rigNamed("sleeved-arm");
  const TrackingMesh one =
      TrackingMesh::build(arm.mesh, test::implicitFieldsOf("sleeved-arm"));
  const TrackingMesh two =
      replicateTrackingMesh(one, 2, arm.skeleton.jointCount());
  const int v = one.vertexCount();
  const std::vector<uint8_t>& a = one.volume_groups.near_other;
  const std::vector<uint8_t>& b = two.volume_groups.near_other;
  ASSERT_EQ(static_cast<int>(a.size()), v);
  ASSERT_EQ(static_cast<int>(b.size()), 2 * v);
  EXPECT_GT(std::count(a.begin(), a.end(), uint8_t{1}), 0);
  for (int u = 0; u < v; ++u) {
    ASSERT_EQ(b[u], a[u]) << "vertex " << u;
    ASSERT_EQ(b[v + u], a[u]) << "vertex " << u;
  }
}

TEST(ImplicitCrowd, OverlappingInstancesStopAtEachOther) {
  // Two cylinders side by side, their surfaces overlapping by half a
  // radius: skinned alone, each passes through the other; in one crowd the
  // vertices of each that enter the other stop at a contact.
  const Rig& cylinder = test::rigNamed("cylinder");
  const auto fields = sharedFields("cylinder");
  const TransformList identity(cylinder.skeleton.jointCount(),
                               Eigen::Affine3f::Identity());
  const std::vector<TransformList> poses = {
      identity, placed(identity, Eigen::Vector3f(0.f, 1.5f, 0.f))};
  ImplicitCrowd crowd(test::sharedContext(), cylinder, fields, 2);
  crowd.run(poses);
  ImplicitSkinner alone(test::sharedContext(), cylinder, fields);
  int alone_contacts = 0;
  for (const TransformList& pose : poses) {
    alone.run(pose);
    alone_contacts += alone.contactCount();
  }
  EXPECT_GT(crowd.contactCount(), alone_contacts + 100);
  Matrix3Xf positions;
  crowd.readPositions(positions);
  ASSERT_TRUE(positions.allFinite());
  // Instance 1's vertices no longer reach as deep into instance 0: its
  // lowest vertex (y, the axis they are apart on), 0.5 below instance 0's
  // top (y = 1) when alone, stops near the surface where the two fields
  // are equal (y = 0.75).
  const int v = cylinder.mesh.vertexCount();
  const float lowest = rowsOf(positions, v, v).col(1).minCoeff();
  alone.run(poses[1]);
  Matrix3Xf own;
  alone.readPositions(own);
  EXPECT_LT(own.col(1).minCoeff(), 0.6f);
  EXPECT_GT(lowest, 0.65f);
  // And instance 0's highest, symmetrically, stops below its own top. Not
  // counting the end rims (rest x within 0.5 of either end): the fields
  // round them off, so instance 1's field stays below its surface value
  // there and the contact bulge pushes them out like any skin beside a
  // contact.
  float highest = -std::numeric_limits<float>::infinity();
  for (int i = 0; i < v; ++i) {
    const float x = cylinder.mesh.positions(i, 0);
    if (x > 0.5f && x < 7.5f) highest = std::max(highest, positions(i, 1));
  }
  EXPECT_LT(highest, 0.85f);
}

// --- Several characters -----------------------------------------------------

// A cylinder a quarter of the built-in one's size (radius 0.25, length 2,
// 3 bones), with its fields: a character whose tracking lengths are a
// quarter of the others'.
using SmallCylinder = test::RigWithFields;
const SmallCylinder& smallCylinder() {
  static const SmallCylinder small = [] {
    CylinderRigOptions options;
    options.bones = 3;
    options.radius = 0.25f;
    options.length = 2.f;
    return test::withDefaultFields(makeCylinderRig(options));
  }();
  return small;
}

// `rig`'s fields with every joint composed by `op`.
std::shared_ptr<const ImplicitFields> fieldsWith(const Rig& rig,
                                                 CompositionOperator op) {
  ImplicitFieldsOptions options;
  options.composition.default_operator = op;
  return std::make_shared<const ImplicitFields>(
      buildImplicitFields(rig, options));
}

// The characters' instances, each at its own pose of its clip and apart
// from every other (3 of the largest diagonals along x), skinned by one
// crowd and each by its own ImplicitSkinner: the same positions and
// normals, vertex by vertex.
void checkCharactersApart(const std::vector<CrowdCharacter>& characters,
                          const ImplicitSkinnerOptions& options = {}) {
  const auto context = test::sharedContext();
  float spacing = 0;
  for (const CrowdCharacter& c : characters)
    spacing = std::max(spacing, 3.f * c.rig->boundingBoxDiagonal());
  std::vector<TransformList> poses;
  std::vector<int> character_of;
  for (size_t c = 0; c < characters.size(); ++c) {
    const std::vector<TransformList> clip =
        test::clipPoses(*characters[c].rig, characters[c].instances + 1);
    for (int i = 0; i < characters[c].instances; ++i) {
      const float x = spacing * static_cast<float>(poses.size());
      poses.push_back(placed(clip[i + 1], Eigen::Vector3f(x, 0.f, 0.f)));
      character_of.push_back(static_cast<int>(c));
    }
  }
  ImplicitCrowd crowd(context, characters, options);
  ASSERT_EQ(crowd.characterCount(), static_cast<int>(characters.size()));
  ASSERT_EQ(crowd.instanceCount(), static_cast<int>(poses.size()));
  crowd.run(poses);
  Matrix3Xf positions, normals;
  crowd.readPositions(positions);
  crowd.readNormals(normals);
  ASSERT_EQ(positions.rows(), crowd.totalVertexCount());
  ASSERT_EQ(normals.rows(), positions.rows());
  // Each character's grids once.
  int grids = 0, fields = 0;
  for (const CrowdCharacter& c : characters) {
    grids += c.fields->grids.fieldCount();
    fields += c.instances * c.fields->grids.fieldCount();
  }
  EXPECT_EQ(crowd.fieldEvaluation().gridCount(), grids);
  EXPECT_EQ(crowd.fieldEvaluation().fieldCount(), fields);
  int row = 0, joint = 0, contacts = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    const int c = character_of[i];
    const Rig& rig = *characters[c].rig;
    SCOPED_TRACE("instance " + std::to_string(i) + " (character " +
                 std::to_string(c) + ", " + rig.source + ")");
    const int v = rig.mesh.vertexCount();
    ASSERT_EQ(crowd.characterOf(static_cast<int>(i)), c);
    ASSERT_EQ(crowd.instanceFirstVertex(static_cast<int>(i)), row);
    ASSERT_EQ(crowd.instanceFirstJoint(static_cast<int>(i)), joint);
    ASSERT_EQ(crowd.vertexCount(c), v);
    ASSERT_EQ(crowd.jointCount(c), rig.skeleton.jointCount());
    ImplicitSkinner alone(context, rig, characters[c].fields,
                          inSceneCoordinates(options));
    alone.run(poses[i]);
    Matrix3Xf own_positions, own_normals;
    alone.readPositions(own_positions);
    alone.readNormals(own_normals);
    contacts += alone.contactCount();
    const float diagonal = rig.boundingBoxDiagonal();
    const test::RowMismatch p =
        test::largestRowDistance(rowsOf(positions, row, v), own_positions);
    EXPECT_LE(p.distance, 1e-6f * diagonal)
        << "first largest position mismatch at vertex " << p.row;
    const test::RowMismatch n =
        test::largestRowDistance(rowsOf(normals, row, v), own_normals);
    EXPECT_LE(n.distance, 1e-5f)
        << "largest normal mismatch at vertex " << n.row;
    row += v;
    joint += rig.skeleton.jointCount();
  }
  EXPECT_EQ(crowd.contactCount(), contacts);
  EXPECT_TRUE(positions.allFinite() && normals.allFinite());
}

TEST(ImplicitCrowd, CharactersOfDifferentSizesApartMatchTheirOwnSkinners) {
  // The built-in rigs and a cylinder a quarter of their size, with union,
  // blend and bulge joints: each character's grids, pairs, operator tables
  // and controllers shifted to its instances, each vertex tracked with its
  // own character's lengths.
  const SmallCylinder& small = smallCylinder();
  const Rig& arm = test::rigNamed("arm");
  const Rig& finger = test::rigNamed("finger");
  const Rig& cylinder = test::rigNamed("cylinder");
  const auto arm_blend = fieldsWith(arm, CompositionOperator::kBlend);
  const auto finger_bulge = fieldsWith(finger, CompositionOperator::kBulge);
  ASSERT_FALSE(arm_blend->composition.tables.empty());
  ASSERT_FALSE(finger_bulge->composition.tables.empty());
  const auto small_blend = fieldsWith(small.rig, CompositionOperator::kBlend);
  ASSERT_EQ(small_blend->composition.tables, arm_blend->composition.tables);
  for (const FieldStorage storage :
       {FieldStorage::kImage, FieldStorage::kBuffer}) {
    SCOPED_TRACE(fieldStorageName(storage));
    ImplicitSkinnerOptions options;
    options.storage = storage;
    // The small cylinder's blend pairs use the arm's blend table, stored
    // once.
    checkCharactersApart({{&arm, sharedFields("arm"), 2},
                          {&small.rig, small.fields, 3},
                          {&finger, finger_bulge, 1},
                          {&arm, arm_blend, 2},
                          {&cylinder, sharedFields("cylinder"), 1},
                          {&small.rig, small_blend, 2}},
                         options);
  }
  // One small character among large ones, and the other way round.
  checkCharactersApart({{&small.rig, small.fields, 1}, {&arm, arm_blend, 3}});
}

TEST(ImplicitCrowd, CharactersOfDifferentSizesApartMatchOnAssets) {
  if (!test::haveAssets())
    GTEST_SKIP() << test::missingAssetsMessage("crowds of several assets");
  std::vector<CrowdCharacter> characters;
  // The dense humans part from their own skinners when placed far out in
  // this crowd (human-female 11th, 30 of the largest diagonals from the
  // origin: 2e-2 of its diagonal, a flipped normal; human-addon does the
  // same 8th, and matches 4th): float rounding of coordinates far out,
  // amplified at contacts, and the crowd computes in the scene's
  // coordinates (docs/architecture.md, "Placement").
  for (const std::string& name : test::assetNamesExcept(
           {{"human-female.glb",
             "placed 11th in the crowd of every asset, it parts from its own "
             "skinner (float rounding far out, amplified at contacts)"}}))
    characters.push_back({&test::rigNamed(name), sharedFields(name), 1});
  characters.push_back({&smallCylinder().rig, smallCylinder().fields, 2});
  checkCharactersApart(characters);
}

TEST(ImplicitCrowd, ConcatenatedTrackingMeshKeepsEachCharactersLengths) {
  const Rig& arm = test::rigNamed("arm");
  const SmallCylinder& small = smallCylinder();
  const TrackingMesh a =
      TrackingMesh::build(arm.mesh, test::implicitFieldsOf("arm"));
  const TrackingMesh b = TrackingMesh::build(small.rig.mesh, *small.fields);
  ASSERT_GT(a.diagonal, 3.f * b.diagonal);
  const int arm_joints = arm.skeleton.jointCount();
  const TrackingMesh mixed =
      concatenateTrackingMeshes({{&a, 1, arm_joints}, {&b, 2, 4}});
  const int va = a.vertexCount(), vb = b.vertexCount();
  ASSERT_EQ(mixed.vertexCount(), va + 2 * vb);
  EXPECT_EQ(mixed.field_count, a.field_count + 2 * b.field_count);
  ASSERT_EQ(mixed.vertex_diagonals.size(), static_cast<size_t>(va + 2 * vb));
  for (int v = 0; v < mixed.vertexCount(); ++v)
    ASSERT_EQ(mixed.diagonalOf(v), v < va ? a.diagonal : b.diagonal)
        << "vertex " << v;
  const TrackingLengths lengths = trackingLengths(mixed, {});
  const TrackingLengths own = trackingLengths(b, {});
  EXPECT_EQ(lengths.smoothing_radius[va + vb + 3], own.smoothing_radius[3]);
  EXPECT_EQ(lengths.max_step[va + 5], own.max_step[5]);
  EXPECT_EQ(lengths.min_gradient[va + 7], own.min_gradient[7]);
  // The second copy of b: indices past a and the first copy.
  const int shift = va + vb;
  for (int u = 0; u < vb; ++u) {
    ASSERT_EQ(mixed.rings.representative[shift + u],
              b.rings.representative[u] + shift)
        << "vertex " << u;
    ASSERT_EQ(mixed.home_field[shift + u],
              b.home_field[u] < 0
                  ? -1
                  : b.home_field[u] + a.field_count + b.field_count)
        << "vertex " << u;
  }
  for (int t = 0; t < b.triangles.rows(); ++t)
    ASSERT_TRUE(
        (mixed.triangles.row(a.triangles.rows() + b.triangles.rows() + t)
             .array() == b.triangles.row(t).array() + shift)
            .all())
        << "triangle " << t;
  for (size_t k = 0; k < b.partner_pairs.size(); ++k) {
    const auto& p = b.partner_pairs[k];
    const auto& q =
        mixed
            .partner_pairs[a.partner_pairs.size() + b.partner_pairs.size() + k];
    EXPECT_EQ(q.field_b, p.field_b + a.field_count + b.field_count);
    EXPECT_EQ(q.joint_a, p.joint_a + arm_joints + 4);
  }
  // Parts of one size keep one diagonal, as replicateTrackingMesh does.
  EXPECT_TRUE(concatenateTrackingMeshes({{&a, 2, arm_joints}, {&a, 1, 3}})
                  .vertex_diagonals.empty());
  EXPECT_THROW(concatenateTrackingMeshes({}), Error);
  TrackingMesh wrong = a;
  wrong.vertex_diagonals.assign(3, 1.f);
  EXPECT_THROW(concatenateTrackingMeshes({{&wrong, 1, 3}}), Error);
  EXPECT_THROW(concatenateTrackingMeshes({{&a, 1, 3}, {nullptr, 1, 3}}), Error);
}

TEST(ImplicitCrowd, FieldGroupsEvaluateAsEachCharacterAlone) {
  // The host path of ClFieldEvaluation with several groups: group 1's
  // second instance gives at its points what its own evaluation gives.
  const Rig& arm = test::rigNamed("arm");
  const SmallCylinder& small = smallCylinder();
  const auto arm_blend = fieldsWith(arm, CompositionOperator::kBlend);
  const auto small_bulge = fieldsWith(small.rig, CompositionOperator::kBulge);
  const auto context = test::sharedContext();
  const int ja = arm.skeleton.jointCount(),
            jb = small.rig.skeleton.jointCount();
  ClFieldEvaluation groups(
      context,
      {{&arm_blend->grids, ja, &arm_blend->composition, 1},
       {&small_bulge->grids, jb, &small_bulge->composition, 2}},
      FieldStorage::kAuto);
  ClFieldEvaluation alone(context, small_bulge->grids, jb, FieldStorage::kAuto,
                          &small_bulge->composition);
  EXPECT_EQ(groups.gridCount(),
            arm_blend->grids.fieldCount() + small_bulge->grids.fieldCount());
  EXPECT_EQ(groups.pairCount(),
            2 * alone.pairCount() +
                static_cast<int>(arm_blend->composition.blended_pairs.size()));
  EXPECT_EQ(groups.tableCount(),
            static_cast<int>(arm_blend->composition.tables.size() +
                             small_bulge->composition.tables.size()));
  // Characters with the same operator share its table.
  const auto small_blend = fieldsWith(small.rig, CompositionOperator::kBlend);
  ClFieldEvaluation shared(
      context,
      {{&arm_blend->grids, ja, &arm_blend->composition, 1},
       {&small_blend->grids, jb, &small_blend->composition, 2}},
      FieldStorage::kAuto);
  EXPECT_EQ(shared.tableCount(),
            static_cast<int>(arm_blend->composition.tables.size()));
  EXPECT_EQ(shared.operatorBytes(), alone.operatorBytes());
  const Eigen::Vector3f offset(50.f, 0.f, 0.f);
  const TransformList pose = placed(test::clipPoses(small.rig, 3)[2], offset);
  TransformList all = test::clipPoses(arm, 2)[1];
  const TransformList far = placed(pose, Eigen::Vector3f(20.f, 0.f, 0.f));
  all.insert(all.end(), far.begin(), far.end());
  all.insert(all.end(), pose.begin(), pose.end());
  Matrix3Xf points = small.rig.mesh.positions;
  points.rowwise() += offset.transpose();
  Matrix4Xf composed, own;
  groups.evaluate(all, points, composed);
  alone.evaluate(pose, points, own);
  for (Eigen::Index p = 0; p < points.rows(); ++p)
    ASSERT_EQ(composed.row(p), own.row(p)) << "point " << p;
  EXPECT_GT(composed.col(0).maxCoeff(), 0.5f);
  // One grid resolution for every group.
  ImplicitFieldsOptions coarse;
  coarse.grid_resolution = 16;
  const ImplicitFields small16 = buildImplicitFields(small.rig, coarse);
  try {
    ClFieldEvaluation(
        context,
        {{&arm_blend->grids, ja, nullptr, 1}, {&small16.grids, jb, nullptr, 1}},
        FieldStorage::kAuto);
    ADD_FAILURE() << "no isk::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("character 1: its grids have 16"),
              std::string::npos)
        << e.what();
  }
}

TEST(ImplicitCrowd, BadInputIsAClearError) {
  const Rig& arm = test::rigNamed("arm");
  const auto context = test::sharedContext();
  const auto fields = sharedFields("arm");
  auto message = [](const auto& call) -> std::string {
    try {
      call();
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
      return e.what();
    }
    ADD_FAILURE() << "no isk::Error";
    return "";
  };
  EXPECT_NE(message([&] {
              ImplicitCrowd(context, arm, fields, 0);
            }).find("0 instances"),
            std::string::npos);
  EXPECT_NE(
      message([&] { ImplicitCrowd(context, arm, 0); }).find("0 instances"),
      std::string::npos);
  EXPECT_NE(message([&] {
              ImplicitCrowd(context, test::rigNamed("finger"), fields, 2);
            }).find("built for another rig"),
            std::string::npos);
  const int field_count = fields->grids.fieldCount();
  EXPECT_NE(message([&] {
              ImplicitCrowd(context, arm, fields, 65535 / field_count + 1);
            }).find("fields a crowd can hold"),
            std::string::npos);

  ImplicitCrowd crowd(context, arm, fields, 2);
  EXPECT_NE(message([&] {
              Matrix3Xf out;
              crowd.readPositions(out);
            }).find("before run()"),
            std::string::npos);
  const TransformList pose = test::clipPoses(arm, 2).back();
  EXPECT_NE(message([&] {
              crowd.run({pose});
            }).find("1 poses given for a crowd of 2 instances"),
            std::string::npos);
  TransformList short_pose(pose.begin(), pose.end() - 1);
  EXPECT_NE(message([&] {
              crowd.run({pose, short_pose});
            }).find("instance 1:"),
            std::string::npos);
  TransformList bad = pose;
  bad[1].matrix()(0, 3) = std::numeric_limits<float>::quiet_NaN();
  const std::string nan = message([&] { crowd.run({bad, pose}); });
  EXPECT_NE(nan.find("instance 0: the transform of joint 1"), std::string::npos)
      << nan;
  EXPECT_NE(nan.find(arm.skeleton.joints[1].name), std::string::npos) << nan;
  // A good frame after the errors.
  crowd.run({pose, pose});
  Matrix3Xf positions;
  crowd.readPositions(positions);
  EXPECT_TRUE(positions.allFinite());
  ImplicitCrowd moved = std::move(crowd);
  EXPECT_NE(message([&] {
              crowd.run({pose, pose});
            }).find("moved from"),
            std::string::npos);
  moved.readPositions(positions);
  EXPECT_EQ(positions.rows(), 2 * arm.mesh.vertexCount());

  // Several characters: each error names the character or the instance.
  const SmallCylinder& small = smallCylinder();
  EXPECT_NE(
      message([&] {
        ImplicitCrowd(context, {{&arm, fields, 1}, {&arm, small.fields, 1}});
      }).find("character 1: the fields hold"),
      std::string::npos);
  EXPECT_NE(message([&] {
              ImplicitCrowd(context,
                            {{&arm, fields, 1}, {&small.rig, small.fields, 0}});
            }).find("character 1: 0 instances"),
            std::string::npos);
  EXPECT_NE(
      message([&] {
        ImplicitCrowd(context, {{&arm, fields, 1}, {nullptr, small.fields, 1}});
      }).find("character 1: no rig"),
      std::string::npos);
  EXPECT_NE(message([&] {
              ImplicitCrowd(context, std::vector<CrowdCharacter>{});
            }).find("no characters"),
            std::string::npos);
  ImplicitFieldsOptions coarse;
  coarse.grid_resolution = 16;
  const auto small16 = std::make_shared<const ImplicitFields>(
      buildImplicitFields(small.rig, coarse));
  EXPECT_NE(
      message([&] {
        ImplicitCrowd(context, {{&arm, fields, 1}, {&small.rig, small16, 1}});
      }).find("character 1: its grids have 16 nodes per axis"),
      std::string::npos);
  // The cylinder has other joints than the arm.
  const Rig& other = test::rigNamed("cylinder");
  ASSERT_NE(other.skeleton.jointCount(), arm.skeleton.jointCount());
  ImplicitCrowd mixed(
      context, {{&arm, fields, 1}, {&other, sharedFields("cylinder"), 2}});
  const TransformList other_pose = test::clipPoses(other, 2).back();
  const std::string wrong = message([&] {
    mixed.run({pose, other_pose, pose});
  });
  EXPECT_NE(wrong.find("instance 2: " + std::to_string(pose.size()) +
                       " joint transforms given for a skeleton of " +
                       std::to_string(other_pose.size()) + " joints"),
            std::string::npos)
      << wrong;
  EXPECT_NE(
      message([&] { mixed.characterOf(3); }).find("instance 3 of a crowd of 3"),
      std::string::npos);
  EXPECT_NE(message([&] {
              mixed.vertexCount(2);
            }).find("character 2 of a crowd of 2"),
            std::string::npos);
  mixed.run({pose, other_pose, other_pose});
  mixed.readPositions(positions);
  EXPECT_EQ(positions.rows(),
            arm.mesh.vertexCount() + 2 * other.mesh.vertexCount());
  EXPECT_TRUE(positions.allFinite());
}

}  // namespace
}  // namespace isk
