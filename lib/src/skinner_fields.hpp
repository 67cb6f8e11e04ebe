// The fields a skinner builds for itself when it is given none
// (ImplicitSkinner, CpuImplicitSkinner, ImplicitCrowd).
#pragma once

#include <memory>

#include "isk/implicit_skinner.hpp"

namespace isk::detail {

// Validates `options` first (isk::Error kInvalidArgument naming the bad
// option), so that a bad option is reported before a long fit.
inline std::shared_ptr<const ImplicitFields> buildSkinnerFields(
    const Rig& rig, const ImplicitSkinnerOptions& options) {
  options.validate().throwIfFailed("ImplicitSkinnerOptions");
  return std::make_shared<const ImplicitFields>(
      buildImplicitFields(rig, options.fields));
}

}  // namespace isk::detail
