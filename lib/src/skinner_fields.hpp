// The fields a skinner builds for itself when it is given none, and its
// tracking mesh (ImplicitSkinner, CpuImplicitSkinner, ImplicitCrowd).
#pragma once

#include <memory>

#include "isk/implicit_skinner.hpp"
#include "isk/tracking/dislocation.hpp"

namespace isk::detail {

// Validates `options` first (isk::Error kInvalidArgument naming the bad
// option), so that a bad option is reported before a long fit.
inline std::shared_ptr<const ImplicitFields> buildSkinnerFields(
    const Rig& rig, const ImplicitSkinnerOptions& options) {
  options.validate().throwIfFailed("ImplicitSkinnerOptions");
  return std::make_shared<const ImplicitFields>(
      buildImplicitFields(rig, options.fields));
}

// TrackingMesh::build, with the dislocation guard's candidates from the
// rig's weights (and the rest creases they blend dropped).
inline TrackingMesh buildSkinnerTrackingMesh(const Rig& rig,
                                             const ImplicitFields& fields) {
  TrackingMesh mesh = TrackingMesh::build(rig.mesh, fields);
  mesh.dislocation_candidates =
      dislocationCandidates(rig, fields.partition, mesh.rings.representative);
  dropBlendedRestCreases(&mesh);
  return mesh;
}

}  // namespace isk::detail
