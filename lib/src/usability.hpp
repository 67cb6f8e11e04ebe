// One rule for when a runtime object's calls may run, and one wording for
// the errors: the skinners, the crowd and both trackings use it.
#pragma once

#include <string>

#include "isk/core/error.hpp"

namespace isk::detail {

// `owner`::`what` on an object that was moved from (`holds_rig` false: it
// holds nothing), or before its first run() when the call reads a frame
// (`needs_run`). Throws isk::Error(kInvalidArgument) naming the call.
inline void checkUsable(const char* owner, const char* noun, const char* what,
                        bool holds_rig, bool needs_run, bool has_run) {
  if (!holds_rig)
    throw Error(ErrorCode::kInvalidArgument,
                std::string(owner) + "::" + what + ": the " + noun +
                    " was moved from (it holds no rig)");
  if (needs_run && !has_run)
    throw Error(ErrorCode::kInvalidArgument,
                std::string(owner) + "::" + what +
                    " before run(): there is no frame yet");
}

// A tracking stage before the frame's begin().
inline void checkBegun(const char* owner, const char* stage, bool begun) {
  if (!begun)
    throw Error(ErrorCode::kInvalidArgument,
                std::string(owner) + "::" + stage +
                    " before begin(): no frame has been started (no pose, "
                    "no positions)");
}

}  // namespace isk::detail
