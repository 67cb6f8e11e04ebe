// Host-only preparation of ClFieldEvaluation's device data: the field
// groups (one per character of a crowd) checked and merged into one list of
// fields, and the fields' static parameters; no device needed, so that each
// step can be tested on its own.
#pragma once

#include <string>
#include <vector>

#include "isk/cl/field_evaluation.hpp"

namespace isk::detail {

// Throws isk::Error(kInvalidArgument) with "ClFieldEvaluation: " + message.
[[noreturn]] void invalid(const std::string& message);

// Checks one character's grids against its skeleton's joint count and its
// composition against its fields (isk::Error kInvalidArgument naming the
// field, pair or table).
void validateFields(const FieldGridSet& fields, int joint_count);
void validateComposition(const Composition& composition, int field_count);

// What the groups hold in all, after every check: grids (each group's once),
// fields and joints (every instance), the operator tables' resolution (0
// without tables).
struct FieldGroupTotals {
  int grids = 0, fields = 0, joints = 0, table_resolution = 0;
};
// Each group checked (validateFields, validateComposition, its instances),
// and the groups against each other: one grid resolution and precision, one
// table resolution. Messages name the character ("character g: ") when
// there are several.
FieldGroupTotals checkFieldGroups(
    const std::vector<ClFieldEvaluation::FieldGroup>& groups);

// Every group's instances one after the other: instance k of group g
// follows joint joint_offset + k * joint_count + j, its field i samples grid
// grid_offset + i, its pairs use the group's tables and controllers.
struct MergedFieldGroups {
  std::vector<const FieldGrid*> stored;  // the grids, each once
  std::vector<int> grid_of_field;        // per field: its index in `stored`
  Composition merged;  // every group's controllers and tables (each once)
  bool any_composition = false;
  // The fields without their nodes (joints, frames, boxes), field_of_joint.
  FieldGridSet layout;
  Composition composition_layout;  // the pairs, without tables
};
MergedFieldGroups mergeFieldGroups(
    const std::vector<ClFieldEvaluation::FieldGroup>& groups, int field_count);

// ClFieldEvaluation::kParamStride float4 per field (kernels/fields/sample.cl's
// layout) without the per-pose rows: box, spacing, grid index, image tile.
std::vector<float> staticFieldParams(
    const std::vector<const FieldGrid*>& stored,
    const std::vector<int>& grid_of_field, int resolution, const int tiles[3],
    bool image);

}  // namespace isk::detail
