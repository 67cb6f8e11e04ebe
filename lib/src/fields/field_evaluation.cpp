#include "isk/fields/field_evaluation.hpp"

#include <algorithm>
#include <string>

#include "isk/core/error.hpp"

namespace isk {

std::vector<Eigen::Affine3f> fieldTransforms(const FieldGridSet& fields,
                                             const TransformList& skinning) {
  std::vector<Eigen::Affine3f> out;
  out.reserve(fields.grids.size());
  for (const FieldGrid& grid : fields.grids) {
    const Eigen::Affine3f bone_to_posed =
        skinning[grid.joint] * Eigen::Affine3f(grid.bone_to_model.matrix());
    out.push_back(bone_to_posed.inverse(Eigen::Affine));
  }
  return out;
}

std::vector<Eigen::Vector4f> posedFieldSpheres(
    const FieldGridSet& fields, const std::vector<Eigen::Affine3f>& to_bone) {
  std::vector<Eigen::Vector4f> out;
  out.reserve(fields.grids.size());
  for (size_t i = 0; i < fields.grids.size(); ++i) {
    const Eigen::Vector4f sphere = fieldBoundingSphere(fields.grids[i]);
    const Eigen::Affine3f to_model = to_bone[i].inverse(Eigen::Affine);
    const Eigen::Vector3f centre = to_model * sphere.head<3>();
    // The largest stretch of the linear part (1 for a rigid pose).
    const float stretch =
        to_model.linear().jacobiSvd().singularValues()[0] * 1.0001f;
    const float radius = sphere[3] * stretch;
    out.emplace_back(centre.x(), centre.y(), centre.z(), radius * radius);
  }
  return out;
}

Validation FieldEvaluationJob::validate() const {
  if (!fields) return Validation::fail("no field set");
  if (!skinning) return Validation::fail("no skinning transforms");
  if (!points) return Validation::fail("no points");
  if (!out_composed)
    return Validation::fail("no output for the composed field");
  for (size_t i = 0; i < fields->grids.size(); ++i) {
    const FieldGrid& g = fields->grids[i];
    if (g.joint < 0 || g.joint >= static_cast<int>(skinning->size()))
      return Validation::fail("field " + std::to_string(i) +
                              " belongs to joint " + std::to_string(g.joint) +
                              " but only " + std::to_string(skinning->size()) +
                              " skinning transforms were given");
    const size_t n = static_cast<size_t>(g.resolution);
    if (g.resolution < 2 || g.nodes.size() != 4 * n * n * n)
      return Validation::fail("field " + std::to_string(i) +
                              " has a malformed grid");
  }
  if (composition) {
    for (const FieldPair& p : composition->pairs)
      if (p.field_a < 0 || p.field_b < 0 || p.field_a >= fields->fieldCount() ||
          p.field_b >= fields->fieldCount())
        return Validation::fail(
            "the composition pairs fields " + std::to_string(p.field_a) +
            " and " + std::to_string(p.field_b) + " but the set has " +
            std::to_string(fields->fieldCount()) +
            " (built for other fields?)");
    for (int k : composition->blended_pairs) {
      const FieldPair& p = composition->pairs.at(k);
      if (p.controller < 0 ||
          p.controller >= static_cast<int>(composition->controllers.size()) ||
          p.table < 0 ||
          p.table >= static_cast<int>(composition->tables.size()) ||
          !composition->tables[p.table])
        return Validation::fail("the composition's pair at joint " +
                                std::to_string(p.joint) +
                                " has no controller or table");
    }
  }
  for (size_t j = 0; j < skinning->size(); ++j)
    if (!(*skinning)[j].matrix().allFinite())
      return Validation::fail("skinning transform " + std::to_string(j) +
                              " is not finite");
  return Validation::ok();
}

ComposedFieldSampler::ComposedFieldSampler(const FieldGridSet& fields,
                                           const TransformList& skinning,
                                           const Composition* composition)
    : fields_(&fields),
      composition_(composition),
      to_bone_(fieldTransforms(fields, skinning)),
      spheres_(posedFieldSpheres(fields, to_bone_)),
      joint_angles_(composition
                        ? pairJointAngles(*composition, fields, skinning)
                        : std::vector<float>()) {}

Eigen::Vector4f ComposedFieldSampler::sample(const Eigen::Vector3f& x,
                                             Eigen::Vector4f* per_field) const {
  const int field_count = fields_->fieldCount();
  // Per-field samples are needed by the pairs; small stack buffer first.
  Eigen::Vector4f local_samples[64];
  std::vector<Eigen::Vector4f> heap_samples;
  Eigen::Vector4f* samples = per_field;
  if (!samples) {
    if (field_count <= 64) {
      samples = local_samples;
    } else {
      heap_samples.resize(field_count);
      samples = heap_samples.data();
    }
  }
  Eigen::Vector4f best = Eigen::Vector4f::Zero();
  for (int i = 0; i < field_count; ++i) {
    samples[i] = sampleField(i, x);
    if (samples[i][0] > best[0]) best = samples[i];  // union: first on ties
  }
  return composePairs(samples, best);
}

Eigen::Vector4f ComposedFieldSampler::sampleSubset(
    const Eigen::Vector3f& x, const int* subset, int subset_count, int mask,
    Eigen::Vector4f* per_field) const {
  std::fill(per_field, per_field + fields_->fieldCount(),
            Eigen::Vector4f::Zero());
  Eigen::Vector4f best = Eigen::Vector4f::Zero();
  for (int n = 0; n < subset_count; ++n) {
    const int i = subset[n] & mask;
    per_field[i] = sampleField(i, x);
    if (per_field[i][0] > best[0]) best = per_field[i];
  }
  return composePairs(per_field, best);
}

bool ComposedFieldSampler::insideBox(int i, const Eigen::Vector3f& x) const {
  const FieldGrid& grid = fields_->grids[i];
  const Eigen::Vector3f u =
      (to_bone_[i] * x - grid.box_min).cwiseQuotient(grid.spacing());
  const float last = static_cast<float>(grid.resolution - 1);
  return u.x() >= 0 && u.y() >= 0 && u.z() >= 0 && u.x() <= last &&
         u.y() <= last && u.z() <= last;
}

Eigen::Vector4f ComposedFieldSampler::sampleField(
    int i, const Eigen::Vector3f& x) const {
  // Broad phase: a point outside the sphere is outside the support box.
  if (!((x - spheres_[i].head<3>()).squaredNorm() <= spheres_[i][3]))
    return Eigen::Vector4f::Zero();
  const Eigen::Vector4f local = fields_->grids[i].sampleLocal(to_bone_[i] * x);
  // Gradient back to model space: transpose of the inverse's linear part.
  Eigen::Vector4f sample;
  sample[0] = local[0];
  sample.tail<3>() = to_bone_[i].linear().transpose() * local.tail<3>();
  return sample;
}

Eigen::Vector4f ComposedFieldSampler::composePairs(
    const Eigen::Vector4f* samples, Eigen::Vector4f best) const {
  if (!composition_) return best;
  for (size_t n = 0; n < joint_angles_.size(); ++n) {
    const FieldPair& pair = composition_->pairs[composition_->blended_pairs[n]];
    const Eigen::Vector4f& a = samples[pair.field_a];
    const Eigen::Vector4f& b = samples[pair.field_b];
    if (!(a[0] > 0.f && b[0] > 0.f)) continue;  // max(a, b) already in
    const Eigen::Vector4f g =
        composePair(*composition_, pair, a, b, joint_angles_[n]);
    if (g[0] > best[0]) best = g;
  }
  return best;
}

void FieldEvaluationJob::run() const {
  validate().throwIfFailed("FieldEvaluationJob");
  const ComposedFieldSampler sampler(*fields, *skinning, composition);
  const int field_count = fields->fieldCount();
  const int point_count = static_cast<int>(points->rows());
  out_composed->resize(point_count, 4);
  if (out_per_field)
    out_per_field->resize(static_cast<Eigen::Index>(point_count) * field_count,
                          4);
  std::vector<Eigen::Vector4f> samples(field_count);
  for (int p = 0; p < point_count; ++p) {
    const Eigen::Vector3f x = points->row(p).transpose();
    const Eigen::Vector4f best =
        sampler.sample(x, out_per_field ? samples.data() : nullptr);
    if (out_per_field)
      for (int i = 0; i < field_count; ++i)
        out_per_field->row(static_cast<Eigen::Index>(p) * field_count + i) =
            samples[i].transpose();
    out_composed->row(p) = best.transpose();
  }
}

Matrix4Xf evaluateComposedField(const FieldGridSet& fields,
                                const TransformList& skinning,
                                const Matrix3Xf& points,
                                const Composition* composition) {
  Matrix4Xf composed;
  FieldEvaluationJob job;
  job.fields = &fields;
  job.skinning = &skinning;
  job.points = &points;
  job.composition = composition;
  job.out_composed = &composed;
  job.run();
  return composed;
}

std::vector<float> computeIsoValues(const FieldGridSet& fields,
                                    const Matrix3Xf& rest_positions,
                                    const Composition* composition,
                                    std::vector<int>* outside) {
  int joint_count = 0;
  for (const auto& g : fields.grids)
    joint_count = std::max(joint_count, g.joint + 1);
  const TransformList identity(joint_count, Eigen::Affine3f::Identity());
  const Matrix4Xf composed =
      evaluateComposedField(fields, identity, rest_positions, composition);
  std::vector<float> iso(composed.rows());
  if (outside) outside->clear();
  for (Eigen::Index v = 0; v < composed.rows(); ++v) {
    iso[v] = composed(v, 0);
    if (outside && !(iso[v] > 0)) outside->push_back(static_cast<int>(v));
  }
  return iso;
}

}  // namespace isk
