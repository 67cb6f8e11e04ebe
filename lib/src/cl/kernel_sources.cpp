#include "cl/kernel_sources.hpp"

#include <string>

#include "isk/cl/runtime.hpp"
#include "isk/core/error.hpp"

namespace isk {

std::vector<std::string> embeddedKernelNames() {
  std::vector<std::string> names;
  for (const auto& source : detail::embeddedKernelSources()) {
    names.emplace_back(source.name);
  }
  return names;
}

std::string embeddedKernelSource(const std::string& kernel_file) {
  for (const auto& source : detail::embeddedKernelSources()) {
    if (source.name == kernel_file) return std::string(source.text);
  }
  throw Error(ErrorCode::kInvalidArgument,
              "no embedded kernel file '" + kernel_file + ".cl'");
}

}  // namespace isk
