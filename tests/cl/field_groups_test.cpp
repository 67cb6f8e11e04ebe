// The host-only preparation of ClFieldEvaluation's device data
// (lib/src/cl/field_groups.hpp): field groups checked and merged, and the
// fields' static parameters; no device.
#include "cl/field_groups.hpp"

#include <gtest/gtest.h>

#include <memory>

#include "isk/core/error.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using Group = ClFieldEvaluation::FieldGroup;

// A composition over `fields` with one blended pair on `table`, so that
// merging can be checked for offsets and for each table stored once.
Composition blendedComposition(const FieldGridSet& fields,
                               std::shared_ptr<const OperatorTable> table) {
  Composition c;
  c.table_resolution = table->resolution;
  c.tables = {table};
  c.controllers.resize(1);
  c.controllers[0].theta.assign(kControllerSamples, 0.5f);
  FieldPair p;
  p.joint = fields.grids.back().joint;
  p.field_a = 0;
  p.field_b = fields.fieldCount() - 1;
  p.op = CompositionOperator::kBlend;
  p.controller = 0;
  p.table = 0;
  c.pairs = {p};
  c.blended_pairs = {0};
  return c;
}

TEST(FieldGroups, MergeOffsetsJointsFieldsPairsAndSharesTables) {
  const Rig& arm = test::rigNamed("arm");
  const Rig& cylinder = test::rigNamed("cylinder");
  const FieldGridSet& a = test::implicitFieldsOf("arm").grids;
  const FieldGridSet& c = test::implicitFieldsOf("cylinder").grids;
  ASSERT_GE(a.fieldCount(), 2);
  ASSERT_GE(c.fieldCount(), 2);
  auto table = std::make_shared<OperatorTable>();
  table->resolution = 2;
  table->nodes.assign(4 * 8, 0.f);
  const Composition ca = blendedComposition(a, table);
  const Composition cc = blendedComposition(c, table);
  const int ja = arm.skeleton.jointCount(), jc = cylinder.skeleton.jointCount();
  const std::vector<Group> groups = {{&a, ja, &ca, 2}, {&c, jc, &cc, 1}};

  const detail::FieldGroupTotals totals = detail::checkFieldGroups(groups);
  EXPECT_EQ(totals.grids, a.fieldCount() + c.fieldCount());
  EXPECT_EQ(totals.fields, 2 * a.fieldCount() + c.fieldCount());
  EXPECT_EQ(totals.joints, 2 * ja + jc);
  EXPECT_EQ(totals.table_resolution, 2);

  const detail::MergedFieldGroups merged =
      detail::mergeFieldGroups(groups, totals.fields);
  // Each group's grids once; the instances sample their group's grids.
  ASSERT_EQ(static_cast<int>(merged.stored.size()), totals.grids);
  EXPECT_EQ(merged.stored[0], &a.grids[0]);
  EXPECT_EQ(merged.stored[a.fieldCount()], &c.grids[0]);
  ASSERT_EQ(static_cast<int>(merged.grid_of_field.size()), totals.fields);
  EXPECT_EQ(merged.grid_of_field[a.fieldCount()], 0);  // arm, instance 1
  EXPECT_EQ(merged.grid_of_field[2 * a.fieldCount()], a.fieldCount());
  // Instance 1 of the arm follows the arm's joints; the cylinder both arms.
  ASSERT_EQ(static_cast<int>(merged.layout.grids.size()), totals.fields);
  EXPECT_EQ(merged.layout.grids[a.fieldCount()].joint, a.grids[0].joint + ja);
  EXPECT_EQ(merged.layout.grids[2 * a.fieldCount()].joint,
            c.grids[0].joint + 2 * ja);
  EXPECT_TRUE(merged.layout.grids[0].nodes.empty());  // no nodes copied
  EXPECT_EQ(static_cast<int>(merged.layout.field_of_joint.size()),
            totals.joints);
  // Pairs: one per instance, fields and controllers offset, one table.
  ASSERT_EQ(merged.composition_layout.pairs.size(), 3u);
  EXPECT_EQ(merged.composition_layout.pairs[1].field_a, a.fieldCount());
  EXPECT_EQ(merged.composition_layout.pairs[2].field_b,
            2 * a.fieldCount() + c.fieldCount() - 1);
  EXPECT_EQ(merged.composition_layout.pairs[2].controller, 1);
  EXPECT_EQ(merged.composition_layout.blended_pairs,
            (std::vector<int>{0, 1, 2}));
  EXPECT_TRUE(merged.any_composition);
  EXPECT_EQ(merged.merged.tables.size(), 1u);
  EXPECT_EQ(merged.merged.controllers.size(), 2u);
}

TEST(FieldGroups, CheckNamesTheCharacterThatDoesNotFit) {
  const FieldGridSet& a = test::implicitFieldsOf("arm").grids;
  const int ja = test::rigNamed("arm").skeleton.jointCount();
  FieldGridSet coarse = a;
  coarse.resolution = a.resolution / 2;
  for (FieldGrid& g : coarse.grids) {
    g.resolution = coarse.resolution;
    g.nodes.assign(4 * static_cast<size_t>(coarse.resolution) *
                       coarse.resolution * coarse.resolution,
                   0.f);
  }
  try {
    detail::checkFieldGroups({{&a, ja, nullptr, 1}, {&coarse, ja, nullptr, 1}});
    FAIL() << "grids of two resolutions accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("character 1: its grids have"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(detail::checkFieldGroups({}), Error);
  EXPECT_THROW(detail::checkFieldGroups({{&a, ja, nullptr, 0}}), Error);
}

TEST(FieldGroups, StaticParamsHoldBoxSpacingGridAndTile) {
  const FieldGridSet& a = test::implicitFieldsOf("arm").grids;
  std::vector<const FieldGrid*> stored;
  for (const FieldGrid& g : a.grids) stored.push_back(&g);
  const std::vector<int> grid_of_field = {1, 0};
  const int tiles[3] = {2, 1, 1};
  for (const bool image : {false, true}) {
    const std::vector<float> p = detail::staticFieldParams(
        stored, grid_of_field, a.resolution, tiles, image);
    const size_t stride = ClFieldEvaluation::kParamStride * 4;
    ASSERT_EQ(p.size(), 2 * stride);
    const FieldGrid& g = a.grids[1];  // field 0 samples grid 1
    EXPECT_EQ(p[12], g.box_min.x());
    EXPECT_EQ(p[16], 1.f / g.spacing().x());
    EXPECT_EQ(p[15], 1.f);
    EXPECT_EQ(p[19], static_cast<float>(a.resolution - 1));
    // Grid 1 is tile (1, 0, 0) of a 2 x 1 x 1 atlas; the buffer has none.
    EXPECT_EQ(p[20], image ? a.resolution + 0.5f : 0.f);
    EXPECT_EQ(p[stride + 15], 0.f);
  }
}

}  // namespace
}  // namespace isk
