#include "cl/field_groups.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>

#include "isk/core/error.hpp"

namespace isk::detail {

[[noreturn]] void invalid(const std::string& message) {
  throw Error(ErrorCode::kInvalidArgument, "ClFieldEvaluation: " + message);
}

void validateFields(const FieldGridSet& fields, int joint_count) {
  if (joint_count < 0) invalid("joint_count is " + std::to_string(joint_count));
  const int n = fields.resolution;
  if (n < 2)
    invalid("the field set's resolution is " + std::to_string(n) +
            ", a grid needs at least 2 nodes per axis");
  const size_t nodes = 4 * static_cast<size_t>(n) * n * n;
  for (size_t i = 0; i < fields.grids.size(); ++i) {
    const FieldGrid& g = fields.grids[i];
    const std::string field = "field " + std::to_string(i);
    if (g.joint < 0 || g.joint >= joint_count)
      invalid(field + " belongs to joint " + std::to_string(g.joint) +
              " but the skeleton has " + std::to_string(joint_count) +
              " joints");
    if (g.resolution != n)
      invalid(field + " has " + std::to_string(g.resolution) +
              " nodes per axis but the set has " + std::to_string(n) +
              " (every field of a set shares one resolution)");
    if (g.nodes.size() != nodes)
      invalid(field + " holds " + std::to_string(g.nodes.size()) + " floats, " +
              std::to_string(nodes) + " expected (4 per node)");
    if (!g.bone_to_model.matrix().allFinite())
      invalid(field + " has a non-finite bone frame");
    if (!g.box_min.allFinite() || !g.box_max.allFinite() ||
        !(g.box_max.array() > g.box_min.array()).all())
      invalid(field + " has an empty or non-finite support box");
    for (size_t k = 0; k < g.nodes.size(); ++k)
      if (!std::isfinite(g.nodes[k]))
        invalid(field + " node " + std::to_string(k / 4) + " is not finite");
    // Stored as halves, the nodes must be halves already, or the device
    // would sample other values than the reference.
    if (fields.precision == GridPrecision::kHalf)
      for (size_t k = 0; k < g.nodes.size(); ++k)
        if (static_cast<float>(Eigen::half(g.nodes[k])) != g.nodes[k])
          invalid(field + " node " + std::to_string(k / 4) + " holds " +
                  std::to_string(g.nodes[k]) +
                  ", not a half-precision value, in a set marked kHalf "
                  "(round it with roundGridsToHalf)");
  }
}

void validateComposition(const Composition& composition, int field_count) {
  for (const FieldPair& p : composition.pairs)
    if (p.field_a < 0 || p.field_b < 0 || p.field_a >= field_count ||
        p.field_b >= field_count)
      invalid("the composition's pair at joint " + std::to_string(p.joint) +
              " pairs fields " + std::to_string(p.field_a) + " and " +
              std::to_string(p.field_b) + " but the set has " +
              std::to_string(field_count) + " (built for other fields?)");
  const int n = composition.table_resolution;
  for (size_t t = 0; t < composition.tables.size(); ++t) {
    const auto& table = composition.tables[t];
    if (!table || table->resolution != n ||
        table->nodes.size() != 4 * static_cast<size_t>(n) * n * n)
      invalid("operator table " + std::to_string(t) + " is missing or not " +
              std::to_string(n) + "^3 float4");
  }
  for (int k : composition.blended_pairs) {
    const FieldPair& p = composition.pairs.at(k);
    if (p.table < 0 || p.table >= static_cast<int>(composition.tables.size()))
      invalid("the pair at joint " + std::to_string(p.joint) +
              " has no operator table");
    if (p.controller < 0 ||
        p.controller >= static_cast<int>(composition.controllers.size()) ||
        composition.controllers[p.controller].theta.size() !=
            static_cast<size_t>(kControllerSamples))
      invalid("the pair at joint " + std::to_string(p.joint) + " has no " +
              std::to_string(kControllerSamples) + "-sample controller");
  }
}

FieldGroupTotals checkFieldGroups(
    const std::vector<ClFieldEvaluation::FieldGroup>& groups) {
  if (groups.empty()) invalid("no field groups");
  // A message about group g: "character g: " first when there are several.
  auto where = [&](size_t g) {
    return groups.size() > 1 ? "character " + std::to_string(g) + ": "
                             : std::string();
  };
  const FieldGridSet* first = groups[0].fields;
  long long fields_total = 0, joints_total = 0, grids_total = 0;
  int table_resolution = 0;
  for (size_t g = 0; g < groups.size(); ++g) {
    const ClFieldEvaluation::FieldGroup& group = groups[g];
    if (!group.fields) invalid(where(g) + "no field set");
    if (group.instances < 1)
      invalid(where(g) + std::to_string(group.instances) +
              " instances, expected at least 1");
    const int count = group.fields->fieldCount();
    if (static_cast<long long>(count) * group.instances > (1 << 24) ||
        static_cast<long long>(std::max(group.joint_count, 1)) *
                group.instances >
            std::numeric_limits<int>::max())
      invalid(where(g) + std::to_string(group.instances) + " instances of " +
              std::to_string(count) + " fields and " +
              std::to_string(group.joint_count) + " joints are too many");
    try {
      validateFields(*group.fields, group.joint_count);
      if (group.composition) validateComposition(*group.composition, count);
    } catch (const Error& e) {
      if (groups.size() == 1) throw;
      // invalid()'s prefix, then which character.
      const std::string prefix = "ClFieldEvaluation: ";
      std::string message = e.what();
      if (message.rfind(prefix, 0) == 0) message.erase(0, prefix.size());
      invalid(where(g) + message);
    }
    // One resolution and precision for every grid (the kernels' arguments),
    // one for every operator table.
    if (group.fields->resolution != first->resolution)
      invalid(where(g) + "its grids have " +
              std::to_string(group.fields->resolution) +
              " nodes per axis, character 0's " +
              std::to_string(first->resolution) +
              " (a crowd shares one grid resolution)");
    if (group.fields->precision != first->precision)
      invalid(where(g) +
              "its grids' precision differs from character 0's "
              "(a crowd shares one grid precision)");
    if (group.composition && !group.composition->tables.empty()) {
      if (table_resolution == 0)
        table_resolution = group.composition->table_resolution;
      else if (group.composition->table_resolution != table_resolution)
        invalid(where(g) + "its operator tables have " +
                std::to_string(group.composition->table_resolution) +
                " nodes per axis, another character's " +
                std::to_string(table_resolution) +
                " (a crowd shares one table resolution)");
    }
    grids_total += count;
    fields_total += static_cast<long long>(count) * group.instances;
    joints_total += static_cast<long long>(group.joint_count) * group.instances;
  }
  if (fields_total > (1 << 24) ||
      joints_total > std::numeric_limits<int>::max())
    invalid(std::to_string(fields_total) + " fields and " +
            std::to_string(joints_total) + " joints in all are too many");
  FieldGroupTotals totals;
  totals.grids = static_cast<int>(grids_total);
  totals.fields = static_cast<int>(fields_total);
  totals.joints = static_cast<int>(joints_total);
  totals.table_resolution = table_resolution;
  return totals;
}

MergedFieldGroups mergeFieldGroups(
    const std::vector<ClFieldEvaluation::FieldGroup>& groups, int field_count) {
  MergedFieldGroups out;
  int joint_offset = 0, field_offset = 0;
  out.layout.grids.reserve(static_cast<size_t>(field_count));
  for (const ClFieldEvaluation::FieldGroup& group : groups) {
    const FieldGridSet& fields = *group.fields;
    const int grid_offset = static_cast<int>(out.stored.size());
    for (const FieldGrid& g : fields.grids) out.stored.push_back(&g);
    const Composition* composition = group.composition;
    const int controller_offset =
        static_cast<int>(out.merged.controllers.size());
    // The group's table t is merged table table_index[t]: a table shared by
    // several characters (sharedOperatorTable bakes each kind once) is
    // stored once.
    std::vector<int> table_index;
    if (composition) {
      out.any_composition = true;
      for (const auto& table : composition->tables) {
        const auto same = std::find(out.merged.tables.begin(),
                                    out.merged.tables.end(), table);
        table_index.push_back(
            static_cast<int>(same - out.merged.tables.begin()));
        if (same == out.merged.tables.end()) out.merged.tables.push_back(table);
      }
      out.merged.controllers.insert(out.merged.controllers.end(),
                                    composition->controllers.begin(),
                                    composition->controllers.end());
    }
    const int count = fields.fieldCount();
    for (int k = 0; k < group.instances; ++k) {
      for (const int f : fields.field_of_joint)
        out.layout.field_of_joint.push_back(f < 0 ? f : f + field_offset);
      for (int i = 0; i < count; ++i) {
        const FieldGrid& g = fields.grids[i];
        FieldGrid meta;
        meta.joint = g.joint + joint_offset;
        meta.resolution = g.resolution;
        meta.bone_to_model = g.bone_to_model;
        meta.box_min = g.box_min;
        meta.box_max = g.box_max;
        out.layout.grids.push_back(std::move(meta));
        out.grid_of_field.push_back(grid_offset + i);
      }
      if (composition) {
        const int pair_offset =
            static_cast<int>(out.composition_layout.pairs.size());
        for (FieldPair p : composition->pairs) {
          p.joint += joint_offset;
          p.field_a += field_offset;
          p.field_b += field_offset;
          if (p.table >= 0) p.table = table_index[p.table];
          if (p.controller >= 0) p.controller += controller_offset;
          out.composition_layout.pairs.push_back(p);
        }
        for (const int b : composition->blended_pairs)
          out.composition_layout.blended_pairs.push_back(b + pair_offset);
      }
      joint_offset += group.joint_count;
      field_offset += count;
    }
  }
  return out;
}

std::vector<float> staticFieldParams(
    const std::vector<const FieldGrid*>& stored,
    const std::vector<int>& grid_of_field, int resolution, const int tiles[3],
    bool image) {
  const int field_count = static_cast<int>(grid_of_field.size());
  const size_t stride = ClFieldEvaluation::kParamStride * 4;
  std::vector<float> params(
      static_cast<size_t>(std::max(field_count, 1)) * stride, 0.f);
  for (int f = 0; f < field_count; ++f) {
    const int i = grid_of_field[f];  // the grid it samples
    const FieldGrid& g = *stored[i];
    float* p = &params[static_cast<size_t>(f) * stride];
    const Eigen::Vector3f spacing = g.spacing();
    for (int a = 0; a < 3; ++a) {
      p[12 + a] = g.box_min[a];
      p[16 + a] = 1.f / spacing[a];
    }
    p[15] = static_cast<float>(i);  // exact: at most 2^24 grids
    p[19] = static_cast<float>(resolution - 1);
    const int tile[3] = {i % tiles[0], (i / tiles[0]) % tiles[1],
                         i / (tiles[0] * tiles[1])};
    for (int a = 0; a < 3; ++a)
      p[20 + a] = image ? static_cast<float>(tile[a] * resolution) + 0.5f : 0.f;
  }
  return params;
}

}  // namespace isk::detail
