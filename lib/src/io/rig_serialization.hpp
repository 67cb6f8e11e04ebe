// A Rig as a flat byte string and back: how an import run in a child process
// (import_isolation.cpp) hands its result to the application.
#pragma once

#include <string>

#include "isk/rig/rig.hpp"

namespace isk::detail {

// Every field of `rig`, in a layout private to this build of the library.
std::string serializeRig(const Rig& rig);

// The inverse of serializeRig. Throws isk::Error(kInternal) naming the field
// when `bytes` is truncated or a count does not fit the remaining bytes.
Rig deserializeRig(const std::string& bytes);

}  // namespace isk::detail
